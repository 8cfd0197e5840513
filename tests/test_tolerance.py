"""The tolerance task (issue 37, item 2): FeedOverrideEnv's ``tolerance`` reward and the classical search for the
fastest look-ahead within T (``experiments/tolerance/tolerance.py``)."""

from __future__ import annotations

import itertools
import math

import gymnasium as gym
import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env

import vcnc_baselines
import vcnc_gym  # noqa: F401  (registers the ids)
from benchmark_script import study_module
from vcnc_gym.envs import step_kernel as sk

tl = study_module("tolerance", "tolerance")
classical_front = study_module("feed-override", "feed_override").classical_front

ID = "VCNC-OmegaOverride-v1"
#: The tolerance study's recipe (its entries of the override ids), as ``vcnc-train --config`` reads it.
RECIPE = "experiments/tolerance/recipes/tolerance.yml"


def _dialled_episode(env, dial_of_step, seed=0, steps=None):
    """``ff-pid-online`` with the override dial ``dial_of_step(k)``: the (reward, info) of every step."""
    policy = vcnc_baselines.make("ff-pid-online", env)
    obs, _ = env.reset(seed=seed)
    out, start, k = [], True, 0
    while steps is None or k < steps:
        a, _ = policy.predict(obs, episode_start=start)
        start = False
        obs, reward, terminated, truncated, info = env.step(np.r_[a, dial_of_step(k)])
        out.append((reward, info))
        k += 1
        if terminated or truncated:
            break
    return out


def test_the_tolerance_reward_is_time_plus_the_priced_excess():
    """Under the same commands the env with a tolerance moves exactly as without one, and its reward is, per step,
    minus the decision period over the full-feed duration d and ``violation_cost * d * min(1, excess / T)``, as
    computed here from the plain env's infos; the violations are counted."""
    tol, cost = 0.004, 25.0
    dial = lambda k: 1.0 if k < 2500 else -0.2  # noqa: E731  (full feed through the first corners, then slower)
    plain = gym.make(ID)
    tolerant = gym.make(ID, tolerance=tol, violation_cost=cost, progress_reward=2.5)
    a, b = _dialled_episode(plain, dial), _dialled_episode(tolerant, dial)
    length = float(tolerant.unwrapped.task.reference_arrays.samples[-1, sk.REF_ARC])
    assert len(a) == len(b)
    u = tolerant.unwrapped
    d = u.task.action_repeat * u.task.dt / float(u.task.reference.t[-1])
    violations, passed = 0, 0.0
    for (r1, i1), (r2, i2) in zip(a, b):
        assert np.array_equal(i1["position"], i2["position"])
        excess = max(0.0, i1["contour_error_max"] - tol)
        violations += excess > 0
        progress = 2.5 * (i1["progress"] - passed) / length
        passed = i1["progress"]
        assert r2 == pytest.approx(-d - cost * d * min(1.0, excess / tol) + progress, rel=1e-12, abs=1e-15)
        assert i2["tolerance_exceeded"] == (excess > 0)
        assert i2["violations"] == violations
    assert 0 < violations < len(b)  # the test sees both: the S-curve's corners at full feed exceed 4 um
    assert b[-1][1]["completed"]
    assert -sum(i["reward_time"] for _, i in b) == pytest.approx(len(b) * d)
    # the shaping's sum is the contour passed: all of it, but the completion's 20 um
    assert sum(i["reward_progress"] for _, i in b) == pytest.approx(2.5, abs=2.5 * 0.021 / length)


