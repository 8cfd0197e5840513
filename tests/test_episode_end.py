"""The v1 contouring ids: an episode ends when the tool has reached the end of the contour, and the
observation shows the contour ahead of the tool.

The contour ahead is checked against geomdl: arc lengths from its dense
samples, points, tangents and curvatures from its derivatives.
"""

from __future__ import annotations

import math

import gymnasium as gym
import numpy as np
import pytest
from geomdl_curve import geomdl_curve

import vcnc_baselines
import vcnc_gym  # noqa: F401  (registers the ids)
from vcnc_gym.envs.registry import LEGACY, SUITE


class GeomdlPath:
    """A NurbsCurve rebuilt in geomdl, with an arc-length table from 500 samples per knot span."""

    def __init__(self, curve, per_span: int = 500):
        g, self.a, self.b = geomdl_curve(curve)
        self.g = g
        vk = np.unique(np.array(g.knotvector))
        self.v = np.concatenate([np.linspace(s, e, per_span + 1)[:-1] for s, e in zip(vk[:-1], vk[1:])] + [[1.0]])
        pts = np.array(g.evaluate_list(self.v.tolist()))
        self.s = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(pts, axis=0), axis=1))])

    def at_arc(self, s: float):
        """Point, unit tangent and signed curvature at arc length s (mm) from the start."""
        v = float(np.interp(min(s, self.s[-1]), self.s, self.v))
        d = np.array(self.g.derivatives(v, order=2))
        speed = np.linalg.norm(d[1])
        kappa = (d[1][0] * d[2][1] - d[1][1] * d[2][0]) / speed**3
        return d[0], d[1] / speed, kappa


def _smc_episode(env_id, **kwargs):
    env = gym.make(env_id, **kwargs)
    policy = vcnc_baselines.make("smc", env)
    obs, info = env.reset(seed=0)
    infos = [info]
    done = False
    while not done:
        action, _ = policy.predict(obs, deterministic=True)
        obs, reward, terminated, truncated, info = env.step(action)
        infos.append(info)
        done = terminated or truncated
    return env, infos, reward, terminated, truncated


def test_the_episode_ends_when_the_tool_arrives():
    env, infos, _, terminated, truncated = _smc_episode("VCNC-Omega-v1")
    u = env.unwrapped
    last = infos[-1]
    assert terminated and not truncated and last["completed"] and not last["diverged"]
    # the tool arrives once the reference has ended, within the in-position band, and the episode ends there
    assert u.reference.duration <= last["cycle_time"] <= u.reference.duration + u.task.completion_timeout
    assert last["time"] == pytest.approx(last["cycle_time"])
    assert u.task.contour_length - last["progress"] <= u.task.completion_tolerance
    assert not any(i.get("completed") for i in infos[:-1]) and all("cycle_time" not in i for i in infos[1:-1])
    progress = np.array([i["progress"] for i in infos[1:]])
    assert np.all(np.diff(progress) >= 0)


def test_a_tool_still_short_of_the_end_at_the_time_limit_is_penalised_and_incomplete():
    # SMC arrives at the reference's end on the omega; without any wait and with a 0.1 um band it cannot
    env, infos, reward, terminated, truncated = _smc_episode(
        "VCNC-Omega-v1", completion_timeout=0.0, completion_tolerance=1e-4
    )
    u = env.unwrapped
    last = infos[-1]
    assert terminated and not last["completed"] and not last["diverged"] and "cycle_time" not in last
    remaining = u.task.contour_length - last["progress"]
    assert remaining > 1e-4
    assert last["reward_incomplete"] == pytest.approx(-remaining / u.reward_scale)
    assert reward == pytest.approx(last["reward_contour"] + last["reward_effort"] + last["reward_incomplete"])
    assert last["time"] == pytest.approx(u.reference.duration)


def test_progress_follows_the_closest_point_and_starts_at_zero_on_closed_contours():
    """Progress is the arc length of the tool's closest point (to a reference sample's spacing); on the heart
    and the circle, whose start is their end, it starts at 0, not at the contour's length."""
    for env_id in ("VCNC-Heart-v1", "VCNC-Circle-v1"):
        env = gym.make(env_id)
        u = env.unwrapped
        path = GeomdlPath(u.curve)
        obs, _ = env.reset(seed=0)
        policy = vcnc_baselines.make("smc" if "Heart" in env_id else "nctf", env)
        spacing = np.max(np.linalg.norm(np.diff(u.reference.position, axis=0), axis=1))
        for t in range(3000):
            action, _ = policy.predict(obs, deterministic=True)
            obs, _, terminated, truncated, info = env.step(action)
            if t % 250 == 0:
                _, foot = u.projector.project(info["position"])
                s_foot = float(np.interp((foot - path.a) / (path.b - path.a), path.v, path.s))
                assert info["progress"] <= s_foot + 1e-6
                assert info["progress"] >= s_foot - spacing - 1e-6
        assert 0 < info["progress"] < 0.5 * u.task.contour_length


