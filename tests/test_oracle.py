"""The non-causal floor (``oracle``, baselines/optimal): its shipped solutions replay to their figures through
``gym.make``'s env, it lies at or below every causal controller, and the headroom the bench reports."""

from __future__ import annotations

import math

import gymnasium as gym
import numpy as np
import pytest

import vcnc_baselines
import vcnc_gym  # noqa: F401
from vcnc_baselines.optimal import oracle as oracle_module, solutions
from vcnc_baselines.optimal.search import causal_names
from vcnc_bench.headroom import NON_CAUSAL, headroom
from vcnc_gym.envs.registry import CONTOURING_IDS
from vcnc_gym.evaluation import run_episode


def _no_solve(*args, **kwargs):
    raise AssertionError("the oracle solved instead of replaying its stored solution")


@pytest.fixture
def stored(monkeypatch):
    """The shipped solutions only: no recompute, no other directory, no solve."""
    monkeypatch.delenv("VCNC_ORACLE_RECOMPUTE", raising=False)
    monkeypatch.setenv("VCNC_ORACLE_SOLUTIONS", str(solutions.DIRECTORY))
    monkeypatch.setattr(oracle_module, "solve", _no_solve)


def test_shipped_floor_replays_to_its_stored_figure(stored):
    """VCNC-OmegaLookaheadShop-v1's nominal floor (seed 0), loaded (not solved), replays through gym.make's env to
    the max contour error stored with it, below its start's own closed-loop episode, which itself matches the stored
    start."""
    env = gym.make("VCNC-OmegaLookaheadShop-v1")
    oracle = vcnc_baselines.make("oracle", env)
    assert oracle.causal is False
    result = run_episode(oracle, env, seed=0)
    sol = oracle.solutions[0]
    assert result.completed
    assert result.max_contour_error_um == sol.max_um
    assert result.rms_contour_error_um == pytest.approx(sol.rms_um, rel=1e-12)
    start = run_episode(vcnc_baselines.make(sol.start, env), env, seed=0)
    assert start.max_contour_error_um == pytest.approx(sol.warm_starts[sol.start][0], rel=1e-12)
    assert result.max_contour_error_um <= start.max_contour_error_um
    # the stored starts are every causal controller that applies, the floor at or below each
    assert set(causal_names(env)) <= {k.split("#")[0] for k in sol.warm_starts}
    assert all(sol.max_um <= v[0] for v in sol.warm_starts.values())


def test_the_bench_checks_a_stored_floor_by_its_own_episode_and_solves_a_stale_one_again(stored, monkeypatch, tmp_path):
    """With ``check_by_episode`` (the bench's kind) the oracle loads a stored floor without a rollout of its own
    (none runs), and the bench's runner confirms it by its episode.  A stored figure the episode does not reproduce
    (here tampered) is refused with a warning, and the runner's second episode is the floor solved again (a stub
    solve returning the genuine solution)."""
    from vcnc_bench.runner import EnvRecipe, run_env

    env_id = "VCNC-OmegaLookaheadShop-v1"
    env = gym.make(env_id)
    env.reset(seed=0)
    u = env.unwrapped
    noise = int(u._batch.plant_arrays.rng[0])
    key = solutions.signature(env, u.parameters, noise)
    genuine = solutions.load(key)
    monkeypatch.setattr(
        oracle_module.OraclePolicy,
        "_replay",
        staticmethod(lambda *a: pytest.fail("a rollout replay ran: the episode is the check")),
    )
    runs = run_env(EnvRecipe(env_id, env_id, specs=("oracle",)), seed=0, trials=1)
    result = runs.runs[0].trials[-1]
    assert result.max_contour_error_um == genuine.max_um

    tampered = solutions.Solution(**{**genuine.__dict__, "max_um": genuine.max_um * 0.5})
    solutions.store(key, tampered, tmp_path)
    monkeypatch.setenv("VCNC_ORACLE_SOLUTIONS", str(tmp_path))
    solved = []
    monkeypatch.setattr(oracle_module, "solve", lambda *a, **k: solved.append(1) or genuine)
    with pytest.warns(UserWarning, match="solving again"):
        runs = run_env(EnvRecipe(env_id, env_id, specs=("oracle",)), seed=0, trials=1)
    assert solved == [1]
    assert [t.max_contour_error_um for t in runs.runs[0].trials] == [genuine.max_um]


