"""Adaptive sliding-mode control of Altintas, Erkorkmaz and Zhu (2000), Jahanpour et al.'s Table 2.

Jahanpour et al. (2014) compare their QFT design with "the sliding mode controller of [32]"
(Altintas, Erkorkmaz and Zhu, *Sliding mode controller design for high speed
feed drives*, CIRP Annals 49(1), 2000) with the parameters of its Table 2:

=============================  =======  =======  ========
SMC parameter                  x axis   y axis   unit
=============================  =======  =======  ========
sliding surface bandwidth lam  200      200      rad/s
feedback gain K_s              0.3      0.3      V s/mm
adaptation gain rho            30       30       V/mm
disturbance limit d-           -0.32    -0.54    V
disturbance limit d+           0.43     0.58     V
=============================  =======  =======  ========

Reading of [32] used here
-------------------------
The paper itself could not be consulted here; this is the design as it is
generally described and as the paper's Table 2 parameterises it.

* Each axis is modelled in volts at the amplifier input,
  ``u = m a + c v + d``, with a and v the table acceleration (mm/s^2) and
  velocity (mm/s), m = J / (K_t K_a r_g) (V s^2/mm) and
  c = B / (K_t K_a r_g) (V s/mm) from the nominal plant of Jahanpour et al.'s eq. (1),
  and d (V) the equivalent disturbance: friction and cutting torque divided
  by K_t K_a.
* Sliding surface ``S = lam e + e_dot``, e = x_d - x (mm); S = 0 makes the
  error decay with time constant 1/lam.
* Control law
  ``u = m (a_d + lam e_dot) + c v_d + d_hat + K_s S``: the equivalent control
  of the nominal model along the reference, the disturbance estimate, and
  a linear feedback on S (the "sliding" action is continuous, no sign
  function, so there is no chattering).  With c v (measured) in place of
  c v_d the Lyapunov function V = m S^2/2 + (d - d_hat)^2/(2 rho) gives
  dV/dt = -K_s S^2; using the reference velocity adds the term -c S e_dot,
  small since c is about 0.004 V s/mm against K_s = 0.3 V s/mm, and keeps
  measured velocity noise out of the feedforward.
* Adaptive disturbance estimate ``d_hat_dot = rho S``, projected onto
  [d-, d+]: integration stops at a limit when S pushes outward.

Table 2 gives d-/d+ without a unit; read as volts (the unit of d in the
model), they are smaller than the Coulomb friction of Table 3 in volts
(T_coul / (K_t K_a), about 0.72 V on x, nominal plant): at constant feed the estimate then
sits at its limit and K_s S supplies the rest, leaving an error of about
(d - d+)/(K_s lam) = a few micrometres.

Discretisation: every quantity is read from the observation at each call
(period T = decision period), e_dot = v_d - v from the reference and table
velocities (no differentiation of float32 positions), and the estimate is
advanced by explicit Euler after the command is formed,
``d_hat <- clip(d_hat + rho S T, d-, d+)``.
"""

from __future__ import annotations

from collections import namedtuple

import numpy as np
from numba import njit
from numba.extending import overload

from vcnc_gym.envs import controller_contract
from vcnc_gym.plants import vcnc_feed_drive as feed_drive
from vcnc_gym.validation import non_negative, per_axis, positive
from ..base import BaselinePolicy

__all__ = ["SMC_TABLE2", "SlidingModePolicy", "SlidingModeArrays"]

#: Jahanpour et al. (2014), Table 2 (both axes unless a pair): lam rad/s, K_s V s/mm, rho V/mm, d-/d+ V (x, y).
SMC_TABLE2 = {
    "lam": 200.0,
    "K_s": 0.3,
    "rho": 30.0,
    "d_minus": (-0.32, -0.54),
    "d_plus": (0.43, 0.58),
}


