"""The scalar checks once written by hand now speak :mod:`vcnc_gym.validation`'s dialect: each refuses a bool, a
string and a NaN (booleans are ints and ``"0.001"`` compares as nothing to Python's ``isinstance(v, (int, float))``
and ``v > 0``, which let them through), with a ValueError naming the argument."""

from __future__ import annotations

import math

import pytest


def _gcode(v):
    from vcnc_gym.gcode.interpreter import read_program_text

    read_program_text("G01 X1 F100", arc_tolerance=v)


def _plant_arrays(argument):
    def call(v):
        from vcnc_gym.plants import get_plant

        model = get_plant("vcnc_feed_drive")
        model.arrays(v, 1e-4) if argument == "n_machines" else model.arrays(1, v)

    return call


def _substeps_for(v):
    from vcnc_gym.plants.vcnc_feed_drive import substeps_for

    substeps_for(v)


def _substep(v):
    from vcnc_gym.plants import get_plant

    get_plant("vcnc_feed_drive").arrays(1, 1e-4, substep=v)


def _layout(v):
    from vcnc_gym.envs.layout import ObservationLayout

    ObservationLayout(preview_steps=(10,), contour_ahead=(), position_bound=v)


def _imc(argument):
    def call(v):
        from vcnc_baselines.feedback.pi_imc_hinf import imc_controller

        imc_controller(**{argument: v})

    return call


def _yadav_dead_time(v):
    from vcnc_bench.reports.yadav2020 import loop_step_metrics

    loop_step_metrics("pi", 9.7, 4.85, dead_time=v)


def _yadav_plants(v):
    from vcnc_bench.reports.yadav2020 import plant_samples

    plant_samples(v)


def _correction(v):
    from vcnc_agents.action_modes import ActionMode

    ActionMode(mode="residual", baseline="qft", correction=v)


def _time_cost(v):
    from vcnc_gym.envs.feed_override_env import FeedOverrideEnv

    FeedOverrideEnv(time_cost=v)


CASES = {
    "arc_tolerance": _gcode,
    "n_machines": _plant_arrays("n_machines"),
    "dt": _plant_arrays("dt"),
    "dt ": _substeps_for,  # vcnc_feed_drive.substeps_for's
    "substep": _substep,
    "position_bound": _layout,
    "mu": _imc("mu"),
    "a": _imc("a"),
    "dead_time": _yadav_dead_time,
    "n (the number of plants)": _yadav_plants,
    "correction": _correction,
    "time_cost": _time_cost,
}


@pytest.mark.parametrize("bad", [True, "0.001", math.nan], ids=["bool", "string", "nan"])
@pytest.mark.parametrize("argument", list(CASES))
def test_a_scalar_argument_refuses_bools_strings_and_nan_by_name(argument, bad):
    if bad != bad and argument in ("n_machines", "n (the number of plants)"):
        bad = 2.5  # an integer argument: NaN is a float, refused as one; so is any other float
    with pytest.raises(ValueError, match=rf"^{__import__('re').escape(argument.strip())} must be"):
        CASES[argument](bad)
