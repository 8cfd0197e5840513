"""The front of max contour error against cycle time on the omega: a feed-override agent against the classical
controllers on the look-ahead feed (issue 24, item 3).

Jahanpour et al. (2014)'s omega at 100 mm/s on the S-curve (``VCNC-Omega-v1``) asks twenty times the drives'
acceleration at its 0.19 mm corners.  A CNC avoids that in one of two ways, and this report puts them side by
side on the nominal plant:

- **planned**: the look-ahead feed (``VCNC-OmegaLookahead-v1``, :class:`~vcnc_gym.motion.LookaheadFeedrate`)
  slows down for every corner before the part runs; each classical controller of :data:`CLASSICAL` runs it at
  each setting of :data:`LOOKAHEAD`: the programmed feed and the path acceleration limit (jerk 30 times it, the
  suite's ratio), the two numbers a CNC engineer commissions the look-ahead with, so that the classical side is
  tuned for time as well as for error (the strongest-opponent rule);
- **online**: the agent on ``VCNC-OmegaOverride-v1`` sets a feed override on the S-curve while it runs (it sees
  the contour 4 mm ahead); one point per cap of its override (:data:`CAPS`: the agent's dial scaled so the
  override never exceeds the cap, as an operator limits the dial).
- **operator**: the classical servo that runs under an override (``ff-pid-online``) on ``VCNC-OmegaOverride-v1``
  with the dial held at each cap from the start, as an operator who turns the override down for the whole part.
- **mpcc**: the contouring MPC (:mod:`vcnc_baselines.predictive.mpcc`, Lam, Manzie and Good 2010) on
  ``VCNC-OmegaOverride-v1``, which chooses its own progress along the path and sets the override from it; one
  point per cap of its progress speed (:data:`MPCC_SPEEDS`), the classical answer to the agent.

:func:`pareto` keeps the points no other point beats in both cycle time and max error: the classical front is
the Pareto set of every planned run.

Run ``python experiments/feed-override/feed_override.py --plot bench-out/omega_front.png`` (the shipped agent, or
``--agent FOLDER``; ``--no-mpcc`` leaves out the contouring MPC, whose episodes take a minute or more each).

**Every other contouring id** (``--id ID``, or ``--id all`` for :data:`CONTOURING_IDS`; :func:`id_front`): the
same kinds of run on that id's contour and machine (the shop floor's included), nominal plant, the agent left out
(one is shipped for the omega only):

- **planned**: each classical controller of :data:`CLASSICAL` on the id itself with its programmed feed scaled by
  :data:`FEED_FRACTIONS` (its own feed planner: S-curve, look-ahead, JLAP or constant), or, on a G-code id, whose
  F words set the feed, with the look-ahead's path acceleration and jerk scaled by :data:`LIMIT_FACTORS`;
- **operator**: ``ff-pid-online`` on the id's override version (:func:`override_env`: the id's task in
  :class:`~vcnc_gym.envs.feed_override_env.FeedOverrideEnv`) with the override held at each of :data:`CAPS`;
- **mpcc**: the contouring MPC on the override version, its progress speed capped at the programmed feed (the
  fastest block's, on a G-code id) times each of :data:`MPCC_FRACTIONS`.

``--json FILE`` writes the points.
"""

from __future__ import annotations

import argparse
import math
from dataclasses import dataclass

import numpy as np

__all__ = [
    "FrontPoint",
    "KINDS",
    "LOOKAHEAD",
    "JERK_PER_ACCELERATION",
    "CAPS",
    "CLASSICAL",
    "OPERATOR",
    "FixedOverride",
    "SCURVE",
    "MPCC_SPEEDS",
    "FEED_FRACTIONS",
    "MPCC_FRACTIONS",
    "LIMIT_FACTORS",
    "classical_front",
    "override_env",
    "planned_settings",
    "id_front",
    "scurve_points",
    "operator_front",
    "agent_front",
    "mpcc_front",
    "pareto",
    "verdicts",
    "plot_fronts",
    "read_fronts",
    "format_front",
    "plot_front",
    "main",
]

