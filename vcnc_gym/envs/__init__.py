"""Gymnasium environments: they wire a reference, a plant and a reward together."""

from .contouring_env import ContouringEnv
from .contouring_vector_env import ContouringVectorEnv
from .layout import Field, ObservationLayout
from .registry import CONTOURING_IDS, ENV_IDS, SUITE, VECTOR_IDS, register_envs, suite_env
from .task import ContouringBatch, ContouringTask

__all__ = [
    "ContouringEnv",
    "ContouringVectorEnv",
    "ContouringTask",
    "ContouringBatch",
    "Field",
    "ObservationLayout",
    "ENV_IDS",
    "CONTOURING_IDS",
    "VECTOR_IDS",
    "SUITE",
    "register_envs",
    "suite_env",
]
