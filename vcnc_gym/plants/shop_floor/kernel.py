"""The compiled control period of the shop floor: the stages run over the composed effects, and the plant
contract's ``advance`` and ``sense`` for :data:`~vcnc_gym.plants.shop_floor.effect.ShopFloorArrays` (numba overloads).

Each stage (:func:`command_stage`, ...) is generated per composition as straight-line code calling the hook of
every effect that has one; :func:`_advance_shop` and :func:`_sense_shop` run a period and the sensors
(:mod:`vcnc_gym.plants.shop_floor`).
"""

from __future__ import annotations

from numba import njit, types
from numba.extending import overload

from .. import contract
from .effect import (
    A_DRIVE,
    A_READING,
    A_READING_VELOCITY,
    A_TABLE,
    A_TABLE_VELOCITY,
    M_DISTURBANCE,
    M_DRIVE,
    M_MEAN_VELOCITY,
    M_READING,
    M_READING_VELOCITY,
    M_TABLE,
    M_TABLE_VELOCITY,
    STAGES,
    ShopFloorArrays,
)

__all__ = ["command_stage", "force_stage", "table_stage", "reading_stage", "sense_stage"]


def _stage(name: str):
    """The kernel of stage ``name``: ``run(effects, plant, k, x)`` calls ``hook(effects[j], plant, k, x)`` of every
    effect of the tuple ``effects`` that has one, in order, as straight-line code generated for the tuple's type
    (the effects' classes are read from their ``Arrays`` types; nothing is looked up at run time)."""

    def run(effects, plant, k, x):  # pragma: no cover - compiled through the overload below
        raise NotImplementedError("the shop floor's stages run in numba code")

    run.__name__ = run.__qualname__ = f"{name}_stage"

    @overload(run, inline="always")
    def _run(effects, plant, k, x):
        if not isinstance(effects, types.BaseTuple):
            return None
        namespace, lines = {}, []
        for j, t in enumerate(effects.types):
            hook = getattr(t.instance_class.effect, name)
            if hook is not None:
                namespace[f"hook{j}"] = hook
                lines.append(f"    hook{j}(effects[{j}], plant, k, x)")
        exec(f"def impl(effects, plant, k, x):\n{chr(10).join(lines) or '    pass'}\n", namespace)
        return namespace["impl"]

    return run


command_stage, force_stage, table_stage, reading_stage, sense_stage = (_stage(name) for name in STAGES)


@njit(cache=True)
def _sense_inner(inner, k, out):
    contract.sense(inner, k, out)


@njit(cache=True, _nrt=False)
def _advance_shop(plant, k, command):
    """One control period of shop-floor machine ``k``: the stages of :mod:`vcnc_gym.plants.shop_floor`.

    Compiled on its own, without numba's reference counting, and called: inlined into the env's kernel (which
    counts references), every hook's copy of ``plant`` would count each of its arrays twice (atomic operations,
    ~20 ns per effect and period), more than this call costs."""
    effects = plant.effects
    memory = plant.memory
    applied = plant.applied[k]
    applied[0] = command[0]
    applied[1] = command[1]
    command_stage(effects, plant, k, applied)
    force = plant.force[k]
    force[0] = -0.0  # -0.0 - f is -f to the bit, and x + -0.0 is x: no force effect, no change
    force[1] = -0.0
    force_stage(effects, plant, k, force)
    for i in range(2):
        d = plant.gain[k, i] * force[i]
        memory[k, i, M_DISTURBANCE] = d
        applied[i] += d
    contract.advance(plant.inner, k, applied)
    sensed = plant.sensed[k]
    contract.sense(plant.inner, k, sensed)
    x = plant.table[k]
    for i in range(2):
        x[i, A_DRIVE] = sensed[contract.SENSE_POSITION + i]
        x[i, A_TABLE] = sensed[contract.SENSE_POSITION + i]
        x[i, A_TABLE_VELOCITY] = sensed[contract.SENSE_VELOCITY + i]
        x[i, A_READING] = sensed[contract.SENSE_MEASURED + i]
    table_stage(effects, plant, k, x)
    inv_dt = 1.0 / plant.dt
    for i in range(2):
        x_t = x[i, A_TABLE]
        memory[k, i, M_MEAN_VELOCITY] = (x_t - memory[k, i, M_TABLE]) * inv_dt
        memory[k, i, M_DRIVE] = x[i, A_DRIVE]
        memory[k, i, M_TABLE] = x_t
        memory[k, i, M_TABLE_VELOCITY] = x[i, A_TABLE_VELOCITY]
        x[i, A_READING_VELOCITY] = x[i, A_TABLE_VELOCITY]
    reading_stage(effects, plant, k, x)
    for i in range(2):
        memory[k, i, M_READING] = x[i, A_READING]
        memory[k, i, M_READING_VELOCITY] = x[i, A_READING_VELOCITY]


@njit(cache=True, _nrt=False)
def _sense_shop(plant, k, out):
    """What machine ``k``'s sensors give (``contract.sense``): the table, the reading, then the ``sense`` stage
    (compiled on its own, as :func:`_advance_shop`)."""
    for i in range(2):
        out[contract.SENSE_POSITION + i] = plant.memory[k, i, M_TABLE]
        out[contract.SENSE_MEASURED + i] = plant.memory[k, i, M_READING]
        out[contract.SENSE_VELOCITY + i] = plant.memory[k, i, M_READING_VELOCITY]
    sense_stage(plant.effects, plant, k, out)


@overload(contract.advance, inline="always", jit_options={"cache": True})
def _advance(plant, k, command):
    if contract.is_plant(plant, ShopFloorArrays):

        def impl(plant, k, command):
            _advance_shop(plant, k, command)

        return impl


@overload(contract.sense, inline="always", jit_options={"cache": True})
def _sense(plant, k, out):
    if contract.is_plant(plant, ShopFloorArrays):

        def impl(plant, k, out):
            _sense_shop(plant, k, out)

        return impl