#: Look-ahead settings of the planned runs: (programmed feed mm/s, path acceleration limit mm/s^2).  The suite's
#: default limit is 1000 mm/s^2 (motion.lookahead: 38 % of the drives' ~2.6e3 at 5 V); the drives take more.
LOOKAHEAD = (
    (100.0, 1000.0),
    (80.0, 1000.0),
    (60.0, 1000.0),
    (45.0, 1000.0),
    (30.0, 1000.0),
    (100.0, 1500.0),
    (100.0, 2000.0),
    (100.0, 2600.0),
    (150.0, 2000.0),
    (150.0, 2600.0),
)
#: The jerk limit of a planned run, as a multiple of its acceleration limit, 1/s (the suite's 3e4 / 1000).
JERK_PER_ACCELERATION = 30.0
#: Caps of the agent's override and the operator's fixed overrides (1 = 100 %); the env's time limit, three times the
#: reference's duration at full feed, ends an override held below 1/3 before the contour's end.
CAPS = (1.0, 0.8, 0.6, 0.45, 0.35)
#: The classical controllers of the front: the strongest causal ones on the omega (README's table).
CLASSICAL = ("ff-pid", "zpetc", "ff-ccc", "ff-pid-online")
#: The controllers run on the S-curve itself: QFT, the strongest causal one there (README's table).
SCURVE = ("qft",)
#: The classical controller run under a fixed override: the one that needs no table computed ahead.
OPERATOR = "ff-pid-online"


#: The caps of the contouring MPC's progress speed, mm/s (its ``v_max``; the programmed feed is 100 mm/s; below
#: ~30 mm/s the omega's 51 mm take longer than the env's time limit, three times the S-curve's 0.63 s).
MPCC_SPEEDS = (100.0, 80.0, 60.0, 45.0, 35.0)

#: The kinds of run on the front: a classical controller on a planned look-ahead feed, a controller on the S-curve
#: itself, a classical controller under an operator's fixed override, the agent with its own override, the
#: contouring MPC with its own progress.
KINDS = ("planned", "s-curve", "operator", "agent", "mpcc")

#: The programmed feed's fractions of an id's planned runs (:func:`id_front`): the omega's :data:`MPCC_SPEEDS` over
#: its 100 mm/s.
FEED_FRACTIONS = (1.0, 0.8, 0.6, 0.45, 0.35)
#: The contouring MPC's caps on another id, as fractions of its programmed feed: three of the omega's five (its
#: episodes cost 3-4 ms a control period, 10 min for the three on the heart's 3.2 s).
MPCC_FRACTIONS = (1.0, 0.6, 0.35)
#: A G-code id's planned runs: its look-ahead's path acceleration and jerk (the plant's declared limits,
#: :func:`vcnc_gym.gcode.path_limits`) times these.
LIMIT_FACTORS = (2.0, 1.5, 1.0, 0.5, 0.25)


@dataclass(frozen=True)
class FrontPoint:
    """One run: ``policy`` at ``setting`` (a feed and path acceleration, or an override), its cycle time (s), max
    and RMS contour error (um), and its ``kind`` (:data:`KINDS`)."""

    policy: str
    setting: str
    cycle_time_s: float
    max_um: float
    rms_um: float
    kind: str = "planned"


def _point(policy_name, setting, result, kind) -> FrontPoint:
    cycle = result.cycle_time_s if result.completed else math.inf
    return FrontPoint(policy_name, setting, cycle, result.max_contour_error_um, result.rms_contour_error_um, kind)


def classical_front(policies=CLASSICAL, settings=LOOKAHEAD) -> list[FrontPoint]:
    """Each classical controller on ``VCNC-OmegaLookahead-v1`` at each (feed mm/s, path acceleration mm/s^2) of
    ``settings``, nominal plant."""
    import gymnasium as gym

    import vcnc_baselines
    from vcnc_gym.evaluation import run_episode
    from vcnc_gym.motion import LookaheadFeedrate

    curve = gym.make("VCNC-OmegaLookahead-v1").unwrapped.curve
    points = []
    for feed, acceleration in settings:
        jerk = JERK_PER_ACCELERATION * acceleration
        profile = LookaheadFeedrate(curve, feed, acceleration, jerk, acceleration, jerk)
        env = gym.make("VCNC-OmegaLookahead-v1", feedrate=float(feed), profile=profile)
        for name in policies:
            points.append(
                _point(
                    name,
                    f"{feed:g} mm/s, {acceleration:g} mm/s^2",
                    run_episode(vcnc_baselines.make(name, env), env),
                    "planned",
                )
            )
        env.close()
    return points


def pareto(points) -> list[FrontPoint]:
    """The points no other point beats in both cycle time and max error (finished runs only), fastest first."""
    done = sorted((p for p in points if math.isfinite(p.cycle_time_s)), key=lambda p: (p.cycle_time_s, p.max_um))
    front, best = [], math.inf
    for p in done:
        if p.max_um < best:
            front.append(p)
            best = p.max_um
    return front


