"""The shipped agents of issue 24: specialists on current ids, generalists on any contour of their machine."""

from __future__ import annotations

import warnings
from pathlib import Path

import gymnasium as gym
import numpy as np
import pytest
import yaml

import vcnc_agents
import vcnc_baselines
import vcnc_gym
from vcnc_agents.action_modes import ResidualAction
from vcnc_agents.policy import ANY_CONTOUR_IDS, check_signature, env_signature
from vcnc_gym.envs.registry import CONTOURING_IDS

ROOT = Path(__file__).resolve().parents[1]
SPECIALISTS = ROOT / "agents" / "hyperparams" / "specialists.yml"
#: The adaptive study's recipes: the shop-floor specialists' entries with a memory.
ADAPTIVE = ROOT / "experiments" / "adaptive" / "recipes" / "adaptive.yml"


def test_shipped_agents_are_on_current_ids_only():
    """No agent is left on an id a newer version replaced (the v0 ids), and every generalist names a plant."""
    assert set(vcnc_agents.TRAINED) <= set(vcnc_gym.ENV_IDS), sorted(set(vcnc_agents.TRAINED) - set(vcnc_gym.ENV_IDS))
    for plant, folder in vcnc_agents.GENERALISTS.items():
        config = yaml.safe_load((folder / "config.yml").read_text())
        assert config["env_id"] in ANY_CONTOUR_IDS and config["env"]["signature"]["plant"] == plant


@pytest.mark.parametrize("name", ["specialists.yml", "adaptive.yml"])
def test_every_specialist_entry_prepares_a_residual_run_over_a_compiled_baseline(tmp_path, name):
    """Each entry of specialists.yml (and of adaptive.yml, the shop-floor specialists with a history) passes
    vcnc-train's checks for its id; the baseline it corrects has a compiled form (the lean trainer steps a whole
    decision in one call).  The adaptive agents differ from their specialists in their history alone."""
    path = SPECIALISTS if name == "specialists.yml" else ADAPTIVE
    entries = yaml.safe_load(path.read_text())
    assert set(entries) <= set(CONTOURING_IDS)
    if name == "adaptive.yml":
        specialists = yaml.safe_load(SPECIALISTS.read_text())
        for env_id, entry in entries.items():
            wrapper = dict(entry["env_wrapper"][0]["vcnc_agents.action_modes.ResidualAction"])
            assert wrapper.pop("history") >= 1
            assert (
                dict(entry, env_wrapper=[{"vcnc_agents.action_modes.ResidualAction": wrapper}]) == specialists[env_id]
            )
    for env_id in entries:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", vcnc_agents.RunWarning)  # n_timesteps rounded up to whole rollouts
            run_dir, config, checkpoint = vcnc_agents.training.prepare_run(env_id, tmp_path / env_id, config_file=path)
        assert checkpoint is None and not run_dir.exists()
        mode = config.mode
        assert mode.mode == "residual"
        assert config.env_kwargs["randomize"] is True
        policy = vcnc_baselines.make(mode.baseline, gym.make(env_id))
        assert hasattr(policy, "compiled"), mode.baseline


def test_a_generalist_signature_fits_any_contour_of_its_machine_and_no_other():
    """An agent trained on the random contours is checked on the machine (plant, dt, preview, shapes) only: the
    heart and the ISO 230-4 circle on Jahanpour et al.'s drive fit, Simba et al.'s drive does not; a specialist
    is still refused on another contour."""
    recorded = env_signature(gym.make("VCNC-RandomContour-v1"))
    for env_id in ("VCNC-Heart-v1", "VCNC-OmegaLookahead-v1", "VCNC-ISO230Circle-v1", "VCNC-Butterfly-v1"):
        check_signature(recorded, env_signature(gym.make(env_id)))
    with pytest.raises(ValueError, match="plant: trained on vcnc_feed_drive"):
        check_signature(recorded, env_signature(gym.make("VCNC-CornersSmooth-v1")))
    with pytest.raises(ValueError, match="dt: trained on"):
        check_signature(recorded, env_signature(gym.make("VCNC-RandomContour-v1", dt=2e-4)))
    specialist = env_signature(gym.make("VCNC-Heart-v1"))
    with pytest.raises(ValueError, match="trained on VCNC-Heart-v1, not VCNC-Butterfly-v1"):
        check_signature(specialist, env_signature(gym.make("VCNC-Butterfly-v1")))


