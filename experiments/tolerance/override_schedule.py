"""The tolerance task's third classical opponent: a look-ahead through the feed override dial (issue 37, item 2).

On a feed-override id (:class:`~vcnc_gym.envs.FeedOverrideEnv`) the reference is the id's S-curve, re-timed by the
override.  A CNC can turn that dial itself, from the part program it reads ahead: the feed it would plan with a
look-ahead (the top feed F, the path's normal and tangential acceleration within A) divided by the S-curve's own
feed at the same point of the path.  This is the tolerance agent's own action space (the dial, at the id's
``override_rate``, up to its ``max_override``) with a classical law in it, and ``ff-pid-online`` (the one classical
controller that runs on a re-timed reference: ``CLASSICAL`` of ``experiments/feed-override/feed_override.py``) on the axes, on
the nominal machine's commissioning or, with ``--controller ff-pid-online@machine``, on each machine's own (an
identification run per plant on the id's own reference before its runs, as the look-ahead search's ``@machine``
controllers):

- **the schedule** (:func:`dial_schedule`, :func:`vcnc_gym.envs.retiming.lookahead_dial`): along the path's arc
  s, ``v(s) = min(F, sqrt(A / |kappa(s)|), m v_S(s))`` (m the dial's top, v_S the S-curve's speed: within the dial's
  reach, from rest; the tolerance ids' v1 left the last term out), then ``v(s)^2`` limited to change by at most
  ``2 A`` per mm of arc, backward and forward (the look-ahead's braking and accelerating, Altintas, Manufacturing Automation, 2nd ed.
  2012, ch. 6); the override is ``v(s)`` over the S-curve's speed at s, within [0, ``max_override``].  The env
  runs it (``FeedOverrideEnv(lookahead=(F, A))``, the dial at 100 %);
- **causal as a CNC is**: the override at each control period is read at the interpolator's own point of the path
  (the re-timed reference's clock), never at the tool's measured position or the plant's state;
- **the grid and the choices** are :mod:`tolerance`'s: F at the feeds of
  :data:`tolerance.FEED_FACTORS` the dial reaches, A at
  :data:`tolerance.ACCELERATIONS`, every setting on every plant (the nominal one and the bench's
  ``--plants`` draws), then refined as the look-ahead search refines its own (:func:`refine_schedule`: bisection
  toward the next faster setting on the nominal plant, settings between each plant's choice and its neighbours); the
  builder's setting is the fastest within T on the nominal plant, the commissioned machine the fastest on each plant
  (:func:`tolerance.tolerance_table`).

``python experiments/tolerance/override_schedule.py --id VCNC-OmegaTolerance-v2 --plants 20 --json OUT`` prints the
table and writes the runs in the search's format, so that ``python experiments/tolerance/tolerance.py --agents BENCH
--search OUT`` judges a tolerance agent against this opponent too.
"""

from __future__ import annotations

import argparse
import math
import sys
import time

import numpy as np

from vcnc_gym.validation import integer

from tolerance import (
    ACCELERATIONS,
    FEED_FACTORS,
    GridRun,
    Setting,
    format_table,
    own_task,
    refine,
    refine_machines,
    runs_json,
    tolerance_table,
    write_search,
)

__all__ = [
    "CONTROLLER",
    "CONTROLLERS",
    "LABEL",
    "label",
    "schedule_settings",
    "dial_schedule",
    "run_schedule",
    "refine_schedule",
    "main",
]

#: The axes' controller under the scheduled dial (by default), and those it may be.
CONTROLLER = "ff-pid-online"
CONTROLLERS = ("ff-pid-online", "ff-pid-online@machine")
_SUFFIX = ", look-ahead dial"


def label(controller: str) -> str:
    """The opponent's name in the tables: the axes' controller under the dial."""
    return controller + _SUFFIX


#: The default opponent's name in the tables.
LABEL = label(CONTROLLER)