class _Capped:
    """An agent's policy with its override dial scaled so that the override never exceeds ``cap``."""

    def __init__(self, policy, cap: float):
        self.policy, self.cap = policy, float(cap)

    def predict(self, observation, state=None, episode_start=None, deterministic=True):
        action, state = self.policy.predict(
            observation, state=state, episode_start=episode_start, deterministic=deterministic
        )
        action = np.array(action, copy=True)  # its own dtype: the axes' commands reach the env unrounded
        action[..., 2] = self.cap * (np.clip(action[..., 2], -1.0, 1.0) + 1.0) - 1.0
        return action, state


class FixedOverride:
    """A two-axis controller on ``VCNC-OmegaOverride-v1`` with the override dial held at ``override`` (1 = 100 %)
    from the first step: the operator's override, not a learned one."""

    def __init__(self, policy, override: float):
        from vcnc_gym.validation import positive

        if positive("override", override, "1 = 100 %") > 1.0:
            raise ValueError(f"override must be at most 1 (100 %), got {override!r}")
        self.policy, self.dial = policy, 2.0 * float(override) - 1.0

    def predict(self, observation, state=None, episode_start=None, deterministic=True):
        action, state = self.policy.predict(
            observation, state=state, episode_start=episode_start, deterministic=deterministic
        )
        action = np.asarray(action)
        dial = np.full(action.shape[:-1] + (1,), self.dial, dtype=action.dtype)
        return np.concatenate([action, dial], axis=-1), state


def operator_front(policy: str = OPERATOR, caps=CAPS, env_id: str = "VCNC-Omega-v1") -> list[FrontPoint]:
    """``policy`` on ``env_id``'s override version (:func:`override_env`; the omega's is ``VCNC-OmegaOverride-v1``,
    the S-curve) with the override held at each cap, nominal plant."""
    import vcnc_baselines
    from vcnc_gym.evaluation import run_episode

    env = override_env(env_id)
    points = [
        _point(
            f"{policy} @ override",
            f"{100 * c:g} %",
            run_episode(FixedOverride(vcnc_baselines.make(policy, env), c), env),
            "operator",
        )
        for c in caps
    ]
    env.close()
    return points


def agent_front(agent, caps=CAPS, label: str = "agent") -> list[FrontPoint]:
    """The agent (a folder of ``agents/trained`` or a run's ``best``) on ``VCNC-OmegaOverride-v1``, nominal plant,
    once per override cap."""
    import gymnasium as gym

    from vcnc_agents import load_agent
    from vcnc_gym.evaluation import run_episode

    env = gym.make("VCNC-OmegaOverride-v1")
    policy = load_agent(agent, env)
    # at 100 % the agent runs as it is: rescaling its dial rounds it, and the omega's corners amplify that
    points = [
        _point(label, f"cap {100 * c:g} %", run_episode(policy if c == 1.0 else _Capped(policy, c), env), "agent")
        for c in caps
    ]
    env.close()
    return points


def mpcc_front(speeds=MPCC_SPEEDS, env_id: str = "VCNC-Omega-v1", **params) -> list[FrontPoint]:
    """The contouring MPC (``mpcc``) on ``env_id``'s override version (:func:`override_env`; the omega's is
    ``VCNC-OmegaOverride-v1``), nominal plant, once per cap of its progress speed (mm/s); ``params`` go to
    :func:`vcnc_baselines.make` (its weights)."""
    import vcnc_baselines
    from vcnc_gym.evaluation import run_episode

    env = override_env(env_id)
    points = [
        _point(
            "mpcc",
            f"v_max {v:.4g} mm/s",
            run_episode(vcnc_baselines.make("mpcc", env, v_max=float(v), **params), env),
            "mpcc",
        )
        for v in speeds
    ]
    env.close()
    return points


def override_env(env_id: str):
    """The override version of contouring id ``env_id``: its task (contour, plant, shop floor, feed; a G-code
    id's program read as :class:`~vcnc_gym.envs.gcode_env.GCodeEnv` reads it) in
    :class:`~vcnc_gym.envs.feed_override_env.FeedOverrideEnv`, made through ``VCNC-OmegaOverride-v1``'s entry."""
    import gymnasium as gym

    from vcnc_gym.envs.gcode_env import gcode_task_kwargs
    from vcnc_gym.envs.registry import CONTOURING_IDS

    if env_id not in CONTOURING_IDS:
        raise ValueError(f"env_id must be a contouring id ({', '.join(CONTOURING_IDS)}), got {env_id!r}")
    spec = gym.spec(env_id)
    kwargs = dict(spec.kwargs)
    if spec.entry_point.endswith(":GCodeEnv"):
        kwargs = gcode_task_kwargs(kwargs.pop("program", None), **kwargs)
    kwargs.pop("completion_timeout", None)  # the override env's own: its time limit
    return gym.make("VCNC-OmegaOverride-v1", **kwargs)


