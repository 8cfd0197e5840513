"""The price of the episode's peak contour error (``peak_weight``): a term of the training reward.

Checked against the contour error of every control period, recorded from the plain env under the wrapper (not the
wrapper's or the kernel's own peak), and the three training paths against each other: the residual wrapper, the
lean trainer's native envs and SB3's native ``VecEnv``.
"""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest

import vcnc_gym  # noqa: F401
from vcnc_agents.action_modes import ActionMode, PeakPrice
from vcnc_agents.config import action_mode_of, with_action_mode
from vcnc_agents.lean_ppo import DecisionEnv
from vcnc_agents.vec_env import VcncVecEnv

CIRCLE = "VCNC-Circle-v1"  # 6284 control periods of 1 ms: a whole episode is quick
W = 40.0


class _Recorder(gym.Wrapper):
    """Keeps the contour error (mm) of every control period the plain env steps."""

    def __init__(self, env):
        super().__init__(env)
        self.errors = []

    def step(self, action):
        out = super().step(action)
        self.errors.append(out[4]["contour_error"])
        return out


def _mode(weight):
    return ActionMode("residual", 20, "ff-pid", 0.2, peak_weight=weight)


def test_an_episode_s_penalties_sum_to_its_max_priced_as_weight_decisions():
    """Two wrappers, priced and not, same seed and actions: the difference of their rewards is never positive, and
    over the whole episode it sums to ``-W * max(e) / reward_scale``, with the max over every control period."""
    rng = np.random.default_rng(0)
    plain = _mode(0.0).wrap(gym.make(CIRCLE, action_repeat=1))
    inner = _Recorder(gym.make(CIRCLE, action_repeat=1))
    priced = _mode(W).wrap(inner)
    plain.reset(seed=3)
    priced.reset(seed=3)
    scale = priced.unwrapped.task.reward_scale
    differences = []
    done = False
    while not done:
        a = rng.uniform(-1, 1, 2)
        _, r0, te0, tr0, _ = plain.step(a)
        _, r1, te, tr, info = priced.step(a)
        assert (te, tr) == (te0, tr0)
        differences.append(r1 - r0)
        done = te or tr
    assert info["completed"]
    d = np.array(differences)
    assert np.all(d <= 1e-12)
    assert np.count_nonzero(d) < d.size  # only decisions that raise the episode's max pay
    np.testing.assert_allclose(d.sum(), -W * max(inner.errors) / scale, rtol=1e-9)
    # a new episode pays for its own max again
    priced.reset(seed=3)
    plain.reset(seed=3)
    a = rng.uniform(-1, 1, 2)
    assert priced.step(a)[1] - plain.step(a)[1] < 0


def test_the_price_stops_at_the_divergence_bound_and_pays_only_the_deciding_envs():
    price = PeakPrice(10.0, 0.01, 5.0, 3)
    np.testing.assert_allclose(price(np.array([0.002, 7.0, 0.001])), [2.0, 5000.0, 1.0])
    np.testing.assert_allclose(price(np.array([0.001, 9.0, 0.004]), rows=np.array([True, True, False])), [0, 0, 0])
    np.testing.assert_allclose(price(np.array([0.003, 0.0, 0.004])), [1.0, 0.0, 3.0])
    price.restart(np.array([True, False, False]))
    np.testing.assert_allclose(price(np.array([0.001, 0.0, 0.0])), [1.0, 0.0, 0.0])


@pytest.mark.parametrize("native", ["lean", "sb3-vecenv"])
def test_the_native_training_envs_price_as_the_wrapper_does(native):
    """The lean trainer's envs (the compiled baseline in the kernel) and SB3's native VecEnv give the wrapper's
    priced rewards, decision by decision, up to the compiled baseline's rounding."""
    mode = _mode(W)
    envs = DecisionEnv(CIRCLE, 2, mode, {}, seed=5) if native == "lean" else VcncVecEnv(CIRCLE, 2, mode, {}, seed=5)
    wrapped = [mode.wrap(gym.make(CIRCLE, action_repeat=1)) for _ in range(2)]
    envs.reset()
    for i, w in enumerate(wrapped):
        w.reset(seed=5 + i)
    rng = np.random.default_rng(1)
    paid = 0
    for _ in range(30):
        a = rng.uniform(-1, 1, (2, 2)).astype(np.float32)
        rewards = envs.step(a)[1]
        own = np.array([w.step(a[i])[1] for i, w in enumerate(wrapped)])
        np.testing.assert_allclose(rewards, own, rtol=1e-4, atol=1e-6)
        paid += int(np.any(envs.price.peak > 0))
    assert paid > 0
    envs.close()


