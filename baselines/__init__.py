"""Classical contouring controllers as policies with Stable-Baselines3's predict.

The three controllers Jahanpour et al. (2014) compare:

- ``"qft"``: the robust QFT controller G(s) with pre-filter F(s), section 2c
  (:class:`QFTPolicy`), with its robust-stability check, eq. (11)
  (:func:`robust_stability_peak`, :func:`sampled_loop_spectral_radius`);
- ``"smc"``: the adaptive sliding-mode controller of ref. [32] with Table 2
  (:class:`SlidingModePolicy`);
- ``"fuzzy"``: the Mamdani fuzzy controller with Table 1's rule base
  (:class:`FuzzyPolicy`).

Example
-------
>>> import gymnasium as gym, vcnc_gym, vcnc_baselines
>>> env = gym.make("VCNC-Omega-v1")
>>> policy = vcnc_baselines.make("qft", env)
>>> obs, info = env.reset()
>>> action, _ = policy.predict(obs, episode_start=True)
"""

from vcnc_gym.extras import require_extra

# ruff: noqa: E402  (the imports below follow the extra's check on purpose)
require_extra("baselines", "vcnc_baselines")  # python-control, scipy, daqp: the extra named if one is missing

from .base import BaselinePolicy
from .coupling.contouring_fb import ContouringFBPolicy
from .feedback.fuzzy import DEFAULT_SCALING, FuzzyPolicy, FuzzyScaling
from .feedback.qft import (
    MU,
    QFTPolicy,
    robust_stability_peak,
    sampled_loop_spectral_radius,
    sampled_loop_stable,
)
from .feedback.nctf import NCTFPolicy
from .feedback.pi_imc_hinf_policies import HinfPolicy, HinfReducedPolicy, IMCPolicy, PIPolicy
from .feedback.smc import SlidingModePolicy
from .learning.ilc import ILCPolicy, run_trials
from .registry import make, names
from .optimal.oracle import OraclePolicy  # registers the floor (vcnc_baselines.registry.register_floor)

__all__ = [
    "make",
    "names",
    "BaselinePolicy",
    "QFTPolicy",
    "SlidingModePolicy",
    "FuzzyPolicy",
    "PIPolicy",
    "IMCPolicy",
    "HinfPolicy",
    "HinfReducedPolicy",
    "ContouringFBPolicy",
    "ILCPolicy",
    "run_trials",
    "NCTFPolicy",
    "OraclePolicy",
    "FuzzyScaling",
    "DEFAULT_SCALING",
    "MU",
    "robust_stability_peak",
    "sampled_loop_spectral_radius",
    "sampled_loop_stable",
]