def planned_settings(env_id: str) -> list[tuple[str, dict]]:
    """The planned runs' settings of contouring id ``env_id`` (module docstring): (label, ``gym.make`` keywords)."""
    import inspect

    import gymnasium as gym

    from vcnc_gym.envs.task import ContouringTask
    from vcnc_gym.gcode import path_limits

    spec = gym.spec(env_id)
    if spec.entry_point.endswith(":GCodeEnv"):
        a, j = path_limits(spec.kwargs.get("plant", "vcnc_feed_drive"), None, None)
        return [
            (f"path limits x {k:g} ({k * a:g} mm/s^2)", {"acceleration": k * a, "jerk": k * j}) for k in LIMIT_FACTORS
        ]
    feed = spec.kwargs.get("feedrate", inspect.signature(ContouringTask).parameters["feedrate"].default)
    return [(f"{f * feed:g} mm/s", {"feedrate": f * feed}) for f in FEED_FRACTIONS]


def id_front(env_id: str, policies=CLASSICAL, mpcc: bool = True, progress=print) -> list[FrontPoint]:
    """The front of contouring id ``env_id`` (module docstring), nominal plant: the planned runs of ``policies``,
    the operator's fixed overrides and, with ``mpcc``, the contouring MPC; ``progress`` gets a line per run."""
    import gymnasium as gym

    import vcnc_baselines
    from vcnc_gym.evaluation import run_episode

    def designed(name, env) -> bool:  # not every controller is designed for every plant (ff-pid-online's two)
        if vcnc_baselines.registry.policy_class(name).designed_for(env.unwrapped.task.plant):
            return True
        progress(f"{env_id}: {name} is not designed for {env.unwrapped.task.plant.name}: left out")
        return False

    points = []
    for label, setting in planned_settings(env_id):
        env = gym.make(env_id, **setting)
        for name in (n for n in policies if designed(n, env)):
            points.append(_point(name, label, run_episode(vcnc_baselines.make(name, env), env), "planned"))
            progress(f"{env_id}: {name} at {label} done")
        env.close()
    env = override_env(env_id)
    if designed(OPERATOR, env):
        points += operator_front(OPERATOR, CAPS, env_id)
        progress(f"{env_id}: the operator's overrides done")
    if mpcc:
        points += id_mpcc_points(env_id, env, progress)
    env.close()
    return points


def id_mpcc_points(env_id: str, env=None, progress=print) -> list[FrontPoint]:
    """The contouring MPC's points of ``env_id``'s front: its progress capped at :data:`MPCC_FRACTIONS` of the
    programmed feed's peak, on the id's override version (``env``, or made here)."""
    import vcnc_baselines

    own = env is None
    env = override_env(env_id) if own else env
    peak = vcnc_baselines.make("mpcc", env).v_max
    points = mpcc_front([f * peak for f in MPCC_FRACTIONS], env_id)
    progress(f"{env_id}: mpcc at {', '.join(f'{f:g}' for f in MPCC_FRACTIONS)} of {peak:.4g} mm/s done")
    if own:
        env.close()
    return points


def format_front(points) -> str:
    """The points as a table, um and s."""
    lines = [f"{'policy':26s} {'setting':26s} {'cycle_s':>8s} {'max_um':>9s} {'rms_um':>9s}", "-" * 82]
    for p in points:
        lines.append(f"{p.policy:26s} {p.setting:26s} {p.cycle_time_s:8.4f} {p.max_um:9.3f} {p.rms_um:9.4f}")
    return "\n".join(lines)


def scurve_points(policies=SCURVE) -> list[FrontPoint]:
    """Each of ``policies`` on ``VCNC-Omega-v1`` itself (the S-curve at 100 mm/s, no override), nominal plant."""
    import gymnasium as gym

    import vcnc_baselines
    from vcnc_gym.evaluation import run_episode

    env = gym.make("VCNC-Omega-v1")
    points = [
        _point(name, "S-curve, 100 mm/s", run_episode(vcnc_baselines.make(name, env), env), "s-curve")
        for name in policies
    ]
    env.close()
    return points