def test_peak_weight_travels_through_the_config_and_is_checked():
    mode = _mode(W)
    entry = with_action_mode({"policy": "MlpPolicy"}, mode)
    assert entry["env_wrapper"][0]["vcnc_agents.action_modes.ResidualAction"]["peak_weight"] == W
    assert action_mode_of(entry) == mode
    assert ActionMode(**mode.to_dict()) == mode
    assert "peak_weight" not in _mode(0.0).to_dict()
    with pytest.raises(ValueError, match="peak_weight"):
        _mode(-1.0)
    with pytest.raises(ValueError, match="peak_weight"):
        ActionMode("direct", 1, peak_weight=1.0)
    with pytest.raises(ValueError, match="peak_weight"):
        ActionMode("residual", 20, "ff-pid", 0.2, peak_weight="much")


def test_vcnc_train_peak_weight_changes_the_entry_s_price_only():
    """``vcnc-train --peak-weight W`` over an entry keeps its baseline, correction, repeat and memory; another option
    keeps the entry's price; on a direct mode it is refused by name."""
    from pathlib import Path

    from vcnc_agents.arguments import action_mode, parser

    root = Path(__file__).resolve().parents[1]
    adaptive = root / "experiments" / "adaptive" / "recipes" / "adaptive_machine.yml"
    omega = "VCNC-OmegaLookaheadShop-v1"
    args = parser().parse_args(["--env", omega, "--config", str(adaptive), "--peak-weight", "100"])
    assert action_mode(args, adaptive) == ActionMode("residual", 5, "ff-pid@machine", 0.3, history=16, peak_weight=100)
    args = parser().parse_args(["--env", omega, "--config", str(adaptive), "--peak-weight", "100", "--history", "0"])
    assert action_mode(args, adaptive) == ActionMode("residual", 5, "ff-pid@machine", 0.3, peak_weight=100)
    args = parser().parse_args(["--env", CIRCLE, "--action-mode", "direct", "--peak-weight", "1"])
    with pytest.raises(ValueError, match="--peak-weight and --dial-rate apply to --action-mode residual"):
        action_mode(args, root / "agents" / "hyperparams" / "ppo.yml")


def test_a_mode_option_keeps_the_entry_s_baseline_arguments_unless_it_names_another_baseline(tmp_path):
    """An entry's ``ResidualAction`` arguments of its baseline (``baseline_params``: here ``integral: false``) stay
    when an option changes something else, and are dropped with a note when ``--baseline`` names another one (they
    were dropped in every case before)."""
    import yaml

    from vcnc_agents.arguments import action_mode, parser
    from vcnc_agents.run_warning import RunWarning

    omega = "VCNC-OmegaTolerance-v2"
    entry = {
        "policy": "MlpPolicy",
        "env_wrapper": [
            {
                "vcnc_agents.action_modes.ResidualAction": {
                    "baseline": "ff-pid-online",
                    "correction": 0.1,
                    "action_repeat": 20,
                    "integral": False,
                }
            }
        ],
    }
    config = tmp_path / "entry.yml"
    config.write_text(yaml.safe_dump({omega: entry}))
    args = parser().parse_args(["--env", omega, "--config", str(config), "--peak-weight", "10"])
    mode = action_mode(args, config)
    assert mode.baseline_params == {"integral": False} and mode.peak_weight == 10
    args = parser().parse_args(["--env", omega, "--config", str(config), "--baseline", "ff-pid"])
    with pytest.warns(RunWarning, match="integral"):
        assert action_mode(args, config).baseline_params == {}