def test_running_out_of_time_costs_the_contour_left_as_if_over_t():
    """At the time limit the tolerance task charges ``violation_cost`` times the fraction of the contour left: the
    plain env's charge (um of contour error: the arc left over the reward scale) over the contour's length (the
    reference's last arc length).  The dial held near 0 leaves most of the omega."""
    plain, tolerant = gym.make(ID), gym.make(ID, tolerance=0.01)
    ((_, i1),) = _dialled_episode(plain, lambda k: -0.9)[-1:]
    ((r2, i2),) = _dialled_episode(tolerant, lambda k: -0.9)[-1:]
    assert not i1["completed"] and not i2["completed"]
    u = tolerant.unwrapped
    length = float(u.task.reference_arrays.samples[-1, sk.REF_ARC])
    left = -i1["reward_incomplete"] * u.task.reward_scale / length
    assert 0.5 < left < 1.0
    assert i2["reward_incomplete"] == pytest.approx(-100.0 * left, rel=1e-12)
    assert r2 == pytest.approx(
        i2["reward_time"] + i2["reward_tolerance"] + i2["reward_progress"] + i2["reward_incomplete"], rel=1e-12
    )


def test_the_tolerance_ids_dial_reaches_150_percent_at_26_per_second():
    """On VCNC-OmegaTolerance-v2's dial alone (``lookahead=None``) the dial held at its top takes the override from 100 % to 150 % at 26/s (a step of
    26 dt per control period, from the rate limit alone) and the tool arrives in the full-feed duration over 1.5,
    plus the ramp's loss (computed here: half the ramp's time times the half-speed it lacks); a third of the way up
    the dial is 50 %, as the half dial of VCNC-OmegaOverride-v1."""
    assert gym.make("VCNC-OmegaTolerance-v2").unwrapped.lookahead == (150.0, 1937.5)  # the id's; the dial alone here:
    env = gym.make("VCNC-OmegaTolerance-v2", lookahead=None).unwrapped
    assert (env.tolerance, env.max_override, env.override_rate) == (0.01, 1.5, 26.0)
    out = _dialled_episode(env, lambda k: 1.0)
    dt, duration = env.dt, float(env.reference.t[-1])
    ramp = [i["override"] for _, i in out[:30]]
    assert ramp == pytest.approx([min(1.5, 1.0 + 26.0 * dt * (k + 1)) for k in range(30)], abs=1e-12)
    assert out[-1][1]["override"] == 1.5
    # the reference's clock reaches its end at (duration + the ramp's lag) / 1.5: over the ramp's 0.5 / 26 s the
    # override averages 1.25, a quarter behind 1.5 (the tool, thrown millimetres off in the corners, arrives later)
    arrival = dt * next(k + 1 for k, (_, i) in enumerate(out) if i["reference_time"] >= duration - 1e-12)
    assert arrival == pytest.approx((duration + 0.25 * 0.5 / 26.0) / 1.5, abs=2 * dt)
    half = _dialled_episode(env, lambda k: -1.0 / 3.0, steps=200)
    assert half[-1][1]["override"] == pytest.approx(0.5, abs=1e-7)  # the action is float32


def test_the_violations_restart_with_the_episode():
    env = gym.make(ID, tolerance=0.004)
    first = _dialled_episode(env, lambda k: 1.0, steps=3000)
    assert first[-1][1]["violations"] > 0
    again = _dialled_episode(env, lambda k: 1.0, steps=5)
    assert again[-1][1]["violations"] == 0


def test_the_tolerance_env_passes_gymnasium_s_checker():
    check_env(gym.make(ID, tolerance=0.01).unwrapped, skip_render_check=True)


@pytest.mark.parametrize(
    "kwargs, word",
    [
        ({"tolerance": -0.01}, "tolerance"),
        ({"tolerance": 0.0}, "tolerance"),
        ({"tolerance": "0.01"}, "tolerance"),
        ({"tolerance": True}, "tolerance"),
        ({"tolerance": math.nan}, "tolerance"),
        ({"tolerance": 0.01, "time_cost": 1e-3}, "time_cost"),
        ({"tolerance": 0.01, "violation_cost": -1.0}, "violation_cost"),
        ({"tolerance": 0.01, "progress_reward": -1.0}, "progress_reward"),
    ],
)
def test_a_bad_tolerance_argument_is_refused_by_name(kwargs, word):
    with pytest.raises((ValueError, TypeError), match=word):
        gym.make(ID, **kwargs)


