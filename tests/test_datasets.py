"""vcnc-datasets (vcnc_bench/datasets.py) and behaviour cloning (agents/behaviour_cloning.py).

A tiny dataset (300 decision steps of the heart, one plant) is written with Minari, read back with
``minari.load_dataset``, and checked against the same policy's episode through
:func:`vcnc_gym.evaluation.run_episode` on a single env (not the vector batch the dataset is collected on).
"""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest

pytest.importorskip("minari")
pytest.importorskip("torch")

import minari  # noqa: E402

import vcnc_gym  # noqa: E402,F401
from vcnc_baselines.registry import make  # noqa: E402
from vcnc_bench import datasets  # noqa: E402
from vcnc_bench.score import normalised_score  # noqa: E402
from vcnc_gym.evaluation import run_episode  # noqa: E402

ENV = "VCNC-Heart-v1"
KWARGS = {"max_episode_steps": 300}
#: The references' returns (and max contour errors, um) a tiny dataset is written with.
SCORES = {"pd-ref": {"return": -3.0e4, "max_um": 42.0}, "oracle": {"return": -900.0, "max_um": 1.25}}


class _Recorder(gym.Wrapper):
    """Keeps every observation and action of the episodes run through it."""

    def reset(self, **kw):
        obs, info = self.env.reset(**kw)
        self.obs, self.act = [obs], []
        return obs, info

    def step(self, action):
        self.act.append(np.array(action, dtype=np.float32))
        out = self.env.step(action)
        self.obs.append(out[0])
        return out


@pytest.fixture(scope="module")
def tiny(tmp_path_factory):
    """The pd-ref dataset of 300 heart steps on the nominal plant, written to a temporary folder."""
    root = tmp_path_factory.mktemp("minari")
    mp = pytest.MonkeyPatch()
    mp.setenv("MINARI_DATASETS_PATH", str(root))
    env = gym.make(ENV, **KWARGS)
    # the controller built directly (resolve_policy("pd-ref", env) is the same; it loads every bench kind, torch too)
    report = datasets.write_dataset(
        ENV,
        "pd-ref",
        parameters=env.unwrapped.nominal_parameters[None],
        kinds=["nominal"],
        scores=SCORES,
        command="pytest tiny",
        seed=3,
        env_kwargs=KWARGS,
        policy=make("pd-ref", env),
    )
    yield report, minari.load_dataset(report.dataset_id)
    mp.undo()


def test_dataset_ids_follow_minaris_rules():
    from minari.dataset.minari_dataset import parse_dataset_id

    assert datasets.dataset_id("VCNC-HeartShop-v1", "pd-ref") == "vcnc/HeartShop-v1/pd-ref-v0"
    assert parse_dataset_id(datasets.dataset_id("VCNC-Circle-v1", "zpetc@machine")) == (
        "vcnc/Circle-v1",
        "zpetc_machine",
        0,
    )
    with pytest.raises(ValueError, match="policy"):
        datasets.dataset_id(ENV, "")


def test_a_tiny_dataset_reads_back_as_the_policys_own_episode(tiny):
    report, ds = tiny
    assert report.dataset_id == "vcnc/Heart-v1/pd-ref-v0" and report.episodes == 1 and report.steps == 300
    ep = next(ds.iterate_episodes())
    # the same policy, a single env, the evaluation loop every bench run uses
    env = _Recorder(gym.make(ENV, **KWARGS))
    result = run_episode(make("pd-ref", env), env, seed=3)
    assert ep.observations.shape == (301, 36) and ep.actions.shape == (300, 2)
    np.testing.assert_array_equal(ep.observations, np.stack(env.obs))
    np.testing.assert_array_equal(ep.actions, np.stack(env.act))
    assert ep.truncations[-1] and not ep.terminations.any()
    meta = ds.storage.metadata
    for key in ("ref_min_score", "ref_max_score", "env_spec", "algorithm_name", "description", "requirements"):
        assert key in meta, key
    v = meta["vcnc"]
    for key in (
        "command",
        "code_version",
        "policy",
        "non_causal",
        "score",
        "plant_parameters",
        "reset_seeds",
        "episodes",
    ):
        assert key in v, key
    assert v["command"] == "pytest tiny" and v["non_causal"] is False and v["reset_seeds"] == [3]
    assert v["code_version"]["vcnc_gym"] == vcnc_gym.__version__
    np.testing.assert_array_equal(np.array(v["plant_parameters"][0]), env.unwrapped.nominal_parameters)
    assert v["episodes"]["max_um"][0] == pytest.approx(result.max_contour_error_um, rel=1e-12)
    # Minari's normalised score is of returns of the env's reward: 0 at pd-ref's, 1 at the floor's
    assert meta["ref_min_score"] == -3.0e4 and meta["ref_max_score"] == -900.0
    episode_return = float(np.sum(ep.rewards))
    assert minari.get_normalized_score(ds, episode_return) == pytest.approx((episode_return + 3.0e4) / 29100.0)
    assert v["score"]["reference_return"] == -3.0e4 and v["score"]["floor_max_um"] == 1.25
    assert normalised_score(42.0, v["score"]["reference_max_um"], v["score"]["floor_max_um"]) == 0.0
    remade = ds.recover_environment()
    assert remade.spec.id == ENV and remade.spec.kwargs == gym.make(ENV, **KWARGS).spec.kwargs
    assert remade.spec.max_episode_steps == 300  # gym's TimeLimit, as the dataset's episodes were cut


