"""A NurbsCurve rebuilt in geomdl, the independent oracle of the geometry tests."""

from __future__ import annotations

import numpy as np
from geomdl import NURBS


def geomdl_curve(curve):
    """(geomdl curve, a, b): ``curve`` in geomdl, whose parameter is v = (u - a) / (b - a)."""
    kv = np.asarray(curve.knots, float)
    a, b = float(kv[0]), float(kv[-1])
    g = NURBS.Curve(normalize_kv=False)
    g.degree = curve.degree
    g.ctrlptsw = [[x * w, y * w, w] for (x, y), w in zip(curve.control_points.tolist(), curve.weights.tolist())]
    g.knotvector = [(k - a) / (b - a) for k in kv.tolist()]
    return g, a, b
