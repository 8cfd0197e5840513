"""The pages of the learnable ids (v2) and of the v0 ids, in the form of Gymnasium's env pages.

Called by :func:`vcnc_pages.write_env_pages` at build time.  A v2 page (:func:`learnable_page`) gives the id's
description, action space (the set-point correction and its range on this id, the other actions), observation space
(every field with its scale and unit, ``layout.describe()``), rewards, starting state, episode end, arguments,
rendering (a frame of ``render_mode="rgb_array"``, :func:`write_frame`), a training snippet of Stable-Baselines3
(:func:`training_snippet`, which ``tests/test_env_pages.py`` runs) and the version history, from the registry, the
env itself and :class:`~vcnc_gym.envs.ContouringEnv`'s docstring (its ``## `` sections).  A v0 page
(:func:`legacy_page`) says what the id is and what to use instead.
"""

from __future__ import annotations

import inspect
import re
from pathlib import Path

#: Agent steps of the training snippet: where SB3's PPO with its defaults finished the v2 heart (the issue's table:
#: 0.26 times the drive's servo alone after 300 000 steps, one seed).
TRAINING_STEPS = 300_000

#: Decisions of the zero action before an env page's frame is drawn (the whole episode if shorter).
FRAME_DECISIONS = 1500


def training_snippet(env_id: str, steps: int = TRAINING_STEPS) -> str:
    """Ten lines that train SB3's PPO with its default hyperparameters on ``env_id`` (4 envs, ``VecNormalize``)
    and run the deterministic policy for one episode, printing its summary."""
    return f"""import gymnasium as gym
import vcnc_gym  # registers the ids
from stable_baselines3 import PPO
from stable_baselines3.common.env_util import make_vec_env
from stable_baselines3.common.vec_env import VecNormalize

env = VecNormalize(make_vec_env("{env_id}", n_envs=4, seed=0))
model = PPO("MlpPolicy", env, seed=0).learn(total_timesteps={steps:_})
env.training, env.norm_reward = False, False  # evaluate: frozen statistics, the env's own rewards
obs, done = env.reset(), [False]
while not done[0]:
    obs, reward, done, info = env.step(model.predict(obs, deterministic=True)[0])
print(info[0]["episode_summary"])  # max, mean, RMS contour error (mm), cycle time, completed, diverged
"""


def docstring_sections(cls) -> dict[str, str]:
    """The ``## Title`` sections of ``cls``'s docstring, by title, in MyST: ``:role:`x``` as ``{role}`x```."""
    doc = inspect.getdoc(cls) or ""
    sections = {}
    for part in re.split(r"^## ", doc, flags=re.M)[1:]:
        title, _, body = part.partition("\n")
        sections[title.strip()] = myst(body.strip())
    return sections


def myst(text: str) -> str:
    """reStructuredText roles (``:class:`X```) as MyST's (``{class}`X```)."""
    return re.sub(r"(?<![\w`]):([a-z]+):`", r"{\1}`", text)


def _bullets(section: str) -> list[str]:
    """The top-level bullets of a docstring section, each as one paragraph of text."""
    items, current = [], None
    for line in section.splitlines():
        if line.startswith("- "):
            current = [line[2:].strip()]
            items.append(current)
        elif current is not None and line.strip():
            current.append(line.strip())
    return [" ".join(i) for i in items]


def write_frame(env_id: str, path: Path, decisions: int = FRAME_DECISIONS) -> None:
    """A frame of ``env_id`` with ``render_mode="rgb_array"`` after ``decisions`` decisions of the zero action
    (the drive's servo alone), as a PNG at ``path``; kept if it exists (the build's cache: ``docs/envs`` is
    generated)."""
    if path.exists():
        return
    import gymnasium as gym
    import matplotlib.image
    import numpy as np

    env = gym.make(env_id, render_mode="rgb_array", render_every=decisions)
    env.reset(seed=0)
    zero = np.zeros(2, dtype=np.float32)
    for _ in range(decisions):
        _, _, term, trunc, _ = env.step(zero)
        if term or trunc:
            break
    frame = env.render()
    env.close()
    path.parent.mkdir(parents=True, exist_ok=True)
    matplotlib.image.imsave(path, frame, metadata={"Software": None})


