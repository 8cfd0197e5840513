"""vcnc-bench --plants N (vcnc_bench.robust): the plants, the batched runs against single episodes, the CLI."""

from __future__ import annotations

import json
import math

import gymnasium as gym
import numpy as np
import pytest

import vcnc_bench as bench
from vcnc_baselines import make as make_baseline
from vcnc_bench import robust
from vcnc_gym.envs import CONTOURING_IDS, SUITE, VECTOR_IDS
from vcnc_gym.evaluation import run_episode
from vcnc_gym.plants import get_plant

#: The shortest contouring id on Jahanpour et al.'s feed drive (6 uncertain coordinates: 64 vertices), and the
#: positioning id (no vector env).
OMEGA = next(i for i in CONTOURING_IDS if "Omega" in i)
STEP = next(e.id for e in SUITE if e.entry_point.endswith(":PositioningEnv"))
N = 3


@pytest.fixture(scope="module")
def omega_robust(tmp_path_factory):
    out = tmp_path_factory.mktemp("robust")
    code = bench.main(
        [
            "--env",
            OMEGA,
            "--policy",
            "smc",
            "--plants",
            str(N),
            "--plant-seed",
            "5",
            "--json",
            str(out / "r.json"),
            "--plots",
            str(out),
            "--no-progress",
        ]
    )
    assert code == 0
    return json.loads((out / "r.json").read_text()), out


def _smc(data) -> dict:
    return next(r for r in data["robust"] if r["policy"] == "smc")


def test_nominal_row_is_the_ordinary_bench_episode(omega_robust):
    data, _ = omega_robust
    rec = _smc(data)
    env = gym.make(OMEGA)
    single = run_episode(make_baseline("smc", env), env, seed=0)  # what vcnc-bench without --plants runs
    assert rec["nominal_max_um"] == pytest.approx(single.max_contour_error_um, rel=1e-9, abs=0.0)
    assert rec["nominal_rms_um"] == pytest.approx(single.rms_contour_error_um, rel=1e-9, abs=0.0)
    assert rec["per_plant"]["steps"][0] == single.episode_steps
    assert rec["nominal_completed"] == single.completed and rec["nominal_diverged"] == single.diverged


def test_json_has_the_figures_of_every_plant(omega_robust):
    data, out = omega_robust
    expected = {
        "plants": N,
        "plant_seed": 5,
        "seed": 0,
        "trials": 1,
        "max_vertices": robust.MAX_VERTICES,
        "feedrate": None,
        "plant": None,
    }
    assert {k: data["settings"][k] for k in expected} == expected
    assert "provenance" in data["settings"]
    # the policy named, and the score's reference PD the bench adds under --plants
    assert [r["policy"] for r in data["robust"]] == ["smc", "pd-ref"]
    rec = _smc(data)
    assert (rec["env"], rec["policy"], rec["n_samples"], rec["n_vertices"], rec["n_plants"]) == (
        OMEGA,
        "smc",
        N,
        64,
        N + 64,
    )
    for key in (
        "nominal_max_um",
        "median_max_um",
        "p95_max_um",
        "worst_max_um",
        "nominal_rms_um",
        "median_rms_um",
        "p95_rms_um",
        "worst_rms_um",
        "nominal_cycle_time_s",
        "median_cycle_time_s",
        "worst_cycle_time_s",
        "n_diverged",
        "n_incomplete",
        "worst_max_plant",
        "wall_s",
    ):
        assert key in rec, key
    per = rec["per_plant"]
    assert per["kind"] == ["nominal"] + ["sample"] * N + ["vertex"] * 64
    assert all(len(v) == 1 + N + 64 for v in per.values())
    # the figures from the per-plant lists (no plant diverged here)
    assert rec["n_diverged"] == 0
    samples = np.array(per["max_um"][1 : 1 + N])
    assert rec["median_max_um"] == pytest.approx(np.median(samples), rel=1e-12)
    assert rec["p95_max_um"] == pytest.approx(np.percentile(samples, 95), rel=1e-12)
    assert rec["worst_max_um"] == max(per["max_um"][1:])
    assert rec["nominal_max_um"] <= rec["worst_max_um"]
    assert (out / f"{OMEGA}_robust.png").stat().st_size > 0


