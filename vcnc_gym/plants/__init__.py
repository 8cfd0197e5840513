"""plants: feed-drive models, one module per seed, as numba kernels."""

from vcnc_gym.plants import vcnc_feed_drive
from vcnc_gym.plants.vcnc_feed_drive import (
    FeedDrivePlant,
    nominal_parameters,
    reset_feed_drives,
    sample_parameters,
    step_feed_drives,
    uncertainty_vertices,
)

__all__ = [
    "vcnc_feed_drive",
    "FeedDrivePlant",
    "nominal_parameters",
    "reset_feed_drives",
    "sample_parameters",
    "step_feed_drives",
    "uncertainty_vertices",
]