def test_without_a_tolerance_the_env_is_as_it_was():
    env = gym.make(ID).unwrapped
    assert env.tolerance is None and env.time_cost == pytest.approx(1e-3)
    _, info = _dialled_episode(env, lambda k: 1.0, steps=3)[-1]
    assert "violations" not in info and "reward_tolerance" not in info


def test_the_grid_is_the_feed_and_acceleration_where_the_path_is_one_curve():
    heart = tl.search_settings("VCNC-Heart-v1")
    assert len(heart) == len(tl.FEED_FACTORS) * len(tl.ACCELERATIONS)
    assert heart[0] == tl.Setting(150.0, tl.ACCELERATIONS[0])
    circle = tl.search_settings("VCNC-Circle-v1")  # a constant feed: the feed alone
    assert [s.feed for s in circle] == pytest.approx([f * 1.0 for f in tl.FEED_FACTORS])
    assert all(s.acceleration is None for s in circle)
    with pytest.raises(ValueError, match="G-code"):
        tl.search_settings("VCNC-ISO230Circle-v1")
    with pytest.raises(ValueError, match="contouring id"):
        tl.search_settings("VCNC-OmegaOverride-v1")


def _synthetic_runs(rng, plants=6):
    runs = []
    for c, s in itertools.product(
        ("a", "b"), (tl.Setting(100.0, 500.0), tl.Setting(80.0, 500.0), tl.Setting(100.0, 1000.0))
    ):
        cycle = rng.uniform(1.0, 2.0, plants)
        cycle[rng.random(plants) < 0.2] = np.inf
        err = rng.uniform(0.0, 30.0, plants)
        err[rng.random(plants) < 0.1] = np.inf
        runs.append(tl.GridRun(c, s, err, cycle))
    return runs


def test_the_choices_are_the_fastest_run_within_t_found_by_brute_force():
    rng = np.random.default_rng(3)
    for _ in range(20):
        runs = _synthetic_runs(rng)
        kinds = ["nominal"] + ["sample"] * 5
        for tol in (0.005, 0.01, 0.02):
            per_plant = tl.machine_choice(runs, tol, 6)
            for i, choice in enumerate(per_plant):
                ok = [
                    (r.cycle_time_s[i], r.controller, r.setting)
                    for r in runs
                    if r.max_um[i] <= 1e3 * tol and np.isfinite(r.cycle_time_s[i])
                ]
                if not ok:
                    assert choice.controller is None
                else:
                    assert choice.cycle_time_s == min(ok, key=lambda x: x[0])[0]
            builder, run = tl.builder_choice(runs, tol)
            assert builder == per_plant[0]
            row = next(r for r in tl.tolerance_table(runs, kinds, (tol,)))
            if run is not None:
                exceed = sum(
                    1 for i in range(1, 6) if run.max_um[i] > 1e3 * tol or not np.isfinite(run.cycle_time_s[i])
                )
                assert row["builder_exceeded"] == exceed
            assert row["machine_unreached"] == sum(c.controller is None for c in per_plant[1:])


@pytest.mark.slow
def test_a_grid_run_is_the_omega_front_s_planned_run_on_the_nominal_plant():
    """A grid run of ``ff-pid`` on the look-ahead omega, batched over the nominal plant and a drawn one, gives on
    the nominal plant the figures of the omega front's planned run at that setting (``classical_front``: one
    env, ``run_episode``); the drawn plant's differ."""
    env = gym.make("VCNC-OmegaLookahead-v1").unwrapped
    from vcnc_bench.robust import plant_set

    parameters = plant_set(env.plant, 1, 0, nominal=env.nominal_parameters, max_vertices=0).parameters
    runs = tl.run_grid(
        "VCNC-OmegaLookahead-v1", parameters, controllers=("ff-pid",), settings=[tl.Setting(100.0, 2000.0)]
    )
    front = classical_front(policies=("ff-pid",), settings=((100.0, 2000.0),))[0]
    assert runs[0].max_um[0] == pytest.approx(front.max_um, rel=1e-9)
    assert runs[0].cycle_time_s[0] == pytest.approx(front.cycle_time_s, rel=1e-12)
    assert runs[0].max_um[1] != pytest.approx(front.max_um, rel=1e-6)


