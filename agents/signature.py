"""The env an agent was trained for: its signature, and the check of an env against it.

:func:`env_signature` reads what an agent's observations and decisions depend on from a plain env (contour,
plant, control period, feed, preview, shapes); :func:`check_signature` compares two of them, as
:func:`vcnc_agents.load_agent` does for an agent folder's ``config.yml`` and a resumed run does for its own.  A leaf
of ``agents``: it reads the env only.
"""

from __future__ import annotations

import dataclasses
import hashlib
import math
import warnings

import numpy as np
import yaml

__all__ = [
    "env_signature",
    "check_signature",
    "check_env_signature",
    "observation_pick",
    "as_seen_through",
    "ANY_CONTOUR_IDS",
    "MACHINE_FIELDS",
    "LAYOUT_FIELDS",
]


#: Fields of :func:`env_signature` with their unit, in the order they are reported.
_SIGNATURE_UNITS = {
    "id": "",
    "contour": "",
    "curve_sha256": "",
    "plant": "",
    "plant_options": "",
    "shop_floor": "",
    "dt": " s",
    "feedrate": " mm/s",
    "ramp_time": " s",
    "preview_steps": " control periods",
    "contour_ahead": " mm",
    "observation_shape": "",
    "action_shape": "",
}


def _attr(obj, dotted: str):
    for name in dotted.split("."):
        obj = getattr(obj, name, None)
        if obj is None:
            return None
    return obj


def _curve_digest(curve) -> str | None:
    if curve is None:
        return None
    h = hashlib.sha256(str(int(curve.degree)).encode())
    for a in (curve.control_points, curve.weights, curve.knots):
        h.update(np.ascontiguousarray(a, dtype=np.float64).tobytes())
    return h.hexdigest()[:16]


def _shop_floor(plant) -> dict | None:
    """The shop-floor settings of ``plant``: {effect parameter: [x, y] nominal value} of the effects
    :func:`vcnc_gym.plants.shop_floor.shop_floor` composed on it (units those of its Parameters), None for the
    ideal machine."""
    inner = getattr(plant, "inner", None)
    if inner is None:
        return None
    return {p.name: [float(v) for v in p.nominal] for p in plant.parameters[inner.n_parameters :]}


def env_signature(env) -> dict:
    """What an agent's observations and decisions depend on, read from a plain (``action_repeat=1``) env.

    A YAML-safe dict: env id (None for an env not made by ``gym.make``), contour
    name and a digest of its NURBS, plant name and options, control period
    ``dt`` (s), feedrate (mm/s) and ramp time (s) of the reference, preview
    steps, contour preview arc lengths (mm), observation and action shapes.  Reward scale and episode bounds
    are not part of it: they change the score, not what the agent sees.
    """
    u = env.unwrapped
    spec = getattr(u, "spec", None)
    options = _attr(u, "task.plant_options") or {}
    floats = {
        k: _attr(u, a)
        for k, a in (
            ("dt", "dt"),
            ("feedrate", "feedrate_profile.feedrate"),
            ("ramp_time", "feedrate_profile.ramp_time"),
        )
    }
    preview = _attr(u, "layout.preview_steps")
    ahead = _attr(u, "layout.contour_ahead")
    return {
        "id": spec.id if spec is not None else None,
        "contour": _attr(u, "contour_name"),
        "curve_sha256": _curve_digest(_attr(u, "curve")),
        "plant": _attr(u, "plant.name"),
        "plant_options": yaml.safe_load(yaml.safe_dump(dict(options))),
        "shop_floor": _shop_floor(_attr(u, "task.plant")),
        **{k: None if v is None else float(v) for k, v in floats.items()},
        "preview_steps": None if preview is None else [int(s) for s in preview],
        "contour_ahead": None if ahead is None else [float(a) for a in ahead],
        "observation_shape": [int(n) for n in u.observation_space.shape],
        "action_shape": [int(n) for n in u.action_space.shape],
    }


def _same(a, b) -> bool:
    if isinstance(a, float) and isinstance(b, (int, float)) and not isinstance(b, bool):
        return math.isclose(a, b, rel_tol=1e-9, abs_tol=0.0)
    return a == b


#: Ids whose contour and feed are drawn anew at every reset: an agent trained there (a generalist) runs on any
#: contour and feed of the same machine, so only the :data:`MACHINE_FIELDS` of its signature are compared.
ANY_CONTOUR_IDS = ("VCNC-RandomContour-v1",)

#: The signature fields that describe the machine and the observation, not the part.
MACHINE_FIELDS = (
    "plant",
    "plant_options",
    "shop_floor",
    "dt",
    "preview_steps",
    "contour_ahead",
    "observation_shape",
    "action_shape",
)


