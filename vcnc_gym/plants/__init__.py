"""plants: the machines, one module per seed, each declaring the plant contract.

Every module of this package that defines ``MODEL`` (a
:class:`~vcnc_gym.plants.contract.PlantModel`) is a plant the envs can hold:
``get_plant("vcnc_feed_drive")`` returns its model, :func:`plant_names`
lists them.  See :mod:`vcnc_gym.plants.contract` for what a plant declares.
"""

from __future__ import annotations

import importlib
import pkgutil

from .contract import Parameter, PlantModel

__all__ = ["Parameter", "PlantModel", "get_plant", "plant_names"]

# shop_floor wraps a plant (shop_floor.shop_floor(name)); exact_zoh and stick_slip are their shared numerics
_NOT_PLANTS = {"contract", "shop_floor", "exact_zoh", "stick_slip"}


def plant_names() -> list[str]:
    """Names of the plant modules of this package, sorted."""
    return sorted(
        m.name for m in pkgutil.iter_modules(__path__) if m.name not in _NOT_PLANTS and not m.name.startswith("_")
    )


def get_plant(plant) -> PlantModel:
    """The :class:`PlantModel` of a plant given by module name (``"vcnc_feed_drive"``) or as a model.

    Raises
    ------
    ValueError
        For an unknown name; the message lists the known ones.
    """
    if isinstance(plant, PlantModel):
        return plant
    if not isinstance(plant, str) or plant not in plant_names():
        raise ValueError(f"unknown plant {plant!r}; known plants are {plant_names()}")
    module = importlib.import_module(f"{__name__}.{plant}")
    model = getattr(module, "MODEL", None)
    if not isinstance(model, PlantModel):
        raise ValueError(f"module {module.__name__} declares no MODEL (a PlantModel)")
    return model