@pytest.mark.slow
def test_a_machine_commissioned_on_the_id_s_own_reference_runs_another_setting_with_those_records():
    """``identify_on``: a ``@machine`` controller built on a slower look-ahead of the shop-floor omega holds, after
    its plan, the records that commissioning the same plants on the id's own reference gives (computed here through
    ``commission``), not those of its own reference."""
    from vcnc_baselines.commissioning.record import commission
    from vcnc_bench.robust import make_batch, plant_set

    env_id = "VCNC-OmegaLookaheadShop-v1"
    own = gym.make(env_id).unwrapped
    parameters = plant_set(own.plant, 2, 0, nominal=own.nominal_parameters, max_vertices=0).parameters
    kwargs = tl.planned_kwargs(env_id, tl.Setting(60.0, 1000.0))
    env = gym.make(env_id, **kwargs)
    batch = make_batch(env_id, parameters.shape[0], **kwargs)
    policy = vcnc_baselines.make("ff-pid@machine", env)
    policy.identify_on(own.task)
    batch.reset(seed=0, options={"parameters": parameters})
    policy.plan(batch)
    expected = commission(own.task, "machine", parameters)
    assert policy.records == expected
    assert len(policy.records) == 3
    assert commission(env.unwrapped.task, "machine", parameters) != expected  # its own reference's differ
    batch.close()
    with pytest.raises(ValueError, match="identify_on"):
        policy.identify_on(gym.make("VCNC-Circle-v1").unwrapped.task)


@pytest.mark.parametrize(
    "agent_id, searched",
    [
        (ID, "VCNC-OmegaLookahead-v1"),
        ("VCNC-OmegaOverrideShop-v1", "VCNC-OmegaLookaheadShop-v1"),
        ("VCNC-OmegaTolerance-v2", "VCNC-OmegaLookahead-v1"),
        ("VCNC-OmegaToleranceShop-v2", "VCNC-OmegaLookaheadShop-v1"),
        ("VCNC-HeartTolerance-v1", "VCNC-Heart-v1"),
        ("VCNC-HeartToleranceShop-v1", "VCNC-HeartShop-v1"),
    ],
)
def test_the_agent_s_bench_plants_are_the_search_s(agent_id, searched):
    """The tolerance agent runs on the override id (``vcnc-bench --plants 20``), its opponents on the look-ahead id:
    the same plant model, so ``plant_set`` with the same seed draws the same plants for both."""
    from vcnc_bench.robust import plant_set

    a = gym.make(agent_id).unwrapped
    b = gym.make(searched).unwrapped
    pa = plant_set(a.plant, 20, 0, nominal=a.nominal_parameters)  # the bench's: the vertices after the draws
    pb = plant_set(b.plant, 20, 0, nominal=b.nominal_parameters, max_vertices=0)
    assert np.array_equal(pa.parameters[:21], pb.parameters)


