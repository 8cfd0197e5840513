"""Commissioning's experiment on the machine: excite each axis, estimate its frequency response, fit a model.

What a CNC's commissioning wizard does on a new drive (the "frequency response measurement" of SINAMICS' and
FANUC's servo tuning tools), written against this project's envs: the machine is stepped through its own
kernel with commands the experiment chooses, and read through its observation only (the measured position,
as the encoder gives it).  Nothing here reads a machine's true parameters; the experiment's holding loop and
its excitation level are set from the *nominal* model, the data a machine builder has before commissioning.

The experiment, both axes at once (the axes of every plant of the suite are decoupled):

1. **Frequency response**: a random binary sequence (a PRBS, one level per control period, amplitude
   ``prbs_level`` of the input limit) added to a low-gain PD loop that holds the axis near its start (its
   gain from :func:`holding_gains`).  The loop keeps the run bounded; the response from command to measured
   position is estimated by the indirect (two-stage) method, ``G = S_rx / S_ru`` (Welch's averaged cross
   spectra of the excitation ``r`` with the position ``x`` and with the command ``u``, :func:`scipy.signal.csd`),
   which the loop's feedback of the sensor noise does not bias (Pintelon & Schoukens, *System Identification:
   A Frequency Domain Approach*, 2nd ed. 2012, ch. 2 and 9).
2. **Slow reversal moves**: the loop (with an integral) moves each axis alone at two speeds, out and back,
   then both together (:func:`leg_schedule`), then both together down a sweep of speeds from four times the
   working feed's to a 16th of it; the mean commands at speed give the viscous coefficient, the Coulomb level of each
   direction, a process force along the path and the Stribeck curve below the working feed
   (:func:`friction_levels`).

The fit (:func:`fit_axis`): per axis the rigid body ``1 / (m s^2 + c s)`` in series with a first structural
mode ``(2 zeta w s + w^2) / (s^2 + 2 zeta w s + w^2)`` and a dead time ``tau`` (the command and sensor delays
and the zero-order hold's half period), by nonlinear least squares (:func:`scipy.optimize.least_squares`) on
the complex logarithm of the ratio of model and estimate, weighted by the coherence, within bounds (a decade
about the nominal mass, up to 20 periods of delay, a mode below the Nyquist frequency); the mode is kept only
where the estimate shows a resonance (more than ``MODE_PEAK_DB`` above the rigid body) and the fitted mode lies
inside the band (below its top: beyond, the estimate does not show it).
"""

from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np
from scipy import optimize, signal

from vcnc_gym.envs import step_kernel as sk
from vcnc_gym.envs.task import ContouringBatch
from vcnc_gym.validation import positive

__all__ = [
    "Experiment",
    "Measurement",
    "AxisModel",
    "Machines",
    "holding_gains",
    "run_experiment",
    "frf",
    "fit_axis",
    "COHERENCE_FLOOR",
    "experiment_task",
    "leg_schedule",
    "friction_levels",
    "LEG_SPEED_TOLERANCE",
    "LEG_SPREAD",
    "REVERSAL_LEGS",
    "STRIBECK_GRID",
    "STRIBECK_GAIN",
    "LEG_RAMP",
    "LEG_RAMP_MAX",
    "identify",
    "model_response",
    "MODE_PEAK_DB",
]

#: The longest travel of a reversal leg, mm (within the observation's tracking-error bound).
LEG_TRAVEL = 6.0

#: A leg's speed is reached over at least this fraction of it, at most ``LEG_RAMP_MAX`` (:func:`run_experiment`).
LEG_RAMP, LEG_RAMP_MAX = 0.1, 0.3

#: The fit's band ends where the excitation's coherence with the position falls below this.
COHERENCE_FLOOR = 0.5

#: A resonance at least this far (dB) above the fitted rigid body is taken for a structural mode.
MODE_PEAK_DB = 3.0


