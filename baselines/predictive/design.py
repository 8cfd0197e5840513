"""Discrete LQ preview control of one axis: the model, the state estimator and the preview gains.

One axis is a linear model from the amplifier input ``u`` (the plant's input unit) to the table position ``y``
(mm), given as a transfer function (:meth:`vcnc_gym.plants.PlantModel.linear_model`, or any model of the same
form: a commissioned, identified one with a structural mode, say) and an input dead time.  :func:`axis_model`
discretises it under zero-order hold at the control period ``T``:

.. math::

    x(k+1) = A x(k) + B u(k), \\qquad y(k) = C x(k), \\qquad v(k) = C_v x(k)

with the dead time as ``d = T_d / T`` states that hold the last ``d`` inputs, and ``C_v = C A_c`` the table
velocity (mm/s) of a model whose relative degree is at least 2.

The preview servo (Tomizuka and Whitney 1975, discrete finite preview; the incremental form with integral action
of Katayama, Ohki, Inoue and Kato 1985) regulates the augmented error system of the tracking error
``e(k) = r(k) - y(k)`` and the state increments ``Dx(k) = x(k) - x(k-1)``, driven by the input increment
``Du(k) = u(k) - u(k-1)`` and the reference increment ``Dr(k+1)`` that the reference table gives ahead:

.. math::

    X(k) = \\begin{bmatrix} e(k) \\\\ \\Delta x(k) \\end{bmatrix}, \\quad
    X(k+1) = \\Phi X(k) + \\Gamma \\Delta u(k) + G \\Delta r(k+1), \\quad
    \\Phi = \\begin{bmatrix} 1 & -CA \\\\ 0 & A \\end{bmatrix},\\;
    \\Gamma = \\begin{bmatrix} -CB \\\\ B \\end{bmatrix},\\;
    G = \\begin{bmatrix} 1 \\\\ 0 \\end{bmatrix}

minimising ``sum q e(k)^2 + rho Du(k)^2`` (``q = 1`` per mm^2; ``rho`` in mm^-2 per input unit^2) with the
increments ``Dr(k+1) .. Dr(k+M)`` known (a shift register of ``M`` preview states, zero beyond).  With ``P`` the
stabilising solution of the Riccati equation of ``(Phi, Gamma, diag(q, 0), rho)``, ``S = rho + Gamma' P Gamma``,
``K = S^-1 Gamma' P Phi`` and the closed loop ``Phi_c = Phi - Gamma K``, the optimal law is

.. math::

    \\Delta u(k) = -K X(k) - \\sum_{j=1}^{M} K_r(j) \\Delta r(k+j), \\qquad
    K_r(j) = S^{-1} \\Gamma' (\\Phi_c')^{j-1} P G

(the preview block of the Riccati solution of the whole augmented system, tested against
:func:`scipy.linalg.solve_discrete_are` and ``control.dlqr`` on it in ``tests/test_predictive.py``); the cost to go
from ``X`` with the preview ``W = (Dr(k+1) .. Dr(k+M))`` is ``X' P X + 2 X' P_xw W + const`` with
``P_xw[:, j] = (Phi_c')^j P G``, the terminal cost of :mod:`.mpc`.  Summing the increments,
``u(k) = u(k-1) + Du(k)`` carries the integral action (zero steady error under a constant load) and, with
``u(k-1)`` the input the plant received, the anti-windup of the velocity form.

The state ``x`` is estimated from the measured position and velocity (:func:`estimator_gain`): where those two
determine the model's state (the nominal models of the suite: ``x = (y, v)`` up to a basis change) the estimate
*is* the measurement; otherwise (a model with a mode, or without a velocity output) a steady-state Kalman filter
in the current-estimator form.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy import linalg

from vcnc_gym.validation import integer, positive

__all__ = [
    "AxisModel",
    "axis_model",
    "Preview",
    "preview_design",
    "augmented",
    "preview_system",
    "estimator_gain",
    "closed_loop_bandwidth",
    "input_weight_for_bandwidth",
    "MAX_DELAY_PERIODS",
    "MAX_PREVIEW",
    "feedback_controller",
    "loop_response",
    "closed_loop_stable",
    "margin_weight",
    "sensor_noise",
]

#: Longest input dead time modelled, control periods (one state each): Yadav et al.'s 0.1 s at 0.1 ms would be
#: 1000 states, which no Riccati equation here should carry; such a plant needs a longer control period.
MAX_DELAY_PERIODS = 200
#: Longest preview, control periods (the gains beyond it are below 1e-6 of the largest on every plant of the suite).
MAX_PREVIEW = 4000


@dataclass(frozen=True)
class AxisModel:
    """One axis discretised at ``dt``: ``x(k+1) = A x + B u``, ``y = C x`` (mm), ``v = C_v x`` (mm/s).

    Attributes
    ----------
    A : ndarray, (n, n)
    B, C : ndarray, (n,)
    Cv : ndarray, (n,) or None
        The velocity output (None: the model's relative degree is below 2, velocity is not measured).
    dt : float
        Control period, s.
    order : int
        States of the plant itself; the last ``n - order`` hold the dead time's inputs (oldest first).
    mode_states : int
        Of the plant's states, those of its structural modes (2 a mode), which the loop's bandwidth leaves out
        (:func:`closed_loop_bandwidth`).
    """

    A: np.ndarray
    B: np.ndarray
    C: np.ndarray
    Cv: np.ndarray | None
    dt: float
    order: int
    mode_states: int = 0

    @property
    def n(self) -> int:
        return self.A.shape[0]

    @property
    def delay_periods(self) -> int:
        return self.n - self.order

    @property
    def input_column(self) -> np.ndarray:
        """(order,) the column through which the input enters the plant's own states (after the dead time's)."""
        return self.A[: self.order, self.order] if self.delay_periods else self.B[: self.order]

    def measurement(self) -> np.ndarray:
        """The rows of the measured outputs, (1 or 2, n): position, and velocity when the model has it."""
        return np.vstack([self.C] + ([self.Cv] if self.Cv is not None else []))


def axis_model(tf, dt: float, delay: float = 0.0, velocity: bool = True, mode_states: int = 0) -> AxisModel:
    """Discretise one axis' transfer function (mm per input unit) under zero-order hold at ``dt`` s.

    Parameters
    ----------
    tf : control.TransferFunction
        SISO, strictly proper; continuous (``tf.dt`` 0 or None) or discrete with ``tf.dt == dt``.
    dt : float
        Control period, s.
    delay : float
        Input dead time, s, rounded to whole control periods (at most :data:`MAX_DELAY_PERIODS`).
    velocity : bool
        Whether the velocity is measured (``C_v``); False leaves the position alone.
    mode_states : int
        States of the model's structural modes (:attr:`AxisModel.mode_states`).
    """
    import control

    dt = positive("dt", dt, "s")
    if not isinstance(tf, control.TransferFunction) or tf.ninputs != 1 or tf.noutputs != 1:
        raise ValueError(f"model must be a SISO control.TransferFunction, got {tf!r}")
    periods = int(round(positive("delay", delay, "s") / dt)) if delay else 0
    if periods > MAX_DELAY_PERIODS:
        raise ValueError(
            f"delay {delay} s is {periods} control periods of {dt} s, more than the {MAX_DELAY_PERIODS} "
            "states the preview design carries; use a longer control period (the env's dt)"
        )
    sys = control.ss(tf)
    if np.any(np.abs(np.asarray(sys.D)) > 0):
        raise ValueError(f"model must be strictly proper (no direct feedthrough), got {tf}")
    A_c, B_c, C_c = (np.asarray(m, dtype=np.float64) for m in (sys.A, sys.B, sys.C))
    if tf.dt in (0, None):
        Cv = (
            C_c @ A_c if velocity and abs((C_c @ B_c).item()) <= 1e-12 * np.abs(C_c).max() * np.abs(B_c).max() else None
        )
        d = control.c2d(sys, dt, "zoh")  # the same state coordinates: expm of the continuous system
        A, B = np.asarray(d.A, dtype=np.float64), np.asarray(d.B, dtype=np.float64)
    else:
        if not np.isclose(tf.dt, dt, rtol=1e-9, atol=0.0):
            raise ValueError(f"a discrete model must have the env's sample time dt = {dt} s, got {tf.dt} s")
        A, B, Cv = A_c, B_c, None
    B, C = B[:, 0], C_c[0]
    n = A.shape[0]
    if periods:  # states n .. n + d - 1: u(k - d) .. u(k - 1)
        m = n + periods
        A_d = np.zeros((m, m))
        A_d[:n, :n] = A
        A_d[:n, n] = B
        A_d[n : m - 1, n + 1 :] = np.eye(periods - 1)
        B_d = np.zeros(m)
        B_d[m - 1] = 1.0
        pad = np.zeros(periods)
        return AxisModel(
            A_d, B_d, np.concatenate([C, pad]), None if Cv is None else np.concatenate([Cv[0], pad]), dt, n, mode_states
        )
    return AxisModel(A, B, C, None if Cv is None else Cv[0], dt, n, mode_states)


def augmented(model: AxisModel):
    """The augmented error system of Katayama et al. (1985): ``(Phi, Gamma, G)``, (1 + n, 1 + n), (1 + n,) each."""
    n = model.n
    Phi = np.zeros((n + 1, n + 1))
    Phi[0, 0] = 1.0
    Phi[0, 1:] = -model.C @ model.A
    Phi[1:, 1:] = model.A
    Gamma = np.concatenate([[-model.C @ model.B], model.B])
    G = np.zeros(n + 1)
    G[0] = 1.0
    return Phi, Gamma, G


@dataclass(frozen=True)
class Preview:
    """The LQ preview design of one axis (see the module docstring).

    Attributes
    ----------
    K : ndarray, (1 + n,)
        Feedback gain on ``X = (e, Dx)``: input unit per mm, and per the state increments' units.
    Kr : ndarray, (M,)
        Preview gains on ``Dr(k+1) .. Dr(k+M)``, input unit per mm.
    P : ndarray, (1 + n, 1 + n)
        The Riccati solution (cost to go, mm^2 in units of ``q``).
    Pxw : ndarray, (1 + n, M)
        The cost to go's cross term with the preview.
    S : float
        ``rho + Gamma' P Gamma``.
    Phi_c : ndarray
        The closed loop ``Phi - Gamma K``.
    q, rho : float
        The weights.
    """

    K: np.ndarray
    Kr: np.ndarray
    P: np.ndarray
    Pxw: np.ndarray
    S: float
    Phi_c: np.ndarray
    q: float
    rho: float

    @property
    def preview(self) -> int:
        return self.Kr.size


def _riccati(model: AxisModel, q: float, rho: float):
    Phi, Gamma, G = augmented(model)
    Q = np.zeros_like(Phi)
    Q[0, 0] = q
    try:
        P = linalg.solve_discrete_are(Phi, Gamma[:, None], Q, np.array([[rho]]))
    except ValueError as exc:  # scipy's ordqz on an ill-conditioned pencil
        raise np.linalg.LinAlgError(
            f"the preview servo's Riccati equation failed for this model at dt = {model.dt} s "
            f"and input weight {rho:g} ({exc}); give another input_weight"
        ) from None
    P = 0.5 * (P + P.T)
    S = rho + Gamma @ P @ Gamma
    K = (Gamma @ P @ Phi) / S
    return Phi, Gamma, G, P, S, K


def preview_design(
    model: AxisModel, rho: float, preview: int | None = None, q: float = 1.0, tolerance: float = 1e-6
) -> Preview:
    """The LQ preview gains of one axis (module docstring) with the weights ``q`` (mm^-2) and ``rho``
    (input unit^-2, same scale).

    ``preview`` control periods of the reference ahead; default the shortest ``M`` beyond which every preview gain
    is below ``tolerance`` times the largest (at most :data:`MAX_PREVIEW`)."""
    rho = positive("rho", rho)
    q = positive("q", q)
    Phi, Gamma, G, P, S, K = _riccati(model, q, rho)
    Phi_c = Phi - np.outer(Gamma, K)
    limit = MAX_PREVIEW if preview is None else integer("preview", preview, minimum=1, maximum=MAX_PREVIEW)
    columns = []  # (Phi_c')^(j-1) P G, j = 1 ..
    c = P @ G
    for _ in range(limit + 1):
        columns.append(c)
        c = Phi_c.T @ c
    Kr_all = np.array([Gamma @ col for col in columns]) / S
    if preview is None:
        big = np.abs(Kr_all).max()
        above = np.flatnonzero(np.abs(Kr_all) >= tolerance * big)
        limit = min(int(above[-1]) + 1, limit) if above.size else 1  # at most the cap: gains still above it are cut
    Kr = Kr_all[:limit]
    Pxw = np.column_stack(columns[1 : limit + 1])
    return Preview(K=K, Kr=Kr, P=P, Pxw=Pxw, S=float(S), Phi_c=Phi_c, q=q, rho=rho)


def preview_system(model: AxisModel, M: int, q: float = 1.0):
    """The whole augmented system with ``M`` preview states (``Z = (X, Dr(k+1) .. Dr(k+M))``, the shift register
    bringing in zeros): ``(A_z, B_z, Q_z)``, what the tests hand to a Riccati solver of their own."""
    Phi, Gamma, G = augmented(model)
    n1 = Phi.shape[0]
    A_z = np.zeros((n1 + M, n1 + M))
    A_z[:n1, :n1] = Phi
    A_z[:n1, n1] = G
    A_z[n1 : n1 + M - 1, n1 + 1 :] = np.eye(M - 1)
    B_z = np.concatenate([Gamma, np.zeros(M)])[:, None]
    Q_z = np.zeros_like(A_z)
    Q_z[0, 0] = q
    return A_z, B_z, Q_z


def closed_loop_bandwidth(model: AxisModel, rho: float, q: float = 1.0) -> float:
    """The geometric mean, rad/s, of the continuous equivalents ``|ln z| / T`` of the ``1 + order - mode_states``
    slowest poles of the LQ loop ``Phi_c`` (the integral and the plant's own states; the dead time's and a
    structural mode's, the fastest, are left out): for a triple pole at ``-w`` (the PID design of
    :func:`vcnc_baselines.commissioning.design.pid_gains`) it is ``w``."""
    *_, K = _riccati(model, q, rho)
    Phi, Gamma, _ = augmented(model)
    z = np.linalg.eigvals(Phi - np.outer(Gamma, K)).astype(complex)
    z = z[np.argsort(np.abs(z))[::-1][: 1 + model.order - model.mode_states]]
    s = np.abs(np.log(np.where(np.abs(z) > 1e-300, z, 1e-300))) / model.dt  # |s| of s = ln(z) / T, complex
    return float(np.exp(np.mean(np.log(np.maximum(s, 1e-300)))))


def input_weight_for_bandwidth(model: AxisModel, bandwidth: float, q: float = 1.0) -> float:
    """The input weight ``rho`` whose LQ loop has :func:`closed_loop_bandwidth` equal to ``bandwidth`` rad/s
    (bisection on ``log rho``: a smaller weight, a faster loop; remembered per model, bandwidth and ``q``, as
    every controller built for an id asks the same)."""
    bandwidth = positive("bandwidth", bandwidth, "rad/s")
    key = (
        model.A.tobytes(),
        model.B.tobytes(),
        model.C.tobytes(),
        model.order,
        model.mode_states,
        model.dt,
        bandwidth,
        float(q),
    )
    if key not in _WEIGHTS:
        _WEIGHTS[key] = _bisect_weight(model, bandwidth, q)
    return _WEIGHTS[key]


_WEIGHTS: dict = {}


def _bisect_weight(model: AxisModel, bandwidth: float, q: float) -> float:
    lo, hi = -40.0, 40.0  # log10 rho: fast ... slow
    if closed_loop_bandwidth(model, 10.0**lo, q) < bandwidth:
        raise ValueError(f"bandwidth {bandwidth} rad/s is beyond what the model's LQ loop reaches at dt = {model.dt} s")
    while hi - lo > 1e-9:
        mid = 0.5 * (lo + hi)
        try:
            faster = closed_loop_bandwidth(model, 10.0**mid, q) > bandwidth
        except np.linalg.LinAlgError:  # a weight so large the Riccati solver loses the integral's pole near z = 1
            faster = False
        if faster:
            lo = mid
        else:
            hi = mid
    return 10.0 ** (0.5 * (lo + hi))


def estimator_gain(model: AxisModel, input_noise: float, position_noise: float, velocity_noise: float) -> np.ndarray:
    """The current estimator's gain ``L`` (n, m) of ``x(k|k) = x(k|k-1) + L (y_m - C_m x(k|k-1))``, ``y_m`` the
    measured position (mm) and velocity (mm/s) (:meth:`AxisModel.measurement`).

    Where the measurement determines the plant's states (``C_m`` square and invertible on them), ``L`` is its
    inverse (the estimate is the measurement; the dead time's states are known inputs).  Otherwise the steady-state
    Kalman filter (Riccati equation of the prediction covariance) for a white input disturbance of standard
    deviation ``input_noise`` (input unit) and white measurement noise ``position_noise`` (mm) and
    ``velocity_noise`` (mm/s)."""
    Cm = model.measurement()
    m, n, o = Cm.shape[0], model.n, model.order
    if m == o and abs(np.linalg.det(Cm[:, :o])) > 1e-12 * np.abs(Cm[:, :o]).max() ** o:
        L = np.zeros((n, m))
        L[:o] = np.linalg.inv(Cm[:, :o])
        return L
    w = positive("input_noise", input_noise)
    R = np.diag(
        [
            positive("position_noise", position_noise, "mm") ** 2,
            positive("velocity_noise", velocity_noise, "mm/s") ** 2,
        ][:m]
    )
    b = np.zeros(n)
    b[:o] = model.input_column
    Qw = np.outer(b, b) * w * w + 1e-30 * np.eye(n)
    Sigma = linalg.solve_discrete_are(model.A.T, Cm.T, Qw, R)  # prediction covariance
    return Sigma @ Cm.T @ np.linalg.inv(Cm @ Sigma @ Cm.T + R)


def feedback_controller(model: AxisModel, design: Preview, L: np.ndarray):
    """The LQ servo's feedback part (the reference and preview at zero) as a discrete state-space map from the
    measured outputs ``y_m`` (position mm, and velocity mm/s where measured) to the command ``u``:
    ``s(k+1) = A_c s(k) + B_c y_m(k)``, ``u(k) = C_c s(k) + D_c y_m(k)``, with ``s = (x(k-1|k-1), u(k-1))`` and
    the law of :mod:`.lq_preview` (``e = -y``, ``Du = -K_e e - K_x (x(k|k) - x(k-1|k-1))``).  Returns
    ``(A_c, B_c, C_c, D_c)``."""
    n = model.n
    Cm = model.measurement()
    I_LC = np.eye(n) - L @ Cm
    Abar, Bbar = I_LC @ model.A, I_LC @ model.B
    Ke, Kx = design.K[0], design.K[1:]
    c1 = np.zeros(Cm.shape[0])
    c1[0] = 1.0
    Cc = np.concatenate([-Kx @ (Abar - np.eye(n)), [1.0 - Kx @ Bbar]])
    Dc = Ke * c1 - Kx @ L
    Ac = np.zeros((n + 1, n + 1))
    Ac[:n, :n], Ac[:n, n] = Abar, Bbar
    Ac[n] = Cc
    Bc = np.vstack([L, Dc[None]])
    return Ac, Bc, Cc, Dc


def loop_response(
    model: AxisModel, design: Preview, L: np.ndarray, omega, plant: AxisModel | None = None
) -> np.ndarray:
    """The loop ``L(e^{j w T}) = -C(z) P_m(z)`` broken at the plant's input (the convention of
    :func:`vcnc_baselines.commissioning.design.margins`: the closed loop is ``1 / (1 + L)``), at ``omega`` rad/s:
    ``C`` :func:`feedback_controller` of ``model``, ``P_m`` from the command to the measured outputs of ``plant``
    (default ``model``; another model with the same measured outputs: the controller on a plant it was not
    designed for)."""
    Ac, Bc, Cc, Dc = feedback_controller(model, design, L)
    plant = model if plant is None else plant
    Cm = plant.measurement()
    z = np.exp(1j * np.asarray(omega, dtype=np.float64) * model.dt)
    P = (
        np.linalg.solve(
            z[:, None, None] * np.eye(plant.n) - plant.A, np.broadcast_to(plant.B, (z.size, plant.n))[..., None]
        )[..., 0]
        @ Cm.T
    )  # (W, m)
    S = np.linalg.solve(z[:, None, None] * np.eye(Ac.shape[0]) - Ac, np.broadcast_to(Bc, (z.size,) + Bc.shape))
    C = np.einsum("i,wim->wm", Cc, S) + Dc  # (W, m)
    return -np.sum(C * P, axis=1)


def closed_loop_stable(model: AxisModel, design: Preview, L: np.ndarray) -> bool:
    """Whether the model under the LQ servo's feedback (with its estimator) is stable: every eigenvalue of the
    interconnection inside the unit circle."""
    Ac, Bc, Cc, Dc = feedback_controller(model, design, L)
    Cm = model.measurement()
    n, c = model.n, Ac.shape[0]
    A = np.zeros((n + c, n + c))
    A[:n, :n] = model.A + np.outer(model.B, Dc @ Cm)
    A[:n, n:] = np.outer(model.B, Cc)
    A[n:, :n] = Bc @ Cm
    A[n:, n:] = Ac
    return bool(np.all(np.abs(np.linalg.eigvals(A)) < 1.0))


def margin_weight(
    model: AxisModel, L: np.ndarray, crossover_limit: float, mode_hz: float = 0.0, step: float = 0.25
) -> float | None:
    """The commissioning rule of :func:`vcnc_baselines.commissioning.design.design_axis`, applied to the LQ servo
    with its estimator gain ``L`` (:func:`estimator_gain`): down a grid of ``log10 rho`` from ``1e8`` in ``step``
    (slow to fast) until the loop (:func:`loop_response`) crosses over above ``crossover_limit`` rad/s (the
    commissioned PID's crossover) or, on a model with a mode at ``mode_hz``, above
    :data:`~vcnc_baselines.commissioning.design.MODE_FRACTION` of it, the smallest (fastest) input weight whose
    loop is stable and meets the phase and gain margins and the sensitivity peak
    (:data:`~vcnc_baselines.commissioning.design.PHASE_MARGIN` and its neighbours).  None where none does."""
    from ..commissioning.design import MODE_FRACTION, margins

    limit = min(crossover_limit, MODE_FRACTION * 2 * np.pi * mode_hz) if mode_hz > 0 else crossover_limit
    key = (
        model.A.tobytes(),
        model.B.tobytes(),
        model.measurement().tobytes(),
        np.asarray(L).tobytes(),
        model.dt,
        float(limit),
        float(step),
    )
    if key in _MARGIN_WEIGHTS:  # every controller built for an id asks the same
        return _MARGIN_WEIGHTS[key]
    omega = np.logspace(-1, np.log10(0.999 * np.pi / model.dt), 2000)
    passed = None
    for log_rho in np.arange(8.0, -14.0, -step):
        try:
            design = preview_design(model, 10.0**log_rho, preview=1)
        except (ValueError, np.linalg.LinAlgError):  # a weight so large the Riccati solver loses the integral
            continue
        if not closed_loop_stable(model, design, L):  # (or a Riccati solution gone wrong at a huge weight)
            continue
        m = margins(loop_response(model, design, L, omega), omega)
        if m.crossover > limit:
            break
        if m.meets():
            passed = float(10.0**log_rho)
    _MARGIN_WEIGHTS[key] = passed
    return passed


_MARGIN_WEIGHTS: dict = {}


def sensor_noise(plant, nominal) -> np.ndarray:
    """Per axis, the standard deviation (mm) of the position reading the plant declares: ``sqrt(resolution^2 / 12
    + noise_std^2)`` from its nominal ``resolution`` / ``encoder_resolution`` and ``noise_std`` (0 for an exact
    one)."""
    names = list(plant.parameter_names)
    variance = np.zeros(2)
    for name, per in (("resolution", 12.0), ("encoder_resolution", 12.0), ("noise_std", 1.0)):
        if name in names:
            variance += nominal[:, names.index(name)] ** 2 / per
    return np.sqrt(variance)