def test_the_comparison_scraps_runs_over_t_and_judges_the_cycle_time_by_the_bench_s_rule():
    from scipy.stats import trim_mean

    rng = np.random.default_rng(5)
    kinds = ["nominal"] + ["sample"] * 12
    seeds = []
    for _ in range(3):
        cycle = rng.uniform(0.70, 0.74, 13)
        err = rng.uniform(2.0, 6.0, 13)
        seeds.append(
            {
                "policy": "a",
                "group": "g",
                "per_plant": {"kind": kinds, "cycle_time_s": cycle.tolist(), "max_um": err.tolist()},
            }
        )
    opponent_cycle = rng.uniform(0.72, 0.75, 13)
    search = {
        "plants": 12,
        "plant_seed": 0,
        "kinds": kinds,
        "runs": [],
        "rows": [
            {
                "tolerance_um": 5.0,
                "builder": {"controller": None, "setting": None},
                "machine_per_plant": [{"cycle_time_s": c} for c in opponent_cycle],
            }
        ],
    }
    (row,) = tl.compare(seeds, search, 0.005)
    x = np.array(
        [
            [np.inf if e > 5.0 else c for c, e in zip(s["per_plant"]["cycle_time_s"], s["per_plant"]["max_um"])]
            for s in seeds
        ]
    )
    assert row["agent_over_t"] == [int(np.sum(np.array(s["per_plant"]["max_um"][1:]) > 5.0)) for s in seeds]
    assert row["agent_nominal_s"] == pytest.approx(list(x[:, 0]))
    assert row["agent_faster"] == sum(int(a < b) for s in x for a, b in zip(s[1:], opponent_cycle[1:]))
    letter = (
        all(c < opponent_cycle[0] for c in x[:, 0])
        and np.median(x[:, 1:]) < np.median(opponent_cycle[1:])
        and sum(row["agent_over_t"]) == 0
    )  # the opponent scraps none
    assert row["goal_letter"] is bool(letter)
    v = row["verdict"]
    assert v["iqm_y"] == pytest.approx(trim_mean(opponent_cycle[1:], 0.25))
    finite = np.sort(x[:, 1:].ravel())  # the IQM with infinities: the middle half of the sorted runs
    k = int(0.25 * finite.size)
    middle = finite[k : finite.size - k]
    assert float(v["iqm_x"]) == pytest.approx(middle.mean())  # "inf" where the middle half holds a scrapped run
    with pytest.raises(ValueError, match="T = 10"):
        tl.compare(seeds, search, 0.01)
    with pytest.raises(ValueError, match="other plants"):
        tl.compare(seeds, {**search, "kinds": ["nominal", "vertex"] + kinds[2:]}, 0.005)
    with_vertices = [
        {**s, "per_plant": {k: v + ([1.0] if k != "kind" else ["vertex"]) for k, v in s["per_plant"].items()}}
        for s in seeds
    ]
    assert tl.compare(with_vertices, search, 0.005) == [row]  # the bench's vertices are left out


def test_vcnc_train_s_tolerance_goes_into_the_entry_s_env_kwargs(tmp_path):
    from vcnc_agents.cli import main
    from vcnc_agents.run_session import prepare_run

    _, config, _ = prepare_run(ID, tmp_path / "run", config_file=RECIPE, tolerance=0.005)
    assert config.env_kwargs == {"randomize": True, "tolerance": 0.005}
    _, shop, _ = prepare_run("VCNC-OmegaOverrideShop-v1", tmp_path / "shop", config_file=RECIPE)
    assert shop.env_kwargs == {"randomize": True}
    assert shop.env["signature"]["id"] == "VCNC-OmegaOverrideShop-v1"  # what keeps its agents off the ideal omega
    with pytest.raises(ValueError, match="tolerance"):  # a contouring id has no tolerance task
        prepare_run("VCNC-Heart-v1", tmp_path / "heart", tolerance=0.005)
    with pytest.raises(ValueError, match="tolerance"):
        prepare_run(ID, tmp_path / "bad", config_file=RECIPE, tolerance=-1.0)
    with pytest.raises(SystemExit):
        main(["--resume", str(tmp_path / "run"), "--tolerance", "0.01"])