def _um(mm: float) -> str:
    return f"{1e3 * mm:.3g} um"


def _versions(entry, env, ids: dict) -> list[str]:
    """The version history of a v2 page: its v2, its v1 and v0 (or shop-floor) bullets, from the docstrings."""
    from vcnc_gym.envs import ContouringEnv

    name = entry.id[: -len("-v2")]
    history = _bullets(docstring_sections(ContouringEnv)["Version History"])
    v2 = next(b for b in history if b.startswith("v2:"))
    out = [f"- **v2** (this page): {v2[len('v2:') :].strip()}"]
    own = _bullets(docstring_sections(type(env)).get("Version History", ""))
    if type(env) is not ContouringEnv:  # a G-code env: its own history of v1
        v1 = next((b for b in own if b.startswith("v1:")), "v1: initial release.")
        out.append(f"- **v1** ([{name}-v1]({name}-v1.md)): {v1[len('v1:') :].strip()}")
        return out
    if "shop_floor" in entry.kwargs:
        shop = next(b for b in history if b.startswith("The ``...Shop-v1`` ids"))
        out += [f"- **v1** ([{name}-v1]({name}-v1.md)): {shop}", "- no v0: the shop-floor ids started at v1."]
        return out
    v1 = next(b for b in history if b.startswith("v1:"))
    out.append(f"- **v1** ([{name}-v1]({name}-v1.md)): {v1[len('v1:') :].strip()}")
    if f"{name}-v0" in ids:
        v0 = next(b for b in history if b.startswith("v0:"))
        out.append(f"- **v0** ([{name}-v0]({name}-v0.md)): {v0[len('v0:') :].strip()}")
    else:
        out.append("- no v0: the id started at v1.")
    return out


def _header(entry, env, frame: bool) -> list[str]:
    name = entry.id[: -len("-v2")]
    task = env.task
    vector = (
        f'`gym.make_vec("{entry.id}", num_envs=N, vectorization_mode="vector_entry_point")`'
        if entry.vector_entry_point
        else "no (Gymnasium's `SyncVectorEnv` or `AsyncVectorEnv`)"
    )
    lines = [f"# {entry.id}", "", entry.summary + ".", ""]
    if frame:
        lines += [
            f"```{{image}} _img/{entry.id}-frame.png",
            f":alt: a frame of {entry.id} with render_mode='rgb_array'",
            ":width: 100%",
            "```",
            "",
            f'*A frame of `render_mode="rgb_array"`: the drive\'s servo alone (the zero action) after '
            f"{min(FRAME_DECISIONS, task.episode_steps)} decisions.*",
            "",
        ]
    rows = [
        ("Action Space", f"`{env.action_space}`: a set-point correction per axis, +-{_um(task.setpoint_range)}"),
        (
            "Observation Space",
            f"`Box` of shape {env.observation_space.shape}, {env.observation_space.dtype}: every field over a fixed "
            "scale (below)",
        ),
        ("import", f'`gym.make("{entry.id}")` after `import vcnc_gym`'),
        (
            "decision",
            f"every {1e3 * task.decision_period:g} ms ({task.action_repeat} control periods of {1e3 * task.dt:g} ms); "
            f"{task.episode_steps} decisions to the reference's end",
        ),
        (
            "reward",
            f"-(contour error / {_um(task.reward_scale)}), clipped at {_um(task.error_clip)}: in "
            f"[{-task.error_clip / task.reward_scale:g}, 0] a decision",
        ),
        ("native vector env", vector),
        ("the papers' interface", f"[{name}-v1]({name}-v1.md): the amplifier's voltage, physical observation"),
    ]
    lines += ["| | |", "|---|---|"] + [f"| {k} | {_cell(v)} |" for k, v in rows] + [""]
    return lines


def _cell(value) -> str:
    return str(value).replace("|", "\\|").replace("\n", " ")