def test_plants_are_reproducible_by_seed():
    model = get_plant("vcnc_feed_drive")
    a, b, c = (robust.plant_set(model, 4, seed=s) for s in (7, 7, 8))
    np.testing.assert_array_equal(a.parameters, b.parameters)
    assert not np.array_equal(a.samples, c.samples)
    np.testing.assert_array_equal(a.nominal, gym.make(OMEGA).unwrapped.nominal_parameters)
    corners = model.vertices()
    assert np.all((corners.min(axis=0) <= a.samples) & (a.samples <= corners.max(axis=0)))  # inside the box
    np.testing.assert_array_equal(a.samples[0], model.sample(np.random.default_rng(7)))


def test_vertices_join_when_the_box_is_small():
    small, large = get_plant("vcnc_feed_drive"), get_plant("current_feed_drive")  # 2^6 and 2^8 vertices
    np.testing.assert_array_equal(robust.plant_set(small, 2).vertices, small.vertices())
    assert robust.plant_set(large, 2).vertices.shape == (0, 2, large.n_parameters)
    assert robust.plant_set(small, 2, max_vertices=63).vertices.shape[0] == 0
    assert robust.plant_set(small, 2).kinds == ["nominal", "sample", "sample"] + ["vertex"] * 64


def test_positioning_env_runs_as_a_batch_of_single_envs():
    assert STEP not in VECTOR_IDS
    env = gym.make(STEP)
    policy = make_baseline("imc", env)
    plants = robust.plant_set(env.unwrapped.plant, 1)
    batch = robust.make_batch(STEP, len(plants.kinds))
    assert isinstance(batch, robust.SingleEnvBatch)
    runs = robust.run_plants(
        policy, batch, plants.parameters, decision_period=env.unwrapped.decision_period, contouring=False
    )
    single = run_episode(make_baseline("imc", env), env, seed=0)
    assert runs.rms_um[0] == pytest.approx(single.rms_contour_error_um, rel=1e-9, abs=0.0)
    assert runs.max_um[0] == pytest.approx(single.max_contour_error_um, rel=1e-9, abs=0.0)
    assert runs.completed[0] == single.completed
    # a sampled plant runs the same as a single env given that plant
    alone = run_episode(make_baseline("imc", env), _FixedPlant(env, plants.parameters[1]), seed=1)
    assert runs.rms_um[1] == pytest.approx(alone.rms_contour_error_um, rel=1e-9, abs=0.0)


class _FixedPlant(gym.Wrapper):
    """Resets its env with the given plant (run_episode passes no options)."""

    def __init__(self, env, parameters):
        super().__init__(env)
        self._parameters = parameters

    def reset(self, *, seed=None, options=None):
        return self.env.reset(seed=seed, options={"parameters": self._parameters})


def test_quantile_reaches_infinite_values():
    x = np.array([1.0, 2.0, 3.0, math.inf])
    assert robust._quantile(x, 0.5) == 2.5
    assert robust._quantile(x, 0.95) == math.inf
    assert robust._quantile(np.array([math.inf, 1.0]), 0.0) == 1.0


@pytest.mark.parametrize(
    "argv, message",
    [
        (["--plants", "0"], "--plants must be >= 1, got 0"),
        (["--plants", "2", "--plant-seed", "-1"], "--plant-seed must be >= 0"),
    ],
)
def test_bad_plants_exit_2(argv, message, capsys):
    with pytest.raises(SystemExit) as exc:
        bench.main(["--env", OMEGA, "--policy", "smc"] + argv)
    assert exc.value.code == 2
    assert message in capsys.readouterr().err


def test_the_robust_bench_on_the_override_id_has_no_floor_to_score_against():
    """``vcnc-bench --env VCNC-OmegaOverride-v1 --plants N`` ended in a traceback after every run: the oracle (the
    score's floor) was built for the override env and refused its batch.  It refuses the env itself now (a re-timed
    reference has no floor), and the bench leaves the score out there."""
    import argparse

    from vcnc_bench import robust_run

    env = gym.make("VCNC-OmegaOverride-v1")
    with pytest.raises(ValueError, match="re-times its reference"):
        make_baseline("oracle", env)
    args = argparse.Namespace(feedrate=None, plant=None, shop_floor=False, seed=0)
    runs = [("VCNC-OmegaOverride-v1", "ff-pid-online", make_baseline("ff-pid-online", env))]
    assert robust_run.nominal_floors(args, {"VCNC-OmegaOverride-v1": env}, runs) == {}
