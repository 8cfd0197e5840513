"""Named fields of the flat observation vector.

A baseline reads ``layout.tracking_error(obs)`` rather than ``obs[6:8]``; the
env's numba step kernel writes the same fields through the offsets held here.
All fields are in the physical units their docstrings give; agents normalise
with ``VecNormalize``.
"""

from __future__ import annotations

from collections import namedtuple
import dataclasses
from dataclasses import dataclass, field

import numpy as np

from ..validation import positive

__all__ = ["ObservationLayout", "Field", "FIELD_NAMES", "ObservationOffsets", "UNIT_BOUND"]

#: The bound of a scaled field, in multiples of its scale: an entry beyond it is clipped there.
UNIT_BOUND = 100.0

#: The observation's fields by name, in the order of the vector.  The step
#: kernel writes each field through ``ObservationOffsets`` (the offsets of
#: these names, computed by :meth:`ObservationLayout.offsets`), never by
#: position, so reordering the fields here reorders the vector and nothing
#: else.
FIELD_NAMES = (
    "reference_position",
    "reference_velocity",
    "reference_acceleration",
    "tracking_error",
    "contour_error",
    "tangential_error",
    "normal_error",
    "velocity",
    "preview",
    "contour_preview",
    "contour_curvature",
    "previous_action",
)

#: Named offsets of the fields in the observation vector, passed to the
#: step kernel (a namedtuple of ints, one per name of ``FIELD_NAMES``).
ObservationOffsets = namedtuple("ObservationOffsets", FIELD_NAMES)


@dataclass(frozen=True)
class Field:
    """One named slice of the observation: name, size, unit, bound, meaning."""

    name: str
    size: int
    unit: str
    bound: float
    description: str
    scale: float = 1.0
    """The constant the env divides the field by (in ``unit``; 1.0: shown in its unit)."""