@dataclass(frozen=True)
class Experiment:
    """The identification experiment's settings.

    Attributes
    ----------
    periods : int
        Control periods of the frequency-response run (the PRBS), per machine.
    segment : int
        Welch segment length, control periods (frequency resolution ``1 / (segment dt)``).
    prbs_level : float
        PRBS amplitude, fraction of the nominal input limit.
    holding_bandwidth : float
        The holding loop's bandwidth as a fraction of ``1 / dt``, rad/s (reduced until its phase margin on the
        nominal model is 60 deg: :func:`holding_gains`).
    reversal_speed : float, optional
        The lower speed of the reversal moves, mm/s (the higher is ``speed_ratio`` times it); default a fifth of
        the followed task's reference's peak speed (the machine's working feed: fast enough that the holding axis'
        jitter takes no share of a process force along the path), at most :data:`LEG_TRAVEL` per leg at the
        higher speed.
    speed_ratio : float
        Ratio of the two speeds of the reversal moves (they separate the viscous from the Coulomb level).
    sweep_steps : int
        Speeds of the friction sweep (both axes together, out and back, at ``v_top 2^-k``, ``k = 0 ..
        sweep_steps - 1``; ``v_top`` four times the working feed's peak axis speed, at most :data:`LEG_TRAVEL` per leg):
        the friction's speed dependence below the working feed, a Stribeck curve's (:func:`friction_levels`).
        0: no sweep.
    leg_time : float, optional
        Duration of each leg, s; default 12.5 time constants of the holding loop (``12.5 / w``).  Each leg's speed
        is reached by a smooth change (:data:`LEG_RAMP`) with the nominal model's feedforward of the move, and the
        command is read over its last 40 %; the loop's remaining transient there (the slow integral's, after a
        reversal's stick) is taken out by :func:`friction_levels` with the measured speed and acceleration.
    seed : int
        Seed of the PRBS and of the machines' sensor noise during the experiment.
    """

    periods: int = 32768
    segment: int = 8192
    prbs_level: float = 0.3
    holding_bandwidth: float = 0.005
    reversal_speed: float | None = None
    speed_ratio: float = 2.0
    sweep_steps: int = 7
    leg_time: float | None = None
    seed: int = 12345


@dataclass(frozen=True)
class Measurement:
    """The experiment's record, per machine ``n`` and axis ``j``: excitation ``r``, command ``u`` (input unit)
    and measured tracking error ``e = x_d - x`` (mm) of the frequency-response run, (N, K, 2); the mean commands ``leg_command``
    (N, L, 2) of the reversal and sweep legs, whose axes' speeds (mm/s) are ``leg_speeds`` (L, 2); the control period ``dt`` (s);
    the wall time of the experiment (s); the measured velocity's noise (N, 2), mm/s (standard deviation about
    its running mean on the legs at speed); the holding loop's bandwidth per axis (2,), rad/s; per leg the measured
    velocity's mean over its window ``leg_velocity`` and the spread of its low-passed value ``leg_spread`` (N, L, 2),
    mm/s (None in a measurement made without them: every leg then counts), and its mean acceleration over the
    window ``leg_acceleration`` (N, L, 2), mm/s^2 (the change of its halves' mean speeds; None: taken as 0)."""

    r: np.ndarray
    u: np.ndarray
    e: np.ndarray
    leg_command: np.ndarray
    leg_speeds: np.ndarray
    dt: float
    seconds: float
    velocity_noise: np.ndarray
    holding_bandwidth: np.ndarray
    leg_velocity: np.ndarray | None = None
    leg_spread: np.ndarray | None = None
    leg_acceleration: np.ndarray | None = None


class Machines:
    """``n`` machines of an env's task, commanded period by period or under a holding loop: the experiment's only
    access.

    ``parameters`` (n, 2, P) are handed to the simulator to *build* the machines (on a real shop floor the
    machines exist); the experiment itself only commands them and reads the observation (:meth:`step`, one period;
    :meth:`hold`, a whole run under a holding loop in one kernel call).  Every machine's
    sensor is seeded with ``seed``, whatever its place in the batch: a machine identified among others gets the
    record it gets alone (the floor's search commissions each machine alone, the robust bench in one batch).
    """

    def __init__(self, task, parameters, seed: int = 0):
        p = np.asarray(parameters, dtype=np.float64)
        p = p[None] if p.ndim == 2 else p
        self.task = task
        self.layout = task.layout
        self.dt = task.dt
        self.n = p.shape[0]
        self._batch = ContouringBatch(task, self.n)
        for i in range(self.n):
            self._batch.reset_env(i, task.check_parameters(p[i]), np.random.default_rng(seed))
        self._batch.run()
        #: the nominal input limit (a builder's data), input unit
        self.u_max = task.plant.input_limits(task.nominal_parameters)

    def observe(self) -> np.ndarray:
        """The current observations, (n, obs_dim) float32."""
        return self._batch.buffers.obs.copy()

    def hold(self, loop) -> None:
        """Run every machine under ``loop`` (:data:`vcnc_gym.envs.step_kernel.HoldingLoop`: a PID holding loop
        with feedforward and excitation) for its periods in one kernel call; fills its ``u``, ``e`` and
        ``velocity``.  The same arithmetic as computing each period's command from :meth:`observe` and calling
        :meth:`step` (``tests/test_commissioning_kernel.py`` runs both)."""
        periods = loop.u.shape[1] if np.ndim(loop.u) == 3 else -1
        for name in ("u", "e", "velocity", "excitation"):
            if np.shape(getattr(loop, name)) != (self.n, periods, 2):
                raise ValueError(
                    f"hold: loop.{name} must be ({self.n} machines, periods, 2) like loop.u, "
                    f"got {np.shape(getattr(loop, name))}"
                )
        for name in ("legs", "offset", "offset_rate"):
            if np.shape(getattr(loop, name)) != (periods, 2):
                raise ValueError(
                    f"hold: loop.{name} must be ({periods} periods, 2), got {np.shape(getattr(loop, name))}"
                )
        sk.run_holding_loop(self._batch.data, loop)

    def step(self, command: np.ndarray) -> np.ndarray:
        """Apply ``command`` (n, 2) in the input unit for one control period; returns the observations."""
        b = self._batch.buffers
        b.action[:] = np.clip(command / self.u_max, -1.0, 1.0)
        b.mode[:] = sk.MODE_STEP
        self._batch.run()
        return b.obs.copy()


