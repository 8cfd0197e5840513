"""The compiled inner loop of the contouring envs: one decision step of N envs.

:func:`step_serial` (a single env, N = 1) and :func:`step_parallel` (the
native vector env, numba ``prange`` over the envs) run the same body,
:func:`_step_env`: for each env, ``n_repeat`` control periods of the plant
(through the plant contract, :func:`vcnc_gym.plants.contract.advance`), the
contour error against the whole contour after each, then the observation
(written through the layout's named offsets), the reward terms and the
episode flags.  A Python ``step`` makes exactly one numba call, with one
argument: a :class:`StepData`, which holds the arrays as a few named
structures:

- ``plant``: the plant's namedtuple of arrays (its type selects the plant's
  kernels at compile time);
- ``reference``: :data:`ReferenceArrays`, the packed reference shared by all envs;
- ``contour``: :class:`~vcnc_gym.contour.projector.ProjectorArrays`, the projector's pieces and grid
  (``ContourProjector.arrays``), for the exact contour error;
- ``config``: :data:`StepConfig`, the scalars of the task;
- ``offsets``: the layout's :data:`~vcnc_gym.envs.layout.ObservationOffsets`;
- ``buffers``: :data:`EnvBuffers`, per-env inputs, memory and outputs.

:func:`step_controlled_serial` and :func:`step_controlled_parallel` run a
whole decision of ``repeat`` control periods of that body per env with a
compiled controller commanding each period (the residual action mode,
:mod:`~vcnc_gym.envs.controller_contract`), its arguments the StepData, the
controller and a :data:`ControlLoop`.

No validation here: the env checks its inputs before calling.
"""

from __future__ import annotations

from collections import namedtuple

import numpy as np
from numba import njit, prange, types
from numba.experimental import structref

from ..contour.projector import project_point_warm
from ..plants import contract
from . import controller_contract

__all__ = [
    "StepData",
    "ReferenceArrays",
    "StepConfig",
    "EnvBuffers",
    "step_serial",
    "step_parallel",
    "ControlLoop",
    "step_controlled_parallel",
    "step_controlled_serial",
    "MODE_IDLE",
    "MODE_STEP",
    "MODE_OBSERVE",
]

# columns of the packed reference samples (K, REF_COLUMNS)
REF_POSITION = 0  # x_d (2) mm
REF_VELOCITY = 2  # dx_d/dt (2) mm/s
REF_ACCELERATION = 4  # d2x_d/dt2 (2) mm/s^2
REF_TANGENT = 6  # unit path tangent at x_d (2)
REF_U = 8  # curve parameter u of x_d (non-decreasing)
REF_ARC = 9  # arc length from the start of the contour to x_d, mm (non-decreasing)
REF_CURVATURE = 10  # signed curvature of the contour at x_d, 1/mm (positive: turning left)
REF_COLUMNS = 11
# the columns _last_at_or_below searches, as numpy ints: numba compiles a function once per integer literal
# argument, once for int64
_U_COLUMN = np.int64(REF_U)
_ARC_COLUMN = np.int64(REF_ARC)

# envs of a parallel step are cut in this many chunks (each unpacks the StepData once),
# enough to balance a few threads
_CHUNKS = 64

# what the kernel does with env i, buffers.mode[i]
MODE_IDLE = 0  # nothing (a finished env awaiting its reset)
MODE_STEP = 1  # one decision step with buffers.action[i]
MODE_OBSERVE = 2  # observe only (just reset): observation and info, no step

# slots of buffers.info (N, INFO_SIZE), float64
INFO_CONTOUR_ERROR = 0  # mm, at the end of the step
INFO_CONTOUR_ERROR_MEAN = 1  # mm, mean over the step's control periods
INFO_CONTOUR_ERROR_MAX = 2  # mm, max over the step's control periods
INFO_POSITION = 3  # (2) mm, true table position
INFO_REFERENCE_POSITION = 5  # (2) mm
INFO_TRACKING_ERROR = 7  # (2) mm, x_d - x (true position)
INFO_COMMAND = 9  # (2) plant input after saturation (V, A)
INFO_REWARD_CONTOUR = 11
INFO_REWARD_EFFORT = 12
INFO_REWARD_DIVERGENCE = 13
INFO_CLIPPED = 14  # number of observation entries clipped to the space's bounds
INFO_MEASURED_POSITION = 15  # (2) mm, the position sensor's reading (what the observation is computed from)
INFO_PROGRESS = 17  # mm, arc length of the contour the tool has passed (its closest point's, never decreasing)
INFO_CYCLE_TIME = 18  # s, time at which the tool reached the end of the contour; NaN before
INFO_REWARD_INCOMPLETE = 19
INFO_SIZE = 20