def _feed_override_env(env_id: str, **kwargs):
    """``gym.make(env_id, **kwargs)`` of a feed-override id; a ValueError naming any other id."""
    import gymnasium as gym

    if not str(gym.spec(env_id).entry_point).endswith(":FeedOverrideEnv"):
        raise ValueError(f"--id: {env_id} is not a feed-override id (its dial is what the schedule turns)")
    return gym.make(env_id, **kwargs)


def schedule_settings(env) -> list[Setting]:
    """The grid on the feed-override env ``env``: the feeds of :data:`FEED_FACTORS` times its programmed feed that its
    dial reaches (fastest first), each at every acceleration of :data:`ACCELERATIONS` (mm/s^2)."""
    u = env.unwrapped
    feed = float(u.task.feedrate_profile.feedrate)
    feeds = [round(f * feed, 6) for f in FEED_FACTORS if f <= u.max_override + 1e-12]
    return [Setting(f, a) for f in feeds for a in ACCELERATIONS]


def dial_schedule(env, setting: Setting) -> tuple[np.ndarray, np.ndarray]:
    """The look-ahead's override along the reference of the feed-override env ``env`` at ``setting`` (top feed mm/s,
    acceleration mm/s^2): ``(t, dial)``, the S-curve's own time of each sample (s) and the override there, within
    [0, ``max_override``] (:func:`~vcnc_gym.envs.retiming.lookahead_dial`)."""
    u = env.unwrapped
    return np.asarray(u.task.reference.t, dtype=float), u.lookahead_override(setting.feed, setting.acceleration)


def _episode(env, policy, parameters) -> tuple[float, float]:
    """One episode on the plant ``parameters`` (2, P), the dial at the look-ahead (1): (max contour error um, inf if
    diverged; cycle time s, inf if the tool did not arrive)."""
    obs, _ = env.reset(seed=0, options={"parameters": parameters})
    policy.plan(env)  # a controller commissioned per machine identifies this plant (once)
    peak, start = 0.0, True
    while True:
        a, _ = policy.predict(obs, episode_start=start)
        start = False
        obs, _, terminated, truncated, info = env.step(np.r_[a, 0.0])  # the dial at 100 % of the look-ahead
        peak = max(peak, info["contour_error_max"])
        if terminated or truncated:
            break
    if info["diverged"]:
        return math.inf, math.inf
    return 1e3 * peak, float(info["cycle_time"]) if info["completed"] else math.inf


def run_schedule(env_id: str, setting: Setting, parameters: np.ndarray, controller: str = CONTROLLER) -> GridRun:
    """``controller`` (one of :data:`CONTROLLERS`) on the feed-override id ``env_id`` made with ``lookahead=setting``
    (the env turns its dial to the look-ahead's override at the reference's clock), the dial at 100 %, on every plant
    of ``parameters`` (M, 2, P), one episode each (the runs are sequential: the override env is not batched).  A
    ``@machine`` controller commissions each plant on the id's own reference (one identification run per plant for
    every setting: :func:`~vcnc_baselines.commissioning.record.commission` keeps its records)."""
    import vcnc_baselines

    if controller not in CONTROLLERS:
        raise ValueError(f"controller must be one of {list(CONTROLLERS)}, got {controller!r}")
    env = _feed_override_env(env_id, lookahead=(setting.feed, setting.acceleration))  # validated by the env
    try:
        policy = vcnc_baselines.make(controller, env)
        if controller.endswith("@machine"):
            policy.identify_on(own_task(env_id))
        runs = [_episode(env, policy, p) for p in parameters]
    finally:
        env.close()
    return GridRun(label(controller), setting, np.array([r[0] for r in runs]), np.array([r[1] for r in runs]))


def refine_schedule(env_id: str, runs: list[GridRun], parameters: np.ndarray) -> list[GridRun]:
    """``runs`` and the look-ahead search's two refinements on the dial's settings (every run on every plant): the
    nominal plant's choice per T by bisection (:func:`tolerance.refine`), then settings between
    each plant's choice and its neighbours (:func:`tolerance.refine_machines`); progress on
    stderr."""

    def run(name, setting):  # the runs' label: the controller under the dial
        return run_schedule(env_id, setting, parameters, name.removesuffix(_SUFFIX))

    def progress(text):
        print(text, file=sys.stderr, flush=True)

    runs = refine(env_id, runs, parameters, run=run, progress=progress)
    return refine_machines(env_id, runs, parameters, run=run, progress=progress)


