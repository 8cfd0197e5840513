"""The composition: :func:`shop_floor` wraps a plant into a :class:`ShopFloorModel` with the effects' parameters
appended, its arrays (:data:`~vcnc_gym.plants.shop_floor.effect.ShopFloorArrays`) made and reset per machine.
"""

from __future__ import annotations

import inspect
import math
from dataclasses import dataclass

import numpy as np

from .. import contract
from ..contract import Parameter, PlantModel
from .effect import A_SIZE, M_DRIVE, M_READING, M_READING_VELOCITY, M_SIZE, M_TABLE, Effect, ShopFloorArrays
from .effects import EFFECTS
from .kernel import _sense_inner

__all__ = ["SHOP_FRICTION_TIME", "ShopFloorModel", "shop_floor"]

#: The feedforward's Coulomb transition on the shop floor, s: the Stribeck friction spreads the reversal, which a
#: switch at the reversal itself does not model (Simba et al.'s drive: ff-ccc 166 um with 1 ms against 181 um with 0
#: on the shop-floor smoothed corners, ``python experiments/classical-opponents/tune_servo.py --shop-floor``).
SHOP_FRICTION_TIME = 1e-3


@dataclass(frozen=True, eq=False)
class ShopFloorModel(PlantModel):
    """A :class:`PlantModel` wrapped by :func:`shop_floor`; ``inner`` the wrapped model, ``effects`` the composed
    :class:`Effect` classes."""

    inner: PlantModel | None = None
    effects: tuple = ()


def _setting(p: Parameter, value, counted: bool) -> tuple:
    """The (x, y) pair of a shop-floor setting, each through :mod:`vcnc_gym.validation` (a count an integer)."""
    from ...validation import integer, per_axis

    name = f"shop-floor setting {p.name}"
    if counted:
        items = value if isinstance(value, (tuple, list)) else (value, value)
        if len(items) != 2:
            raise ValueError(f"{name} must be an integer or an (x, y) pair of them ({p.unit}), got {value!r}")
        whole = [int(v) if isinstance(v, float) and v.is_integer() else v for v in items]  # 4.0 (YAML) is 4
        return tuple(float(integer(f"{name} ({p.unit})", v, minimum=0)) for v in whole)
    return tuple(float(v) for v in per_axis(name, value, p.unit))


def _set(p: Parameter, value, counted: bool) -> Parameter:
    """Parameter ``p`` with the nominal value ``value``: outside the interval, the default's relative spread
    around it (none around 0, off, or a default of 0)."""
    pair = _setting(p, value, counted)
    if p.physical_range is not None and not all(p.physical_range[0] <= v <= p.physical_range[1] for v in pair):
        raise ValueError(
            f"shop-floor setting {p.name} = {value!r} {p.unit} is outside its physical range "
            f"[{p.physical_range[0]:g}, {p.physical_range[1]:g}] ({p.range_source})"
        )
    interval = p.interval
    if interval is not None and not all(lo <= v <= hi for v, (lo, hi) in zip(pair, interval)):
        top = math.inf if p.physical_range is None else p.physical_range[1]  # within the physical range
        interval = (
            None
            if min(pair) <= 0 or min(p.nominal) <= 0
            else tuple((v * lo / n, min(v * hi / n, max(v, top))) for v, n, (lo, hi) in zip(pair, p.nominal, interval))
        )
    return Parameter(
        p.name,
        p.unit,
        nominal=pair,
        interval=interval,
        shared=p.shared,
        source=p.source,
        sign=p.sign,
        description=p.description,
        physical_range=p.physical_range,
        range_source=p.range_source,
    )


