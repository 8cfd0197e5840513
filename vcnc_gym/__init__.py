"""vcnc-gym: Gymnasium environments for contouring control of CNC feed drives.

``import vcnc_gym`` registers the environment ids of :data:`vcnc_gym.envs.SUITE`::

    import gymnasium as gym
    import vcnc_gym

    env = gym.make("VCNC-Heart-v1")
    envs = gym.make_vec("VCNC-Heart-v1", num_envs=1024, vectorization_mode="vector_entry_point")
"""

from .envs import ENV_IDS, SUITE, ContouringEnv, ContouringVectorEnv, ObservationLayout, register_envs

__version__ = "0.3.0"  # the one place: pyproject.toml reads it (CHANGELOG.md)

register_envs()

__all__ = ["ContouringEnv", "ContouringVectorEnv", "ObservationLayout", "ENV_IDS", "SUITE", "__version__"]