def holding_gains(mass, damping, delay, dt, fraction: float):
    """PD gains (kp, kd) per axis of the experiment's holding loop and its bandwidth (rad/s): a double pole at
    ``w = fraction / dt`` on the nominal ``m s^2 + c s``, halved until the phase margin with the nominal dead time
    plus two control periods is at least 60 deg."""
    m, c = np.asarray(mass, float), np.asarray(damping, float)
    w = np.full(2, fraction / dt)
    for j in range(2):
        for _ in range(60):
            kp, kd = m[j] * w[j] ** 2, max(2 * m[j] * w[j] - c[j], 0.0)
            om = np.logspace(-3, np.log10(np.pi / dt), 4000)
            s = 1j * om
            L = (kp + kd * s) / (m[j] * s**2 + c[j] * s) * np.exp(-s * (delay[j] + 2 * dt))
            i = np.argmax(np.abs(L) < 1.0)
            if i > 0 and 180.0 + np.degrees(np.angle(L[i])) >= 60.0:
                break
            w[j] *= 0.5
    return m * w**2, np.maximum(2 * m * w - c, 0.0), w


def run_experiment(
    machines: Machines, nominal_inverse, experiment: Experiment = Experiment(), working_speed: float | None = None
) -> Measurement:
    """Run :class:`Experiment` on ``machines``; ``nominal_inverse`` (the plant's nominal
    :class:`~vcnc_gym.plants.contract.InverseDynamics`) sets the holding loop and the feedforward with which
    the axes follow the task's reference during the run (so that the excitation acts on a moving axis, whose
    friction keeps its sign, and the observation's tracking error stays within its bound).  ``working_speed``
    (mm/s): the peak speed of the machine's working feed, which sets the friction sweep's speeds; default the
    machines' task's (:func:`identify` passes the env's own task's, which a slowed experiment task,
    :func:`experiment_task`, does not show; the reversal legs' speed is the followed task's,
    :attr:`Experiment.reversal_speed`)."""
    from ..inverse_model import inverse_feedforward

    t0 = time.perf_counter()
    dt, n = machines.dt, machines.n
    kp, kd, w = holding_gains(
        nominal_inverse.mass, nominal_inverse.damping, nominal_inverse.delay, dt, experiment.holding_bandwidth
    )
    ki = kp * w / 4.0
    alpha = np.exp(-5.0 * w * dt)  # the velocity the loop damps with: the count difference low-passed at 5 w
    samples = machines.task.reference_arrays.samples
    u_ff = inverse_feedforward(nominal_inverse, samples, dt)
    rng = np.random.default_rng(experiment.seed)
    K = int(experiment.periods)
    leg_time = 12.5 / float(np.min(w)) if experiment.leg_time is None else experiment.leg_time
    ref_v = samples[:, sk.REF_VELOCITY : sk.REF_VELOCITY + 2]
    followed = float(np.max(np.hypot(ref_v[:, 0], ref_v[:, 1])))
    working_speed = followed if working_speed is None else working_speed
    speed = experiment.reversal_speed
    if speed is None:  # a fifth of the followed feed, at most LEG_TRAVEL per leg at the higher speed
        speed = min(0.2 * followed, LEG_TRAVEL / (leg_time * experiment.speed_ratio))
    per_leg = max(int(round(leg_time / dt)), 25)
    settle = per_leg
    top = min(4.0 * working_speed, LEG_TRAVEL / leg_time)
    schedule = leg_schedule(
        positive("reversal_speed", speed, "mm/s"),
        experiment.speed_ratio,
        top * 0.5 ** np.arange(experiment.sweep_steps),
    )
    legs = len(schedule)
    start = max(K, samples.shape[0]) + settle  # the legs begin once the reference has stopped
    total = start + legs * per_leg
    level = experiment.prbs_level * machines.u_max
    r = np.zeros((n, total, 2))
    # one PRBS for every machine (drawn as a batch of one draws it): a machine's record does not depend on its place
    # in a batch
    r[:, :K] = level * np.where(rng.random((K, 2)) < 0.5, -1.0, 1.0)[None]
    offset_rate, offset, u_legs = _leg_moves(schedule, start, per_leg, total, dt, nominal_inverse, machines.u_max)
    u = np.zeros((n, total, 2))
    e = np.zeros((n, total, 2))
    velocity = np.zeros((n, total, 2))
    c = np.ascontiguousarray
    machines.hold(
        sk.HoldingLoop(
            c(u_ff, dtype=np.float64),
            c(u_legs, dtype=np.float64),
            c(offset),
            c(offset_rate),
            r,
            c(kp, dtype=np.float64),
            c(kd, dtype=np.float64),
            c(ki, dtype=np.float64),
            c(alpha, dtype=np.float64),
            float(dt),
            c(machines.u_max, dtype=np.float64),
            u,
            e,
            velocity,
        )
    )
    leg_command = np.zeros((n, legs, 2))
    leg_spread = np.zeros((n, legs, 2))
    leg_velocity = np.zeros((n, legs, 2))
    leg_acceleration = np.zeros((n, legs, 2))
    for leg in range(legs):
        a = start + leg * per_leg
        window = slice(a + (3 * per_leg) // 5, a + per_leg)  # its last 40 %: at speed
        leg_command[:, leg] = u[:, window].mean(axis=1)
        leg_spread[:, leg] = _velocity_spread(velocity[:, window], alpha)
        leg_velocity[:, leg] = velocity[:, window].mean(axis=1)
        half = (window.stop - window.start) // 2  # the mean acceleration: the change of the halves' mean speeds
        leg_acceleration[:, leg] = (
            velocity[:, window.stop - half : window.stop].mean(axis=1)
            - velocity[:, window.start : window.start + half].mean(axis=1)
        ) / (half * dt)
    # the sensor's velocity noise: the measured velocity less its 21-period running mean on the legs at speed
    legs_v = velocity[:, start + (3 * per_leg) // 5 : start + per_leg]
    kernel = np.ones(21) / 21.0
    smooth = np.apply_along_axis(lambda v: np.convolve(v, kernel, mode="same"), 1, legs_v)
    velocity_noise = np.std((legs_v - smooth)[:, 10:-10], axis=1)
    return Measurement(
        r=r[:, :K],
        u=u[:, :K],
        e=e[:, :K],
        leg_command=leg_command,
        leg_speeds=schedule,
        dt=dt,
        seconds=time.perf_counter() - t0,
        velocity_noise=velocity_noise,
        holding_bandwidth=w,
        leg_velocity=leg_velocity,
        leg_spread=leg_spread,
        leg_acceleration=leg_acceleration,
    )


def _leg_moves(schedule, start: int, per_leg: int, total: int, dt: float, nominal_inverse, u_max):
    """The legs' moves on top of the reference: their rate (total, 2) mm/s, the offset (total, 2) mm and their
    nominal feedforward (total, 2) in input units, each leg ``per_leg`` periods from period ``start``."""
    from ..inverse_model import inverse_feedforward

    # the legs' moves on top of the reference, mm/s: each leg's speed reached by a Hann-shaped change at its start
    # (a step at ramp / 2 smoothed symmetrically: each leg's travel is the step's, no drift), over a tenth of the leg
    # or longer, so that its nominal inertia force (m pi / 2 dv / ramp at most) takes at most half the input limit
    # (a clipped command leaves the loop a lag), and at most LEG_RAMP_MAX of the leg
    change = np.max(np.abs(np.diff(np.vstack([np.zeros(2), schedule]), axis=0)))
    mass = float(np.max(np.abs(nominal_inverse.mass)))
    ramp_time = 0.5 * np.pi * change * mass / (0.5 * float(np.min(u_max)))
    ramp = int(np.clip(np.ceil(ramp_time / dt), per_leg * LEG_RAMP, per_leg * LEG_RAMP_MAX))
    steps = np.zeros((total + ramp, 2))
    for leg, speeds in enumerate(schedule):
        a = start + leg * per_leg + ramp // 2
        steps[a : a + per_leg] = speeds
    window = np.hanning(ramp + 2)[1:-1]
    offset_rate = np.stack([np.convolve(steps[:, j], window / window.sum(), mode="same") for j in range(2)], axis=1)[
        :total
    ]
    offset = np.cumsum(offset_rate, axis=0) * dt
    # and their own nominal feedforward (inertia, viscous and Coulomb levels): the loop then takes up only the
    # machine's difference from the nominal model and the stick at a reversal; what it has not taken up by the
    # leg's last 40 % (where the command is read) the fit's acceleration term accounts for (friction_levels)
    legs_reference = np.zeros((total, sk.REF_COLUMNS))
    legs_reference[:, sk.REF_VELOCITY : sk.REF_VELOCITY + 2] = offset_rate
    legs_reference[:, sk.REF_ACCELERATION : sk.REF_ACCELERATION + 2] = np.gradient(offset_rate, dt, axis=0)
    u_legs = inverse_feedforward(nominal_inverse, legs_reference, dt)
    return offset_rate, offset, u_legs


def _velocity_spread(v: np.ndarray, alpha) -> np.ndarray:
    """Standard deviation (mm/s) of the measured velocity ``v`` (n, K, 2) low-passed as the holding loop sees it
    (pole ``alpha`` (2,)), over its window: where the axis sticks and slips it swings about the leg's speed."""
    out = np.empty((v.shape[0], 2))
    for j in range(2):
        filtered = signal.lfilter([1.0 - alpha[j]], [1.0, -alpha[j]], v[:, :, j], axis=1)
        out[:, j] = filtered[:, filtered.shape[1] // 4 :].std(axis=1)
    return out


def frf(measurement: Measurement, machine: int, axis: int, segment: int | None = None):
    """The frequency-response estimate of one machine's axis from command to measured position: frequencies
    (Hz), ``G`` (complex, mm per input unit) and the coherence of the excitation with the position, by Welch's
    method with Hann windows (``segment`` periods, half overlap)."""
    fs = 1.0 / measurement.dt
    r, u, e = (a[machine, :, axis] for a in (measurement.r, measurement.u, measurement.e))
    x = -e  # the reference is independent of the excitation: S_rx = -S_re
    nper = min(segment or 8192, r.size)
    f, s_rx = signal.csd(r, x, fs=fs, nperseg=nper, detrend="linear")
    _, s_ru = signal.csd(r, u, fs=fs, nperseg=nper, detrend="linear")
    _, coh = signal.coherence(r, x, fs=fs, nperseg=nper, detrend="linear")
    return f[1:], s_rx[1:] / s_ru[1:], coh[1:]


@dataclass(frozen=True)
class AxisModel:
    """One axis as identified: ``m s^2 + c s`` (input unit per mm/s^2 and per mm/s), a first mode of
    ``mode_frequency`` Hz (0: none found) and ``mode_damping``, a dead time ``delay`` s (ZOH included), the
    Coulomb levels ``coulomb`` (f+, f-) in input units, the fit's rms log error and the band (Hz) it used, the
    measured velocity's noise (mm/s), the control period ``dt`` (s), the viscous coefficient the reversal legs
    measured (input unit per mm/s: the steady-state one, which the feedforward uses; ``damping`` is the
    frequency response's), the process force along the path they measured (input unit) and the Stribeck curve
    the friction sweep measured, ``(F_s, v_s)`` (input unit, mm/s; ``F_s = 0``: none)."""

    mass: float
    damping: float
    mode_frequency: float
    mode_damping: float
    delay: float
    coulomb: tuple
    fit_error: float
    band: tuple
    velocity_noise: float = 0.0
    dt: float = 0.0
    viscous: float = 0.0
    process_force: float = 0.0
    stribeck: tuple = (0.0, 0.0)

    @property
    def command_delay(self) -> float:
        """The dead time's whole control periods beyond the hold's half period, s (what the feedforward leads by)."""
        if self.dt <= 0:
            return max(self.delay, 0.0)
        return max(0.0, round(self.delay / self.dt - 0.5)) * self.dt


def model_response(model_or_params, frequency_hz):
    """The model's frequency response at ``frequency_hz`` (mm per input unit): an :class:`AxisModel`, or
    ``(m, c, f_mode, zeta, delay)``."""
    if isinstance(model_or_params, AxisModel):
        a = model_or_params
        m, c, fm, z, tau = a.mass, a.damping, a.mode_frequency, a.mode_damping, a.delay
    else:
        m, c, fm, z, tau = model_or_params
    s = 2j * np.pi * np.asarray(frequency_hz, dtype=np.float64)
    g = 1.0 / (m * s**2 + c * s) * np.exp(-s * tau)
    if fm > 0:
        w = 2 * np.pi * fm
        g = g * (2 * z * w * s + w**2) / (s**2 + 2 * z * w * s + w**2)
    return g


def fit_axis(
    f, G, coherence, nominal_mass, nominal_damping, dt, *, low_hz=None, high_hz=None, holding_bandwidth: float = 0.0
) -> AxisModel:
    """Fit :class:`AxisModel`'s linear part to one axis' estimate (see the module docstring).  The band is
    ``low_hz`` (default 20 frequency bins or four times the holding loop's ``holding_bandwidth`` (rad/s), whichever
    is higher: below, the friction and the holding loop dominate) to ``high_hz`` (default where the coherence,
    median-filtered over 31 bins, first falls below :data:`COHERENCE_FLOOR` beyond three times the low end, at
    most 0.4 of the Nyquist frequency); the nominal mass and damping are the starting point only."""
    low_default = 4.0 * holding_bandwidth / (2 * np.pi)
    low = low_hz if low_hz is not None else max(20.0 * f[0], low_default)
    if high_hz is None:  # up to where the response sinks into the sensor's counts and noise
        smooth = signal.medfilt(np.asarray(coherence, dtype=np.float64), 31)
        poor = np.flatnonzero((f > 3.0 * low) & (smooth < COHERENCE_FLOOR))
        high = min(f[poor[0]] if poor.size else np.inf, 0.2 / dt)
    else:
        high = high_hz
    band = (f >= low) & (f <= high) & np.isfinite(G) & (np.abs(G) > 0)
    coh = np.clip(coherence[band], 1e-3, 0.999)
    fb, Gb, wgt = f[band], G[band], np.sqrt(coh / (1.0 - coh))  # the estimate's inverse standard deviation
    if fb.size < 8:
        raise ValueError(f"frequency band {low:g}-{high:g} Hz holds {fb.size} bins: lengthen the experiment")

    def residual(theta, with_mode):
        m, c, tau = np.exp(theta[0]), np.exp(theta[1]), theta[2]
        params = (m, c, np.exp(theta[3]), np.exp(theta[4]), tau) if with_mode else (m, c, 0.0, 0.0, tau)
        ratio = model_response(params, fb) / Gb
        lr = np.log(ratio)
        return np.concatenate([wgt * lr.real, wgt * np.angle(ratio)])

    # where a resonance would be: the peak of |G| w^2, flat for the rigid body at high frequency
    flat = np.abs(Gb) * (2 * np.pi * fb) ** 2
    peak = int(np.argmax(signal.medfilt(flat, 5)))
    f_peak = fb[peak]
    lower = fb <= 0.6 * f_peak
    if np.count_nonzero(lower) < 8:
        lower = np.ones_like(fb, dtype=bool)
    # the rigid body on the band below the peak, its dead time from the nominal start (one period and the hold's)
    theta0 = np.array([np.log(nominal_mass), np.log(max(nominal_damping, 1e-9)), 1.5 * dt])
    # bounds (log m, log c, tau, log f, log zeta): a decade either side of the nominal mass, a viscous term
    # between nothing and a hundred times the mass per second, up to 20 periods of delay, a mode below Nyquist (one
    # fitted beyond the band's top is not kept, below)
    bound_lo = np.array([np.log(nominal_mass / 10), np.log(nominal_mass * 1e-6), -dt, np.log(low), np.log(1e-3)])
    bound_hi = np.array([np.log(nominal_mass * 10), np.log(nominal_mass * 1e2), 20 * dt, np.log(0.5 / dt), 0.0])

    def solve(fun, start, n):
        start = np.clip(start, bound_lo[:n] + 1e-9, bound_hi[:n] - 1e-9)
        return optimize.least_squares(fun, start, bounds=(bound_lo[:n], bound_hi[:n]), method="trf", x_scale="jac")

    def rigid_residual(t):
        return residual(t, False)[np.concatenate([lower, lower])]

    rigid = solve(rigid_residual, theta0, 3)
    m, c, tau = np.exp(rigid.x[0]), np.exp(rigid.x[1]), rigid.x[2]
    excess = 20 * np.log10(np.abs(Gb / model_response((m, c, 0.0, 0.0, tau), fb)))
    height = float(signal.medfilt(excess, 5)[peak])
    best, with_mode = solve(lambda t: residual(t, False), rigid.x, 3), False
    if height > MODE_PEAK_DB:
        near = fb <= 2.5 * f_peak  # the mode's neighbourhood (beyond, the response sinks into the counts)

        def mode_residual(t):
            return residual(t, True)[np.concatenate([near, near])]

        # a lightly damped mode: the peak's height above the rigid body is about 1 / (2 zeta)
        zeta0 = float(np.clip(0.5 / 10 ** (height / 20.0), 0.005, 0.7))
        start = np.array([rigid.x[0], rigid.x[1], rigid.x[2], np.log(f_peak), np.log(zeta0)])
        fitted = solve(mode_residual, start, 5)
        # a mode fitted beyond the band's top is not one the estimate shows (on Purtojo et al.'s table, whose 1 um
        # sensor ends the band at 40-70 Hz, such fits took up the dead time and the counts: 69 Hz at zeta 0.47)
        inside = np.exp(fitted.x[3]) <= fb[-1]
        if inside and 0.5 * np.sum(residual(fitted.x, True) ** 2) < best.cost:
            best, with_mode = fitted, True
    t = best.x
    rms = float(np.sqrt(2.0 * best.cost / (2 * fb.size)))
    return AxisModel(
        mass=float(np.exp(t[0])),
        damping=float(np.exp(t[1])),
        mode_frequency=float(np.exp(t[3])) if with_mode else 0.0,
        mode_damping=float(np.exp(t[4])) if with_mode else 0.0,
        delay=float(t[2]),
        coulomb=(0.0, 0.0),
        fit_error=rms,
        band=(float(low), float(high)),
        dt=float(dt),
    )


def leg_schedule(speed: float, ratio: float, sweep=()) -> np.ndarray:
    """The reversal legs' axis speeds (L, 2), mm/s: each axis alone at ``speed`` and ``ratio`` times it, in both
    directions (the other axis holding), then both together at ``speed`` (a diagonal), each out and back; then
    both together at each speed of ``sweep`` (the friction sweep), out and back."""
    v1, v2 = speed, speed * ratio
    legs = []
    for j in range(2):
        for v in (v1, v2):
            move = np.zeros(2)
            move[j] = v
            legs += [move, -move]
    for v in (v1, *sweep):
        legs += [np.array([v, v]), np.array([-v, -v])]
    return np.array(legs)


#: A leg counts for the friction fit where the axis' mean measured speed over its window is within this fraction of
#: the leg's speed, and the spread of its low-passed measured velocity (:class:`Measurement`'s ``leg_spread``) is
#: at most ``LEG_SPREAD`` of it: a stuck axis' mean command is a static friction, and the mean command of one that
#: sticks and slips is not the friction at the leg's speed.
LEG_SPEED_TOLERANCE = 0.2
LEG_SPREAD = 0.5
#: The reversal legs of :func:`leg_schedule` (each axis alone at two speeds, then the diagonal, out and back); the
#: sweep's follow.
REVERSAL_LEGS = 10

#: The Stribeck velocities the fit tries: a geometric grid of this many from the slowest counted leg's speed to
#: half the fastest's (above, the curve has not decayed within the legs and is not told from the Coulomb level).
STRIBECK_GRID = 48
#: The Stribeck term is kept where it leaves at most this fraction of the residual sum of squares without it.
STRIBECK_GAIN = 0.5


def friction_levels(measurement: Measurement, machine: int, mass=None):
    """Per axis the viscous coefficient (input unit per mm/s), the Coulomb levels (f+ >= 0, f- <= 0), a process
    force along the path (input unit) and a Stribeck curve (level in input units, velocity in mm/s), from the
    reversal legs and the friction sweep by least squares.

    On a leg where axis ``j`` moves at ``v_j`` (the path at ``|v|``) its mean command is

    .. math::

        c v_j + f^{\\mathrm{sgn}\\, v_j} + F_s e^{-(v_j / v_s)^2} \\mathrm{sgn}\\, v_j + F v_j / |v|

    (Armstrong-Helouvry, Dupont & Canudas de Wit 1994's static map: Coulomb, viscous and Stribeck friction): a
    process force against the path's motion (a cutting force) shares itself among the axes as the motion does,
    a Coulomb level does not; the single-axis and diagonal legs separate them.  The model is linear but in
    ``v_s``: for each ``v_s`` of a geometric grid (:data:`STRIBECK_GRID`) the rest by linear least squares, the
    best ``v_s`` kept (variable projection; each term's sign bounded, :func:`scipy.optimize.lsq_linear`), on every
    pair of legs (out and back, reversal or sweep) where the axis moved steadily at its speed both ways
    (:data:`LEG_SPEED_TOLERANCE`, :data:`LEG_SPREAD`).  Where that curve is not found (its best level negative,
    fewer than four speeds counted, or it removes less than half the residual of the same legs' fit without it:
    :data:`STRIBECK_GAIN`) the map is the reversal legs' alone, without ``F_s``, as before the sweep (the map of
    the experiment's followed feed).

    Where the measurement holds them, a leg's speed ``v_j`` is the measured one (its mean over the window; the
    signs and the path's direction are the schedule's), and its command the mean command less ``mass[j]`` (input
    unit per mm/s^2, the frequency response's) times the axis' mean acceleration over the window: a leg whose loop
    has not quite settled (a reversal's stick leaves the holding loop a lag it takes up slowly) still gives its
    static map.

    Returns ``(c (2,), coulomb (2, 2), force (2,), stribeck (2, 2))``, ``stribeck[j] = (F_s, v_s)``."""
    speeds = measurement.leg_speeds
    path = np.hypot(speeds[:, 0], speeds[:, 1])
    c, coulomb, force, stribeck = np.zeros(2), np.zeros((2, 2)), np.zeros(2), np.zeros((2, 2))
    measured = speeds if measurement.leg_velocity is None else measurement.leg_velocity[machine]
    command = measurement.leg_command[machine].copy()
    if mass is not None and measurement.leg_acceleration is not None:
        command -= np.asarray(mass, dtype=float)[None, :] * measurement.leg_acceleration[machine]

    def columns(rows, j):
        v = speeds[rows, j]
        return measured[rows, j], np.column_stack(
            [measured[rows, j], (v > 0).astype(float), (v < 0).astype(float), v / path[rows]]
        )

    for j in range(2):
        moving = np.flatnonzero(speeds[:, j] != 0)
        reversal = moving[moving < REVERSAL_LEGS]
        _, A = columns(reversal, j)
        x, *_ = np.linalg.lstsq(A, command[reversal, j], rcond=None)
        level, vs = 0.0, 0.0
        rows = moving
        if measurement.leg_velocity is not None:  # every pair of legs (out and back) where the axis moved steadily
            target = np.abs(speeds[:, j])
            ok = (
                (np.abs(measurement.leg_velocity[machine, :, j] - speeds[:, j]) <= LEG_SPEED_TOLERANCE * target)
                & (measurement.leg_spread[machine, :, j] <= LEG_SPREAD * target)
                & (target > 0)
            )
            pair = np.arange(len(speeds)) ^ 1  # leg_schedule's legs come out and back: (0, 1), (2, 3), ...
            rows = np.flatnonzero(ok & ok[np.minimum(pair, len(speeds) - 1)])
        v, A = columns(rows, j)
        y = command[rows, j]
        speed = np.abs(speeds[rows, j])
        if np.unique(speed).size >= 4 and np.any(rows >= REVERSAL_LEGS):
            # every term of the map is a friction or a force against the motion: c, f+, F, F_s >= 0, f- <= 0 (without
            # the signs a Stribeck column near sgn v and the Coulomb columns cancel each other at any size)
            lower, upper = np.array([0.0, 0.0, -np.inf, 0.0]), np.array([np.inf, np.inf, 0.0, np.inf])
            plain = float(np.sum((A @ optimize.lsq_linear(A, y, bounds=(lower, upper)).x - y) ** 2))
            best = (plain, None, 0.0, 0.0)
            for grid_vs in np.geomspace(speed.min(), 0.5 * speed.max(), STRIBECK_GRID):
                As = np.column_stack([A, np.exp(-((v / grid_vs) ** 2)) * np.sign(v)])
                xs = optimize.lsq_linear(As, y, bounds=(np.append(lower, 0.0), np.append(upper, np.inf))).x
                sse = float(np.sum((As @ xs - y) ** 2))
                if xs[4] > 0.0 and sse < best[0]:
                    best = (sse, xs[:4], float(xs[4]), float(grid_vs))
            # (a map the plain fit already meets to rounding keeps none)
            if best[1] is not None and best[0] <= STRIBECK_GAIN * plain and plain > 1e-12 * float(y @ y):
                _, x, level, vs = best
        c[j], coulomb[j] = x[0], (max(x[1], 0.0), min(x[2], 0.0))
        force[j] = max(x[3], 0.0)
        stribeck[j] = (level, vs)
    return c, coulomb, force, stribeck


def experiment_task(task, experiment: Experiment = Experiment()):
    """The task the experiment's axes follow: ``task`` itself when its reference lasts at least half the PRBS
    run, else the same contour and machine at the feed that makes it last the run (an axis standing still
    through most of the run sticks in its friction, and the estimate loses the band above its holding loop)."""
    from vcnc_gym.envs.task import ContouringTask

    if task.reference_arrays.samples.shape[0] >= 0.5 * experiment.periods:
        return task
    length = float(task.reference_arrays.samples[-1, sk.REF_ARC])
    feed = length / (1.05 * experiment.periods * task.dt)
    return ContouringTask(
        contour=task.curve, plant=task.plant, dt=task.dt, feedrate=feed, plant_options=task.plant_options or None
    )


def identify(task, parameters, nominal_inverse, experiment: Experiment = Experiment()):
    """Build ``parameters``' machines (one per (2, P) row) on ``task``, run the experiment and fit each axis.

    Returns ``(models, measurement)``: ``models[n][j]`` the :class:`AxisModel` of machine n's axis j.
    """
    positive("experiment.periods", experiment.periods)
    machines = Machines(experiment_task(task, experiment), parameters, seed=experiment.seed)
    ref_v = task.reference_arrays.samples[:, sk.REF_VELOCITY : sk.REF_VELOCITY + 2]
    meas = run_experiment(
        machines, nominal_inverse, experiment, working_speed=float(np.max(np.hypot(ref_v[:, 0], ref_v[:, 1])))
    )
    models = []
    for i in range(machines.n):
        axes = []
        for j in range(2):
            f, G, coh = frf(meas, i, j, experiment.segment)
            axes.append(
                fit_axis(
                    f,
                    G,
                    coh,
                    nominal_inverse.mass[j],
                    nominal_inverse.damping[j],
                    meas.dt,
                    holding_bandwidth=meas.holding_bandwidth[j],
                )
            )
        viscous, levels, force, stribeck = friction_levels(meas, i, mass=[a.mass for a in axes])
        axes = [
            AxisModel(
                **{
                    **a.__dict__,
                    "viscous": float(viscous[j]),
                    "coulomb": (float(levels[j, 0]), float(levels[j, 1])),
                    "process_force": float(force[j]),
                    "stribeck": (float(stribeck[j, 0]), float(stribeck[j, 1])),
                    "velocity_noise": float(meas.velocity_noise[i, j]),
                }
            )
            for j, a in enumerate(axes)
        ]
        models.append(axes)
    return models, meas