def _action_section(entry, env) -> list[str]:
    task = env.task
    gains = task.servo_gains
    kp = ", ".join(f"{v:.4g}" for v in gains.kp)
    kd = ", ".join(f"{v:.4g}" for v in gains.kd)
    ki = ", ".join(f"{v:.4g}" for v in gains.ki)
    unit = env.plant.input_unit
    limits = ", ".join(f"{v:g}" for v in env.plant.input_limits(task.nominal_parameters))
    notch = "a notch at the structural mode" if (gains.notch[:, 1:] != 0).any() else "no notch (an ideal machine)"
    return [
        "## Action Space",
        "",
        f"`{env.action_space}`: for each axis, a value `a` in [-1, 1] moves the set-point of the drive's servo by "
        f"`a * setpoint_range`, with `setpoint_range` = {task.setpoint_range:.6g} mm ({_um(task.setpoint_range)}) "
        "on this id (`env.unwrapped.task.setpoint_range`), held for the decision.  Values outside [-1, 1] are clipped.",
        "",
        "The drive's servo closes the position loop every control period inside the step, as a real feed drive does "
        "under a CNC's outer loop ({mod}`vcnc_gym.envs.drive_servo`): the PID of the commissioning record of this "
        f"id's nominal machine (`{gains.key}`), with velocity feedforward and {notch}; per axis (x, y) "
        f"K_p = {kp} {unit}/mm, K_d = {kd} {unit} s/mm, K_i = {ki} {unit}/(mm s), input limits {limits} {unit}.  "
        "The zero action is the servo alone, which finishes the contour; `setpoint_range` is the set-point error "
        "at which its proportional term alone reaches the input limit (`u_max / K_p` of the stiffer axis).",
        "",
        "The other actions of the same task, through `gym.make` arguments:",
        "",
        f'- `gym.make("{entry.id}", base="ff-pid")` (any classical controller with a compiled form, '
        "`vcnc_baselines.names()`; the baselines extra): the controller runs every control period inside the step "
        "and the action adds up to `correction` (default 0.5) times the input limit to its command.",
        f'- `gym.make("{entry.id}", action="voltage")`: the amplifier command over its limit, held for the decision '
        f"(the v1 interface has it every control period, `action_repeat=1`).",
        "- `setpoint_range=` (mm) and `servo_gains=` (a dict of the servo's gains) change the set-point action.",
        "",
    ]


def _observation_section(env) -> list[str]:
    return [
        "## Observation Space",
        "",
        f"`Box` of shape {env.observation_space.shape}: the fields of `env.unwrapped.layout`, each the physical "
        "value divided by a fixed constant of the task, its scale (`layout.fields[k].scale`, in the field's unit; "
        "no running statistics), so that typical values are of order one; a field is bounded at 100 scales. "
        '`layout.get(obs, "tracking_error")` gives a field back in its unit.  `env.unwrapped.layout.describe()`:',
        "",
        env.layout.describe().strip(),
        "",
    ]


def _reward_section(env) -> list[str]:
    task = env.task
    worst = task.error_clip / task.reward_scale
    return [
        "## Rewards",
        "",
        f"Every control period earns `-min(e, {task.error_clip:g}) / {task.reward_scale:g}`, `e` its contour error "
        f"in mm (the distance from the table to the whole contour; `error_clip` = {_um(task.error_clip)}, "
        f"`reward_scale` = {_um(task.reward_scale)}); a decision's reward is the mean over its "
        f"{task.action_repeat} control periods, between {-worst:g} and 0.  An episode's return is therefore of the "
        f"order of its {task.episode_steps} decisions at worst and 0 for no error.  The effort term "
        f"(`effort_weight`, {task.effort_weight:g}) is off.",
        "",
        f"- Divergence (a contour error beyond {task.divergence_bound:g} mm, a tracking error beyond "
        f"{task.tracking_bound:g} mm, or a non-finite state) ends the episode with {-worst:g} for every decision "
        "left to the contour's natural end: ending early never pays more than finishing.",
        "- Running out of time ends it with minus the contour left untraversed over `reward_scale`, divided by "
        f"{task.action_repeat} (the decision's mean of its periods' rewards).",
        '- `info`: `"reward_contour"`, `"reward_effort"`, `"reward_divergence"`, `"reward_incomplete"` (the last '
        'control period\'s terms), `"step_contour_error_max"` and `"step_contour_error_mean"` (mm, over the '
        "decision's control periods), `\"contour_error\"` (the last period's).",
        "",
    ]