def test_an_existing_dataset_is_not_overwritten_unless_asked(tiny, monkeypatch):
    report, _ = tiny
    monkeypatch.setenv("MINARI_DATASETS_PATH", str(report.path.parent.parent.parent))
    env = gym.make(ENV, **KWARGS)
    with pytest.raises(ValueError, match="overwrite"):
        datasets.write_dataset(
            ENV,
            "pd-ref",
            parameters=env.unwrapped.nominal_parameters[None],
            kinds=["nominal"],
            scores=SCORES,
            command="again",
            env_kwargs=KWARGS,
        )


@pytest.mark.slow  # torch and Stable-Baselines3 imported (agents): ~10 s before the fit
def test_behaviour_cloning_fits_and_round_trips(tiny, tmp_path):
    from vcnc_agents.behaviour_cloning import BehaviourCloning, dataset_pairs, fit, load_bc
    from vcnc_agents.policy import env_signature

    _, ds = tiny
    obs, act = dataset_pairs(ds)
    assert obs.shape == (300, 36) and act.shape == (300, 2)
    env = gym.make(ENV, **KWARGS)
    bc = fit(obs, act, hidden=(32,), epochs=30, batch_size=64, validation=0.1, signature=env_signature(env))
    losses = bc.header["losses"]
    assert losses["train"][-1] < 0.5 * losses["initial_train"]
    # the numpy forward of the saved weights gives torch's training MSE (an independent evaluation of the net)
    keep = np.random.default_rng(0).permutation(300)[30:]
    mse = float(np.mean((bc.forward(obs[keep]) - np.clip(act[keep], -1, 1)) ** 2))
    assert mse == pytest.approx(losses["train"][-1], rel=1e-4)
    path = bc.save(tmp_path / "bc.npz")
    back = load_bc(path, env)
    np.testing.assert_array_equal(back.predict(obs)[0], bc.predict(obs)[0])
    assert back.predict(obs[0])[0].shape == (2,)
    with pytest.raises(ValueError, match="behaviour-cloning"):
        load_bc(path, gym.make("VCNC-Circle-v1"))
    with pytest.raises(ValueError, match="path"):
        BehaviourCloning.load(tmp_path / "missing.npz")
    from vcnc_bench.kinds.bc import KIND
    from vcnc_bench.policies import register_policy_kind, resolve_policy

    register_policy_kind(KIND)
    assert np.array_equal(resolve_policy(f"bc:{path}", env).predict(obs[:5])[0], bc.predict(obs[:5])[0])


@pytest.mark.slow  # torch and Stable-Baselines3 imported (agents)
def test_a_clone_with_history_sees_the_observations_it_was_fitted_on(tiny):
    """With history 3 the policy's own buffer gives, step by step, the inputs the fit saw: o_t, o_t-1, o_t-2
    (written out here, the start padded with o_0), and a new episode starts its buffer again."""
    from vcnc_agents.behaviour_cloning import dataset_pairs, fit

    _, ds = tiny
    x, act = dataset_pairs(ds, history=3)
    o = next(ds.iterate_episodes()).observations[:-1].astype(np.float32)
    by_hand = np.concatenate([o, np.r_[o[:1], o[:-1]], np.r_[o[:1], o[:1], o[:-2]]], axis=1)
    np.testing.assert_array_equal(x, by_hand)
    bc = fit(x, act, hidden=(16,), epochs=2, batch_size=64, history=3)
    for _ in range(2):  # the second episode restarts the history
        stepped = np.stack([bc.predict(o[t], episode_start=np.array([t == 0]))[0] for t in range(20)])
        np.testing.assert_allclose(stepped, bc.forward(by_hand[:20]), rtol=0, atol=1e-6)
    two = bc.predict(np.stack([o[0], o[0]]), episode_start=np.array([True, True]))[0]
    np.testing.assert_allclose(two, np.repeat(bc.forward(by_hand[:1]), 2, axis=0), rtol=0, atol=1e-6)


def test_the_command_names_a_bad_argument(tmp_path, capsys):
    assert datasets.main(["--env", ENV, "--plants", "-1", "--out", str(tmp_path)]) == 2
    assert "--plants" in capsys.readouterr().err
    assert datasets.main(["--env", "VCNC-Nope-v1", "--policy", "strongest", "--out", str(tmp_path)]) == 2
    assert "Nope" in capsys.readouterr().err


# -- the learnable ids ---------------------------------------------------------------------------------------------
LEARNABLE = "VCNC-Heart-v2"


