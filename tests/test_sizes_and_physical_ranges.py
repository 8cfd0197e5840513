"""Issue 23: sizes with limits, physically meaningless plants refused, one turn-back rule, the last silent cases.

One test (or a few) per case of the issue's table, numbered as there, then the
items it asks for: every size a user gives is checked against a limit derived
from memory or a documented ceiling (:func:`vcnc_gym.validation.size`), plant
parameters against their physical range, contours against the turn-back
rule, and the fuzz's NaN check can fail.  The training cases share one tiny
direct-mode run whose evaluations diverge (an untrained agent lags the
reference past the tracking bound while its table stays on the contour).
"""

from __future__ import annotations

import contextlib
import csv
import io
import math
import pickle
import shutil
import time
import warnings
import zipfile
from pathlib import Path

import gymnasium as gym
import numpy as np
import pytest

import vcnc_gym
from vcnc_gym import validation
from vcnc_gym.envs.task import ContouringBatch
from vcnc_gym.geometry import NurbsCurve
from vcnc_gym.geometry.corners import MIN_BLEND_ANGLE, design_corner, polyline, smooth_polyline
from vcnc_gym.geometry.nurbs import TURN_BACK_ANGLE
from vcnc_gym.plants import get_plant
from vcnc_gym.plants.contract import ParameterWarning

OMEGA = "VCNC-Omega-v1"
HEART = "VCNC-Heart-v1"
PLANTS = ("vcnc_feed_drive", "current_feed_drive", "nct_xy_table", "cncmt_axis")


def _bench(argv) -> tuple[int, str]:
    from vcnc_bench.cli import main

    err = io.StringIO()
    with contextlib.redirect_stderr(err), contextlib.redirect_stdout(io.StringIO()):
        try:
            code = main(argv)
        except SystemExit as exc:
            code = exc.code
    return code, err.getvalue()


def _train(argv) -> tuple[int, str, str]:
    from vcnc_agents.cli import main

    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        try:
            code = main([*argv, "--no-progress", "--no-tensorboard"])
        except SystemExit as exc:
            code = exc.code
    return code, out.getvalue(), err.getvalue()