def shop_floor(plant, settings: dict | bool | None = True, effects: tuple = EFFECTS) -> ShopFloorModel:
    """The plant ``plant`` (a name of :mod:`vcnc_gym.plants` or a PlantModel) on the shop floor.

    Parameters
    ----------
    plant : str or PlantModel
    settings : dict or True
        Nominal values of effect parameters, ``{name: value}`` (one value for
        both axes, or a pair (x, y)), over the defaults of the effects'
        parameters; a parameter set outside its interval keeps the default's
        relative spread around it (0, off, is fixed).  True: the defaults.
    effects : tuple of Effect subclasses
        The effects composed, in order (default :data:`EFFECTS`, the shop
        floor's; the shop ids use those).

    Raises
    ------
    ValueError
        For an unknown setting (the message lists the effects' parameters), a
        value the parameter's rules refuse, effects that are not
        :class:`Effect` subclasses or share a parameter name, or force
        effects on a plant that declares no ``force_gain``.
    """
    from .. import get_plant

    inner = get_plant(plant)
    if isinstance(inner, ShopFloorModel):
        raise ValueError(f"plant {inner.name!r} is already on the shop floor")
    effects = tuple(effects) if isinstance(effects, (tuple, list)) else effects
    if not isinstance(effects, tuple) or not all(
        isinstance(e, type) and issubclass(e, Effect) and e is not Effect for e in effects
    ):
        raise ValueError(f"effects must be a tuple of Effect subclasses, got {effects!r}")
    names = [p.name for e in effects for p in e.parameters]
    clash = sorted({n for n in names if names.count(n) > 1} | (set(names) & {p.name for p in inner.parameters}))
    if clash:
        raise ValueError(f"effects {[e.__name__ for e in effects]}: parameter names {clash} appear twice")
    if settings is True or settings is None:
        settings = {}
    if not isinstance(settings, dict):
        raise ValueError(f"shop_floor settings must be a dict {{effect parameter: value}} or True, got {settings!r}")
    unknown = sorted(set(settings) - set(names))
    if unknown:
        raise ValueError(f"unknown shop-floor setting(s) {unknown}; the effects' parameters are {names}")
    parameters = tuple(
        _set(p, settings[p.name], p.name in e.counts) if p.name in settings else p
        for e in effects
        for p in e.parameters
    )
    on = {
        p.name
        for p in parameters
        if max(p.nominal) > 0 or (p.interval is not None and max(hi for _, hi in p.interval) > 0)
    }
    forces = [name for e in effects if e.uses_force_gain() for name in e.switches if name in on]
    if forces and inner.force_gain is None:
        raise ValueError(
            f"plant {inner.name} declares no force_gain (input per N): the effects "
            f"{forces} cannot act on it; set them to 0"
        )
    n_inner = inner.n_parameters

    linear, delay, inverse, gain = inner.linear_coefficients, inner.delay, inner.inverse_dynamics, inner.force_gain

    def inner_part(params):
        return np.asarray(params)[..., :n_inner]

    def check(p):  # the effects' own rules are their Parameters' (sign, physical range)
        if inner.check is not None:
            inner.check(p[..., :n_inner])

    def make_arrays(n_machines, dt, **options):
        return _make_arrays(model, n_machines, dt, **options)

    make_arrays.__signature__ = inspect.signature(inner.make_arrays)  # its options are the inner plant's

    model = ShopFloorModel(
        name=inner.name,
        source=f"{inner.source}; on the shop floor (vcnc_gym.plants.shop_floor)",
        parameters=inner.parameters + parameters,
        state_names=inner.state_names,
        input_name=inner.input_name,
        input_unit=inner.input_unit,
        input_limit=inner.input_limit,
        make_arrays=make_arrays,
        reset_machine=lambda arrays, k, position: _reset_machine(model, arrays, k, position),
        check=check,
        linear_coefficients=None if linear is None else lambda params, axis: linear(inner_part(params), axis),
        delay=None if delay is None else lambda params, axis: delay(inner_part(params), axis),
        inverse_dynamics=None if inverse is None else lambda params: inverse(inner_part(params)),
        force_gain=None if gain is None else lambda params: gain(inner_part(params)),
        seed_machine=_seed_machine,
        servo_bandwidth=inner.servo_bandwidth,
        friction_time=SHOP_FRICTION_TIME,
        path_limits=inner.path_limits,
        random_contour=dict(inner.random_contour),
        inner=inner,
        effects=effects,
    )
    return model


def _make_arrays(model: ShopFloorModel, n_machines: int, dt: float, **options) -> ShopFloorArrays:
    inner = model.inner
    assert inner is not None
    arrays = inner.make_arrays(n_machines, dt, **options)
    P = inner.n_parameters
    params = np.repeat(model.nominal()[None], n_machines, axis=0)
    params[:, :, :P] = arrays.params
    arrays = arrays._replace(params=params[:, :, :P])
    n = n_machines
    effects, column, fcol, icol = [], P, 0, 0
    for effect in model.effects:
        effects.append(effect.columns(column, fcol, icol))
        column += len(effect.parameters)
        fcol, icol = fcol + effect.sizes()[0], icol + effect.sizes()[1]
    out = ShopFloorArrays(
        inner=arrays,
        state=arrays.state,
        params=params,
        dt=float(dt),
        n_inner=P,
        gain=np.zeros((n, 2)),
        memory=np.zeros((n, 2, M_SIZE)),
        rng=np.zeros(n, dtype=np.uint64),
        applied=np.zeros((n, 2)),
        force=np.zeros((n, 2)),
        table=np.zeros((n, 2, A_SIZE)),
        sensed=np.zeros((n, contract.SENSE_SIZE)),
        fstate=np.zeros((n, fcol)),
        istate=np.zeros((n, icol), dtype=np.int64),
        effects=tuple(effects),
    )
    for k in range(n):
        _reset_machine(model, out, k, np.zeros(2))
    return out


def _reset_machine(model: ShopFloorModel, arrays: ShopFloorArrays, k: int, position) -> None:
    """Machine ``k`` at rest at ``position`` (2,) mm: the inner plant reset, the table on the drive, the reading
    the inner plant's, the noise generator at seed ``k`` (the envs then draw it from their generator:
    ``seed_machine``); then each effect's ``reset``, in order."""
    inner = model.inner
    assert inner is not None
    P = arrays.n_inner
    inner.reset_machine(arrays.inner, k, position)
    arrays.gain[k] = inner.force_gain(arrays.params[k, :, :P]) if inner.force_gain is not None else 0.0
    sensed = arrays.sensed[k]
    _sense_inner(arrays.inner, k, sensed)
    memory = arrays.memory[k]
    memory[:] = 0.0
    memory[:, M_DRIVE] = sensed[contract.SENSE_POSITION : contract.SENSE_POSITION + 2]
    memory[:, M_TABLE] = sensed[contract.SENSE_POSITION : contract.SENSE_POSITION + 2]
    memory[:, M_READING] = sensed[contract.SENSE_MEASURED : contract.SENSE_MEASURED + 2]
    memory[:, M_READING_VELOCITY] = sensed[contract.SENSE_VELOCITY : contract.SENSE_VELOCITY + 2]
    arrays.rng[k] = np.uint64(k)
    for effect, s in zip(model.effects, arrays.effects):
        if effect.reset is not None:
            effect.reset(effect.views(arrays, s), arrays, k)


def _seed_machine(arrays: ShopFloorArrays, k: int, rng: np.random.Generator) -> None:
    """Machine ``k``'s noise generator seeded from the env's generator (one ``integers`` draw)."""
    arrays.rng[k] = rng.integers(0, 2**63, dtype=np.uint64)