class SlidingModePolicy(BaselinePolicy):
    """Adaptive sliding-mode controller, per axis, of Jahanpour et al.'s ref. [32] with Table 2.

    Parameters
    ----------
    layout : vcnc_gym.envs.layout.ObservationLayout
        Names the observation fields.
    decision_period : float
        Period T in s at which :meth:`predict` is called (Euler step of d_hat).
    nominal_parameters : array_like, (2, P)
        Nominal plant; m = J/(K_t K_a r_g) in V s^2/mm and
        c = B/(K_t K_a r_g) in V s/mm per axis come from it.
    lam : float or (float, float)
        Sliding surface bandwidth in rad/s, > 0.  Default 200.
    K_s : float or (float, float)
        Feedback gain on S in V s/mm, >= 0.  Default 0.3.
    rho : float or (float, float)
        Disturbance adaptation gain in V/mm, >= 0.  Default 30.
    d_minus, d_plus : float or (float, float)
        Limits of the disturbance estimate in V, d_minus <= 0 <= d_plus
        (the estimate starts at 0).  Default (-0.32, -0.54) and (0.43, 0.58).

    Attributes
    ----------
    m, c : ndarray, (2,)
        Equivalent mass (V s^2/mm) and damping (V s/mm) of the x and y axes.
    """

    name = "smc"
    plants = ("vcnc_feed_drive",)
    paper = "Jahanpour et al. (2014)"
    state_shape = (2,)  # d_hat per axis, V

    def __init__(
        self,
        layout,
        decision_period,
        nominal_parameters,
        plant=None,
        lam=SMC_TABLE2["lam"],
        K_s=SMC_TABLE2["K_s"],
        rho=SMC_TABLE2["rho"],
        d_minus=SMC_TABLE2["d_minus"],
        d_plus=SMC_TABLE2["d_plus"],
    ):
        super().__init__(layout, decision_period, nominal_parameters, plant)
        self.lam = per_axis("lam", lam, rule=positive)
        self.K_s = per_axis("K_s", K_s, rule=non_negative)
        self.rho = per_axis("rho", rho, rule=non_negative)
        self.d_minus = per_axis("d_minus", d_minus)
        self.d_plus = per_axis("d_plus", d_plus)
        if np.any(self.d_minus > 0) or np.any(self.d_plus < 0):
            raise ValueError(
                f"need d_minus <= 0 <= d_plus (the estimate starts at 0), "
                f"got d_minus={self.d_minus}, d_plus={self.d_plus}"
            )
        p = self.nominal_parameters
        r_g, K_t, K_a, J, B = (p[:, feed_drive.PARAMETER_NAMES.index(n)] for n in ("r_g", "K_t", "K_a", "J", "B"))
        gain = K_t * K_a * r_g  # Nm mm / (V rad): torque-to-voltage times transmission
        if np.any(gain <= 0):
            raise ValueError("nominal r_g K_t K_a must be > 0")
        self.m = J / gain
        self.c = B / gain

    def sliding_surface(self, obs) -> np.ndarray:
        """S = lam e + e_dot in mm/s, (..., 2), from an observation."""
        e = self.layout.tracking_error(obs)
        e_dot = self.layout.reference_velocity(obs) - self.layout.velocity(obs)
        return self.lam * e + e_dot

    @property
    def disturbance_estimate(self):
        """d_hat in V, (n_envs, 2), or None before the first predict."""
        return self._state

    def _command(self, obs):
        e = self.layout.tracking_error(obs)
        v_d = self.layout.reference_velocity(obs)
        a_d = self.layout.reference_acceleration(obs)
        e_dot = v_d - self.layout.velocity(obs)
        S = self.lam * e + e_dot
        d_hat = self._state
        u = self.m * (a_d + self.lam * e_dot) + self.c * v_d + d_hat + self.K_s * S
        np.clip(d_hat + self.rho * S * self.decision_period, self.d_minus, self.d_plus, out=d_hat)
        return u

    def _compiled_arrays(self) -> SlidingModeArrays:
        """The compiled form (:mod:`vcnc_gym.envs.controller_contract`) around the current memory."""
        return SlidingModeArrays(
            self._state,
            self.m,
            self.c,
            self.lam,
            self.K_s,
            self.rho,
            self.d_minus,
            self.d_plus,
            self.decision_period,
            self.u_max,
        )


#: The compiled controller's arrays: the memory d_hat (N, 2) V, the gains of :class:`SlidingModePolicy` ((2,)
#: each), its period T (s) and u_max (V, (2,)).
SlidingModeArrays = namedtuple(
    "SlidingModeArrays", ["d_hat", "m", "c", "lam", "K_s", "rho", "d_minus", "d_plus", "period", "u_max"]
)


@njit(cache=True, _nrt=False)
def _smc_command(s, i, obs, o, out):
    """:meth:`SlidingModePolicy._command` and ``predict``'s normalisation for env ``i``, in the same floating-point
    operations (float64, as the layout reads the float32 observation)."""
    for j in range(2):
        e = np.float64(obs[o.tracking_error + j])
        v_d = np.float64(obs[o.reference_velocity + j])
        a_d = np.float64(obs[o.reference_acceleration + j])
        e_dot = v_d - np.float64(obs[o.velocity + j])
        S = s.lam[j] * e + e_dot
        d_hat = s.d_hat[i, j]
        u = s.m[j] * (a_d + s.lam[j] * e_dot) + s.c[j] * v_d + d_hat + s.K_s[j] * S
        s.d_hat[i, j] = min(max(d_hat + s.rho[j] * S * s.period, s.d_minus[j]), s.d_plus[j])
        out[j] = np.float32(min(max(u / s.u_max[j], -1.0), 1.0))


@overload(controller_contract.command, jit_options={"cache": True})
def _command(controller, i, obs, o, out):
    if controller_contract.is_controller(controller, SlidingModeArrays):
        return lambda controller, i, obs, o, out: _smc_command(controller, i, obs, o, out)