def _run_grid(
    env_id: str, settings: list[Setting], parameters: np.ndarray, t0: float, controller: str = CONTROLLER
) -> list[GridRun]:
    """Every setting on every plant, each acceleration's feeds fastest first, a slower feed run only while some plant
    has no run within the smallest tolerance yet (as the look-ahead search's grid: a slower feed never shortens a
    cycle) and the last one brought some plant's max contour error down by 1 % or more (below the feed at which the
    corners' ``sqrt(A / kappa)`` sets the speed, a lower top feed changes little but the time); progress on
    stderr."""
    from vcnc_gym.envs.feed_override_env import TOLERANCES

    smallest_um = 1e3 * min(TOLERANCES)
    runs = []
    for acceleration in dict.fromkeys(s.acceleration for s in settings):
        within = np.zeros(parameters.shape[0], dtype=bool)
        last = np.full(parameters.shape[0], np.inf)
        for setting in (s for s in settings if s.acceleration == acceleration):
            if within.all():
                break
            r = run_schedule(env_id, setting, parameters, controller)
            runs.append(r)
            within |= (r.max_um <= smallest_um) & np.isfinite(r.cycle_time_s)
            print(
                f"{env_id}, {controller} at {setting.label}: nominal {r.max_um[0]:.4g} um in {r.cycle_time_s[0]:.4g} s; "
                f"{int(within.sum())}/{within.size} plants within {smallest_um:g} um "
                f"({time.perf_counter() - t0:.0f} s)",
                file=sys.stderr,
                flush=True,
            )
            if np.all(r.max_um >= 0.99 * last):
                break
            last = r.max_um
    return runs


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(
        prog="python experiments/tolerance/override_schedule.py", description=__doc__.split("\n\n")[0]
    )
    parser.add_argument("--id", dest="ids", nargs="+", required=True, metavar="ID", help="feed-override ids")
    parser.add_argument(
        "--plants",
        type=int,
        default=20,
        help="plants drawn from the box (default 20, the box's vertices left out; 0: the nominal plant alone)",
    )
    parser.add_argument("--plant-seed", type=int, default=0, help="seed of the plants (default 0, the bench's)")
    parser.add_argument(
        "--controller",
        default=CONTROLLER,
        choices=CONTROLLERS,
        help=f"the axes' controller under the dial (default {CONTROLLER}, the nominal machine's "
        "commissioning; @machine: each plant's own)",
    )
    parser.add_argument("--json", help="write the runs and the tables here (the tolerance search's format)")
    args = parser.parse_args(argv)
    from vcnc_bench.robust import plant_set

    n = integer("--plants", args.plants, 0)
    out = {}
    for env_id in args.ids:
        try:
            env = _feed_override_env(env_id)
        except ValueError as e:
            parser.error(str(e))
        u = env.unwrapped
        if n:
            plants = plant_set(
                u.plant, n, integer("--plant-seed", args.plant_seed, 0), nominal=u.nominal_parameters, max_vertices=0
            )
            parameters, kinds = plants.parameters, plants.kinds
        else:
            parameters, kinds = u.nominal_parameters[None], ["nominal"]
        settings = schedule_settings(env)
        env.close()
        t0 = time.perf_counter()
        runs = _run_grid(env_id, settings, parameters, t0, args.controller)
        runs = refine_schedule(env_id, runs, parameters)
        rows = tolerance_table(runs, kinds)
        print(format_table(env_id, rows), flush=True)
        print(f"({len(runs)} settings of {len(kinds)} plants in {time.perf_counter() - t0:.0f} s)\n", flush=True)
        out[env_id] = {
            "plants": n,
            "plant_seed": args.plant_seed,
            "kinds": list(kinds),
            "rows": rows,
            "runs": runs_json(runs),
        }
    if args.json:
        write_search(args.json, out, "experiments/tolerance/override_schedule.py", argv)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
