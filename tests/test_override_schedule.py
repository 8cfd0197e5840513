"""The look-ahead through the feed override dial (``experiments/tolerance/override_schedule.py``): the tolerance task's third
classical opponent."""

from __future__ import annotations

import json
import math

import gymnasium as gym
import numpy as np
import pytest

import vcnc_gym  # noqa: F401  (registers the ids)
from benchmark_script import study_module
from vcnc_gym.envs import step_kernel as sk

osch = study_module("tolerance", "override_schedule")
tl = study_module("tolerance", "tolerance")

ID = "VCNC-OmegaTolerance-v2"
V1 = "VCNC-OmegaTolerance-v1"  # the look-ahead at its top feed from the first sample (lookahead_reach=False)


@pytest.fixture(scope="module")
def env():
    e = gym.make(ID)
    yield e
    e.close()


@pytest.mark.parametrize("env_id", [ID, V1])
@pytest.mark.parametrize("feed, acceleration", [(150.0, 1000.0), (100.0, 2600.0), (40.0, 500.0)])
def test_the_dial_is_the_fastest_feed_within_the_look_ahead_s_limits(env_id, feed, acceleration):
    """The scheduled feed (the dial times the S-curve's speed) is the closed form of the look-ahead computed here
    another way: the least over every sample j of ``sqrt(L_j^2 + 2 A |s - s_j|)`` (braking into and accelerating
    out of every limit at A), with ``L_j = min(F, sqrt(A / kappa_j), m v_j)`` (v2: within the dial's reach m times
    the S-curve's speed v_j, so from rest at both ends) or, in v1, without the last term and the dial clipped at m
    after (where it is, slower than that look-ahead, never faster)."""
    env = gym.make(env_id)
    t, dial = osch.dial_schedule(env, tl.Setting(feed, acceleration))
    s = env.unwrapped.task.reference_arrays.samples
    arc = s[:, sk.REF_ARC]
    speed = np.hypot(s[:, sk.REF_VELOCITY], s[:, sk.REF_VELOCITY + 1])
    top = env.unwrapped.max_override
    limit2 = np.minimum(feed, np.sqrt(acceleration / np.maximum(np.abs(s[:, sk.REF_CURVATURE]), 1e-12))) ** 2
    if env_id == ID:
        limit2 = np.minimum(limit2, (top * speed) ** 2)
    closed = np.empty(arc.size)
    for i in range(0, arc.size, 512):
        rows = slice(i, i + 512)
        closed[rows] = np.sqrt((limit2[None, :] + 2 * acceleration * np.abs(arc[rows, None] - arc[None, :])).min(1))
    moving = speed > 1e-9
    inside = (dial > 0) & (dial < top) & moving
    assert inside.sum() > arc.size // 4
    assert np.allclose(dial[inside] * speed[inside], closed[inside], rtol=1e-9, atol=1e-9)
    assert np.all(dial[~inside & moving] * speed[~inside & moving] <= closed[~inside & moving] * (1 + 1e-9))
    if env_id == ID:  # within reach: nowhere clipped, and from rest (at A) to the top of its first limit
        assert np.allclose(dial[moving] * speed[moving], closed[moving], rtol=1e-9, atol=1e-9)
        first = np.argmax(moving)
        assert dial[first] * speed[first] <= math.sqrt(2 * acceleration * (arc[first] - arc[0]) + 1e-18) * (1 + 1e-9)
    else:  # v1: at the top feed's dial (clipped) at the first moving sample
        assert dial[np.argmax(moving)] == top
    assert np.array_equal(t, env.unwrapped.reference.t)
    with pytest.raises(ValueError, match="acceleration"):
        env.unwrapped.lookahead_override(feed, -acceleration)


def test_the_grid_is_the_dial_s_reach(env):
    """Feeds up to the dial's top (150 % of the omega's 100 mm/s), every acceleration of the look-ahead search."""
    settings = osch.schedule_settings(env)
    assert max(x.feed for x in settings) == 150.0
    assert {x.acceleration for x in settings} == set(tl.ACCELERATIONS)
    assert len(settings) == sum(f <= 1.5 for f in tl.FEED_FACTORS) * len(tl.ACCELERATIONS)
    with pytest.raises(ValueError, match="not a feed-override id"):
        osch.run_schedule("VCNC-Omega-v1", settings[0], env.unwrapped.nominal_parameters[None])


def test_a_scheduled_run_reads_only_the_interpolator_s_clock():
    """The env's look-ahead dial (``lookahead=(F, A)``, the dial at 100 %) is the schedule read at the re-timed
    reference's own clock (what a CNC's interpolator knows): replayed here on the plain dial, step by step from the
    env's ``info["reference_time"]``, the same max contour error (to the float32 rounding of the dial) and cycle."""
    import vcnc_baselines

    setting = tl.Setting(150.0, 1500.0)
    plain = gym.make(ID, lookahead=None)
    run = osch.run_schedule(ID, setting, plain.unwrapped.nominal_parameters[None])
    t, dial = osch.dial_schedule(plain, setting)
    policy = vcnc_baselines.make("ff-pid-online", plain)
    obs, _ = plain.reset(seed=0, options={"parameters": plain.unwrapped.nominal_parameters})
    tau, peak, start = 0.0, 0.0, True
    while True:
        a, _ = policy.predict(obs, episode_start=start)
        start = False
        obs, _, terminated, truncated, info = plain.step(np.r_[a, 2.0 * float(np.interp(tau, t, dial)) / 1.5 - 1.0])
        tau, peak = info["reference_time"], max(peak, info["contour_error_max"])
        if terminated or truncated:
            break
    assert info["completed"] and run.cycle_time_s[0] == pytest.approx(info["cycle_time"], abs=2 * plain.unwrapped.dt)
    assert run.max_um[0] == pytest.approx(1e3 * peak, rel=1e-5)
    assert run.cycle_time_s[0] > float(plain.unwrapped.reference.t[-1]) / 1.5  # it slows for the corners


