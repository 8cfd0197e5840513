"""The machine as it is on the shop floor: any plant with a real sensor, delays, a structural mode and process forces.

:func:`shop_floor` wraps a plant of :mod:`vcnc_gym.plants` (its
:class:`~vcnc_gym.plants.contract.PlantModel`) into another plant: the same
drive, with the effects the source papers leave out, each with its units, a
physical default and its source, and each a :class:`Parameter` appended to
the inner plant's (so ``randomize`` draws them from their intervals, and
``vcnc-bench --plants`` samples them with the rest).  An effect whose
switch parameters are 0 is off; with every effect off the wrapped plant gives
the inner plant's observations to the bit (``tests/test_shop_floor.py``).  The
papers' ids do not use the wrapper at all.

Effects
-------
An effect is one declaration, a subclass of :class:`Effect` (its docstring
the physics, its source and units): its ``parameters``, its per-machine
``state`` arrays, its ``reset`` and its numba steps, one per stage of the
control period it acts in.  :data:`EFFECTS` are the shop floor's, in the
order of their parameters (appended to the inner plant's in this order):

- :class:`PositionSensor`: quantisation and white noise of the position reading;
- :class:`CommandDelay`: the computation / transport delay of the command;
- :class:`SensorDelay`: the reading's transmission delay;
- :class:`StructuralMode`: the first structural mode between drive and table;
- :class:`CuttingForce`: the milling force and its tooth-passing component;
- :class:`StribeckFriction`: the guideways' Stribeck effect.

``shop_floor(plant, settings, effects=...)`` composes any tuple of effects
(the add-a-shop-floor-effect guide, ``docs/guides/add-a-shop-floor-effect.md``,
adds one in its own module); the kernel is compiled per composition.

The control period
------------------
Per control period ``dt`` of machine ``k`` (:func:`contract.advance`), the
stages in this order, each running the hooks of the effects that have one,
in the order of the composition's effects:

1. ``command``: the command ``x`` ((2,), input units) may be changed (the
   command delay's FIFO).
2. ``force``: the effects add their force ``x`` ((2,) N, it starts at 0)
   on the table; the force enters as the input the plant declares
   equivalent (``PlantModel.force_gain``, input unit per N), added to the
   command before the inner plant's amplifier saturation (so a saturated
   command also clips the disturbance: the disturbance of an amplifier
   model, not of a force on the table).
3. The inner plant advances (:func:`contract.advance` on its own arrays).
4. ``table``: from the drive's position (the inner plant's table position,
   rigid) the effects may move the table: ``x`` (2, A_SIZE), per axis the
   drive's position ``A_DRIVE``, the table's position and velocity
   (``A_TABLE``, ``A_TABLE_VELOCITY``, by default the drive's) and the
   reading (``A_READING``, by default the inner plant's own sensor).  The
   contour error is measured on ``A_TABLE``.
5. ``reading``: the effects may replace the reading and the velocity read
   (``A_READING_VELOCITY``, by default the table's).
6. ``sense`` (in :func:`contract.sense`): ``x`` the contract's ``out``, the
   table, the reading and its velocity written; the effects may replace what
   the controller sees (the sensor delay's FIFO).

Every hook is ``hook(s, plant, k, x)``: ``s`` the effect's columns (its
``Arrays`` record of integers: ``s.params`` the column of its first
parameter in ``plant.params``, each state array's first column in
``plant.fstate`` (float64) or ``plant.istate`` (int64), row-major),
``plant`` the :data:`ShopFloorArrays`, whose ``memory`` holds the last
period's table (``M_*`` columns), ``dt`` and ``rng`` (the machine's
splitmix64 noise generator, seeded from the env's generator at every reset:
``PlantModel.seed_machine``).  The effects' state lives in the plant's two
state arrays, not in arrays of their own: a record of arrays taken from a
tuple inside the env's kernel would be reference-counted (atomic
operations) at every use, which costs more than the effects themselves.

The observation therefore shows the quantised, noisy, delayed measurement;
the exact contour error (on the true table position) stays in ``info``.

The wrapped model keeps the inner plant's ``name`` (it is the same machine,
and every controller designed for that machine runs on it), its input, its
linear model, dead time and inverse dynamics (the *nominal* model a
controller is designed from: the effects are what the nominal model lacks);
``model.inner`` is the inner model and ``model.effects`` the composed
effects (:class:`Effect` subclasses).

Arrays
------
:data:`ShopFloorArrays`: ``inner`` (the inner plant's namedtuple; its
``params`` a view of the first P columns of ``params``), ``state`` (the
inner plant's state array itself, so a NaN written there diverges the
episode), ``params`` (N, 2, P + E), ``dt``, the force gain, the table's
memory, scratch, the noise generators, the effects' state ``fstate`` and
``istate`` and ``effects``, the tuple of the effects' column records.
"""

from __future__ import annotations

from . import kernel as _kernel  # noqa: F401  (registers contract.advance and contract.sense for the shop floor)
from .effect import (
    A_DRIVE,
    A_READING,
    A_READING_VELOCITY,
    A_SIZE,
    A_TABLE,
    A_TABLE_VELOCITY,
    M_DISTURBANCE,
    M_DRIVE,
    M_MEAN_VELOCITY,
    M_READING,
    M_READING_VELOCITY,
    M_SIZE,
    M_TABLE,
    M_TABLE_VELOCITY,
    MAX_DELAY,
    STAGES,
    Effect,
    ShopFloorArrays,
)
from .effects import (
    EFFECT_NAMES,
    EFFECT_PARAMETERS,
    EFFECTS,
    OFF,
    STRIBECK_SIGN_WIDTH,
    CommandDelay,
    CuttingForce,
    PositionSensor,
    SensorDelay,
    StribeckFriction,
    StructuralMode,
    mode_response,
    mode_transition,
)
from .model import SHOP_FRICTION_TIME, ShopFloorModel, shop_floor
from .noise import normal_pair, splitmix64

__all__ = [
    "Effect",
    "EFFECTS",
    "EFFECT_PARAMETERS",
    "EFFECT_NAMES",
    "OFF",
    "MAX_DELAY",
    "ShopFloorArrays",
    "ShopFloorModel",
    "shop_floor",
    "PositionSensor",
    "CommandDelay",
    "SensorDelay",
    "StructuralMode",
    "CuttingForce",
    "StribeckFriction",
    "mode_response",
    "mode_transition",
    "splitmix64",
    "normal_pair",
    "SHOP_FRICTION_TIME",
    "STRIBECK_SIGN_WIDTH",
    "STAGES",
    "M_DRIVE",
    "M_TABLE",
    "M_TABLE_VELOCITY",
    "M_MEAN_VELOCITY",
    "M_DISTURBANCE",
    "M_READING",
    "M_READING_VELOCITY",
    "M_SIZE",
    "A_DRIVE",
    "A_TABLE",
    "A_TABLE_VELOCITY",
    "A_READING",
    "A_READING_VELOCITY",
    "A_SIZE",
]
