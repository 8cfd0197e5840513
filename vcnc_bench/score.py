"""The normalised contour score of an id: 0 = the reference PD loop, 1 = the floor; the one number a user compares.

For a figure ``e`` (the max contour error, and the RMS, um) of a policy on an id,

.. math::

    s = \\frac{e_{ref} - e}{e_{ref} - e_{floor}}

with ``e_ref`` the reference PD loop's figure (``pd-ref``, :mod:`vcnc_baselines.feedback.pd_ref`: a fixed PD by pole
placement at a fifth of the plant's declared servo bandwidth, no feedforward, no commissioning) and ``e_floor``
the non-causal floor's (today's ``oracle``, :mod:`vcnc_baselines.optimal`: the best causal controller on the exact plant
plus an optimised correction; never a controller).  As D4RL's normalised score (Fu et al., 2020) runs from a random
policy (0) to an expert (1), this one runs from a PD commissioned by nobody (0) to what no causal controller can
beat (1): above 1 is impossible for a causal controller up to the floor's search tolerance, below 0 is worse than
the plain PD, a diverged run is ``-inf``.

Where it is computed
--------------------
On the **nominal plant** of every id (``score_max``, ``score_rms``): the floor's solution of every contouring id's
nominal plant is shipped, so the floor there costs a replay.  With ``vcnc-bench --plants N`` the score is also
given **per plant** where the floor ran on the same plants (``--policy oracle``: a search per plant, minutes
each), as the IQM over the sampled plants with its stratified-bootstrap interval (:mod:`vcnc_bench.verdicts`);
without it only the nominal score is given (the floor is not extrapolated from the nominal plant to others).
"""

from __future__ import annotations

import math

import numpy as np

from .headroom import NON_CAUSAL
from .verdicts import REPS, stratified_bootstrap_ci

__all__ = ["REFERENCE", "normalised_score", "add_scores"]

#: The registry name (and bench label) of the score's 0.
REFERENCE = "pd-ref"


def normalised_score(e, e_ref, e_floor):
    """``(e_ref - e) / (e_ref - e_floor)`` elementwise (errors in one unit, um); NaN where the reference is not
    above the floor or either is not finite (no scale), ``-inf`` where ``e`` is infinite (diverged)."""
    e, r, f = (np.asarray(a, dtype=np.float64) for a in (e, e_ref, e_floor))
    span = r - f
    ok = np.isfinite(r) & np.isfinite(f) & (span > 0)
    with np.errstate(invalid="ignore", divide="ignore"):
        s = np.where(ok, (r - e) / np.where(ok, span, 1.0), np.nan)
    s = np.where(ok & np.isinf(e), -np.inf, s)
    return float(s) if s.ndim == 0 else s


def _figures(rec: dict, name: str) -> np.ndarray:
    """The per-plant figure ``name`` (``max_um``, ``rms_um``) of a robust record, a diverged plant as inf."""
    per = rec["per_plant"]
    x = np.array([np.inf if v is None else v for v in per[name]], dtype=np.float64)
    return np.where(np.array(per["diverged"], dtype=bool), np.inf, x)


def add_scores(records: list[dict], floors: dict | None = None, *, reps: int = REPS, seed: int = 0) -> list[dict]:
    """Add the normalised scores to the robust records (:func:`vcnc_bench.robust.summarize`'s, with ``env`` and
    ``policy``), in place; returns them.

    Per env: ``e_ref`` is the record labelled :data:`REFERENCE`; ``e_floor`` the record whose label ends in the
    non-causal mark, or ``floors[env]`` (``{"max_um": float, "rms_um": float}`` on the nominal plant) when the
    floor did not run on the plants.  Every record of the env gets ``score`` = ``{"reference", "floor",
    "max", "rms"}`` (the nominal plant's scores) and, where the floor ran on every plant, ``"iqm_max"`` and
    ``"iqm_rms"``, ``[IQM, low, high]`` over the sampled plants.  An env without a reference or a floor gets
    ``score = None`` and the reason.
    """
    for env_id in dict.fromkeys(r["env"] for r in records):
        group = [r for r in records if r["env"] == env_id]
        ref = next((r for r in group if r["policy"] == REFERENCE), None)
        floor = next((r for r in group if r["policy"].endswith(NON_CAUSAL)), None)
        given = (floors or {}).get(env_id)
        if ref is None or (floor is None and given is None):
            why = f"no {REFERENCE} run" if ref is None else "no floor (oracle) on the nominal plant"
            for r in group:
                r["score"], r["score_missing"] = None, why
            continue
        ref_nom = {k: float(_figures(ref, f"{k}_um")[0]) for k in ("max", "rms")}
        if floor is not None:
            floor_nom = {k: float(_figures(floor, f"{k}_um")[0]) for k in ("max", "rms")}
        else:
            floor_nom = {k: float(given[f"{k}_um"]) for k in ("max", "rms")}
        for r in group:
            out = {
                "reference": REFERENCE,
                "floor": floor["policy"] if floor is not None else given.get("label"),
                "reference_nominal_um": ref_nom,
                "floor_nominal_um": floor_nom,
            }
            for k in ("max", "rms"):
                s = normalised_score(_figures(r, f"{k}_um")[0], ref_nom[k], floor_nom[k])
                out[k] = s if math.isfinite(s) else None
            if floor is not None:
                kinds = np.array(r["per_plant"]["kind"])
                sampled = kinds == "sample"
                for k in ("max", "rms"):
                    s = normalised_score(_figures(r, f"{k}_um"), _figures(ref, f"{k}_um"), _figures(floor, f"{k}_um"))[
                        sampled
                    ]
                    s = s[~np.isnan(s)]
                    out[f"iqm_{k}"] = (
                        [None if not math.isfinite(v) else v for v in stratified_bootstrap_ci(s, reps=reps, seed=seed)]
                        if s.size
                        else None
                    )
            r["score"] = out
    return records