def test_the_command_writes_the_search_s_format(monkeypatch, tmp_path, capsys):
    """``--json`` holds the tolerance search's rows and runs, which ``tolerance.py``'s comparison reads as its
    opponents."""
    monkeypatch.setattr(osch, "schedule_settings", lambda env: [tl.Setting(150.0, 2000.0), tl.Setting(100.0, 2000.0)])
    out = tmp_path / "schedule.json"
    assert osch.main(["--id", ID, "--plants", "0", "--json", str(out)]) == 0
    data = json.loads(out.read_text())
    assert data["settings"]["command"].startswith("python experiments/tolerance/override_schedule.py")
    entry = data[ID]
    assert [r["tolerance_um"] for r in entry["rows"]] == [5.0, 10.0, 20.0]
    opponents = tl._opponents(entry, 0.02)
    cycle = entry["runs"][0]["cycle_time_s"][0]
    assert math.isfinite(cycle) and opponents["per-plant search"][0] <= cycle
    assert "look-ahead dial" in capsys.readouterr().out
    # refined as the look-ahead search is: bisection from 100 mm/s (within 5 um on the nominal plant) toward 150
    feeds = [r["setting"]["feed"] for r in entry["runs"]]
    assert feeds[:2] == [150.0, 100.0] and any(100.0 < f < 150.0 for f in feeds[2:])


def test_the_contouring_mpc_refuses_a_dial_it_does_not_set_alone():
    """The MPCC maps its progress to the dial itself: on the tolerance ids (a look-ahead under the dial) it refuses,
    naming it; with ``lookahead=None`` it runs on their dial to 150 %."""
    import vcnc_baselines

    with pytest.raises(ValueError, match="lookahead="):
        vcnc_baselines.make("mpcc", gym.make(ID))
    assert vcnc_baselines.make("mpcc", gym.make(ID, lookahead=None)).max_override == 1.5


def test_the_dial_on_each_machine_s_commissioning_is_the_same_one_plant_at_a_time_and_in_the_bench_s_batch():
    """``run_schedule(controller="ff-pid-online@machine")`` (one episode per plant, each plant commissioned when its
    episode starts) and the robust bench's loop over a batch of the same plants (``run_plants``: the controller
    commissions the batch's plants after its reset, ``SingleEnvBatch.parameters``) give every plant the same max
    contour error and cycle time; the nominal design gives the hard plant another."""
    from vcnc_bench.robust import SingleEnvBatch, plant_set, run_plants

    import vcnc_baselines

    shop = "VCNC-OmegaToleranceShop-v2"
    setting = tl.Setting(150.0, 1500.0)
    u = gym.make(shop).unwrapped
    params = plant_set(u.plant, 2, 0, nominal=u.nominal_parameters, max_vertices=0).parameters[1:]
    alone = osch.run_schedule(shop, setting, params, "ff-pid-online@machine")
    nominal = osch.run_schedule(shop, setting, params)
    assert alone.controller == "ff-pid-online@machine, look-ahead dial"

    class AtTheLookAhead:  # the dial at 100 % of the look-ahead, the axes' law planned on the batch
        def __init__(self, law):
            self.law = law

        def plan(self, batch):
            self.law.plan(batch)

        def predict(self, obs, episode_start=None, deterministic=True):
            a, _ = self.law.predict(obs, episode_start=episode_start)
            return np.c_[a, np.zeros(len(a), dtype=a.dtype)], None

    kwargs = {"lookahead": (setting.feed, setting.acceleration)}
    batch = SingleEnvBatch(shop, 2, **kwargs)
    law = vcnc_baselines.make("ff-pid-online@machine", gym.make(shop, **kwargs))
    law.identify_on(tl.own_task(shop))
    for order in ([0, 1], [1, 0]):  # env i's sensor noise is seeded i: each plant first once, as run_schedule's are
        runs = run_plants(AtTheLookAhead(law), batch, params[order], decision_period=u.decision_period)
        assert np.array_equal(batch.parameters, params[order]) and batch.task.plant.name == u.plant.name
        assert law.coefficients.shape[0] == 2
        assert runs.max_um[0] == pytest.approx(alone.max_um[order[0]], rel=1e-12), order
        assert runs.cycle_time_s[0] == alone.cycle_time_s[order[0]], order
    assert not np.allclose(nominal.max_um, alone.max_um, rtol=0.05)
    with pytest.raises(ValueError, match="controller must be one of"):
        osch.run_schedule(shop, setting, params, "ff-pid")
