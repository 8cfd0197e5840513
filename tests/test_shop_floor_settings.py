"""shop_floor(settings): every number through vcnc_gym.validation, the setting named in every refusal."""

from __future__ import annotations

import pytest

from vcnc_gym.plants.shop_floor import EFFECT_NAMES, shop_floor


@pytest.mark.parametrize("name", EFFECT_NAMES)
@pytest.mark.parametrize("value", ["abc", None, "1e-4", True, [True, 1.0], float("nan"), 1j])
def test_a_setting_that_is_not_a_number_is_refused_naming_it(name, value):
    with pytest.raises(ValueError, match=f"shop-floor setting {name}"):
        shop_floor("vcnc_feed_drive", {name: value})


@pytest.mark.parametrize("name", ["command_delay", "sensor_delay", "teeth"])
@pytest.mark.parametrize("value", [1.5, (1, 2.5), (1, True)])
def test_a_count_setting_must_be_a_whole_number(name, value):
    with pytest.raises(ValueError, match=f"shop-floor setting {name}.*integer"):
        shop_floor("vcnc_feed_drive", {name: value})


def test_counts_and_reals_given_well_are_taken_as_given():
    model = shop_floor(
        "vcnc_feed_drive",
        {"command_delay": 2, "sensor_delay": (0, 1), "teeth": 2.0, "noise_std": 1e-4, "mode_frequency": (120, 180.5)},
    )
    nominal = {p.name: p.nominal for p in model.parameters}
    assert nominal["command_delay"] == (2.0, 2.0) and nominal["sensor_delay"] == (0.0, 1.0)
    assert nominal["teeth"] == (2.0, 2.0) and nominal["noise_std"] == (1e-4, 1e-4)
    assert nominal["mode_frequency"] == (120.0, 180.5)


def test_a_pair_of_the_wrong_length_is_refused_naming_the_setting():
    with pytest.raises(ValueError, match="shop-floor setting noise_std"):
        shop_floor("vcnc_feed_drive", {"noise_std": (1e-4, 1e-4, 1e-4)})
    with pytest.raises(ValueError, match="shop-floor setting teeth"):
        shop_floor("vcnc_feed_drive", {"teeth": (4,)})
