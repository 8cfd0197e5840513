"""vcnc_gym.evaluation.run_episode, the plots and the vcnc-bench command."""

from __future__ import annotations

import json
import math
import re

import gymnasium as gym
import numpy as np
import pytest

import vcnc_gym
import vcnc_bench as bench
from vcnc_bench.policies import PolicyKind
from vcnc_gym.evaluation import plot_contour_errors, plot_contours, run_episode, sharp_corners

OMEGA = "VCNC-Omega-v1"


class PDPolicy:
    """PD tracking controller with SB3's predict: u = kp e + kd (v_ref - v) in V, action = u / 5 V.

    Records the episode_start flags and checks that the state it returned
    last is the state it is given (SB3's state threading).
    """

    def __init__(self, layout, kp=300.0, kd=1.0):
        self.layout, self.kp, self.kd = layout, kp, kd
        self.starts = []
        self.state_mismatches = 0
        self._last_state = None

    def predict(self, observation, state=None, episode_start=None, deterministic=True):
        self.starts.append(bool(np.asarray(episode_start).reshape(-1)[0]))
        if state is not self._last_state:
            self.state_mismatches += 1
        lay = self.layout
        u = self.kp * lay.tracking_error(observation) + self.kd * (
            lay.reference_velocity(observation) - lay.velocity(observation)
        )
        self._last_state = (len(self.starts),)  # a fresh object every call
        return np.clip(u / 5.0, -1.0, 1.0).astype(np.float32), self._last_state


@pytest.fixture(scope="module")
def omega_pd():
    env = gym.make(OMEGA)
    policy = PDPolicy(env.unwrapped.layout)
    return env, policy, run_episode(policy, env, seed=0)


# -- run_episode ----------------------------------------------------------------------
def test_run_episode_metrics_match_the_traces(omega_pd):
    env, _, res = omega_pd
    n = env.unwrapped.episode_steps
    assert res.episode_steps == n
    assert res.terminated and not res.truncated and not res.diverged
    for trace, shape in [
        (res.time, (n,)),
        (res.contour_error, (n,)),
        (res.position, (n, 2)),
        (res.reference_position, (n, 2)),
        (res.command, (n, 2)),
    ]:
        assert trace.shape == shape
        assert np.all(np.isfinite(trace))
    e_um = 1e3 * res.contour_error
    assert res.max_contour_error_um == pytest.approx(e_um.max(), rel=1e-12)
    assert res.mean_contour_error_um == pytest.approx(e_um.mean(), rel=1e-12)
    assert res.rms_contour_error_um == pytest.approx(math.sqrt(np.mean(e_um**2)), rel=1e-12)
    assert res.mean_contour_error_um < res.rms_contour_error_um < res.max_contour_error_um
    track = 1e3 * np.hypot(*(res.reference_position - res.position).T)
    assert res.max_tracking_error_um == pytest.approx(track.max(), rel=1e-12)
    # one control period per step, ending where the reference ends plus the settling time
    dt = env.unwrapped.dt
    np.testing.assert_allclose(np.diff(res.time), dt, rtol=1e-9)
    assert res.time[-1] == pytest.approx(n * dt)
    np.testing.assert_allclose(res.reference_position[-1], env.unwrapped.reference.position[-1], atol=1e-9)
    assert res.wall_s > 0


def test_run_episode_records_what_a_hand_written_loop_sees(omega_pd, pd_episode):
    env, _, res = omega_pd
    infos = pd_episode(env)[0]  # the same PD loop written out by hand (tests/conftest.py), no run_episode
    assert len(infos) == res.episode_steps
    np.testing.assert_array_equal(res.contour_error, [i["contour_error"] for i in infos])
    np.testing.assert_array_equal(res.position, [i["position"] for i in infos])
    np.testing.assert_array_equal(res.reference_position, [i["reference_position"] for i in infos])
    np.testing.assert_array_equal(res.command, [i["command"] for i in infos])
    np.testing.assert_array_equal(res.time, [i["time"] for i in infos])