def test_a_controller_of_the_agent_s_bench_run_is_an_opponent_too():
    kinds = ["nominal"] + ["sample"] * 4
    agent = {"policy": "a", "group": "g", "per_plant": {"kind": kinds, "cycle_time_s": [0.7] * 5, "max_um": [4.0] * 5}}
    mpcc = {
        "policy": "mpcc",
        "per_plant": {
            "kind": kinds,
            "cycle_time_s": [0.68, 0.69, None, 0.7, 0.71],
            "max_um": [4.5, 6.0, 3.0, 4.0, 4.9],
        },
    }
    search = {
        "plants": 4,
        "plant_seed": 0,
        "kinds": kinds,
        "runs": [],
        "rows": [
            {
                "tolerance_um": 5.0,
                "builder": {"controller": None, "setting": None},
                "machine_per_plant": [{"cycle_time_s": 0.75}] * 5,
            }
        ],
    }
    rows = tl.compare([agent], search, 0.005, others=[mpcc])
    row = next(r for r in rows if r["opponent"] == "`mpcc`")
    assert row["opponent_nominal_s"] == 0.68
    assert row["opponent_over_t"] == 2  # 6.0 um over T, and the unfinished run
    assert row["agent_over_t"] == [0]
    # slower at the nominal plant (0.7 against 0.68 s): the goal's letter is not met, though faster at the median
    assert row["agent_median_s"] < row["opponent_median_s"] and row["goal_letter"] is False
    assert row["agent_faster"] == 3  # the MPCC's two scrapped runs and its 0.71 s; 0.7 against 0.7 is not faster
    assert "| 3 of 1 x 4 |" in tl.format_comparison(rows) and "| not met |" in tl.format_comparison(rows)


def test_the_contouring_mpc_runs_on_a_feed_override_id_only():
    with pytest.raises(ValueError, match="feed-override id"):
        tl.run_mpcc("VCNC-OmegaLookahead-v1", np.zeros((1, 2, 6)))


def test_a_cap_beyond_the_dial_s_reach_is_refused_before_the_grid_runs(capsys):
    """The MPCC's progress caps go to the dial's top, 1.5 x the programmed feed: a larger one is named by the
    command before any run (and by ``run_mpcc`` itself)."""
    with pytest.raises(SystemExit):
        tl.main(["--id", "VCNC-Heart-v1", "--mpcc", "VCNC-HeartTolerance-v1", "--mpcc-caps", "1.5", "2"])
    assert "--mpcc-caps: each in (0, 1.5]" in capsys.readouterr().err
    with pytest.raises(ValueError, match="caps: at most 1.5"):
        tl.run_mpcc("VCNC-OmegaOverride-v1", np.zeros((1, 2, 6)), caps=(1.0, 1.6))


@pytest.mark.slow
def test_the_search_s_contouring_mpc_is_the_omega_front_s():
    """``run_mpcc`` on the nominal plant (a batch of one) gives the omega front's MPCC point at 100 mm/s
    (``mpcc_front``: one env, ``run_episode``)."""
    mpcc_front = study_module("feed-override", "feed_override").mpcc_front

    env = gym.make(ID).unwrapped
    (run,) = tl.run_mpcc(ID, env.nominal_parameters[None], caps=(1.0,))
    (front,) = mpcc_front(speeds=(100.0,))
    assert run.max_um[0] == pytest.approx(front.max_um, rel=1e-9)
    assert run.cycle_time_s[0] == pytest.approx(front.cycle_time_s, rel=1e-12)
    assert run.setting == tl.Setting(100.0)


