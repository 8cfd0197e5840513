"""Headroom: how far the strongest causal controller is above the floor, per env.

Per env, the headroom is the strongest causal controller's max contour error divided by the non-causal floor's
(the ``oracle`` of :mod:`vcnc_baselines.optimal`): the factor a learned controller can still win on that env.  1.0
means the strongest controller is at the floor; 1.25, that it is 25 % above it.  The bench marks a non-causal
policy's label with :data:`NON_CAUSAL` (``vcnc_bench.cli``); any such label is the floor here.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any, Mapping

__all__ = ["NON_CAUSAL", "Headroom", "headroom", "figure"]

#: The suffix of a non-causal policy's label in the bench's tables and JSON.
NON_CAUSAL = " (non-causal)"


@dataclass(frozen=True)
class Headroom:
    """The strongest causal controller and the floor of one env, and their ratio.

    Attributes
    ----------
    strongest : str
        Label of the causal controller with the least max contour error (ties: the lower RMS).
    strongest_max_um, strongest_rms_um : float
    floor : str
        Label of the floor.
    floor_max_um, floor_rms_um : float
    ratio : float
        ``strongest_max_um / floor_max_um`` (inf for a floor at 0).
    """

    strongest: str
    strongest_max_um: float
    strongest_rms_um: float
    floor: str
    floor_max_um: float
    floor_rms_um: float
    ratio: float


def figure(result: Any, key: str) -> float:
    """``key`` (``max_contour_error_um``, ``rms_contour_error_um``) of an EpisodeResult or a record dict; NaN if
    it has none."""
    value = result.get(key) if isinstance(result, Mapping) else getattr(result, key, None)
    return math.nan if value is None else float(value)


def headroom(results: Mapping[str, Any], floor: str | None = None) -> Headroom | None:
    """The headroom of one env from its results, ``{label: EpisodeResult or record dict}``.

    Parameters
    ----------
    results : mapping
        The bench's results of one env (``ctx.results[env_id]``), labels as the bench writes them.
    floor : str, optional
        The floor's label; default the (first) label ending in :data:`NON_CAUSAL`.

    Returns
    -------
    Headroom or None
        None when there is no floor, or no causal controller with a finite max contour error.
    """
    if floor is None:
        floors = [label for label in results if label.endswith(NON_CAUSAL)]
        if not floors:
            return None
        floor = floors[0]
    elif floor not in results:
        raise ValueError(f"floor {floor!r} is not among the results' labels {sorted(results)}")
    causal = [
        (figure(r, "max_contour_error_um"), figure(r, "rms_contour_error_um"), label)
        for label, r in results.items()
        if not label.endswith(NON_CAUSAL) and label != floor
    ]
    causal = [c for c in causal if math.isfinite(c[0])]
    if not causal:
        return None
    best_max, best_rms, best = min(causal, key=lambda c: (c[0], c[1] if math.isfinite(c[1]) else math.inf))
    floor_max = figure(results[floor], "max_contour_error_um")
    floor_rms = figure(results[floor], "rms_contour_error_um")
    ratio = math.inf if floor_max == 0 else best_max / floor_max
    return Headroom(best, best_max, best_rms, floor, floor_max, floor_rms, ratio)