def test_run_episode_speaks_sb3_episode_start_and_state(omega_pd):
    _, policy, res = omega_pd
    assert len(policy.starts) == res.episode_steps
    assert policy.starts[0] is True and not any(policy.starts[1:])
    assert policy.state_mismatches == 0  # None first, then always the state it returned last


def test_run_episode_runs_an_sb3_agent_and_stops_on_truncation():
    ppo = pytest.importorskip("stable_baselines3").PPO
    env = gym.make(OMEGA, max_episode_steps=300)  # a short TimeLimit: the env warns, that is expected
    model = ppo("MlpPolicy", env, device="cpu", seed=0, n_steps=64, batch_size=64)
    calls = []
    res = run_episode(model, env, progress=calls.append, progress_every=100)
    assert res.episode_steps == 300 and res.truncated and not res.terminated
    assert res.contour_error.shape == (300,)
    assert calls == [100, 100, 100]


# -- plots ------------------------------------------------------------------------------
def test_sharp_corners_of_the_omega_are_its_two_small_radius_corners():
    """The env's docstring: the omega's corners have radius 0.19 mm."""
    env = gym.make(OMEGA)
    corners = sharp_corners(env, n=3)
    assert len(corners) == 3
    radii = sorted(1.0 / k for _, k in corners)
    assert 0.15 < radii[0] <= radii[1] < 0.25 and radii[2] > 0.5
    pts = np.array([p for p, _ in corners])
    gaps = [np.hypot(*(a - b)) for i, a in enumerate(pts) for b in pts[i + 1 :]]
    assert min(gaps) > 2.0  # mm: three different places, not one corner three times


def _assert_png(path):
    import matplotlib.image as mpimg

    data = path.read_bytes()
    assert data[:8] == b"\x89PNG\r\n\x1a\n" and len(data) > 10_000
    img = mpimg.imread(path)
    assert img.ndim == 3 and img.shape[0] > 300 and img.shape[1] > 300
    assert img[..., :3].std() > 0.01  # not a blank canvas


def test_plots_are_written(omega_pd, tmp_path):
    env, _, res = omega_pd
    results = {"pd": res}
    plot_contours(results, env, tmp_path / "c.png")
    plot_contour_errors(results, env, tmp_path / "e.png")
    _assert_png(tmp_path / "c.png")
    _assert_png(tmp_path / "e.png")


# -- vcnc-bench ---------------------------------------------------------------------------
def _install_pd(monkeypatch):
    """Register kind "pd" ("pd:KP", KP in V/mm) the way a trained-agent kind would be."""
    bench.policy_kinds()  # the installed kinds first, so that "pd" is added to them
    monkeypatch.setitem(
        bench.POLICY_KINDS,
        "pd",
        PolicyKind("pd", make=lambda arg, env: PDPolicy(env.unwrapped.layout, kp=float(arg or 300.0))),
    )


def _parse_table(text):
    """Rows of the printed table: {(env, policy): [cells after the policy]}."""
    rows = {}
    for line in text.splitlines():
        cells = line.split()
        if cells and cells[0] in vcnc_gym.ENV_IDS:
            rows[(cells[0], cells[1])] = cells[2:]
    return rows