def test_a_generalist_signature_tells_the_shop_floor_from_the_ideal_machine():
    """The signature records the shop-floor settings (issue 37, item 3): a generalist trained on the shop floor's
    random contours fits the shop-floor heart and omega, not the ideal heart; an ideal generalist, and one recorded
    before the field (every such one was ideal), is refused on the shop floor, naming the field."""
    shop = env_signature(gym.make("VCNC-RandomContour-v1", shop_floor=True))
    assert shop["shop_floor"]["mode_frequency"] == [150.0, 150.0]
    for env_id in ("VCNC-HeartShop-v1", "VCNC-OmegaLookaheadShop-v1"):
        check_signature(shop, env_signature(gym.make(env_id)))
    with pytest.raises(ValueError, match="shop_floor: trained on"):
        check_signature(shop, env_signature(gym.make("VCNC-Heart-v1")))
    ideal = env_signature(gym.make("VCNC-RandomContour-v1"))
    assert ideal["shop_floor"] is None
    before = {k: v for k, v in ideal.items() if k != "shop_floor"}
    for recorded in (ideal, before):
        with pytest.raises(ValueError, match="shop_floor: trained on None"):
            check_signature(recorded, env_signature(gym.make("VCNC-HeartShop-v1")))
        check_signature(recorded, env_signature(gym.make("VCNC-Heart-v1")))


def test_the_residual_wrapper_replans_its_baseline_for_each_random_contour():
    """ResidualAction over a model-based baseline hands every new contour to it: after each reset the baseline's
    table is built from the env's current reference (not the first contour's)."""
    env = ResidualAction(gym.make("VCNC-RandomContour-v1"), baseline="ff-ccc", correction=0.1, action_repeat=10)
    seen = []
    for seed in (1, 2):
        env.reset(seed=seed)
        samples = env.unwrapped.task.reference_arrays.samples
        assert env.baseline.reference is samples or np.array_equal(env.baseline.reference, samples)
        seen.append(samples.shape[0])
        env.step(np.zeros(2))
    assert seen[0] != seen[1]  # two contours of different lengths: the table followed


#: A named contour of each generalist's machine (none of which it trained on).
NAMED_CONTOUR = {
    "vcnc_feed_drive": "VCNC-Heart-v1",
    "current_feed_drive": "VCNC-CornersSmooth-v1",
    "nct_xy_table": "VCNC-Circle-v1",
}


def test_a_generalist_is_shipped_for_every_contouring_plant():
    """One generalist per plant a contouring id runs on (Yadav et al.'s axis has positioning ids only)."""
    plants = {gym.make(env_id).unwrapped.plant.name for env_id in CONTOURING_IDS}  # a shop floor's is its machine's
    assert plants == set(vcnc_agents.GENERALISTS) == set(NAMED_CONTOUR)


@pytest.mark.slow  # > 10 s on 2 cores: one whole episode per generalist
@pytest.mark.parametrize("plant", sorted(NAMED_CONTOUR))
def test_a_generalist_finishes_a_named_contour_it_never_saw(plant):
    """Each generalist, trained on VCNC-RandomContour-v1 only, finishes a named contour of its machine within
    twice the error of the controller it corrects (its correction is 5 % of the input limit)."""
    from vcnc_gym.evaluation import run_episode

    env = gym.make(NAMED_CONTOUR[plant])
    mine = run_episode(vcnc_agents.load_agent(vcnc_agents.GENERALISTS[plant], env), env, seed=0)
    base = run_episode(vcnc_baselines.make("ff-ccc", env), env, seed=0)
    assert mine.completed and not mine.diverged
    assert mine.max_contour_error_um < 2 * base.max_contour_error_um + 0.01