#: The info keys of a step, read from the kernel's info row: key -> (first column, columns).  Besides
#: these, an env's step info has "diverged", "completed" (flags) and "time" (s); "cycle_time" is there only
#: once the tool has arrived (completed).
INFO_FIELDS = {
    "contour_error": (INFO_CONTOUR_ERROR, 1),
    "contour_error_mean": (INFO_CONTOUR_ERROR_MEAN, 1),
    "contour_error_max": (INFO_CONTOUR_ERROR_MAX, 1),
    "position": (INFO_POSITION, 2),
    "measured_position": (INFO_MEASURED_POSITION, 2),
    "reference_position": (INFO_REFERENCE_POSITION, 2),
    "tracking_error": (INFO_TRACKING_ERROR, 2),
    "command": (INFO_COMMAND, 2),
    "progress": (INFO_PROGRESS, 1),
    "cycle_time": (INFO_CYCLE_TIME, 1),
    "reward_contour": (INFO_REWARD_CONTOUR, 1),
    "reward_effort": (INFO_REWARD_EFFORT, 1),
    "reward_divergence": (INFO_REWARD_DIVERGENCE, 1),
    "reward_incomplete": (INFO_REWARD_INCOMPLETE, 1),
    "observation_clipped": (INFO_CLIPPED, 1),
}

# columns of buffers.episode (N, EPISODE_SIZE): the episode's contour error over its control periods
EPISODE_SUM = 0  # mm
EPISODE_SQUARES = 1  # mm^2
EPISODE_MAX = 2  # mm
EPISODE_PERIODS = 3
EPISODE_SIZE = 4

# flags of buffers.flags (N, FLAG_SIZE), bool
FLAG_TERMINATED = 0
FLAG_TRUNCATED = 1
FLAG_DIVERGED = 2
FLAG_COMPLETED = 3  # the tool has reached the end of the contour
FLAG_SIZE = 4

# how an episode ends, StepConfig.episode_end
END_REFERENCE = 0  # once the reference has reached the end plus a settling time (the v0 ids)
END_TOOL = 1  # once the tool has reached the end, or at the completion time limit (the v1 ids)

#: The packed reference, shared by every env: ``samples`` (K, REF_COLUMNS)
#: float64 (x_d, dx_d/dt, d2x_d/dt2, unit tangent, u, arc length, signed
#: curvature; past the end the last sample holds), ``preview_steps`` (n,)
#: int64, offsets in control periods, and ``contour_ahead`` (m,) float64,
#: arc lengths in mm ahead of the tool's closest point.
ReferenceArrays = namedtuple("ReferenceArrays", ["samples", "preview_steps", "contour_ahead"])

#: The scalars of a task: ``n_repeat`` control periods per decision;
#: ``reward_scale`` mm; ``effort_weight``; ``divergence_bound`` and
#: ``tracking_bound`` mm; ``episode_end`` (END_REFERENCE or END_TOOL);
#: ``end_index`` (the control period at which the episode ends: END_REFERENCE's
#: end, END_TOOL's completion time limit); ``episode_steps`` (its natural
#: length in decisions); ``max_steps`` (decisions after which it is
#: truncated); ``completion_tolerance`` (mm of contour left at which the tool
#: has reached the end); ``progress_window`` (mm: the farthest the tool's
#: progress may jump ahead in one control period, so that a closest point on
#: another branch of the contour is not taken for progress); ``dt`` (s); ``error_clip`` (mm: the contour error at
#: which a control period's reward saturates, and the worst per-step reward the divergence penalty charges per
#: remaining decision).
StepConfig = namedtuple(
    "StepConfig",
    [
        "n_repeat",
        "reward_scale",
        "effort_weight",
        "divergence_bound",
        "tracking_bound",
        "episode_end",
        "end_index",
        "episode_steps",
        "max_steps",
        "completion_tolerance",
        "progress_window",
        "dt",
        "error_clip",
    ],
)