def verdicts(points) -> list[str]:
    """For each finished agent and contouring-MPC point: the classical (planned) run that beats it in both cycle
    time and max error, or that none does."""
    front = pareto([p for p in points if p.kind == "planned"])
    lines = []
    for a in (p for p in points if p.kind in ("agent", "mpcc") and math.isfinite(p.cycle_time_s)):
        better = [c for c in front if c.cycle_time_s <= a.cycle_time_s and c.max_um <= a.max_um]
        lines.append(
            f"{a.policy} {a.setting} ({a.cycle_time_s:.4f} s, {a.max_um:.3f} um): "
            + (
                f"beaten by {better[0].policy} at {better[0].setting} ({better[0].cycle_time_s:.4f} s, "
                f"{better[0].max_um:.3f} um)"
                if better
                else "no classical run is both faster and more accurate"
            )
        )
    return lines


def plot_front(
    points,
    path,
    title: str = "Omega, nominal plant: planned look-ahead (classical) vs online feed override (agent, MPCC)",
) -> None:
    """Max contour error (um, log) against cycle time (s): every classical planned run (markers), their Pareto
    front (line), the operator's fixed overrides, the S-curve runs and the agent."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(7.5, 5.0))
    _draw_front(ax, points, title, legend_size=7)
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)


def plot_fronts(fronts: dict, path) -> None:
    """One panel per id of ``fronts`` (id -> points), as :func:`plot_front` draws one, on a grid of three columns."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    rows = math.ceil(len(fronts) / 3)
    fig, axes = plt.subplots(rows, 3, figsize=(15.0, 3.6 * rows), squeeze=False)
    for ax, (env_id, points) in zip(axes.ravel(), fronts.items()):
        _draw_front(ax, points, env_id, legend_size=5)
    for ax in axes.ravel()[len(fronts) :]:
        ax.set_visible(False)
    fig.suptitle(
        "Max contour error against cycle time, nominal plant: planned feeds (classical), the operator's "
        "override, the contouring MPC (own progress)",
        fontsize=10,
    )
    fig.tight_layout(rect=(0.0, 0.0, 1.0, 0.985))
    fig.savefig(path, dpi=100)
    plt.close(fig)


def _draw_front(ax, points, title: str, legend_size: int) -> None:
    finished = [p for p in points if math.isfinite(p.cycle_time_s)]
    planned = [p for p in finished if p.kind == "planned"]
    for name, marker in zip(CLASSICAL, "sD^v"):
        mine = [p for p in planned if p.policy == name]
        if mine:
            ax.scatter(
                [p.cycle_time_s for p in mine],
                [p.max_um for p in mine],
                marker=marker,
                s=22,
                alpha=0.6,
                label=f"{name}, planned",
            )
    front = pareto(planned)
    ax.step(
        [p.cycle_time_s for p in front],
        [p.max_um for p in front],
        "k-",
        where="post",
        lw=1.2,
        label="classical front (planned)",
    )
    for kind, name in dict.fromkeys((p.kind, p.policy) for p in finished if p.kind != "planned"):
        mine = sorted((p for p in finished if (p.kind, p.policy) == (kind, name)), key=lambda p: p.cycle_time_s)
        style = {"agent": "o-", "mpcc": "s--"}.get(kind, "x:")
        ax.plot(
            [p.cycle_time_s for p in mine],
            [p.max_um for p in mine],
            style,
            ms=7,
            lw=1.5,
            label=f"{name} (S-curve)"
            if kind == "s-curve"
            else ("mpcc (own progress, override)" if kind == "mpcc" else name),
        )
    ax.set_yscale("log")
    ax.set_xlabel("cycle time (s)")
    ax.set_ylabel("max contour error (um)")
    ax.set_title(title, fontsize=9)
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=legend_size)


