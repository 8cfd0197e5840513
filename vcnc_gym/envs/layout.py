"""Named fields of the flat observation vector.

A baseline reads ``layout.tracking_error(obs)`` rather than ``obs[6:8]``; the
env's numba step kernel writes the same fields through the offsets held here.
All fields are in the physical units their docstrings give; agents normalise
with ``VecNormalize``.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

__all__ = ["ObservationLayout", "Field"]


@dataclass(frozen=True)
class Field:
    """One named slice of the observation: name, size, unit, bound, meaning."""

    name: str
    size: int
    unit: str
    bound: float
    description: str


@dataclass(frozen=True)
class ObservationLayout:
    """The observation of a contouring env: fields, offsets, bounds.

    Parameters
    ----------
    preview_steps : tuple of int
        Offsets, in control periods, of the upcoming reference points given
        relative to the tool (the "preview" field).
    position_bound : float
        Bound in mm on every absolute and relative position field.
    velocity_bound, acceleration_bound, error_bound : float
        Bounds in mm/s, mm/s^2 and mm on the matching fields.  Values beyond a
        bound are clipped, so every observation lies inside the space.
    """

    preview_steps: tuple[int, ...] = (10, 50, 100)
    position_bound: float = 1000.0
    velocity_bound: float = 1000.0
    acceleration_bound: float = 1.0e6
    error_bound: float = 10.0
    fields: tuple[Field, ...] = field(init=False)

    def __post_init__(self):
        pb, vb, ab, eb = self.position_bound, self.velocity_bound, self.acceleration_bound, self.error_bound
        fields = (
            Field("reference_position", 2, "mm", pb, "reference point x_d (x, y)"),
            Field("reference_velocity", 2, "mm/s", vb, "reference velocity dx_d/dt"),
            Field("reference_acceleration", 2, "mm/s^2", ab, "reference acceleration"),
            Field("tracking_error", 2, "mm", eb, "x_d - x per axis, seed 002 eq. (2)"),
            Field("contour_error", 1, "mm", eb, "shortest distance from the tool to the whole contour"),
            Field("tangential_error", 1, "mm", eb, "tracking error along the path tangent, seed 002 eq. (3)"),
            Field("normal_error", 1, "mm", eb, "tracking error along the path normal, seed 002 eq. (3)"),
            Field("velocity", 2, "mm/s", vb, "table velocity"),
            Field("preview", 2 * len(self.preview_steps), "mm", pb,
                  f"reference points {list(self.preview_steps)} control periods ahead, minus the tool position"),
            Field("previous_action", 2, "1", 1.0, "last normalised action in [-1, 1]"),
        )
        object.__setattr__(self, "fields", fields)

    # -- offsets -------------------------------------------------------------
    @property
    def size(self) -> int:
        """Length of the observation vector."""
        return sum(f.size for f in self.fields)

    def slice(self, name: str) -> slice:
        """The slice of field ``name`` in the observation vector."""
        start = 0
        for f in self.fields:
            if f.name == name:
                return slice(start, start + f.size)
            start += f.size
        raise KeyError(f"no observation field {name!r}; fields are {[f.name for f in self.fields]}")

    def offset(self, name: str) -> int:
        """Index of the first element of field ``name``."""
        return self.slice(name).start

    def high(self) -> np.ndarray:
        """Upper bounds of the observation space (float32); low is -high."""
        return np.concatenate([np.full(f.size, f.bound, dtype=np.float32) for f in self.fields])

    def get(self, obs: np.ndarray, name: str) -> np.ndarray:
        """Field ``name`` of one observation (..., size) as float64."""
        return np.asarray(obs, dtype=np.float64)[..., self.slice(name)]

    # -- named accessors, so that policies read fields, not indices ----------
    def reference_position(self, obs):
        """x_d in mm, (..., 2)."""
        return self.get(obs, "reference_position")

    def reference_velocity(self, obs):
        """dx_d/dt in mm/s, (..., 2)."""
        return self.get(obs, "reference_velocity")

    def reference_acceleration(self, obs):
        """d^2x_d/dt^2 in mm/s^2, (..., 2)."""
        return self.get(obs, "reference_acceleration")

    def tracking_error(self, obs):
        """x_d - x in mm, (..., 2)."""
        return self.get(obs, "tracking_error")

    def contour_error(self, obs):
        """Contour error in mm, (..., 1), >= 0."""
        return self.get(obs, "contour_error")

    def velocity(self, obs):
        """Table velocity in mm/s, (..., 2)."""
        return self.get(obs, "velocity")

    def position(self, obs):
        """Table position x = x_d - e in mm, (..., 2) (float32 resolution ~10 nm at 100 mm)."""
        return self.reference_position(obs) - self.tracking_error(obs)

    def preview(self, obs):
        """Upcoming reference points minus the tool position in mm, (..., n_preview, 2)."""
        p = self.get(obs, "preview")
        return p.reshape(p.shape[:-1] + (len(self.preview_steps), 2))

    def previous_action(self, obs):
        """The previous normalised action, (..., 2)."""
        return self.get(obs, "previous_action")

    def describe(self) -> str:
        """A Markdown table of the fields: index range, name, unit, meaning."""
        rows = ["| index | field | unit | meaning |", "|---|---|---|---|"]
        for f in self.fields:
            s = self.slice(f.name)
            rows.append(f"| {s.start}-{s.stop - 1} | {f.name} | {f.unit} | {f.description} |")
        return "\n".join(rows)