def test_the_per_plant_refinement_runs_between_each_plant_s_choice_and_its_faster_neighbour(monkeypatch):
    """``refine_machines`` runs, per T, settings evenly between each plant's choice and the next faster feed of its
    column (and the next larger acceleration), each once (the runs stubbed: their settings are the point)."""
    ran = []

    def fake_run(env_id, controller, setting, parameters, curve):
        ran.append((controller, setting))
        return tl.GridRun(controller, setting, np.full(2, 100.0), np.full(2, 1.0))

    monkeypatch.setattr(tl, "_run", fake_run)
    inf = np.inf
    runs = [
        tl.GridRun("a", tl.Setting(100.0, 1000.0), np.array([30.0, 30.0]), np.array([1.0, 1.0])),
        tl.GridRun("a", tl.Setting(80.0, 1000.0), np.array([3.0, 30.0]), np.array([1.2, 1.2])),
        tl.GridRun("a", tl.Setting(60.0, 1000.0), np.array([2.0, 4.0]), np.array([1.5, 1.5])),
        tl.GridRun("a", tl.Setting(80.0, 2000.0), np.array([50.0, 50.0]), np.array([1.1, inf])),
    ]
    out = tl.refine_machines("VCNC-OmegaLookahead-v1", runs, np.zeros((2, 2, 6)), tolerances=(0.005,), points=3)
    assert out[:4] == runs
    expected = [("a", tl.Setting(60.0 + 5.0 * k, 1000.0)) for k in (1, 2, 3)]  # plant 1: 60 -> 80
    expected += [("a", tl.Setting(80.0 + 5.0 * k, 1000.0)) for k in (1, 2, 3)]  # plant 0: 80 -> 100
    expected += [("a", tl.Setting(80.0, 1000.0 + 250.0 * k)) for k in (1, 2, 3)]  # and 1000 -> 2000 mm/s^2
    assert sorted(ran, key=str) == sorted(expected, key=str)


def test_the_command_writes_the_search_and_compares_an_agent_with_it(monkeypatch, tmp_path, capsys):
    """``main``: a search (its grid stubbed) written with its settings, then ``--agents`` read against it."""
    import json

    rng = np.random.default_rng(2)
    fake = _synthetic_runs(rng, plants=3)
    monkeypatch.setattr(tl, "run_grid", lambda env_id, parameters, progress=None: fake)
    monkeypatch.setattr(tl, "refine", lambda env_id, runs, parameters, progress=None: runs)
    monkeypatch.setattr(tl, "refine_machines", lambda env_id, runs, parameters, progress=None: runs)
    out = tmp_path / "search.json"
    assert tl.main(["--id", "VCNC-OmegaLookahead-v1", "--plants", "2", "--json", str(out)]) == 0
    data = json.loads(out.read_text())
    assert data["settings"]["command"].endswith(f"--json {out}") and "cpu" in data["settings"]["provenance"]
    assert [r["tolerance_um"] for r in data["VCNC-OmegaLookahead-v1"]["rows"]] == [5.0, 10.0, 20.0]
    kinds = data["VCNC-OmegaLookahead-v1"]["kinds"]
    bench = {
        "robust": [
            {
                "env": ID,
                "policy": f"ppo:x/seed{k}/final",
                "group": "ppo:x/final",
                "per_plant": {"kind": kinds, "cycle_time_s": [0.7] * 3, "max_um": [1.0] * 3},
            }
            for k in range(2)
        ]
    }
    (tmp_path / "bench.json").write_text(json.dumps(bench))
    assert tl.main(["--agents", str(tmp_path / "bench.json"), "--search", str(out), "--tolerance", "0.01"]) == 0
    printed = capsys.readouterr().out
    assert "ppo:x/final (2 seeds)" in printed and "| 10 | per-plant search |" in printed


