"""Seed 001's robust PI, IMC and H-infinity controllers (Yadav, Pathak and Gaur, 2020) and their analysis.

- :mod:`.controllers`: the controllers as python-control transfer functions
  (:func:`controller_tf`), the IMC derivation of eqs. (21)-(22) and the PI
  tuning of eqs. (17)-(19);
- :mod:`.policies`: the controllers as SB3-style policies on
  :class:`~vcnc_gym.envs.positioning_env.PositioningEnv` (registered as
  "pi", "imc", "hinf", "hinf-reduced");
- :mod:`.report`: the Kharitonov polynomials and stability margins of
  section 3.5 and Table 2's step metrics over the uncertainty box
  (``python -m baselines.seed001.report`` prints them).
"""

from .controllers import (
    CONTROLLER_SOURCES,
    SEED_CONTROLLERS,
    controller_names,
    controller_tf,
    imc_controller,
    robust_pi_gains,
)
from .policies import HinfPolicy, HinfReducedPolicy, IMCPolicy, PIPolicy, Seed001Policy

__all__ = [
    "CONTROLLER_SOURCES",
    "SEED_CONTROLLERS",
    "controller_names",
    "controller_tf",
    "imc_controller",
    "robust_pi_gains",
    "Seed001Policy",
    "PIPolicy",
    "IMCPolicy",
    "HinfPolicy",
    "HinfReducedPolicy",
]