def _episode_end_section(env) -> list[str]:
    task = env.task
    return [
        "## Episode End",
        "",
        f"- **Terminated, completed**, once the table has reached the contour's end: at most "
        f"{task.completion_tolerance:g} mm of contour ahead of its closest point, at the reference's end or later "
        '(`info["completed"]`, `info["cycle_time"]` in s).',
        f"- **Terminated, out of time**, {task.completion_timeout:g} s after the reference's end "
        f"({task.time_limit_steps} decisions), with the penalty for the untraversed contour.",
        '- **Terminated, diverged** (`info["diverged"]`), as under Rewards.',
        f"- **Truncated** only by `max_episode_steps` (an argument): the id registers no `TimeLimit`; its natural "
        f"length is {task.episode_steps} decisions (`env.unwrapped.episode_steps`).",
        "",
        "The last step's `info[\"episode_summary\"]` holds the episode's figures: `contour_error_max`, "
        "`contour_error_mean` and `contour_error_rms` over every control period (mm), `cycle_time` (s, NaN unless "
        "completed), `completed`, `diverged`, `control_periods` (the native vector env: one array per key, masked "
        'by `_episode_summary`).  It does not clash with `RecordEpisodeStatistics`\' `info["episode"]`.',
        "",
    ]


def _arguments_section(entry, env, v1_kwargs: dict) -> list[str]:
    from vcnc_gym.envs import ContouringEnv

    own = ", ".join(f"`{k}={v!r}`" for k, v in entry.kwargs.items())
    changed = [k for k in entry.kwargs if v1_kwargs.get(k, inspect.Parameter.empty) != entry.kwargs[k]]
    rows = ["| argument | this id | v1 |", "|---|---|---|"]
    defaults = {p.name: p.default for p in inspect.signature(ContouringEnv).parameters.values()}
    for k in changed:
        before = v1_kwargs.get(k, defaults.get(k))
        note = (
            f" (the divergence bound, {env.task.divergence_bound:g} mm)" if k == "error_clip" and before is None else ""
        )
        rows.append(f"| `{k}` | `{entry.kwargs[k]!r}` | `{before!r}`{note} |")
    cls = type(env)
    return [
        "## Arguments",
        "",
        f'Registered: {own}.  `gym.make("{entry.id}", **kwargs)` takes every argument of '
        f"{{py:class}}`{cls.__module__}.{cls.__name__}` (its Arguments section) over these.  What this id sets "
        "differently from its v1:",
        "",
        *rows,
        "",
        'The arguments of the learnable interface: `action` ("setpoint", "voltage" or "correction"), '
        "`setpoint_range` (mm), `servo_gains`, `base` (a classical controller's name, with `correction`, a fraction "
        'of the input limit), `error_clip` (mm), `observation_scale` ("unit" or "raw"), and for rendering '
        "`render_mode` and `render_every`.",
        "",
    ]


def _rendering_section(entry, env) -> list[str]:
    fps = env.metadata["render_fps"]
    video = env.task.episode_steps / fps
    return [
        "## Rendering",
        "",
        f'`render_mode="rgb_array"` gives 800 x 360 RGB frames (above): the contour with the table\'s path, its '
        'contour error magnified, and the contour error over time; `"human"` shows them in a window. '
        f'`metadata["render_fps"]` = {fps}, one frame per decision: a video of one frame per step plays the '
        f"episode in real time ({video:.1f} s).  A new picture is drawn every `render_every` decisions (default "
        f"{env.render_every}, about 30 per simulated second) and at the episode's end; `render()` returns the last "
        "one in between.  Gymnasium's `RecordVideo` (moviepy: `pip install 'vcnc-gym[video]'`):",
        "",
        "```python",
        "from gymnasium.wrappers import RecordVideo",
        "",
        f'env = RecordVideo(gym.make("{entry.id}", render_mode="rgb_array"), "videos")',
        "```",
        "",
    ]