#: Per-env arrays, first axis N: inputs ``mode`` (int8) and ``action``
#: (N, 2) float64, normalised; memory ``k`` (control periods done),
#: ``steps`` (decisions done), ``foot`` (the closest point's curve parameter
#: of the last control period, the next search's warm start; NaN = none),
#: ``input_limit`` (N, 2) in the plant's unit, ``previous_action`` (N, 2),
#: ``progress`` (the reference sample at or before the tool's closest point,
#: never decreasing), ``cycle_time`` (s, NaN until the tool reaches the end),
#: ``reference_end`` (the control period at which the reference reaches the
#: contour's end: its last sample for a reference computed ahead; a feed
#: override, :class:`~vcnc_gym.envs.feed_override_env.FeedOverrideEnv`,
#: moves it while it re-times the reference);
#: outputs ``obs`` (N, D) float32, ``reward`` (N,), ``flags`` (N,
#: FLAG_SIZE) bool, ``info`` (N, INFO_SIZE); constant ``obs_high`` (D,)
#: float32; scratch ``sensed`` (N, SENSE_SIZE) and ``der`` (N, 3, 2); the episode's contour error so far
#: ``episode`` (N, EPISODE_SIZE): its sum and sum of squares over the control periods (mm, mm^2), its largest
#: value (mm) and the control periods counted.
EnvBuffers = namedtuple(
    "EnvBuffers",
    [
        "mode",
        "action",
        "k",
        "steps",
        "foot",
        "input_limit",
        "previous_action",
        "progress",
        "cycle_time",
        "reference_end",
        "obs",
        "reward",
        "flags",
        "info",
        "obs_high",
        "sensed",
        "der",
        "episode",
    ],
)


#: A decision of :func:`step_controlled_serial`: ``agent`` (N, 2) float32, the agent's correction in [-1, 1] (clipped
#: here); ``correction`` (float32), its scale as a fraction of u_max; ``repeat``, control periods per decision;
#: scratch ``base`` (N, 2), the controller's command; outputs ``reward`` (N,), the sum of the periods' rewards,
#: and ``peak`` (N,), the largest contour error of the decision, mm.
ControlLoop = namedtuple("ControlLoop", ["agent", "correction", "repeat", "base", "reward", "peak"])


@structref.register
class StepDataType(types.StructRef):
    def preprocess_fields(self, fields):
        return tuple((name, types.unliteral(t)) for name, t in fields)


class StepData(structref.StructRefProxy):
    """Everything one kernel call needs, as one object (one argument: a fast numba call).

    Build it once per env; the numpy arrays inside are the env's own, so
    writing ``buffers.action`` from Python is what the kernel reads.
    """

    def __new__(cls, plant, reference, contour, config, offsets, buffers):
        return _new_step_data(plant, reference, contour, config, offsets, buffers)


structref.define_proxy(StepData, StepDataType, ["plant", "reference", "contour", "config", "offsets", "buffers"])


@njit(cache=True)
def _new_step_data(plant, reference, contour, config, offsets, buffers):
    """:class:`StepData`'s constructor, compiled once per plant into numba's cache (``StructRefProxy.__new__``
    compiles its own, uncached, in every process: 2 s per plant and process)."""
    return StepData(plant, reference, contour, config, offsets, buffers)