def read_fronts(paths) -> dict:
    """The fronts of ``--json`` files (id -> :class:`FrontPoint` list), later files' ids over earlier ones'."""
    import json
    from pathlib import Path

    fronts = {}
    for path in paths:
        for env_id, points in json.loads(Path(path).read_text()).items():
            fronts[env_id] = [FrontPoint(**p) for p in points]
    return fronts


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(
        prog="python experiments/feed-override/feed_override.py", description=__doc__.split("\n\n")[0]
    )
    parser.add_argument("--agent", help="the feed-override agent's folder (default: the shipped one)")
    parser.add_argument("--plot", help="write the front as a PNG here (with --id: a folder, one PNG per id)")
    parser.add_argument(
        "--no-mpcc",
        action="store_true",
        help="leave out the contouring MPC (a QP per control period: a minute or more per point)",
    )
    parser.add_argument(
        "--id",
        nargs="+",
        metavar="ID",
        dest="ids",
        help="the front of these contouring ids instead of the omega's ('all': every one)",
    )
    parser.add_argument("--json", help="write the points here (JSON, a list per front)")
    parser.add_argument(
        "--mpcc-only",
        action="store_true",
        help="with --id and --json: run the contouring MPC's points again and replace them in the "
        "--json file's fronts, keeping the other runs (after a change of mpcc)",
    )
    parser.add_argument(
        "--replot",
        nargs="+",
        metavar="JSON",
        help="run nothing: print the fronts of these --json files and, with --plot, draw them on one grid",
    )
    args = parser.parse_args(argv)
    if args.replot:
        fronts = read_fronts(args.replot)
        for env_id, points in fronts.items():
            print(f"\n== {env_id} ==")
            _report(points, None)
        if args.plot:
            plot_fronts(fronts, args.plot)
            print(f"wrote {args.plot}")
        return 0
    if args.ids:
        return _id_fronts(parser, args)
    agent = args.agent
    if agent is None:
        from vcnc_agents import TRAINED

        agent = TRAINED.get("VCNC-OmegaOverride-v1")
        if agent is None or not agent.is_dir():
            parser.error("no agent is shipped for VCNC-OmegaOverride-v1: give --agent FOLDER")
    points = (
        classical_front()
        + scurve_points()
        + operator_front()
        + agent_front(agent)
        + ([] if args.no_mpcc else mpcc_front())
    )
    _report(points, args.plot)
    if args.json:
        _write_json({"VCNC-OmegaOverride-v1": points}, args.json)
    return 0


def _report(points, plot, title=None) -> None:
    print(format_front(points))
    print("\nclassical front (look-ahead runs no other beats in both cycle time and max error):")
    print(format_front(pareto([p for p in points if p.kind == "planned"])))
    print()
    print("\n".join(verdicts(points)))
    if plot:
        plot_front(points, plot, **({} if title is None else {"title": title}))
        print(f"wrote {plot}")


def _write_json(fronts: dict, path) -> None:
    import json
    from dataclasses import asdict
    from pathlib import Path

    Path(path).write_text(json.dumps({k: [asdict(p) for p in v] for k, v in fronts.items()}, indent=1))
    print(f"wrote {path}")


def _id_fronts(parser, args) -> int:
    from pathlib import Path

    from vcnc_gym.envs.registry import CONTOURING_IDS

    ids = list(CONTOURING_IDS) if args.ids == ["all"] else args.ids
    unknown = [i for i in ids if i not in CONTOURING_IDS]
    if unknown:
        parser.error(f"--id: {', '.join(unknown)} is not a contouring id ({', '.join(CONTOURING_IDS)}, or all)")
    if args.agent:
        parser.error("--agent runs on the omega's front only (no override agent is shipped for another id)")
    if args.mpcc_only:
        return _replace_mpcc(parser, args, ids)
    fronts = {}
    for env_id in ids:
        fronts[env_id] = points = id_front(env_id, mpcc=not args.no_mpcc, progress=lambda line: print(line, flush=True))
        print(f"\n== {env_id} ==")
        plot = None
        if args.plot:
            Path(args.plot).mkdir(parents=True, exist_ok=True)
            plot = str(Path(args.plot) / f"{env_id}.png")
        _report(points, plot, f"{env_id}, nominal plant: planned feeds (classical), operator's override, MPCC")
        if args.json:
            _write_json(fronts, args.json)
    return 0


def _replace_mpcc(parser, args, ids) -> int:
    """``--mpcc-only``: each id's MPCC points run again and replaced in ``--json``'s fronts, written after each id."""
    from pathlib import Path

    if not args.json or not Path(args.json).exists():
        parser.error("--mpcc-only replaces the MPCC points of an existing --json file")
    fronts = read_fronts([args.json])
    for env_id in ids:
        if env_id not in fronts:
            parser.error(f"--mpcc-only: {args.json} has no front of {env_id}")
        kept = [p for p in fronts[env_id] if p.kind != "mpcc"]
        fronts[env_id] = kept + id_mpcc_points(env_id, progress=lambda line: print(line, flush=True))
        print(f"\n== {env_id} ==")
        _report(fronts[env_id], None)
        _write_json(fronts, args.json)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
