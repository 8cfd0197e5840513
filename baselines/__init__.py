"""Classical contouring controllers as policies with Stable-Baselines3's predict.

The three controllers seed 000 compares (Jahanpour et al., 2014):

- ``"qft"``: the robust QFT controller G(s) with pre-filter F(s), section 2c
  (:class:`QFTPolicy`), with its robust-stability check, eq. (11)
  (:func:`robust_stability_peak`, :func:`sampled_loop_spectral_radius`);
- ``"smc"``: the adaptive sliding-mode controller of ref. [32] with Table 2
  (:class:`SlidingModePolicy`);
- ``"fuzzy"``: the Mamdani fuzzy controller with Table 1's rule base
  (:class:`FuzzyPolicy`).

Example
-------
>>> import gymnasium as gym, vcnc_gym, baselines
>>> env = gym.make("VCNC-Omega-v1")
>>> policy = baselines.make("qft", env)
>>> obs, info = env.reset()
>>> action, _ = policy.predict(obs, episode_start=True)
"""

from .base import BaselinePolicy
from .contouring_fb import ContouringFBPolicy
from .fuzzy import DEFAULT_SCALING, FuzzyPolicy, FuzzyScaling
from .qft import (
    MU,
    QFTPolicy,
    robust_stability_peak,
    sampled_loop_spectral_radius,
    sampled_loop_stable,
)
from .ilc import ILCPolicy, run_trials
from .nctf import NCTFPolicy
from .registry import make, names
from .seed001 import HinfPolicy, HinfReducedPolicy, IMCPolicy, PIPolicy
from .smc import SlidingModePolicy

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
    "FuzzyScaling",
    "DEFAULT_SCALING",
    "MU",
    "robust_stability_peak",
    "sampled_loop_spectral_radius",
    "sampled_loop_stable",
]
