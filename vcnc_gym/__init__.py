"""vcnc-gym: Gymnasium environments for contouring control of CNC feed drives.

``import vcnc_gym`` registers the environment ids::

    import gymnasium as gym
    import vcnc_gym

    env = gym.make("VCNC-Heart-v0")
"""

from gymnasium.envs.registration import register, registry

from .envs import ContouringEnv, ObservationLayout

__version__ = "0.1.0"

# id -> (contour, max_episode_steps): the natural length at the default
# arguments (dt = 1e-4 s, 100 mm/s, 0.12 s ramps, 10 ms settling) plus ~5 %.
ENV_IDS = {
    "VCNC-Heart-v0": ("heart", 34_000),
    "VCNC-Omega-v0": ("omega", 7_000),
}

for _id, (_contour, _steps) in ENV_IDS.items():
    if _id not in registry:
        register(
            id=_id,
            entry_point="vcnc_gym.envs.contouring_env:ContouringEnv",
            kwargs={"contour": _contour},
            max_episode_steps=_steps,
        )

__all__ = ["ContouringEnv", "ObservationLayout", "ENV_IDS", "__version__"]