@pytest.mark.parametrize("env_id", ["VCNC-Omega-v1", "VCNC-CornersSmooth-v1", "VCNC-Circle-v1"])
def test_the_contour_ahead_matches_geomdl(env_id):
    env = gym.make(env_id)
    u = env.unwrapped
    lay = u.layout
    path = GeomdlPath(u.curve)
    policy = vcnc_baselines.make(
        {"VCNC-Omega-v1": "qft", "VCNC-CornersSmooth-v1": "contouring-fb", "VCNC-Circle-v1": "nctf"}[env_id], env
    )
    obs, _ = env.reset(seed=0)
    checked = 0
    for t in range(4000):
        action, _ = policy.predict(obs, deterministic=True)
        obs, _, terminated, truncated, info = env.step(action)
        if t % 97 == 0:
            origin, tangent, _ = path.at_arc(info["progress"])
            normal = np.array([-tangent[1], tangent[0]])
            for j, ahead in enumerate(lay.contour_ahead):
                point, _, kappa = path.at_arc(info["progress"] + ahead)
                rel = point - info["measured_position"]
                np.testing.assert_allclose(lay.contour_preview(obs)[j], [tangent @ rel, normal @ rel], atol=1e-4)
                # curvature: linear between samples, so within the exact values around the point
                near = [path.at_arc(info["progress"] + ahead + d)[2] for d in (-0.02, 0.0, 0.02)]
                assert (
                    min(near) - 1e-3 * abs(kappa) - 1e-4
                    <= lay.contour_curvature(obs)[j]
                    <= max(near) + 1e-3 * abs(kappa) + 1e-4
                )
            checked += 1
        if terminated or truncated:
            break
    assert checked >= 10


def test_v0_ids_keep_their_episode_and_observation():
    """The v0 ids stay registered for agents trained on them: the episode ends 10 ms after the reference,
    and the observation has no contour preview; their shared fields equal v1's."""
    tolerance_v1 = {"VCNC-OmegaTolerance-v1", "VCNC-OmegaToleranceShop-v1"}  # their look-ahead at full feed at once
    assert {e.id for e in LEGACY if not e.id.endswith("-v0")} == tolerance_v1
    assert {e.id for e in LEGACY if e.id.endswith("-v0")} == {
        e.id.replace("-v1", "-v0")
        for e in SUITE
        if e.contouring
        and e.kwargs.get("profile") != "lookahead"
        and "shop_floor" not in e.kwargs  # the shop-floor ids began at v1
        and "program" not in e.kwargs
    }  # so did the G-code ids
    v0 = gym.make("VCNC-Omega-v0").unwrapped
    v1 = gym.make("VCNC-Omega-v1").unwrapped
    assert v0.observation_space.shape == (21,) and v0.layout.contour_ahead == ()
    assert v0.episode_steps == len(v0.reference.t) - 1 + 100
    o0, _ = v0.reset(seed=0)
    o1, _ = v1.reset(seed=0)
    for _ in range(200):
        a = np.array([0.4, -0.3])
        o0, r0, *_ = v0.step(a)
        o1, r1, *_ = v1.step(a)
    for f in (f for f in v0.layout.fields if f.size):
        np.testing.assert_array_equal(v0.layout.get(o0, f.name), v1.layout.get(o1, f.name))
    assert r0 == r1


def test_the_vector_env_reports_cycle_times_only_for_arrived_envs():
    env = gym.make_vec("VCNC-Omega-v1", num_envs=3, vectorization_mode="vector_entry_point", autoreset_mode="Disabled")
    single = gym.make("VCNC-Omega-v1")
    policy = vcnc_baselines.make("smc", single)
    obs, info = env.reset(seed=0)
    done = np.zeros(3, dtype=bool)
    cycle = np.full(3, math.nan)
    while not done.all():
        actions, _ = policy.predict(obs, deterministic=True)
        actions[1] = 0.0  # env 1 does not move: it diverges on the tracking bound
        obs, _, terminated, truncated, info = env.step(actions)
        cycle[info["_cycle_time"]] = info["cycle_time"][info["_cycle_time"]]
        done |= terminated | truncated
    assert np.isfinite(cycle[[0, 2]]).all() and math.isnan(cycle[1])
    assert cycle[0] == cycle[2]


def test_the_kernel_search_agrees_with_numpy():
    """The progress' and preview's search (galloping, then bisection) against np.searchsorted, ties included."""
    from vcnc_gym.envs.step_kernel import _last_at_or_below

    rng = np.random.default_rng(0)
    column = np.sort(np.round(rng.uniform(0, 50, 400), 1))  # many ties
    samples = np.column_stack([column, column])
    for _ in range(2000):
        lo = int(rng.integers(0, len(column)))
        value = float(column[lo] + rng.uniform(0, 60) * rng.integers(0, 2))
        expected = np.searchsorted(column, value, side="right") - 1
        assert _last_at_or_below(samples, 1, value, lo) == max(expected, lo)