# -- the one size check ----------------------------------------------------------------------------------
def test_size_limit_is_half_the_available_memory_over_the_bytes_each(monkeypatch):
    monkeypatch.setattr(validation, "available_memory", lambda: 10_000_000)
    limit = int(0.5 * 10_000_000 // 3_000)  # computed here, not by the helper
    assert validation.size("num_envs", limit, bytes_each=3_000) == limit
    with pytest.raises(ValueError, match=rf"num_envs must be at most {limit:,} \(.*3 kB each.*10 MB") as exc:
        validation.size("num_envs", limit + 1, bytes_each=3_000)
    assert f"got {limit + 1:,}" in str(exc.value)
    with pytest.raises(ValueError, match=r"--trials must be at most 7 \(a reason\), got 8"):
        validation.size("--trials", 8, ceiling=7, why="a reason")
    for bad in (0, True, 2.0, "3"):
        with pytest.raises(ValueError, match="x must be an integer"):
            validation.size("x", bad, ceiling=10)


def test_available_memory_reads_meminfo():
    text = Path("/proc/meminfo").read_text() if Path("/proc/meminfo").exists() else None
    if text is None:
        pytest.skip("no /proc/meminfo")
    kb = next(int(line.split()[1]) for line in text.splitlines() if line.startswith("MemAvailable:"))
    assert abs(validation.available_memory() - kb * 1024) < 0.2 * kb * 1024  # the figure moves while we read it


# -- case 1: vcnc-bench --plants 10**9 ----------------------------------------------------------------------
def test_case_1_bench_plants_has_a_memory_limit():
    t0 = time.perf_counter()
    code, err = _bench(["--no-progress", "--env", OMEGA, "--policy", "smc", "--plants", str(10**9)])
    assert (
        code == 2 and "the plants of --plants 1000000000" in err and "must be at most" in err and "available" in err
    ), err
    assert time.perf_counter() - t0 < 10.0


def test_bench_trials_have_a_ceiling():
    code, err = _bench(["--no-progress", "--env", OMEGA, "--policy", "smc", "--trials", "100000"])
    assert code == 2 and "--trials must be at most 10,000" in err, err


# -- case 2: gym.make_vec(num_envs=10**7) ------------------------------------------------------------------
def test_case_2_num_envs_has_a_memory_limit():
    t0 = time.perf_counter()
    with pytest.raises(ValueError, match=r"num_envs must be at most [\d,]+ \(each env's rows"):
        gym.make_vec(OMEGA, num_envs=10**7, vectorization_mode="vector_entry_point")
    assert time.perf_counter() - t0 < 10.0


def test_bytes_per_env_counts_the_batch_rows():
    env = gym.make(OMEGA)
    task = env.unwrapped.task
    one = ContouringBatch(task, 1)
    rows = sum(a.nbytes for a in one.buffers if isinstance(a, np.ndarray) and a is not one.buffers.obs_high)
    rows += sum(a.nbytes for a in one.plant_arrays if isinstance(a, np.ndarray))
    estimate = ContouringBatch.bytes_per_env(task)
    assert 2 * rows <= estimate <= 2 * rows + 2048  # twice the rows, plus the generator's ~0.9 kB


# -- case 3: a NURBS that turns back on itself --------------------------------------------------------------
def _reversing_curve() -> NurbsCurve:
    return NurbsCurve([[0, 0], [20, 0], [0, 0]], [1] * 3, [0, 0, 0.5, 1, 1], 1)


def test_case_3_a_curve_that_turns_back_is_refused_like_its_polyline():
    with pytest.raises(ValueError, match=r"turns back on itself at the knot u = 0.5"):
        vcnc_gym.ContouringEnv(contour=_reversing_curve())
    with pytest.raises(ValueError, match="turns back on itself at vertex 1"):
        polyline([[0, 0], [20, 0], [0, 0]])


@pytest.mark.parametrize("degree", [1, 2, 3])
def test_the_turn_back_rule_is_the_same_for_curves_and_polylines(degree):
    """A C0 corner of a NURBS of any degree and the same corner as polyline vertices: both refused at an
    interior angle of 0, both accepted at 1e-6 rad; the angle computed here from the legs."""
    for end, refused in (([0.0, 0.0], True), ([0.0, 20.0 * math.tan(1e-6)], False)):
        legs = np.array([[20.0, 0.0], np.subtract(end, [20.0, 0.0])])
        theta = math.pi - abs(math.atan2(legs[0, 0] * legs[1, 1] - legs[0, 1] * legs[1, 0], legs[0] @ legs[1]))
        assert (theta <= TURN_BACK_ANGLE) == refused
        # the corner at (20, 0) as a degree-p curve: p copies of the corner's line points, knot multiplicity p
        first = np.linspace([0.0, 0.0], [20.0, 0.0], degree + 1)
        second = np.linspace([20.0, 0.0], end, degree + 1)[1:]
        points = np.vstack([first, second])
        knots = np.concatenate([[0.0] * (degree + 1), [0.5] * degree, [1.0] * (degree + 1)])
        curve = NurbsCurve(points, np.ones(len(points)), knots, degree)
        if refused:
            with pytest.raises(ValueError, match="turns back"):
                curve.check_regular()
            with pytest.raises(ValueError, match="turns back"):
                polyline([[0, 0], [20, 0], end])
        else:
            curve.check_regular()
            polyline([[0, 0], [20, 0], end])


def test_every_shape_passes_the_turn_back_rule():
    from vcnc_gym.envs.task import make_contour
    from vcnc_gym.geometry import SHAPES

    for name in SHAPES:
        make_contour(name)[0].check_regular()


# -- case 4: ppo: with nothing after the colon -------------------------------------------------------------------
def test_case_4_an_empty_policy_argument_is_refused():
    code, err = _bench(["--no-progress", "--env", "VCNC-Omega-v0", "--policy", "ppo:"])
    assert code == 2 and "nothing after ':'" in err, err


# -- case 5: parameters outside their physical range ---------------------------------------------------------
@pytest.mark.parametrize(
    "env_id,name,value",
    [
        (HEART, "J", 1e-300),
        (HEART, "K_a", 1e300),
        (HEART, "K_t", 1e300),
        (HEART, "B", 1e300),
        (HEART, "u_max", 1e300),
        ("VCNC-Corners-v1", "m", 1e-300),
    ],
)
def test_case_5_physically_meaningless_parameters_are_refused(env_id, name, value):
    plant = gym.make(env_id).unwrapped.plant
    p = plant.nominal()
    p[:, plant.index(name)] = value
    lo, hi = plant.parameters[plant.index(name)].physical_range
    with pytest.raises(ValueError, match=rf"parameter {name} must lie in its physical range \[{lo:g}, {hi:g}\]"):
        gym.make(env_id, parameters=p)


@pytest.mark.parametrize("plant_name", PLANTS)
def test_every_parameter_has_a_range_wider_than_its_box(plant_name):
    plant = get_plant(plant_name)
    for par in plant.parameters:
        assert par.physical_range is not None and par.range_source, par.name
        lo, hi = par.physical_range
        for a in range(2):
            assert lo <= par.nominal[a] <= hi
            if par.uncertain:
                assert lo < par.interval[a][0] and par.interval[a][1] < hi, par.name
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # the box's corners and the nominal plant: no warning
        plant.validate(plant.vertices()[:8])
        plant.validate(plant.nominal())


def test_outside_the_box_inside_the_range_is_accepted_with_a_warning():
    plant = get_plant("vcnc_feed_drive")
    p = plant.nominal()
    p[0, plant.index("K_a")] = 9.0  # box 5.71-7.07 A/V on x
    with pytest.warns(ParameterWarning, match=r"K_a = \[9.\] A/V on the x axis is outside .*\[5.71, 7.07\]"):
        env = gym.make(HEART, parameters=p)
    assert env.unwrapped.task.fixed_parameters[0, plant.index("K_a")] == 9.0


# -- case 6: a NaN in the plant state ----------------------------------------------------------------------------
def test_case_6_a_nan_state_is_rewarded_with_the_divergence_penalty():
    env = gym.make(OMEGA)
    u = env.unwrapped
    env.reset(seed=0)
    for _ in range(5):
        env.step(np.zeros(2, dtype=np.float32))
    u._batch.plant_arrays.state[0] = np.nan
    obs, reward, terminated, truncated, info = env.step(np.zeros(2, dtype=np.float32))
    t = u.task
    per_step = t.divergence_bound / t.reward_scale
    left = t.episode_steps - 6  # decisions the diverged episode no longer takes
    assert terminated and info["diverged"] and np.all(np.isfinite(obs))
    assert reward == pytest.approx(-per_step * (1 + left))
    assert math.isinf(info["contour_error"])


def test_a_nan_state_in_the_vector_env_ends_only_that_env():
    envs = gym.make_vec(OMEGA, num_envs=3, vectorization_mode="vector_entry_point")
    envs.reset(seed=0)
    envs.unwrapped._batch.plant_arrays.state[1] = np.nan
    obs, reward, terminated, _, info = envs.step(np.zeros((3, 2), dtype=np.float32))
    assert np.all(np.isfinite(obs)) and np.all(np.isfinite(reward))
    assert terminated.tolist() == [False, True, False] and info["diverged"].tolist() == [False, True, False]
    assert reward[1] < -envs.unwrapped.task.divergence_bound / envs.unwrapped.task.reward_scale


# -- case 10: a preview past the contour's end ----------------------------------------------------------------
def test_case_10_preview_steps_and_contour_ahead_past_the_end_are_refused():
    with pytest.raises(ValueError, match=r"preview_steps must be at most [\d,]+ \(the reference's length"):
        gym.make(HEART, preview_steps=(10**9,))
    end = len(gym.make(OMEGA).unwrapped.task.reference.t) - 1
    gym.make(OMEGA, preview_steps=(10, end))  # the last sample itself is fine
    with pytest.raises(ValueError, match="preview_steps must be at most"):
        gym.make(OMEGA, preview_steps=(10, end + 1))
    with pytest.raises(ValueError, match=r"contour_ahead must be at most 310.1\d* mm"):
        gym.make(HEART, contour_ahead=(1.0, 1e6))
    with pytest.raises(ValueError, match=r"max_episode_steps must be at most"):
        vcnc_gym.ContouringEnv(contour="omega", max_episode_steps=10**9)


def test_the_positioning_env_s_episode_length_has_a_ceiling():
    with pytest.raises(ValueError, match=r"duration / dt must be at most 2,000,000 .*got 100,000,000,000"):
        gym.make("VCNC-Step-v0", duration=1e9)
    with pytest.raises(ValueError, match=r"duration / dt must be at most 2,000,000"):
        gym.make("VCNC-Step-v0", dt=1e-9)


# -- case 11: a corner too sharp to blend ------------------------------------------------------------------------
def test_case_11_a_corner_too_sharp_to_blend_is_named():
    with pytest.raises(ValueError, match=r"corner at vertex 1 \(\[10.0, 0.0\] mm\) is too sharp.*0.01 deg.*MIN_BLEND"):
        smooth_polyline([[0, 0], [10, 0], [0, 10 * np.tan(np.radians(0.01))]], 0.05, 1e3, 1e5)


def test_min_blend_angle_is_where_the_search_leaves_its_range(monkeypatch):
    import vcnc_gym.geometry.corners as corners

    design_corner(MIN_BLEND_ANGLE * (1 + 1e-6), 0.05, 1e3, 1e5)  # just above: designed
    monkeypatch.setattr(corners, "MIN_BLEND_ANGLE", 0.0)
    with pytest.raises(RuntimeError, match="left the search range"):  # just below, unguarded: the search fails
        corners.design_corner(MIN_BLEND_ANGLE * (1 - 1e-6), 0.05, 1e3, 1e5)


# -- case 12: NurbsCurve names the argument ------------------------------------------------------------------------
@pytest.mark.parametrize("which", ["control_points", "weights", "knots"])
def test_case_12_a_non_numeric_argument_is_named(which):
    args = {"control_points": [[0, 0], [1, 1], [2, 0], [3, 1]], "weights": [1] * 4, "knots": [0, 0, 0, 0.5, 1, 1, 1]}
    args[which] = {"control_points": "abcd", "weights": ["1", "1", "1", "1"], "knots": [0, 0, 0, True, 1, 1, 1]}[which]
    with pytest.raises(ValueError, match=rf"^{which} must be an array of real numbers"):
        NurbsCurve(args["control_points"], args["weights"], args["knots"], 2)


# -- case 15: --parallel without --plants ------------------------------------------------------------------------
def test_case_15_parallel_without_plants_is_an_error():
    code, err = _bench(["--no-progress", "--env", OMEGA, "--policy", "smc", "--parallel"])
    assert code == 2 and "--parallel" in err and "--plants" in err, err


# -- the trainer: cases 7, 8, 9, 13, 14 -----------------------------------------------------------------------------
TINY = """\
VCNC-Omega-v1:
  n_envs: 2
  n_timesteps: 512
  policy: MlpPolicy
  normalize: "{'norm_obs': True, 'norm_reward': True}"
  env_kwargs:
    action_repeat: 40
  n_steps: 128
  batch_size: 128
  n_epochs: 1
  policy_kwargs: "dict(log_std_init=-1.0, net_arch=dict(pi=[16], vf=[16]))"
"""


@pytest.fixture(scope="module")
def tiny_config(tmp_path_factory) -> Path:
    path = tmp_path_factory.mktemp("hp") / "tiny.yml"
    path.write_text(TINY)
    return path


@pytest.fixture(scope="module")
def diverging_run(tiny_config, tmp_path_factory):
    """768 steps, a checkpoint every 256 and an evaluation every 256: the untrained agent's evaluations diverge."""
    pytest.importorskip("stable_baselines3")
    run = tmp_path_factory.mktemp("run") / "run"
    code, out, err = _train(
        [
            "--env",
            OMEGA,
            "--config",
            str(tiny_config),
            "--output",
            str(run),
            "--timesteps",
            "768",
            "--checkpoint-freq",
            "256",
            "--eval-freq",
            "256",
            "--threads",
            "1",
        ]
    )
    assert code == 0, err
    return run, out


def test_case_13_14_diverged_evaluations_are_written_as_diverged(diverging_run):
    run, out = diverging_run
    rows = list(csv.DictReader((run / "evaluations.csv").open()))
    assert rows and all(r["diverged"] == "True" for r in rows), rows
    assert all(r[k] == "inf" for r in rows for k in ("max_um", "mean_um", "rms_um", "score_um")), rows
    assert not (run / "best").exists()
    last = out.strip().splitlines()[-1]
    assert str(run / "best") not in last and "no best/: every evaluation diverged" in last
    assert str(run / "final") in last


def _pickle_the_policy(model_zip: Path, marker: Path) -> None:
    """Replace policy.pth by a pickle that creates ``marker`` when loaded (what a tampered checkpoint holds)."""
    import torch

    class Payload:
        def __reduce__(self):
            return (Path.touch, (marker,))

    buffer = io.BytesIO()
    torch.save({"weights": Payload()}, buffer, pickle_module=pickle)
    with zipfile.ZipFile(model_zip) as z:
        members = {n: z.read(n) for n in z.namelist()}
    members["policy.pth"] = buffer.getvalue()
    with zipfile.ZipFile(model_zip, "w") as z:
        for name, data in members.items():
            z.writestr(name, data)


def test_case_7_resume_skips_a_checkpoint_with_a_pickled_policy(diverging_run, tmp_path):
    run = tmp_path / "run"
    shutil.copytree(diverging_run[0], run)
    marker = tmp_path / "ran"
    newest = run / "checkpoints" / "rl_model_768_steps.zip"
    _pickle_the_policy(newest, marker)
    code, out, err = _train(["--resume", str(run), "--timesteps", "1024"])
    assert code == 0, err
    assert "rl_model_768_steps.zip is damaged" in err and "falling back to the one at 512 steps" in err, err
    assert not marker.exists(), "the pickled policy.pth was unpickled"
    assert (run / "checkpoints" / "rl_model_768_steps.zip.damaged").exists()
    assert (run / "checkpoints" / "rl_model_1024_steps.zip").exists()


def test_case_8_n_envs_is_limited_by_open_files_and_memory(tiny_config, tmp_path, monkeypatch):
    out = tmp_path / "run"
    t0 = time.perf_counter()
    code, _, err = _train(
        [
            "--env",
            OMEGA,
            "--config",
            str(tiny_config),
            "--output",
            str(out),
            "--timesteps",
            "256",
            "--n-envs",
            str(10**6),
        ]
    )
    assert code == 2 and "n_envs must be at most" in err and "Traceback" not in err, err
    assert not out.exists() and time.perf_counter() - t0 < 10.0
    from vcnc_agents import run_config

    monkeypatch.setattr(validation, "available_memory", lambda: 10**9)
    each = 2048 * (40 + 2 + 6) * 4 + run_config.ENV_BYTES  # float32 rollout rows, plus the env's own
    limit = int(0.5 * 10**9 // each)
    assert run_config.check_n_envs(limit, 2048, 40) == limit
    with pytest.raises(ValueError, match=rf"n_envs must be at most {limit:,} \(each env fills n_steps = 2048 rows"):
        run_config.check_n_envs(limit + 1, 2048, 40)


def test_case_9_an_output_folder_that_cannot_be_made_is_an_error(tiny_config):
    if not Path("/proc/self").exists():
        pytest.skip("no procfs")
    code, _, err = _train(["--env", OMEGA, "--config", str(tiny_config), "--output", "/proc/run", "--timesteps", "256"])
    assert code == 2 and "cannot make the run folder /proc/run" in err and "Traceback" not in err, err


def test_timesteps_have_a_ceiling(tiny_config, tmp_path):
    code, _, err = _train(
        ["--env", OMEGA, "--config", str(tiny_config), "--output", str(tmp_path / "run"), "--timesteps", str(10**11)]
    )
    assert code == 2 and "n_timesteps must be at most 10,000,000,000" in err, err


# -- item 5: the fuzz's NaN check can fail ---------------------------------------------------------------------------
def _fuzz_module():
    from benchmark_script import probe_script

    return probe_script("fuzz_envs", "fuzz_envs_round2")


def test_the_id_fuzz_is_clean_and_its_nan_check_can_fail(monkeypatch):
    fuzz = _fuzz_module()
    ids = (OMEGA, "VCNC-Step-v0")
    out = fuzz.fuzz_ids(episodes=4, steps=40, seed=3, ids=ids, progress=False)
    c = out["counts"]
    assert c["episodes"] == 8 and c["NaN checks"] >= 2, c
    assert {k: c[k] for k in fuzz.ID_FAILURE_KEYS} == {k: 0 for k in fuzz.ID_FAILURE_KEYS}, out["failures"][:1]

    step = vcnc_gym.ContouringEnv.step

    def nan_reward_on_divergence(self, action):  # what the kernel did before this issue
        obs, reward, terminated, truncated, info = step(self, action)
        return obs, (math.nan if info["diverged"] else reward), terminated, truncated, info

    monkeypatch.setattr(vcnc_gym.ContouringEnv, "step", nan_reward_on_divergence)
    bad = fuzz.fuzz_ids(episodes=2, steps=40, seed=3, ids=(OMEGA,), progress=False)["counts"]
    assert bad["NaN state not ended as a divergence"] > 0 and bad["non-finite reward"] > 0
