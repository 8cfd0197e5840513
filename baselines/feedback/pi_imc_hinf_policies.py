"""Yadav et al.'s controllers as policies with Stable-Baselines3's ``predict``, on :class:`PositioningEnv`.

Each axis runs the unity-feedback loop of Yadav et al. (2020) (Figs. 3(b) and 4(b)),

    u = C(z) e,    e = r - x    (mm -> V),

with ``e`` the observation's ``position_error`` field (set-point minus the
measured position, mm) and ``C(z)`` the controller of
:func:`~vcnc_baselines.feedback.pi_imc_hinf.controller_tf` (V/mm) discretised once
by :func:`control.c2d` (Tustin by default) at the env's decision period and
stepped by :func:`vcnc_baselines.linear.lti_step`.  The controller's state starts
at zero at every episode start (the loop at rest before the step).
"""

from __future__ import annotations

import numpy as np

from ..base import BaselinePolicy
from ..linear import DiscreteLTI, discretize
from .pi_imc_hinf import CONTROLLER_SOURCES, controller_tf

__all__ = ["Yadav2020Policy", "PIPolicy", "IMCPolicy", "HinfPolicy", "HinfReducedPolicy"]


class Yadav2020Policy(BaselinePolicy):
    """One of Yadav et al.'s controllers, per axis, on the CNCMT axis of eq. (2); subclasses name it.

    Parameters
    ----------
    layout : object
        The env's observation layout (a ``position_error`` field in mm).
    decision_period : float
        Period in s at which :meth:`predict` is called; C(s) is discretised at it.
    nominal_parameters : array_like, (2, P)
        The plant's nominal parameters; ``u_max`` (V) scales the action.
    plant : str or PlantModel, optional
        Must be ``"cncmt_axis"``.
    method : str
        Discretisation method of :func:`control.c2d` (default ``"tustin"``).
    """

    name = "yadav2020"
    plants = ("cncmt_axis",)
    paper = "Yadav et al. (2020)"

    @property
    def controller_name(self) -> str:
        """Which of Yadav et al.'s controllers (:func:`~vcnc_baselines.feedback.pi_imc_hinf.controller_names`): the
        subclass's registry ``name``."""
        return self.name

    def __init__(self, layout, decision_period: float, nominal_parameters, plant=None, method: str = "tustin"):
        super().__init__(layout, decision_period, nominal_parameters, plant)
        try:
            layout.slice("position_error")
        except KeyError:
            raise ValueError(
                "Yadav et al.'s controllers need an observation with a 'position_error' field "
                "(the PositioningEnv, e.g. VCNC-Step-v0)"
            ) from None
        self.continuous = controller_tf(self.controller_name)  # ValueError for an unknown name
        self.source = CONTROLLER_SOURCES[self.controller_name]
        self.discrete = discretize(self.continuous, self.decision_period, method=method)
        self._lti = DiscreteLTI(self.discrete)
        self.state_shape = (2, self._lti.nx)

    def _command(self, obs: np.ndarray) -> np.ndarray:
        e = self.layout.get(obs, "position_error")  # (n, 2) mm
        n = e.shape[0]
        x = self._state.reshape(2 * n, self._lti.nx)
        u = self._lti.step(x, e.reshape(2 * n, 1))
        return u.reshape(n, 2)

    def __repr__(self) -> str:
        return f"{type(self).__name__}({self.controller_name!r}, decision_period={self.decision_period:g} s)"


class PIPolicy(Yadav2020Policy):
    """Robust PI, ``K_P + K_I / s`` with K_P = 38.33 V/m, K_I = 45.65 V/(m s) (Yadav et al. (2020), section 3.2)."""

    name = "pi"


class IMCPolicy(Yadav2020Policy):
    """IMC, ``(0.21 s + 2) / (s + 2)`` V/m (Yadav et al. (2020), eq. (23))."""

    name = "imc"


class HinfPolicy(Yadav2020Policy):
    """Fourth-order H-infinity controller (Yadav et al. (2020), eq. (28))."""

    name = "hinf"


class HinfReducedPolicy(Yadav2020Policy):
    """First-order reduced H-infinity controller, ``20.97 / (s + 5.5)`` V/m (Yadav et al. (2020), eq. (29))."""

    name = "hinf-reduced"