def test_every_contouring_id_ships_a_floor_within_a_few_megabytes():
    """A stored solution named after every contouring id (the keys: the slow test below), a few MB in all."""
    shipped = {p.name.rsplit("-", 1)[0] for p in solutions.DIRECTORY.glob("*.npz")}
    assert set(CONTOURING_IDS) <= shipped, sorted(set(CONTOURING_IDS) - shipped)
    total = sum(p.stat().st_size for p in solutions.DIRECTORY.glob("*.npz"))
    assert total < 5e6, total


@pytest.mark.slow
def test_every_contouring_id_ships_its_nominal_floor(stored):
    """A stored solution for every contouring id's nominal plant at the bench's seed 0, found by its key."""
    missing = []
    for env_id in CONTOURING_IDS:
        env = gym.make(env_id)
        env.reset(seed=0)
        u = env.unwrapped
        arrays = u._batch.plant_arrays
        noise = int(arrays.rng[0]) if hasattr(arrays, "rng") else None
        if solutions.load(solutions.signature(env, u.parameters, noise)) is None:
            missing.append(env_id)
        env.close()
    assert not missing


def test_the_robust_path_reports_the_floor_s_plants_as_it_plans_them(stored):
    """``robust.run_plants(planning=...)`` hands the callback to the floor's ``plan`` (it plans each plant apart,
    minutes each when solved), which calls it after each plant: here the shipped nominal floor, loaded, one call
    (1, 1); a controller without ``plans_per_plant`` is planned as before and never calls it.  The vector env finds
    the floor stored from a single env: its key leaves out the vector env's own arguments (with them it was solved
    again, and here the solve is refused)."""
    from vcnc_bench import robust

    env_id = "VCNC-OmegaLookaheadShop-v1"
    env = gym.make(env_id)
    u = env.unwrapped
    calls = []
    for policy in (vcnc_baselines.make("oracle", env), vcnc_baselines.make("ff-pid@machine", env)):
        batch = robust.make_batch(env_id, 1)
        try:
            robust.run_plants(
                policy,
                batch,
                u.nominal_parameters[None],
                decision_period=u.decision_period,
                seed=0,
                planning=lambda done, total, name=policy.name: calls.append((name, done, total)),
            )
        finally:
            batch.close()
    assert calls == [("oracle", 1, 1)]


def test_oracle_refuses_to_act_without_a_plan():
    env = gym.make("VCNC-Circle-v1")
    oracle = vcnc_baselines.make("oracle", env)
    obs, _ = env.reset(seed=0)
    with pytest.raises(RuntimeError, match="plan"):
        oracle.predict(obs)
    with pytest.raises(ValueError, match="population"):
        vcnc_baselines.make("oracle", env, population=2)


def test_headroom_is_the_strongest_causal_figure_over_the_floors():
    results = {
        "qft": {"max_contour_error_um": 547.0, "rms_contour_error_um": 247.0},
        "ff-pid": {"max_contour_error_um": 1790.0, "rms_contour_error_um": 650.0},
        "smc": {"max_contour_error_um": math.inf, "rms_contour_error_um": math.inf},
        "oracle" + NON_CAUSAL: {"max_contour_error_um": 500.0, "rms_contour_error_um": 240.0},
    }
    h = headroom(results)
    assert (h.strongest, h.floor) == ("qft", "oracle" + NON_CAUSAL)
    assert h.ratio == 547.0 / 500.0
    assert headroom({"qft": results["qft"]}) is None
    with pytest.raises(ValueError, match="floor"):
        headroom(results, floor="nothing")