def check_signature(recorded: dict, given: dict, *, what: str = "the agent", allow_mismatch: bool = False) -> None:
    """ValueError listing every field where the ``given`` :func:`env_signature` differs from the ``recorded`` one.

    An unknown id on either side (an env made without ``gym.make``) is not
    compared; fields the recorded signature lacks are not compared; an agent
    trained on an id of :data:`ANY_CONTOUR_IDS` is compared on the
    :data:`MACHINE_FIELDS` only (one recorded before its signature had ``shop_floor`` was trained on the ideal
    machine: every such generalist was).  With ``allow_mismatch`` the differences are
    a warning instead, except a different observation or action shape, which
    no agent can run on.
    """
    diffs, fatal = [], False
    generalist = recorded.get("id") in ANY_CONTOUR_IDS
    if generalist and "shop_floor" not in recorded:
        recorded = {**recorded, "shop_floor": None}
    for key, unit in _SIGNATURE_UNITS.items():
        if key not in recorded or key not in given or (key == "id" and (recorded[key] is None or given[key] is None)):
            continue
        if generalist and key not in MACHINE_FIELDS:
            continue
        if not _same(recorded[key], given[key]):
            diffs.append(f"{key}: trained on {recorded[key]}{unit}, this env has {given[key]}{unit}")
            fatal |= key in ("observation_shape", "action_shape")
    if not diffs:
        return
    head = (
        f"{what} was trained on {recorded['id']}, not {given['id']}"
        if recorded.get("id") and given.get("id") and recorded["id"] != given["id"]
        else f"{what} was trained on another env configuration"
    )
    message = f"{head}: " + "; ".join(diffs)
    if fatal or not allow_mismatch:
        raise ValueError(message + ("" if fatal else " (allow_mismatch=True runs it anyway)"))
    warnings.warn(message, stacklevel=3)


def check_env_signature(recorded: dict, env, *, what: str = "the agent", allow_mismatch: bool = False) -> None:
    """:func:`check_signature` of ``env``'s :func:`env_signature` against ``recorded``."""
    check_signature(recorded, env_signature(env), what=what, allow_mismatch=allow_mismatch)


#: The signature fields that describe the observation's layout: an agent that sees part of the env's observation
#: (:func:`observation_pick`) is compared on the others only.
LAYOUT_FIELDS = ("preview_steps", "contour_ahead", "observation_shape")


def observation_pick(recorded: dict, env) -> np.ndarray | None:
    """The entries of ``env``'s observation an agent recorded with a smaller preview sees, in its order.

    An agent trained with fewer ``preview_steps`` or ``contour_ahead`` points than ``env`` gives (an ablation's
    agent trained without the preview) observes the same fields by name, the preview fields holding only its own
    points: the answer is the index array that picks them out of ``env``'s observation.  None where the agent's
    layout is ``env``'s, or the ``recorded`` signature does not say (an older agent: its observation shape is
    checked as before).  ValueError naming the points the env does not give.
    """
    layout = getattr(env.unwrapped, "layout", None)
    steps, ahead = recorded.get("preview_steps"), recorded.get("contour_ahead")
    if layout is None or steps is None:
        return None
    steps = tuple(int(s) for s in steps)
    ahead = layout.contour_ahead if ahead is None else tuple(float(a) for a in ahead)
    if steps == layout.preview_steps and ahead == layout.contour_ahead:
        return None
    missing = [f"preview step {s}" for s in steps if s not in layout.preview_steps] + [
        f"contour preview at {a:g} mm" for a in ahead if a not in layout.contour_ahead
    ]
    if missing:
        raise ValueError(
            f"the agent observes {', '.join(missing)}, which this env's observation does not give "
            f"(preview_steps {list(layout.preview_steps)}, contour_ahead {list(layout.contour_ahead)})"
        )
    agent = dataclasses.replace(layout, preview_steps=steps, contour_ahead=ahead)
    columns = {
        "preview": [2 * layout.preview_steps.index(s) + k for s in steps for k in (0, 1)],
        "contour_preview": [2 * layout.contour_ahead.index(a) + k for a in ahead for k in (0, 1)],
        "contour_curvature": [layout.contour_ahead.index(a) for a in ahead],
    }
    pick = [layout.slice(f.name).start + c for f in agent.fields for c in columns.get(f.name, range(f.size))]
    return np.array(pick, dtype=np.int64)


def as_seen_through(recorded: dict, env) -> dict:
    """``recorded`` with its :data:`LAYOUT_FIELDS` replaced by ``env``'s: what :func:`check_signature` compares
    for an agent that sees part of ``env``'s observation (:func:`observation_pick`)."""
    given = env_signature(env)
    return {**recorded, **{k: given[k] for k in LAYOUT_FIELDS if k in recorded}}