def test_bench_json_holds_what_was_printed_and_plots_exist(monkeypatch, tmp_path, capsys):
    _install_pd(monkeypatch)
    out_json, plots = tmp_path / "out" / "bench.json", tmp_path / "plots"
    code = bench.main(
        [
            "--env",
            OMEGA,
            "--policy",
            "pd:300",
            "--policy",
            "pd:100",
            "--json",
            str(out_json),
            "--plots",
            str(plots),
            "--no-progress",
        ]
    )
    assert code == 0
    out = capsys.readouterr().out
    assert re.search(r"total wall time \d+\.\d s", out)

    records = json.loads(out_json.read_text())["records"]
    rows = _parse_table(out)
    assert [(r["env"], r["policy"]) for r in records] == [(OMEGA, "pd:300"), (OMEGA, "pd:100")]
    assert set(rows) == {(OMEGA, "pd:300"), (OMEGA, "pd:100")}
    for rec in records:
        assert {
            "env",
            "policy",
            "max_contour_error_um",
            "mean_contour_error_um",
            "rms_contour_error_um",
            "episode_steps",
            "wall_s",
        } <= set(rec)
        mx, mean, rms, paper, ratio, cycle, steps, wall, diverged, complete = rows[(rec["env"], rec["policy"])]
        assert complete == ("yes" if rec["completed"] else "no")
        assert cycle == ("-" if rec["cycle_time_s"] is None else f"{rec['cycle_time_s']:.4f}")
        for printed, key in [
            (mx, "max_contour_error_um"),
            (mean, "mean_contour_error_um"),
            (rms, "rms_contour_error_um"),
            (wall, "wall_s"),
        ]:
            assert float(printed) == pytest.approx(rec[key], abs=0.005 + 1e-9), key
        assert paper == "-" and ratio == "-" and rec["paper_max_contour_error_um"] is None
        assert int(steps) == rec["episode_steps"] <= gym.make(OMEGA).unwrapped.task.time_limit_steps
        assert diverged == ("yes" if rec["diverged"] else "no")

    # the JSON numbers are run_episode's: rerun the first policy independently
    env = gym.make(OMEGA)
    again = run_episode(PDPolicy(env.unwrapped.layout, kp=300.0), env, seed=0)
    assert records[0]["max_contour_error_um"] == pytest.approx(again.max_contour_error_um, rel=1e-12)
    assert records[0]["rms_contour_error_um"] == pytest.approx(again.rms_contour_error_um, rel=1e-12)
    # two different gains, two different runs: each row is its own policy's
    assert records[0]["max_contour_error_um"] != pytest.approx(records[1]["max_contour_error_um"], rel=1e-3)

    for kind in ("contour", "error", "deviation"):
        _assert_png(plots / f"{OMEGA}_{kind}.png")


def test_paper_table_covers_every_env_and_baseline():
    jahanpour_envs = ("VCNC-Heart", "VCNC-Omega")
    assert set(bench.PAPER_TABLE_4) == {(e, p) for e in jahanpour_envs for p in ("qft", "smc", "fuzzy")}
    assert bench.paper_figures("VCNC-Heart-v1", "qft")["max_contour_error_um"] == 10.14
    assert bench.paper_figures("VCNC-Omega-v0", "fuzzy")["max_contour_error_um"] == 44.19
    assert bench.paper_figures("VCNC-OmegaLookahead-v1", "fuzzy") == {}  # the paper ran the S-curve
    vcnc_baselines = pytest.importorskip("vcnc_baselines")
    assert {p for _, p in bench.PAPER_TABLE_4} <= set(vcnc_baselines.names())


def test_resolve_policy_builds_baselines_by_name():
    vcnc_baselines = pytest.importorskip("vcnc_baselines")
    from vcnc_bench.kinds.baseline import applies

    env = gym.make(OMEGA)
    names = [n for n in vcnc_baselines.names() if applies(n, env)]
    assert {"qft", "smc", "fuzzy"} <= set(names)
    for name in names:
        for spec in (name, f"baseline:{name}"):
            policy = bench.resolve_policy(spec, env)
            assert type(policy) is type(vcnc_baselines.make(name, env))
            assert bench.policy_label(spec) == name


@pytest.mark.parametrize(
    "argv, must_name",
    [
        (["--env", "VCNC-Nope-v0"], list(vcnc_gym.ENV_IDS)),
        (["--policy", "nope"], ["KIND:ARGUMENT", "baseline"]),
        (["--policy", "nope:x"], ["KIND:ARGUMENT", "baseline"]),
    ],
)
def test_unknown_env_or_policy_exits_2_naming_the_valid_choices(argv, must_name, capsys):
    with pytest.raises(SystemExit) as exc:
        bench.main(argv + ["--no-progress"])
    assert exc.value.code == 2
    err = capsys.readouterr().err
    assert "unknown" in err
    for name in must_name:
        assert name in err
    if "--policy" in argv:
        vcnc_baselines = pytest.importorskip("vcnc_baselines")
        for name in vcnc_baselines.names():
            assert name in err