@njit(cache=True, _nrt=False)
def _step_env(plant, reference, c, cfg, o, b, i):
    """One decision step (or, in MODE_OBSERVE, one observation) of env ``i``.

    Takes the fields of a :class:`StepData` unpacked once by the caller:
    reading a StructRef field hands out new references to every array in it.
    Compiled without numba's reference counting (``_nrt=False``: it allocates
    nothing): with it, every array argument is incref'd and decref'd per call,
    atomic operations on counters that all threads share, which cost more
    than the step itself (2.4 M against 1.1 M env-steps/s on one thread, and
    no scaling on two; ``benchmarks/vector_env.py``).  ``_nrt`` is a private
    numba option (0.68); without it the kernel stays correct, only slower.
    """
    mode = b.mode[i]
    if mode == MODE_IDLE:
        return
    samples = reference.samples
    last = samples.shape[0] - 1
    sensed = b.sensed[i]
    n = 0
    a0 = 0.0
    a1 = 0.0
    if mode == MODE_STEP:
        n = cfg.n_repeat
        a0 = min(1.0, max(-1.0, b.action[i, 0]))
        a1 = min(1.0, max(-1.0, b.action[i, 1]))
        b.previous_action[i, 0] = a0
        b.previous_action[i, 1] = a1
    command = b.info[i, INFO_COMMAND : INFO_COMMAND + 2]
    command[0] = a0 * b.input_limit[i, 0]
    command[1] = a1 * b.input_limit[i, 1]

    err = 0.0
    err_sum = 0.0
    err_max = 0.0
    for _ in range(max(n, 1)):
        if n > 0:
            contract.advance(plant, i, command)
            b.k[i] += 1
        contract.sense(plant, i, sensed)
        err, b.foot[i] = project_point_warm(
            sensed[contract.SENSE_POSITION], sensed[contract.SENSE_POSITION + 1], b.foot[i], c, b.der[i]
        )
        err_sum += err
        err_max = max(err_max, err)
        if n > 0:
            ep = b.episode[i]
            ep[EPISODE_SUM] += err
            ep[EPISODE_SQUARES] += err * err
            ep[EPISODE_MAX] = max(ep[EPISODE_MAX], err)
            ep[EPISODE_PERIODS] += 1.0
        _advance_progress(samples, cfg, b, i)
    if n > 0:
        b.steps[i] += 1

    k = b.k[i]
    kr = min(k, last)
    x = sensed[contract.SENSE_POSITION]
    y = sensed[contract.SENSE_POSITION + 1]
    xm = sensed[contract.SENSE_MEASURED]
    ym = sensed[contract.SENSE_MEASURED + 1]
    xd = samples[kr, REF_POSITION]
    yd = samples[kr, REF_POSITION + 1]
    finite = (
        np.isfinite(x)
        and np.isfinite(y)
        and np.isfinite(sensed[contract.SENSE_VELOCITY])
        and np.isfinite(sensed[contract.SENSE_VELOCITY + 1])
    )

    # info
    info = b.info[i]
    info[INFO_CONTOUR_ERROR] = err
    info[INFO_CONTOUR_ERROR_MEAN] = err_sum / max(n, 1)
    info[INFO_CONTOUR_ERROR_MAX] = err_max
    info[INFO_POSITION] = x
    info[INFO_POSITION + 1] = y
    info[INFO_REFERENCE_POSITION] = xd
    info[INFO_REFERENCE_POSITION + 1] = yd
    info[INFO_TRACKING_ERROR] = xd - x
    info[INFO_TRACKING_ERROR + 1] = yd - y
    info[INFO_MEASURED_POSITION] = xm
    info[INFO_MEASURED_POSITION + 1] = ym
    p = b.progress[i]
    arc_left = max(0.0, samples[last, REF_ARC] - samples[p, REF_ARC])  # mm of contour ahead of the progress
    info[INFO_PROGRESS] = samples[p, REF_ARC]
    info[INFO_CYCLE_TIME] = b.cycle_time[i]
    completed = np.isfinite(b.cycle_time[i])
    for j in range(2):
        command[j] = min(b.input_limit[i, j], max(-b.input_limit[i, j], command[j]))

    # reward and flags
    flags = b.flags[i]
    lag = np.hypot(xd - x, yd - y)
    diverged = n > 0 and (not finite or err_max > cfg.divergence_bound or lag > cfg.tracking_bound)
    r_contour = 0.0
    r_effort = 0.0
    r_div = 0.0
    r_incomplete = 0.0
    if cfg.episode_end == END_TOOL:
        out_of_time = k >= cfg.end_index and not completed
        terminated = diverged or completed or out_of_time
        if n > 0 and out_of_time and not diverged:
            r_incomplete = -arc_left / cfg.reward_scale
    else:
        terminated = diverged or k >= cfg.end_index
    if n > 0:
        mean_err = err_sum / n
        if not mean_err < cfg.error_clip:  # beyond the clip, or NaN (a non-finite state): the clip
            mean_err = cfg.error_clip
        r_contour = -mean_err / cfg.reward_scale
        r_effort = -cfg.effort_weight * 0.5 * (a0 * a0 + a1 * a1)
        if diverged:
            steps_left = max(0, cfg.episode_steps - (k + cfg.n_repeat - 1) // cfg.n_repeat)
            r_div = -steps_left * cfg.error_clip / cfg.reward_scale
            if not np.isfinite(err):
                info[INFO_CONTOUR_ERROR] = np.inf
    info[INFO_REWARD_CONTOUR] = r_contour
    info[INFO_REWARD_EFFORT] = r_effort
    info[INFO_REWARD_DIVERGENCE] = r_div
    info[INFO_REWARD_INCOMPLETE] = r_incomplete
    b.reward[i] = r_contour + r_effort + r_div + r_incomplete
    flags[FLAG_TERMINATED] = terminated
    flags[FLAG_TRUNCATED] = (not terminated) and b.steps[i] >= cfg.max_steps
    flags[FLAG_DIVERGED] = diverged
    flags[FLAG_COMPLETED] = completed

    # observation, field by field through the layout's named offsets
    obs = b.obs[i]
    ex = xd - xm
    ey = yd - ym
    tx = samples[kr, REF_TANGENT]
    ty = samples[kr, REF_TANGENT + 1]
    for j in range(2):
        obs[o.reference_position + j] = samples[kr, REF_POSITION + j]
        obs[o.reference_velocity + j] = samples[kr, REF_VELOCITY + j]
        obs[o.reference_acceleration + j] = samples[kr, REF_ACCELERATION + j]
        obs[o.velocity + j] = sensed[contract.SENSE_VELOCITY + j]
        obs[o.previous_action + j] = b.previous_action[i, j]
    obs[o.tracking_error] = ex
    obs[o.tracking_error + 1] = ey
    obs[o.contour_error] = err
    obs[o.tangential_error] = tx * ex + ty * ey  # Simba et al., eq. (3): e_l = R^T e_w
    obs[o.normal_error] = -ty * ex + tx * ey
    preview = reference.preview_steps
    for j in range(preview.shape[0]):
        kp = min(kr + preview[j], last)
        obs[o.preview + 2 * j] = samples[kp, REF_POSITION] - xm
        obs[o.preview + 2 * j + 1] = samples[kp, REF_POSITION + 1] - ym
    _contour_preview(samples, reference.contour_ahead, p, xm, ym, obs, o)
    clipped = 0
    high = b.obs_high
    for j in range(obs.shape[0]):
        v = obs[j]
        if not np.isfinite(v):
            obs[j] = 0.0
            clipped += 1
        elif v > high[j]:
            obs[j] = high[j]
            clipped += 1
        elif v < -high[j]:
            obs[j] = -high[j]
            clipped += 1
    info[INFO_CLIPPED] = clipped


@njit(cache=True, _nrt=False)
def _last_at_or_below(samples, column, value, lo):
    """Largest q >= lo with ``samples[q, column] <= value`` (the column non-decreasing, ``samples[lo, column] <=
    value``): galloping from ``lo`` then bisection, O(log(q - lo)) (the progress moves a sample or two per
    control period)."""
    last = samples.shape[0] - 1
    step = 1
    hi = lo + 1
    while hi <= last and samples[hi, column] <= value:
        lo = hi
        step *= 2
        hi = lo + step
    if hi > last:
        if samples[last, column] <= value:
            return last
        hi = last
    while hi - lo > 1:
        mid = (lo + hi) // 2
        if samples[mid, column] <= value:
            lo = mid
        else:
            hi = mid
    return lo


@njit(cache=True, _nrt=False)
def _advance_progress(samples, cfg, b, i):
    """Move env ``i``'s progress to the reference sample at or before its closest point (never back, at most
    ``progress_window`` mm at once), and time its arrival at the end of the contour: the first control period,
    the reference's end (``b.reference_end[i]``) or later, with at most ``completion_tolerance`` mm of contour
    left."""
    p = b.progress[i]
    foot = b.foot[i]
    if foot > samples[p, REF_U]:
        q = _last_at_or_below(samples, _U_COLUMN, foot, p)
        if samples[q, REF_ARC] - samples[p, REF_ARC] <= cfg.progress_window:
            b.progress[i] = q
            p = q
    last = samples.shape[0] - 1
    if (
        np.isnan(b.cycle_time[i])
        and b.k[i] >= b.reference_end[i]
        and samples[last, REF_ARC] - samples[p, REF_ARC] <= cfg.completion_tolerance
    ):
        b.cycle_time[i] = b.k[i] * cfg.dt


@njit(cache=True, _nrt=False)
def _contour_preview(samples, ahead, p, xm, ym, obs, o):
    """The contour ``ahead`` (mm of arc length) beyond sample ``p``, in the tool's frame: points relative to the
    measured position (xm, ym) along the contour's tangent and normal at ``p``, and their signed curvature."""
    last = samples.shape[0] - 1
    tx = samples[p, REF_TANGENT]
    ty = samples[p, REF_TANGENT + 1]
    s0 = samples[p, REF_ARC]
    q = p
    for j in range(ahead.shape[0]):
        s = s0 + ahead[j]
        q = _last_at_or_below(samples, _ARC_COLUMN, s, q if j > 0 and ahead[j] >= ahead[j - 1] else p)
        r = q + 1 if q < last else q
        span = samples[r, REF_ARC] - samples[q, REF_ARC]
        w = min(1.0, (s - samples[q, REF_ARC]) / span) if span > 0.0 else 0.0
        px = samples[q, REF_POSITION] + w * (samples[r, REF_POSITION] - samples[q, REF_POSITION]) - xm
        py = samples[q, REF_POSITION + 1] + w * (samples[r, REF_POSITION + 1] - samples[q, REF_POSITION + 1]) - ym
        obs[o.contour_preview + 2 * j] = tx * px + ty * py
        obs[o.contour_preview + 2 * j + 1] = -ty * px + tx * py
        obs[o.contour_curvature + j] = samples[q, REF_CURVATURE] + w * (
            samples[r, REF_CURVATURE] - samples[q, REF_CURVATURE]
        )


@njit(cache=True)
def _step_range(d, start, stop):
    """Envs ``start`` to ``stop - 1`` of ``d``, with the StepData's fields unpacked once."""
    plant, reference, contour, config, offsets, buffers = (
        d.plant,
        d.reference,
        d.contour,
        d.config,
        d.offsets,
        d.buffers,
    )
    for i in range(start, stop):
        _step_env(plant, reference, contour, config, offsets, buffers, i)


@njit(cache=True)
def step_serial(d):
    """One decision step of every env of ``d`` in turn (the single env: N = 1)."""
    _step_range(d, 0, d.buffers.mode.shape[0])


@njit(cache=True, parallel=True)
def step_parallel(d):
    """One decision step of every env of ``d``, spread over the cores (numba ``prange`` over chunks of envs)."""
    n = d.buffers.mode.shape[0]
    chunks = min(n, _CHUNKS)
    for c in prange(chunks):
        _step_range(d, c * n // chunks, (c + 1) * n // chunks)


@njit(cache=True, _nrt=False)
def _control_env(plant, reference, c, cfg, o, b, i, controller, loop):
    """A decision of env ``i`` (in MODE_STEP) with a compiled controller in the loop: ``loop.repeat`` control
    periods (fewer if the episode ends), each commanding ``clip(u_c / u_max + correction * a, -1, 1)`` in float32,
    u_c the controller's command on the current observation (:mod:`~vcnc_gym.envs.controller_contract`), ``a``
    the agent's held correction: the arithmetic of ``vcnc_agents.action_modes.ActionMode.command``, to the bit."""
    if b.mode[i] != MODE_STEP:
        return
    one = np.float32(1.0)
    a0 = min(one, max(-one, loop.agent[i, 0]))
    a1 = min(one, max(-one, loop.agent[i, 1]))
    base = loop.base[i]
    total = 0.0
    peak = 0.0
    for _ in range(loop.repeat):
        controller_contract.command(controller, i, b.obs[i], o, base)
        b.action[i, 0] = min(one, max(-one, np.float32(base[0]) + loop.correction * a0))
        b.action[i, 1] = min(one, max(-one, np.float32(base[1]) + loop.correction * a1))
        _step_env(plant, reference, c, cfg, o, b, i)
        total += b.reward[i]
        peak = max(peak, b.info[i, INFO_CONTOUR_ERROR_MAX])
        if b.flags[i, FLAG_TERMINATED] or b.flags[i, FLAG_TRUNCATED]:
            break
    loop.reward[i] = total
    loop.peak[i] = peak


@njit(cache=True)
def _control_range(d, controller, loop, start, stop):
    """Envs ``start`` to ``stop - 1`` of ``d`` under ``controller``, the StepData's fields unpacked once."""
    plant, reference, contour, config, offsets, buffers = (
        d.plant,
        d.reference,
        d.contour,
        d.config,
        d.offsets,
        d.buffers,
    )
    for i in range(start, stop):
        _control_env(plant, reference, contour, config, offsets, buffers, i, controller, loop)


@njit(cache=True)
def step_controlled_serial(d, controller, loop):
    """One decision of every env of ``d`` in MODE_STEP, a compiled controller and the agent's correction
    commanding each control period (:class:`ControlLoop`), env after env."""
    _control_range(d, controller, loop, 0, d.buffers.mode.shape[0])


@njit(cache=True, parallel=True)
def step_controlled_parallel(d, controller, loop):
    """:func:`step_controlled_serial` spread over the cores (numba ``prange`` over chunks of envs)."""
    n = d.buffers.mode.shape[0]
    chunks = min(n, _CHUNKS)
    for c in prange(chunks):
        _control_range(d, controller, loop, c * n // chunks, (c + 1) * n // chunks)


#: A run of every env under a holding loop (:func:`run_holding_loop`), per control period ``k``, env ``i`` and axis
#: ``j``: the feedforward (K_f, 2) (period ``min(k, K_f - 1)``) and the moves' own feedforward ``legs`` (K, 2), in
#: the input unit; the loop reference's ``offset`` (K, 2), mm, and its rate ``offset_rate`` (K, 2), mm/s, on top of
#: the task's reference; the ``excitation`` (N, K, 2), input unit; the PID's ``kp``, ``kd``, ``ki`` (2,) and the
#: velocity low-pass pole ``alpha`` (2,); the control period ``dt`` (s) and the input limit ``u_max`` (2,); and what
#: the run writes: the command ``u``, the measured tracking error ``e`` (mm) and velocity ``velocity`` (mm/s), each
#: (N, K, 2).  The run lasts K periods.
HoldingLoop = namedtuple(
    "HoldingLoop",
    [
        "feedforward",
        "legs",
        "offset",
        "offset_rate",
        "excitation",
        "kp",
        "kd",
        "ki",
        "alpha",
        "dt",
        "u_max",
        "u",
        "e",
        "velocity",
    ],
)


@njit(cache=True)
def run_holding_loop(d, h):
    """Every env of ``d``, K control periods (:data:`HoldingLoop`), each commanding the clipped sum of the
    feedforward, the moves' feedforward, a PID on the tracking error plus the offset (the derivative on the
    reference velocity plus the offset's rate less the low-passed measured velocity) and the excitation, and
    stepping one period: an identification experiment's loop (``vcnc_baselines.commissioning.identify``), in one
    call instead of one per period."""
    plant, reference, contour, config, o, b = d.plant, d.reference, d.contour, d.config, d.offsets, d.buffers
    n = b.obs.shape[0]
    last = h.feedforward.shape[0] - 1
    vf = np.zeros((n, 2))
    integral = np.zeros((n, 2))
    for k in range(h.u.shape[1]):
        f = min(k, last)
        for i in range(n):
            for j in range(2):
                e = np.float64(b.obs[i, o.tracking_error + j])
                v = np.float64(b.obs[i, o.velocity + j])
                h.velocity[i, k, j] = v
                vf[i, j] = h.alpha[j] * vf[i, j] + (1.0 - h.alpha[j]) * v
                ek = e + h.offset[k, j]
                h.e[i, k, j] = e
                integral[i, j] += ek * h.dt
                rate = np.float64(b.obs[i, o.reference_velocity + j]) + h.offset_rate[k, j] - vf[i, j]
                c = (
                    h.feedforward[f, j]
                    + h.legs[k, j]
                    + h.kp[j] * ek
                    + h.kd[j] * rate
                    + h.ki[j] * integral[i, j]
                    + h.excitation[i, k, j]
                )
                c = min(max(c, -h.u_max[j]), h.u_max[j])
                h.u[i, k, j] = c
                b.action[i, j] = min(max(c / h.u_max[j], -1.0), 1.0)
            b.mode[i] = MODE_STEP
            _step_env(plant, reference, contour, config, o, b, i)
