"""Shared test fixtures and the ``slow`` marker.

``slow`` marks a test that takes more than about 10 s on the 2-core CI machine.
``make test`` (CI) runs every test but the slow ones (``pytest -m "not slow"``), which keeps the CI run well
under 15 minutes; ``make test-all`` runs them too.
"""

from __future__ import annotations

import numpy as np
import pytest

#: The PD tracking loop the tests use as a plain, hand-written controller:
#: 300 V/mm on the tracking error and 1 V s/mm on the velocity error, the
#: action being the voltage over the 5 V limit of Jahanpour et al.'s drive.
PD_KP = 300.0  # V/mm
PD_KD = 1.0  # V s/mm
PD_LIMIT = 5.0  # V


def pytest_configure(config):
    config.addinivalue_line("markers", "slow: takes more than ~10 s on CI's 2 cores (deselect with -m 'not slow')")


#: Tests measured among the slowest of ``make test`` (``pytest --durations``, 2 workers on 2 shared cores: 20-160 s
#: each there), marked slow here so that CI's whole run (install, tests, the main job) fits its budget;
#: ``make test-all`` runs them.  Each is a heavier twin of a test that stays (another id, a longer run).
SLOW_BY_MEASUREMENT = (
    "test_agents.py::test_short_run_writes_agents_checkpoints_and_logs",
    "test_baselines_controllers.py::test_fuzzy_inference_matches_skfuzzy",
    "test_bench.py::test_plant_option_runs_the_env_on_another_plant_as_gym_make_does",
    "test_envs.py::test_random_action_sequences_keep_observations_finite_and_in_space",
    "test_env_fuzz.py::test_the_fuzz_sees_a_nan",
    "test_docs_guides.py::test_page_code_runs[guides/add-a-controller.md]",
    "test_contour.py::test_around_centres_of_curvature[omega]",
    "test_episode_end.py::test_progress_follows_the_closest_point_and_starts_at_zero_on_closed_contours",
    "test_bench.py::test_run_episode_runs_an_sb3_agent_and_stops_on_truncation",
    "test_baselines_closed_loop.py::test_omega_completes_on_every_vertex_of_the_uncertainty_box[fuzzy]",
    "test_bench_robust.py::test_positioning_env_runs_as_a_batch_of_single_envs",
    "test_agents.py::test_an_env_without_a_native_vector_env_trains_on_sb3s",
    "test_envs.py::test_halving_the_substep_changes_the_contour_error_trace_by_under_one_percent",
    "test_agents.py::test_cli_resume_goes_on_to_a_new_total",
    "test_contour.py::test_around_centres_of_curvature[heart]",
    "test_agents.py::test_direct_agent_on_the_plain_env_matches_its_repeating_env",
    "test_baselines_closed_loop.py::test_heart_completes[fuzzy-nominal]",
    "test_agent_files_and_run_data.py::test_a_failed_fresh_start_never_blocks_a_retry",
    "test_docs_guides.py::test_page_code_runs[guides/add-a-contour.md]",
    "test_agents.py::test_residual_agent_on_the_plain_env_matches_its_wrapper",
    "test_envs.py::test_default_control_period_makes_jahanpour_qft_loop_stable_on_every_vertex",
    "test_contour_warm.py::test_concurrent_calls_from_prange_threads",
    "test_baselines_controllers.py::test_sampled_loop_stable_at_0p1_ms_not_at_1_ms",
    "test_baselines_closed_loop.py::test_heart_completes[fuzzy-vertex0]",
    "test_baselines_closed_loop.py::test_heart_completes[qft-vertex0]",
)

#: The ids test_envs.py's per-id checks run on in ``make test``: one of every kind and machine with a short episode
#: (the others are marked slow by :func:`pytest_collection_modifyitems`).
FAST_ENV_IDS = (
    "VCNC-Omega-v1",
    "VCNC-Circle-v1",
    "VCNC-CircleShop-v1",
    "VCNC-OmegaLookaheadShop-v1",
    "VCNC-GCode-v1",
    "VCNC-RandomContour-v1",
    "VCNC-OmegaOverride-v1",
    "VCNC-Step-v0",
)


def pytest_collection_modifyitems(config, items):
    slow = pytest.mark.slow
    for item in items:
        node = item.nodeid.split("tests/", 1)[-1]
        if node in SLOW_BY_MEASUREMENT:
            item.add_marker(slow)
        elif node.startswith("test_envs.py::") and "[VCNC-" in node:
            if not any(node.endswith(f"[{e}]") or f"[{e}-" in node for e in FAST_ENV_IDS):
                item.add_marker(slow)


def _pd_action(layout, obs, kp=PD_KP, kd=PD_KD):
    """The PD loop's normalised action for ``obs`` (one env or a batch), float32 like the observation."""
    u = kp * layout.tracking_error(obs) + kd * (layout.reference_velocity(obs) - layout.velocity(obs))
    return np.clip(u / PD_LIMIT, -1.0, 1.0).astype(np.float32)


def _pd_episode(env, kp=PD_KP, kd=PD_KD, seed=0):
    """Run the PD loop for one episode of ``env``; return (infos, terminated, truncated) of its last step."""
    layout = env.unwrapped.layout
    obs, _ = env.reset(seed=seed)
    infos = []
    while True:
        obs, _, term, trunc, info = env.step(_pd_action(layout, obs, kp, kd))
        infos.append(info)
        if term or trunc:
            return infos, term, trunc


@pytest.fixture
def pd_action():
    """``pd_action(layout, obs, kp=300, kd=1)``: the PD loop's action (V/mm, V s/mm, over 5 V)."""
    return _pd_action


@pytest.fixture
def pd_episode():
    """``pd_episode(env, kp=300, kd=1, seed=0)``: one PD episode, (infos, terminated, truncated)."""
    return _pd_episode


@pytest.fixture(scope="module")
def one_torch_thread():
    """Torch on one thread for a module (the agents' networks are tiny: one thread is several times faster than
    threads fighting over 2 cores); the previous count restored after it."""
    torch = pytest.importorskip("torch")
    n = torch.get_num_threads()
    torch.set_num_threads(1)
    yield
    torch.set_num_threads(n)


def _short_run_in_the_bench(tmp_path, env_id: str, change, timesteps: int):
    import json

    import yaml

    import vcnc_bench as bench
    from vcnc_agents.cli import main as train_main
    from vcnc_agents.config import load_hyperparameters

    entry = load_hyperparameters(env_id)
    change(entry)
    config = tmp_path / "ppo.yml"
    config.write_text(yaml.safe_dump({env_id: entry}, sort_keys=False))
    run = tmp_path / "run"
    assert (
        train_main(
            [
                "--env",
                env_id,
                "--config",
                str(config),
                "--timesteps",
                str(timesteps),
                "--eval-freq",
                "0",
                "--output",
                str(run),
                "--no-progress",
            ]
        )
        == 0
    )
    recorded = yaml.safe_load((run / "best" / "config.yml").read_text())
    out = tmp_path / "bench.json"
    assert bench.main(["--env", env_id, "--policy", f"ppo:{run / 'best'}", "--no-progress", "--json", str(out)]) == 0
    return run, recorded, json.loads(out.read_text())["records"][0]


@pytest.fixture
def short_run_in_the_bench():
    """``short_run_in_the_bench(tmp_path, env_id, change, timesteps)``: the id's shipped entry changed in place by
    ``change(entry)``, trained by ``vcnc-train`` for ``timesteps`` (evaluated at the end), its best agent scored by
    ``vcnc-bench``: (run folder, the agent's config.yml as a dict, the bench's record)."""
    return _short_run_in_the_bench