@dataclass(frozen=True)
class ObservationLayout:
    """The observation of a contouring env: fields, offsets, bounds.

    Parameters
    ----------
    preview_steps : tuple of int
        Offsets, in control periods, of the upcoming reference points given
        relative to the tool (the "preview" field); empty: no such field (an
        agent's ablation: the controllers read their preview from the
        reference, not from the observation).
    contour_ahead : tuple of float
        Arc lengths in mm beyond the tool's closest point at which the
        contour itself is shown (the "contour_preview" and
        "contour_curvature" fields); empty: no such fields (the v0 ids).
    position_bound : float
        Bound in mm on every absolute and relative position field.
    velocity_bound, acceleration_bound, error_bound : float
        Bounds in mm/s, mm/s^2 and mm on the matching fields.  Values beyond a
        bound are clipped, so every observation lies inside the space.
    """

    preview_steps: tuple[int, ...] = (10, 50, 100)
    contour_ahead: tuple[float, ...] = ()
    position_bound: float = 1000.0
    velocity_bound: float = 1000.0
    acceleration_bound: float = 1.0e6
    error_bound: float = 10.0
    curvature_bound: float = 1.0e4
    scales: tuple[tuple[str, float], ...] = ()
    fields: tuple[Field, ...] = field(init=False)

    def __post_init__(self):
        pb, vb, ab, eb = self.position_bound, self.velocity_bound, self.acceleration_bound, self.error_bound
        for name, bound in (
            ("position_bound", pb),
            ("velocity_bound", vb),
            ("acceleration_bound", ab),
            ("error_bound", eb),
        ):
            positive(name, bound)
        steps = self.preview_steps
        if not isinstance(steps, tuple) or not all(
            isinstance(s, (int, np.integer)) and not isinstance(s, bool) and s >= 1 for s in steps
        ):
            raise ValueError(f"preview_steps must be a tuple of integers >= 1 (control periods), got {steps!r}")
        object.__setattr__(self, "preview_steps", tuple(int(s) for s in steps))
        ahead = self.contour_ahead
        if not isinstance(ahead, tuple) or not all(
            isinstance(a, (int, float, np.integer, np.floating))
            and not isinstance(a, bool)
            and np.isfinite(a)
            and a > 0
            for a in ahead
        ):
            raise ValueError(f"contour_ahead must be a tuple of positive finite arc lengths in mm, got {ahead!r}")
        object.__setattr__(self, "contour_ahead", tuple(float(a) for a in ahead))
        by_name = {
            "reference_position": Field("reference_position", 2, "mm", pb, "reference point x_d (x, y)"),
            "reference_velocity": Field("reference_velocity", 2, "mm/s", vb, "reference velocity dx_d/dt"),
            "reference_acceleration": Field("reference_acceleration", 2, "mm/s^2", ab, "reference acceleration"),
            "tracking_error": Field(
                "tracking_error",
                2,
                "mm",
                eb,
                "x_d - x per axis, x as the position sensor reads it, Simba et al.'s eq. (2)",
            ),
            "contour_error": Field(
                "contour_error", 1, "mm", eb, "shortest distance from the tool to the whole contour"
            ),
            "tangential_error": Field(
                "tangential_error", 1, "mm", eb, "tracking error along the path tangent, Simba et al.'s eq. (3)"
            ),
            "normal_error": Field(
                "normal_error", 1, "mm", eb, "tracking error along the path normal, Simba et al.'s eq. (3)"
            ),
            "velocity": Field("velocity", 2, "mm/s", vb, "table velocity"),
            "preview": Field(
                "preview",
                2 * len(self.preview_steps),
                "mm",
                pb,
                f"reference points {list(self.preview_steps)} control periods ahead, minus the tool position",
            ),
            "contour_preview": Field(
                "contour_preview",
                2 * len(self.contour_ahead),
                "mm",
                pb,
                f"contour points {list(self.contour_ahead)} mm of arc beyond the tool's "
                f"closest point, minus the tool position, along the contour's tangent and "
                f"normal there",
            ),
            "contour_curvature": Field(
                "contour_curvature",
                len(self.contour_ahead),
                "1/mm",
                self.curvature_bound,
                "signed curvature of the contour at those points (positive: turning left)",
            ),
            "previous_action": Field("previous_action", 2, "1", 1.0, "last normalised action in [-1, 1]"),
        }
        scales = dict(self.scales)
        unknown = sorted(set(scales) - set(FIELD_NAMES))
        if unknown or not all(np.isfinite(v) and v > 0 for v in scales.values()):
            raise ValueError(f"scales must map field names to positive scales, got {self.scales!r}")
        for name, scale in scales.items():  # a scaled field is clipped at UNIT_BOUND of its scale
            f = by_name[name]
            by_name[name] = Field(f.name, f.size, f.unit, min(f.bound, UNIT_BOUND * scale), f.description, scale)
        object.__setattr__(self, "fields", tuple(by_name[n] for n in FIELD_NAMES))
        slices, start = {}, 0
        for f in self.fields:  # the offsets, once: a controller reads fields every control period
            slices[f.name] = slice(start, start + f.size)
            start += f.size
        object.__setattr__(self, "_slices", slices)

    # -- offsets -------------------------------------------------------------
    @property
    def size(self) -> int:
        """Length of the observation vector."""
        return self._slices[self.fields[-1].name].stop  # pyright: ignore[reportAttributeAccessIssue]  (__post_init__)

    def slice(self, name: str) -> slice:
        """The slice of field ``name`` in the observation vector."""
        try:
            return self._slices[name]  # pyright: ignore[reportAttributeAccessIssue]  (__post_init__)
        except KeyError:
            raise KeyError(f"no observation field {name!r}; fields are {[f.name for f in self.fields]}") from None

    def offset(self, name: str) -> int:
        """Index of the first element of field ``name``."""
        return self.slice(name).start

    def offsets(self) -> ObservationOffsets:
        """The offset of every field, by name: what the step kernel writes through."""
        return ObservationOffsets(**{f.name: self.offset(f.name) for f in self.fields})

    def high(self) -> np.ndarray:
        """Upper bounds of the fields in their units (float32; low is -high): where the step kernel clips."""
        return np.concatenate([np.full(f.size, f.bound, dtype=np.float32) for f in self.fields])

    def get(self, obs: np.ndarray, name: str) -> np.ndarray:
        """Field ``name`` of one observation (..., size) as float64, in the field's unit (a scaled field is
        multiplied back by its scale)."""
        values = np.asarray(obs, dtype=np.float64)[..., self.slice(name)]
        scale = self.fields[FIELD_NAMES.index(name)].scale
        return values if scale == 1.0 else values * scale

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

    def contour_preview(self, obs):
        """Contour points ahead in the tool's frame (along, across the contour) in mm, (..., n_ahead, 2)."""
        p = self.get(obs, "contour_preview")
        return p.reshape(p.shape[:-1] + (len(self.contour_ahead), 2))

    def contour_curvature(self, obs):
        """Signed curvature of the contour at the points ahead in 1/mm, (..., n_ahead)."""
        return self.get(obs, "contour_curvature")

    def previous_action(self, obs):
        """The previous normalised action, (..., 2)."""
        return self.get(obs, "previous_action")

    def describe(self) -> str:
        """A Markdown table of the fields: index or index range, name, unit, scale, meaning (a field of size 0,
        such as no contour preview, is left out)."""
        rows = ["| index | field | unit | scale | meaning |", "|---|---|---|---|---|"]
        for f in self.fields:
            s = self.slice(f.name)
            if f.size == 0:
                continue
            index = str(s.start) if f.size == 1 else f"{s.start}-{s.stop - 1}"
            rows.append(f"| {index} | {f.name} | {f.unit} | {f.scale:g} | {f.description} |")
        return "\n".join(rows)

    @property
    def is_scaled(self) -> bool:
        """True if any field is divided by a scale (an env made with ``observation_scale="unit"``)."""
        return any(f.scale != 1.0 for f in self.fields)

    def scaled(self, scales: dict) -> "ObservationLayout":
        """This layout with the fields of ``scales`` (name -> scale, in the field's unit) divided by their scale."""
        return dataclasses.replace(self, scales=tuple(sorted(scales.items())))

    def scale_vector(self) -> np.ndarray:
        """The scale of every entry, (size,) float64: the observation is the physical one divided by it."""
        return np.concatenate([np.full(f.size, f.scale) for f in self.fields])
