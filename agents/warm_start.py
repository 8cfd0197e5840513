"""A new run that starts from a trained agent (``vcnc-train --init-from AGENT``, RL Baselines3 Zoo's
``--trained-agent``): its policy and value weights and its observation normalisation, in a run folder of its own.

What it is for: fine-tuning an agent on another reward (a tighter training tolerance, a price on the max), another
budget or another machine of the same observation, the source agent left as it is.  The run counts its steps from
0 and trains with its own env arguments (the reward among them), seed, learning rate and clip range from its first
step; its config.yml records the
agent it started from (:attr:`vcnc_agents.run_config.RunConfig.init_from`).

The agent must fit the run, and :func:`check_init_agent` says why not before anything is written:

- the same observation and action: the signature fields that set them (:data:`FITTING_FIELDS`: the control period,
  the preview, the shapes), compared as :func:`vcnc_agents.load_agent` compares them; the contour, the plant and the
  shop floor may differ (a warm start onto another machine of the same observation);
- the same action mode (what the action means: mode, baseline, correction, action repeat), the training reward's
  ``peak_weight`` and the dial's rate (``dial_rate``, a limit the run may add) aside, and a memory (``history``) as
  long as the agent's or longer.  The baseline's commissioning
  may differ (``ff-pid-online`` to ``ff-pid-online@machine``: the same law, fitted to each machine), as the machine
  may;
- the same policy, network and PPO arguments, but for :data:`RUN_OWN` (the learning rate and clip ranges, which the
  run sets anew).

**A memory grown** (the run's ``history`` K longer than the agent's K0: as on an agent trained
without one).  The decisions K0+1..K are new inputs at the observation's end (:mod:`vcnc_gym.envs.history`: the past,
newest first).  :func:`grow_agent` gives them weight 0 in every first layer (actor, critic), so the run starts from
the agent's very actions and values, and normalises each as the present observation's field it remembers (a past
velocity as the present velocity); the rest is the agent's (Chen, Goodfellow and Shlens 2016, Net2Net: a wider
network that computes the same function).  Adam's moments start afresh.

With ``--seeds``, ``{seed}`` in the path is each seed's number (``--init-from RUNS/seed{seed}/final``), so that seed k
starts from seed k's agent.  The lean trainer only (SB3's refuses, naming the option).
"""

from __future__ import annotations

from dataclasses import fields, replace
from pathlib import Path

import numpy as np

from .action_modes import ActionMode
from .config import ppo_arguments
from .normalization import NormalizationStats
from .run_folder import agent_files, read_agent_config
from .signature import check_signature

__all__ = [
    "SEED_FIELD",
    "FITTING_FIELDS",
    "RUN_OWN",
    "init_agent_path",
    "check_init_agent",
    "grow_agent",
    "load_init_agent",
]

#: The placeholder of ``--init-from`` that each seed of ``--seeds`` replaces with its number.
SEED_FIELD = "{seed}"

#: The :func:`vcnc_agents.signature.env_signature` fields an agent and a run it starts must share: what the
#: observation and the action mean, not the part or the machine.
FITTING_FIELDS = ("dt", "preview_steps", "contour_ahead", "observation_shape", "action_shape")

#: The PPO arguments a warm-started run may set anew (:func:`vcnc_agents.model_file.load_ppo` replaces them in the
#: loaded model); every other one (the network, n_steps, gamma, ...) must be the agent's.
RUN_OWN = ("learning_rate", "clip_range", "clip_range_vf")


def init_agent_path(init_from, seed: int) -> Path:
    """The agent folder of ``init_from`` for ``seed`` (``{seed}`` replaced by its number)."""
    text = str(init_from)
    if not text:
        raise ValueError("init_from is empty: give an agent folder (RUN/final, RUN/best) or its model.zip")
    return Path(text.replace(SEED_FIELD, str(seed)))


def _agent_config(path: Path) -> dict:
    """The agent's config.yml: its env signature, action mode and hyperparameter entry, checked."""
    config_file = agent_files(path)[2]
    try:
        data = read_agent_config(config_file)
        if not isinstance(data.get("action_mode"), dict) or not isinstance(data.get("hyperparams"), dict):
            raise ValueError(f"{config_file} is not an agent's config.yml (it lacks action_mode or hyperparams)")
        mode = ActionMode(**data["action_mode"])
    except (ValueError, TypeError) as exc:
        raise ValueError(f"init_from: {exc}") from None
    return {
        "signature": (data.get("env") or {}).get("signature") or {},
        "mode": mode,
        "ppo": ppo_arguments(data["hyperparams"]),
    }