def test_a_learnable_ids_dataset_holds_its_own_observations_actions_and_rewards(tmp_path, monkeypatch):
    """``random`` on the v2 heart: the dataset's env is the v2 id, its episode replays from its seed and plant."""
    monkeypatch.setenv("MINARI_DATASETS_PATH", str(tmp_path))
    env = gym.make(LEARNABLE, **KWARGS)
    report = datasets.write_dataset(
        LEARNABLE,
        "random",
        parameters=env.unwrapped.nominal_parameters[None],
        kinds=["nominal"],
        scores=SCORES,
        command="pytest learnable",
        seed=5,
        env_kwargs=KWARGS,
    )
    ds = minari.load_dataset(report.dataset_id)
    assert report.dataset_id == "vcnc/Heart-v2/random-v0" and ds.recover_environment().spec.id == LEARNABLE
    ep = next(ds.iterate_episodes())
    assert ep.actions.shape == (300, 2) and np.abs(ep.actions).max() <= 1.0 and ep.actions.std() > 0.3
    assert np.all(ep.rewards <= 0.0) and np.all(ep.rewards >= -10.0)
    assert np.abs(ep.observations).max() < 100.0  # the scaled observation
    obs, _ = env.reset(seed=5, options={"parameters": ds.storage.metadata["vcnc"]["plant_parameters"][0]})
    np.testing.assert_array_equal(obs, ep.observations[0])
    rewards = [env.step(a)[1] for a in ep.actions]
    np.testing.assert_array_equal(rewards, ep.rewards)
    peak = ds.storage.metadata["vcnc"]["episodes"]["max_um"][0]
    assert peak == pytest.approx(1e3 * env.unwrapped._batch.buffers.episode[0, 2])  # the summary's, every period


@pytest.mark.parametrize("env_id", ["VCNC-Omega-v2", "VCNC-Circle-v2"])
def test_a_references_return_is_what_the_learnable_id_returns_for_it(env_id):
    """pd-ref run on the v1 id and scored with the v2 reward returns what the v2 id with ``base="pd-ref"`` and a zero
    correction returns (the floor, with no compiled form, is scored the same way)."""
    env = gym.make(env_id, base="pd-ref")
    env.reset(seed=0)
    total, done = 0.0, False
    while not done:
        _, r, term, trunc, info = env.step(np.zeros(2, dtype=np.float32))
        total, done = total + r, term or trunc
    scored = datasets.learnable_return(env_id, "pd-ref", seed=0)
    assert scored["return"] == pytest.approx(total, rel=1e-9)
    assert scored["max_um"] == pytest.approx(1e3 * info["episode_summary"]["contour_error_max"], rel=1e-12)


def test_a_v1_references_return_is_the_sum_of_its_rewards():
    lines = []
    scores = datasets.reference_scores(
        ENV, KWARGS, seed=3, known={"oracle": {"return": -1.0, "max_um": 1.0}}, report=lines.append
    )
    env = gym.make(ENV, **KWARGS)
    policy = make("pd-ref", env)
    obs, _ = env.reset(seed=3)
    total, done = 0.0, False
    while not done:
        obs, r, term, trunc, _ = env.step(policy.predict(obs, deterministic=True)[0])
        total, done = total + r, term or trunc
    assert scores["pd-ref"]["return"] == pytest.approx(total, rel=1e-12) and scores["oracle"]["return"] == -1.0
    assert len(lines) == 1 and lines[0].startswith(f"# {ENV}: pd-ref on the nominal plant: return")


def test_the_behaviour_policies_fit_the_ids_action():
    v2, v1 = gym.make(LEARNABLE), gym.make(ENV)
    with pytest.raises(ValueError, match="set-point correction"):
        datasets.behaviour_policy("pd-ref", v2)
    with pytest.raises(ValueError, match="learnable ids"):
        datasets.behaviour_policy("servo", v1)
    servo = datasets.behaviour_policy("servo", v2)
    assert np.array_equal(servo.predict(np.zeros((3, 36)))[0], np.zeros((3, 2), dtype=np.float32))
    a = datasets.behaviour_policy("random", v2, seed=1).predict(np.zeros(36))[0]
    assert a.shape == (2,) and np.array_equal(
        a, datasets.behaviour_policy("random", v2, seed=1).predict(np.zeros(36))[0]
    )


def test_the_command_shows_its_progress_and_defaults_to_servo_and_random_on_a_learnable_id(
    tmp_path, capsys, monkeypatch
):
    monkeypatch.setattr(datasets, "reference_scores", lambda env_id, seed=0, report=None, **kw: SCORES)
    assert datasets.main(["--env", "VCNC-Circle-v2", "--plants", "1", "--out", str(tmp_path)]) == 0
    out, err = capsys.readouterr()
    assert "vcnc/Circle-v2/servo-v0" in out and "vcnc/Circle-v2/random-v0" in out
    assert "decision" in err  # the progress bar of the episodes' decisions
    assert datasets.main(["--env", "VCNC-Circle-v2", "--policy", "pd-ref", "--out", str(tmp_path)]) == 2
    assert "VCNC-Circle-v1" in capsys.readouterr().err