def test_feedrate_option_runs_a_slower_pass_without_paper_columns(tmp_path, capsys):
    out = tmp_path / "slow.json"
    assert (
        bench.main(
            ["--env", "VCNC-Omega-v1", "--policy", "smc", "--feedrate", "20", "--no-progress", "--json", str(out)]
        )
        == 0
    )
    (record,) = json.loads(out.read_text())["records"]
    assert record["paper_max_contour_error_um"] is None
    assert record["episode_steps"] == gym.make("VCNC-Omega-v1", feedrate=20.0).unwrapped.episode_steps
    assert not record["diverged"] and record["max_contour_error_um"] < 50.0  # feasible at 20 mm/s
    assert "at 20 mm/s" in capsys.readouterr().out


def test_plant_option_runs_the_env_on_another_plant_as_gym_make_does(tmp_path, capsys):
    """--plant NAME makes every env with plant=NAME: the bench's figure is run_episode's on that env (an
    independent gym.make), the papers' columns stay empty, and a bad name is an argument error naming it."""
    import vcnc_baselines

    out = tmp_path / "plant.json"
    assert (
        bench.main(
            [
                "--env",
                "VCNC-Butterfly-v1",
                "--policy",
                "zpetc",
                "--plant",
                "current_feed_drive",
                "--no-progress",
                "--json",
                str(out),
            ]
        )
        == 0
    )
    (record,) = json.loads(out.read_text())["records"]
    env = gym.make("VCNC-Butterfly-v1", plant="current_feed_drive")
    assert env.unwrapped.plant.name == "current_feed_drive"
    mine = run_episode(vcnc_baselines.make("zpetc", env), env)
    assert record["max_contour_error_um"] == pytest.approx(mine.max_contour_error_um, rel=1e-12)
    assert record["paper_max_contour_error_um"] is None
    with pytest.raises(SystemExit) as exc:
        bench.main(["--env", "VCNC-Butterfly-v1", "--policy", "zpetc", "--plant", "nope", "--no-progress"])
    assert exc.value.code == 2 and "nope" in capsys.readouterr().err


def test_shop_floor_option_runs_the_env_on_its_shop_floor_as_gym_make_does(tmp_path):
    """--shop-floor makes every env (and every --program) with shop_floor=True: the bench's figure is
    run_episode's on that env (an independent gym.make), and the papers' columns stay empty."""
    import vcnc_baselines
    from vcnc_bench.programs import program_recipes
    from vcnc_gym.plants.shop_floor import ShopFloorModel

    out = tmp_path / "shop.json"
    assert (
        bench.main(
            ["--env", "VCNC-Butterfly-v1", "--policy", "zpetc", "--shop-floor", "--no-progress", "--json", str(out)]
        )
        == 0
    )
    data = json.loads(out.read_text())
    (record,) = data["records"]
    assert data["settings"]["shop_floor"] is True
    env = gym.make("VCNC-Butterfly-v1", shop_floor=True)
    assert isinstance(env.unwrapped.plant, ShopFloorModel)
    mine = run_episode(vcnc_baselines.make("zpetc", env), env)
    assert record["max_contour_error_um"] == pytest.approx(mine.max_contour_error_um, rel=1e-12)
    assert record["max_contour_error_um"] != pytest.approx(
        run_episode(
            vcnc_baselines.make("zpetc", gym.make("VCNC-Butterfly-v1")), gym.make("VCNC-Butterfly-v1")
        ).max_contour_error_um,
        rel=1e-3,
    )  # the shop floor is another machine
    assert record["paper_max_contour_error_um"] is None
    (recipe,) = program_recipes([("part", "G1 X1 F600")], 0.01, shop_floor=True)
    assert recipe[2]["shop_floor"] is True


def test_commissioned_predictive_variants_are_extras_of_the_default_table():
    from vcnc_bench.kinds.baseline import KIND

    env = gym.make("VCNC-HeartShop-v1")
    defaults, extras = KIND.defaults(env), KIND.extras(env)
    assert "lq-preview" in defaults and "mpc" in extras
    assert {"lq-preview@commissioned", "mpc@commissioned"} <= set(extras)
    assert not {"lq-preview@commissioned", "mpc@commissioned"} & set(defaults)