@pytest.mark.slow
@pytest.mark.parametrize("env_id", ["VCNC-Circle-v1", "VCNC-CircleShop-v1"])
def test_floor_is_at_or_below_every_causal_controller_on_plants_from_the_box(env_id, monkeypatch, tmp_path):
    """On plants drawn from the box (one batch, the bench's robust path; on the shop floor each with its own
    noise), the floor, solved with a small budget, is at or below every causal controller that applies."""
    from vcnc_bench import robust

    monkeypatch.setenv("VCNC_ORACLE_SOLUTIONS", str(tmp_path))
    env = gym.make(env_id)
    plants = robust.plant_set(env.unwrapped.plant, 2, seed=5, max_vertices=0)
    period = env.unwrapped.decision_period

    def runs(policy):
        batch = robust.make_batch(env_id, len(plants.kinds))
        return robust.run_plants(policy, batch, plants.parameters, decision_period=period, seed=3)

    floor = runs(vcnc_baselines.make("oracle", env, population=4, ilc_iterations=1, rounds=1, generations=2, trials=2))
    names = causal_names(env)
    assert {"ff-pid", "zpetc", "nctf"} <= set(names)
    for name in names:
        other = runs(vcnc_baselines.make(name, env))
        assert np.all(floor.max_um <= other.max_um), (name, floor.max_um, other.max_um)
    assert len(list(tmp_path.glob("*.npz"))) == len(plants.kinds)  # solved and stored per plant


def test_an_at_machine_start_is_the_controller_commissioned_on_that_machine():
    """The floor's warm start of an @machine design is the controller the bench runs (its identification run on
    the machine solved on), not the nominal record's: its replay on the exact plant is the env episode's figure.
    On the look-ahead omega the two differ: its nominal record is the heart's machine (the same drive and period),
    identified along the heart, and its machine run follows the omega."""
    from vcnc_baselines.optimal.rollout import Rollouts
    from vcnc_baselines.optimal.search import warm_starts

    env = gym.make("VCNC-OmegaLookahead-v1")
    env.reset(seed=0)
    u = env.unwrapped
    starts = warm_starts(env, Rollouts(u.task, np.asarray(u.parameters), 1, None), names=["zpetc", "zpetc@machine"])
    for name in ("zpetc", "zpetc@machine"):
        episode = run_episode(vcnc_baselines.make(name, env), env, seed=0)
        assert 1e3 * starts[name].max == pytest.approx(episode.max_contour_error_um, rel=1e-12, abs=0.0), name
    assert starts["zpetc"].max != starts["zpetc@machine"].max  # two designs, not one


def test_a_key_s_next_stored_solution_is_tried_before_solving_again(monkeypatch, tmp_path):
    """A floor solved on another CPU's code paths is stored beside the first as ``KEY~CPU.npz``: where the first does
    not replay (tampered here), the bench's episode tries the next and reports it, solving nothing; where none
    replays, it solves again."""
    from vcnc_baselines.optimal import oracle as oracle_module
    from vcnc_bench.runner import EnvRecipe, run_env

    env_id = "VCNC-OmegaLookaheadShop-v1"
    env = gym.make(env_id)
    env.reset(seed=0)
    u = env.unwrapped
    key = solutions.signature(env, u.parameters, int(u._batch.plant_arrays.rng[0]))
    genuine = solutions.load(key)
    solutions.store(key, genuine, tmp_path).rename(tmp_path / f"{key}~othercpu.npz")
    solutions.store(key, solutions.Solution(**{**genuine.__dict__, "max_um": genuine.max_um * 0.5}), tmp_path)
    monkeypatch.setenv("VCNC_ORACLE_SOLUTIONS", str(tmp_path))
    assert [p.name for p in solutions.paths(key)] == [f"{key}.npz", f"{key}~othercpu.npz"]
    solved = []
    monkeypatch.setattr(oracle_module, "solve", lambda *a, **k: solved.append(1) or genuine)
    with pytest.warns(UserWarning, match="the next stored solution"):
        runs = run_env(EnvRecipe(env_id, env_id, specs=("oracle",)), seed=0, trials=1)
    assert solved == [] and runs.runs[0].trials[-1].max_contour_error_um == genuine.max_um
    (tmp_path / f"{key}~othercpu.npz").unlink()
    solutions.store(key, solutions.Solution(**{**genuine.__dict__, "max_um": genuine.max_um * 0.7}), tmp_path)
    (tmp_path / f"{key}.npz").rename(tmp_path / f"{key}~othercpu.npz")
    solutions.store(key, solutions.Solution(**{**genuine.__dict__, "max_um": genuine.max_um * 0.5}), tmp_path)
    with pytest.warns(UserWarning, match="solving again"):
        runs = run_env(EnvRecipe(env_id, env_id, specs=("oracle",)), seed=0, trials=1)
    assert solved == [1] and runs.runs[0].trials[-1].max_contour_error_um == genuine.max_um