def check_init_agent(init_from, config):
    """``config`` (a new run's :class:`vcnc_agents.run_config.RunConfig`, with its env block) recording the agent
    it starts from; FileNotFoundError or ValueError naming ``init_from`` and every field where the agent does not
    fit the run (see the module docstring)."""
    path = init_agent_path(init_from, config.seed)
    agent = _agent_config(path)
    what = f"init_from: the agent in {str(path)!r}"
    recorded = agent["signature"]
    given = config.env["signature"]
    check_signature(
        {k: recorded[k] for k in FITTING_FIELDS if k in recorded},
        {k: given[k] for k in FITTING_FIELDS if k in given},
        what=what,
    )
    if agent["mode"].history > config.mode.history:
        raise ValueError(
            f"{what} remembers {agent['mode'].history} decisions, the run {config.mode.history}: a "
            "memory may grow in a warm start, not shrink"
        )
    theirs, ours = (
        replace(m, peak_weight=0.0, dial_rate=0.0, history=0, baseline=_law(m.baseline))
        for m in (agent["mode"], config.mode)
    )
    if theirs != ours:
        diffs = [
            f"{f.name}: the agent's {getattr(theirs, f.name)!r}, the run's {getattr(ours, f.name)!r}"
            for f in fields(ActionMode)
            if getattr(theirs, f.name) != getattr(ours, f.name)
        ]
        raise ValueError(f"{what} acts in another action mode: {'; '.join(diffs)}")
    (p_theirs, k_theirs), (p_ours, k_ours) = agent["ppo"], config.ppo_arguments()
    if p_theirs != p_ours:
        raise ValueError(f"{what} is a {p_theirs}, the run's policy a {p_ours}")
    diffs = [
        f"{k}: the agent's {k_theirs.get(k)!r}, the run's {k_ours.get(k)!r}"
        for k in sorted(set(k_theirs) | set(k_ours))
        if k not in RUN_OWN and k_theirs.get(k) != k_ours.get(k)
    ]
    if diffs:
        raise ValueError(
            f"{what} was trained with other PPO arguments (only {', '.join(RUN_OWN)} may differ): " + "; ".join(diffs)
        )
    return replace(config, init_from=str(path))


def _law(baseline: str | None) -> str | None:
    """The residual's law without its commissioning (``ff-pid-online@machine``: ``ff-pid-online``)."""
    return baseline.split("@")[0] if baseline else baseline


def _grown_weights(old: dict, new: dict) -> dict:
    """``new``'s state dict (shapes) filled from ``old``'s: equal shapes copied; a first layer with more input
    columns (dimension 1) gets ``old``'s columns first and zeros after; anything else a ValueError naming it."""
    import torch

    grown = {}
    for key, target in new.items():
        source = old.get(key)
        if source is None:
            raise ValueError(f"grow_agent: the agent has no {key!r}")
        if source.shape == target.shape:
            grown[key] = source.clone()
        elif source.dim() == 2 and source.shape[0] == target.shape[0] and source.shape[1] < target.shape[1]:
            grown[key] = torch.cat([source, torch.zeros_like(target[:, source.shape[1] :])], dim=1)
        else:
            raise ValueError(
                f"grow_agent: {key!r} has shape {tuple(source.shape)} in the agent and "
                f"{tuple(target.shape)} in the run: only a first layer's inputs may grow"
            )
    return grown


def grow_agent(model, stats: NormalizationStats, layout, before: int, after: int, observation_space):
    """The agent ``model`` (an SB3 PPO remembering ``before`` decisions) and its ``stats`` grown to remember
    ``after`` (> ``before``) decisions on an env of observation ``layout``, the model's policy rebuilt on
    ``observation_space`` (the grown agent's); see the module docstring.  ``model`` is changed in place; returns
    (model, grown stats)."""
    from vcnc_gym.envs.history import history_columns

    columns = history_columns(layout)
    extra = (after - before) * columns.size
    if stats.observation_size + extra != observation_space.shape[0]:
        raise ValueError(
            f"grow_agent: {stats.observation_size} entries and {after - before} decisions of "
            f"{columns.size} make {stats.observation_size + extra}, the run's observation has "
            f"{observation_space.shape[0]}"
        )
    old = model.policy
    policy = model.policy_class(observation_space, model.action_space, model.lr_schedule, **model.policy_kwargs)
    policy.load_state_dict(_grown_weights(old.state_dict(), policy.state_dict()))
    model.policy, model.observation_space = policy.to(model.device), observation_space
    reps = after - before
    grown = replace(
        stats,
        obs_mean=np.r_[stats.obs_mean, np.tile(stats.obs_mean[columns], reps)],
        obs_var=np.r_[stats.obs_var, np.tile(stats.obs_var[columns], reps)],
    )
    return model, grown


def load_init_agent(config, *, env_space, action_space, layout, device: str = "cpu"):
    """(PPO model, :class:`vcnc_agents.normalization.NormalizationStats`) of the agent ``config.init_from`` on an
    env of observation space ``env_space`` and ``layout``, the model with the run's hyperparameters
    (:func:`vcnc_agents.model_file.load_ppo`) and seeded with its seed; its memory grown to the run's
    (:func:`grow_agent`) if shorter."""
    from vcnc_gym.envs.history import agent_space

    from .model_file import load_ppo

    model_file, norm_file, config_file = agent_files(config.init_from)
    policy, kwargs = config.ppo_arguments()
    before, after = ActionMode(**read_agent_config(config_file)["action_mode"]).history, config.mode.history
    model = load_ppo(
        model_file,
        observation_space=agent_space(env_space, before, layout),
        action_space=action_space,
        ppo_kwargs=kwargs,
        device=device,
        policy=policy,
    )
    stats = NormalizationStats.load(norm_file)
    if before < after:
        model, stats = grow_agent(model, stats, layout, before, after, agent_space(env_space, after, layout))
    model.set_random_seed(config.seed)
    return model, stats