def learnable_page(entry, env, v1_kwargs: dict, ids: dict, parameter_table, frame: bool) -> str:
    """The page of the learnable id ``entry`` (a :class:`~vcnc_gym.envs.registry.SuiteEnv` of ``LEARNABLE``),
    ``env`` its unwrapped env, ``v1_kwargs`` its v1's registered arguments, ``ids`` every registered suite id."""
    from vcnc_gym.envs import ContouringEnv

    doc = docstring_sections(ContouringEnv)
    task = env.task
    lines = _header(entry, env, frame)
    lines += [
        "## Description",
        "",
        doc["Description"],
        "",
        f"This id: {entry.summary}.  The plant is `{env.plant.name}` ({env.plant.source}); the contour "
        f'"{task.contour_name}", {task.contour_length:.4g} mm, followed at {env.feedrate_profile}.',
        "",
    ]
    lines += _action_section(entry, env)
    lines += _observation_section(env)
    lines += _reward_section(env)
    lines += ["## Starting State", "", doc["Starting State"], ""]
    lines += _episode_end_section(env)
    lines += _arguments_section(entry, env, v1_kwargs)
    lines += _rendering_section(entry, env)
    lines += [
        "## Training with Stable-Baselines3",
        "",
        'SB3\'s `PPO("MlpPolicy")` with its default hyperparameters, 4 envs and `VecNormalize` '
        f"({TRAINING_STEPS:,} agent steps: minutes on 2 cores); `python benchmarks/learnability.py --env "
        f"{entry.id}` trains it over several seeds and prints the result beside the drive's servo alone and the "
        "classical controllers.",
        "",
        "```python",
        training_snippet(entry.id).rstrip(),
        "```",
        "",
        "## Version History",
        "",
        *_versions(entry, env, ids),
        "",
        "## Plant parameters",
        "",
        "`env.unwrapped.plant.parameters`, the box `randomize=True` draws from:",
        "",
        *parameter_table(env.plant),
        "",
    ]
    return "\n".join(lines)


def legacy_page(entry, env, ids: dict) -> str:
    """The page of a v0 id: what it is and what to use instead."""
    name = entry.id[: -len("-v0")]
    task = env.task
    v1, v2 = f"{name}-v1", f"{name}-v2"
    lines = [
        f"# {entry.id}",
        "",
        entry.summary + ".",
        "",
        "```{note}",
        f"This is the papers' original version of the task, registered so that the figures measured on it "
        f"reproduce; Gymnasium warns that it is out of date.  To learn a controller use [{v2}]({v2}.md); to run "
        f"the classical controllers use [{v1}]({v1}.md).",
        "```",
        "",
        "## What it is",
        "",
        f'- The episode ends {task.settling_time:g} s after the reference\'s end (`episode_end="reference"`), not '
        f"when the table has reached the contour's end: a table lagging the reference is scored only on the part it "
        f"has traversed (v1 and v2 end when it arrives).",
        "- The observation has no contour preview (`contour_ahead=()`): no `contour_preview` and "
        f"`contour_curvature` fields, {env.observation_space.shape[0]} entries (v1: 36).",
        f"- Otherwise the v1 interface: the amplifier's command every control period ({1e3 * task.dt:g} ms, "
        f"{task.episode_steps} decisions), the observation in physical units, the reward -(contour error / "
        f"{_um(task.reward_scale)}) clipped at {task.error_clip:g} mm, and a divergence penalty of "
        f"{-task.error_clip / task.reward_scale:g} per remaining decision.",
        "",
        "## Why not to learn on it",
        "",
        "Stable-Baselines3's PPO with its default settings did not learn the v0 heart: every episode diverged at "
        "decision 1 603, 0.16 s into the heart's 3.2 s (return -1.5e7).  The divergence penalty was a million times "
        "a step's reward, the raw observation spanned nine orders of magnitude, 20 000 steps were less than one "
        "episode, and an untrained policy's random voltages left the tracking bound at once.  "
        f"[{v2}]({v2}.md) changes each (its Version History).",
        "",
        "## Observation Space",
        "",
        "`env.unwrapped.layout.describe()` (raw units: every scale 1):",
        "",
        env.layout.describe().strip(),
        "",
        "## Arguments",
        "",
        "Registered: " + ", ".join(f"`{k}={v!r}`" for k, v in entry.kwargs.items()) + ".",
        "",
    ]
    return "\n".join(lines)