def test_several_searches_are_one_whose_choices_are_the_fastest_of_any(tmp_path, capsys):
    """``merge_searches``: per plant the least cycle time of the searches' choices (numpy's elementwise minimum here),
    the builder's setting the fastest nominal choice; ``--search A B:ID`` judges the agent against the merged search;
    searches over other plants are refused."""
    import json

    rng = np.random.default_rng(5)
    kinds = ["nominal", "sample", "sample", "sample"]

    def search(name):
        runs = [
            {
                "controller": name,
                "setting": {"feed": 100.0, "acceleration": a},
                "max_um": [1.0] * 4,
                "cycle_time_s": list(rng.uniform(0.6, 0.8, 4)),
            }
            for a in (1000.0, 2000.0)
        ]
        rows = []
        for t in (5.0, 10.0, 20.0):
            per_plant = [
                {
                    "controller": name,
                    "setting": runs[k % 2]["setting"],
                    "cycle_time_s": runs[k % 2]["cycle_time_s"][k],
                    "max_um": 1.0,
                }
                for k in range(4)
            ]
            rows.append({"tolerance_um": t, "builder": per_plant[0], "machine_per_plant": per_plant, "n_plants": 3})
        return {"plants": 3, "plant_seed": 0, "kinds": kinds, "rows": rows, "runs": runs}

    a, b = search("ff-pid"), search("look-ahead dial")
    merged = tl.merge_searches([a, b])
    for k in range(3):
        cycles = [np.array([c["cycle_time_s"] for c in x["rows"][k]["machine_per_plant"]]) for x in (a, b)]
        assert np.array_equal([c["cycle_time_s"] for c in merged["rows"][k]["machine_per_plant"]], np.minimum(*cycles))
        assert merged["rows"][k]["builder"]["cycle_time_s"] == min(cycles[0][0], cycles[1][0])
    assert len(merged["runs"]) == 4
    with pytest.raises(ValueError, match="other plants"):
        tl.merge_searches([a, {**b, "plant_seed": 1}])
    (tmp_path / "a.json").write_text(json.dumps({"VCNC-OmegaLookahead-v1": a}))
    (tmp_path / "b.json").write_text(json.dumps({"VCNC-OmegaTolerance-v1": b, "other": b}))
    bench = {
        "robust": [
            {
                "env": ID,
                "policy": f"ppo:x/seed{k}/final",
                "group": "ppo:x/final",
                "per_plant": {"kind": kinds, "cycle_time_s": [0.5] * 4, "max_um": [1.0] * 4},
            }
            for k in range(3)
        ]
    }
    (tmp_path / "bench.json").write_text(json.dumps(bench))
    assert (
        tl.main(
            [
                "--agents",
                str(tmp_path / "bench.json"),
                "--search",
                str(tmp_path / "a.json"),
                f"{tmp_path / 'b.json'}:VCNC-OmegaTolerance-v1",
                "--tolerance",
                "0.01",
            ]
        )
        == 0
    )
    printed = capsys.readouterr().out
    assert "VCNC-OmegaLookahead-v1 (a.json) and VCNC-OmegaTolerance-v1 (b.json)" in printed  # each search's file
    per_plant = np.minimum(*[[c["cycle_time_s"] for c in x["rows"][1]["machine_per_plant"]] for x in (a, b)])
    assert f"| 10 | per-plant search | 0.5, 0.5, 0.5 | 0.5 | 0+0+0 of 3 x 3 | {per_plant[0]:.4g} |" in printed


def test_the_table_of_the_nominal_plant_alone_prints_no_median():
    """``--plants 0``: no sampled plant, so the medians over them are '-' (they were printed as nan)."""
    format_table = tl.format_table

    choice = {
        "controller": "mpcc",
        "setting": {"feed": 150.0, "acceleration": None},
        "cycle_time_s": 2.1518,
        "max_um": 4.55,
    }
    row = {
        "tolerance_um": 5.0,
        "builder": choice,
        "machine_nominal": choice,
        "machine_median_cycle_time_s": math.nan,
        "machine_unreached": 0,
        "n_plants": 0,
        "builder_median_cycle_time_s": math.nan,
        "builder_exceeded": 0,
    }
    line = format_table("VCNC-Heart-v1", [row]).splitlines()[-1]
    assert line == "| 5 | `mpcc` 150 mm/s: 2.152 s, 4.55 um | - | 0 of 0 | - | 0 of 0 |"
