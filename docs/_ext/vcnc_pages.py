"""Sphinx extension: the pages generated from the code, written before the build reads the sources.

- ``envs/``: one page per env id of :data:`vcnc_gym.envs.registry.SUITE` (its
  summary, registered arguments, spaces, observation fields, plant and a
  picture of its contour), and an index that lists the legacy ids too;
- ``controllers.md``: the controllers of :mod:`vcnc_baselines.registry`, grouped by
  the family folders of ``baselines/`` (feedback, feedforward, coupling,
  learning, predictive, optimal), with the variants;
- ``api/``: one page per package, an ``automodule`` per public module found
  by walking the package, so that a new module appears without editing the docs.

A page is rewritten only when its text changes, so incremental builds stay
incremental.  The papers are named by authors and year in the code itself
(docstrings, parameter sources, env summaries); the references page maps
them to the project's paper folder.
"""

from __future__ import annotations

import importlib
import inspect
import pkgutil
from pathlib import Path

#: The controller families, in the order of the page: folder of baselines/ -> heading.
FAMILIES = {
    "feedback": "Feedback",
    "feedforward": "Feedforward",
    "coupling": "Cross-coupling",
    "learning": "Learning",
    "predictive": "Predictive (LQ preview, MPC)",
    "optimal": "Optimal (non-causal floors)",
}

#: The packages of the API reference, with a one-line heading each.
API_PACKAGES = {
    "vcnc_gym": "vcnc_gym: the environments",
    "vcnc_baselines": "vcnc_baselines: the classical controllers (folder baselines/)",
    "vcnc_agents": "vcnc_agents: PPO training and trained agents (folder agents/)",
    "vcnc_bench": "vcnc_bench: the benchmark",
}


def _write(path: Path, text: str) -> None:
    path.parent.mkdir(parents=True, exist_ok=True)
    if not path.exists() or path.read_text() != text:
        path.write_text(text)


def _md_cell(value) -> str:
    return str(value).replace("|", "\\|").replace("\n", " ")


# -- envs -------------------------------------------------------------------------------------------


def _picture(env, path: Path) -> bool:
    """Draw the env's contour and its reference start into ``path`` (PNG); False for an env without a curve."""
    curve = getattr(env, "curve", None)
    if curve is None:
        return False
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    import numpy as np

    lo, hi = curve.u_range
    pts = curve.points(np.linspace(lo, hi, 4000))
    fig, ax = plt.subplots(figsize=(4.2, 3.6), dpi=100)
    ax.plot(pts[:, 0], pts[:, 1], lw=1.2, color="tab:blue", label="contour")
    ax.plot(*pts[0], "o", color="tab:green", label="start")
    ax.plot(*pts[-1], "s", color="tab:red", ms=4, label="end")
    ax.set_aspect("equal", adjustable="datalim")
    ax.set_xlabel("x [mm]")
    ax.set_ylabel("y [mm]")
    ax.legend(loc="best", fontsize=7)
    ax.grid(alpha=0.3)
    fig.tight_layout()
    path.parent.mkdir(parents=True, exist_ok=True)
    # metadata without a date: the same figure gives the same bytes
    fig.savefig(path, metadata={"Software": None})
    plt.close(fig)
    return True


def _parameter_table(plant) -> list[str]:
    lines = ["| parameter | unit | nominal (x, y) | uncertainty interval (x; y) | source |", "|---|---|---|---|---|"]
    for p in plant.parameters:
        nominal = ", ".join(f"{v:.6g}" for v in p.nominal)
        interval = "; ".join(f"[{lo:.6g}, {hi:.6g}]" for lo, hi in p.interval) if p.interval else "fixed"
        lines.append(f"| `{p.name}` | {_md_cell(p.unit)} | {nominal} | {interval} | {_md_cell(p.source)} |")
    return lines


def _env_page(entry, env, picture: bool) -> str:
    cls = type(env)
    kwargs = ", ".join(f"`{k}={v!r}`" for k, v in entry.kwargs.items()) or "none"
    plant = env.plant
    vector = (
        'yes: `gym.make_vec("%s", num_envs=N, vectorization_mode="vector_entry_point")`' % entry.id
        if entry.vector_entry_point
        else "no (Gymnasium's `SyncVectorEnv` or `AsyncVectorEnv`)"
    )
    rows = [
        ("class", f"{{py:class}}`{cls.__module__}.{cls.__name__}`"),
        ("registered arguments", kwargs),
        ("native vector env", vector),
        ("plant", f"`{plant.name}`: {plant.source}"),
        (
            "action",
            f"`{env.action_space}`: the {plant.input_name} per axis over its limit "
            f"(`{plant.input_limit}`, {plant.input_unit})",
        ),
        (
            "observation",
            f"`Box` of shape {env.observation_space.shape}, {env.observation_space.dtype}, "
            f"bounded per field (`env.observation_space.low`, `high`); the fields below",
        ),
        ("control period `dt`", f"{env.dt:g} s"),
        ("episode steps", f"{env.episode_steps}"),
    ]
    if hasattr(env, "reward_scale"):
        rows.append(("reward scale", f"{env.reward_scale:g} mm (reward = -contour error / scale)"))
    learnable = entry.id.replace("-v1", "-v2")
    if learnable != entry.id and entry.contouring:
        rows.append(
            ("to learn on", f"[{learnable}]({learnable}.md): the drive's servo inside the step, a set-point action")
        )
    lines = [f"# {entry.id}", "", entry.summary + ".", ""]
    if picture:
        lines += [f"```{{image}} _img/{entry.id}.png", f":alt: the contour of {entry.id}", ":width: 420px", "```", ""]
    lines += [
        "```python",
        "import gymnasium as gym",
        "import vcnc_gym  # registers the ids",
        "",
        f'env = gym.make("{entry.id}")',
        "```",
        "",
        "| | |",
        "|---|---|",
    ]
    lines += [f"| {k} | {_md_cell(v)} |" for k, v in rows]
    lines += [
        "",
        "## Observation",
        "",
        "The fields of `env.unwrapped.layout`, in order (`env.unwrapped.layout.describe()`):",
        "",
        env.layout.describe().strip(),
        "",
        "## Plant parameters",
        "",
        "`env.unwrapped.plant.parameters`, the box `randomize=True` draws from:",
        "",
    ]
    lines += _parameter_table(plant)
    lines += [
        "",
        "## Full description",
        "",
        f"Episode end, reward terms, arguments and version history: the docstring of "
        f"{{py:class}}`{cls.__module__}.{cls.__name__}`.",
        "",
    ]
    return "\n".join(lines)


def write_env_pages(docs: Path) -> None:
    import gymnasium as gym

    import vcnc_gym  # noqa: F401  (registers the ids)
    from vcnc_gym.envs.registry import LEGACY, SUITE

    out = docs / "envs"
    index = [
        "# Environments",
        "",
        "Every id is registered by `import vcnc_gym` from one table, "
        "{py:data}`vcnc_gym.envs.registry.SUITE`; these pages are generated from it.",
        "",
        "| id | task |",
        "|---|---|",
    ]
    for entry in SUITE:
        env = gym.make(entry.id).unwrapped
        picture = _picture(env, out / "_img" / f"{entry.id}.png")
        _write(out / f"{entry.id}.md", _env_page(entry, env, picture))
        env.close()
        index.append(f"| [{entry.id}]({entry.id}.md) | {_md_cell(entry.summary)} |")
    learnable, legacy = _learnable_and_legacy_pages(out)
    index += [
        "",
        "## Learnable ids (v2)",
        "",
        "The ids to learn on: the same tasks, the drive's servo closed inside the step under a set-point action "
        "every 1 ms, the observation scaled to order one, the reward clipped at 100 um.",
        "",
        "| id | task |",
        "|---|---|",
    ]
    index += [f"| [{e.id}]({e.id}.md) | {_md_cell(e.summary)} |" for e in learnable]
    index += [
        "",
        "## Legacy ids",
        "",
        "Still registered so that agents trained on them keep running; `vcnc-bench` runs the current ids.",
        "",
        "| id | task |",
        "|---|---|",
    ]
    index += [
        f"| [{e.id}]({e.id}.md) | {_md_cell(e.summary)} |" if e in legacy else f"| `{e.id}` | {_md_cell(e.summary)} |"
        for e in LEGACY
    ]
    pages = [e.id for e in SUITE] + [e.id for e in learnable] + [e.id for e in legacy]
    index += ["", "```{toctree}", ":hidden:", ""] + pages + ["```", ""]
    _write(out / "index.md", "\n".join(index))


def _learnable_and_legacy_pages(out: Path) -> tuple[list, list]:
    """The pages of the learnable ids (v2) and of the v0 contouring ids (:mod:`vcnc_env_pages`): the entries
    written, each list in the registry's order."""
    import gymnasium as gym

    import vcnc_env_pages
    from vcnc_gym.envs.registry import LEARNABLE, LEGACY, SUITE

    ids = {e.id: e for e in SUITE + LEARNABLE + LEGACY}
    written = []
    for entry in LEARNABLE:
        env = gym.make(entry.id).unwrapped
        vcnc_env_pages.write_frame(entry.id, out / "_img" / f"{entry.id}-frame.png")
        v1 = ids[entry.id.replace("-v2", "-v1")].kwargs
        _write(out / f"{entry.id}.md", vcnc_env_pages.learnable_page(entry, env, v1, ids, _parameter_table, True))
        env.close()
        written.append(entry)
    legacy = []
    for entry in LEGACY:
        if entry.id.endswith("-v0") and entry.id.replace("-v0", "-v2") in ids:
            env = gym.make(entry.id).unwrapped
            _write(out / f"{entry.id}.md", vcnc_env_pages.legacy_page(entry, env, ids))
            env.close()
            legacy.append(entry)
    return written, legacy


# -- controllers ------------------------------------------------------------------------------------


def _first_paragraph(obj) -> str:
    doc = inspect.getdoc(obj) or ""
    return " ".join(doc.split("\n\n")[0].split())


def write_controllers_page(docs: Path) -> None:
    from vcnc_baselines import registry

    by_family: dict[str, list[str]] = {f: [] for f in FAMILIES}
    for name in registry.REGISTRY:
        family = registry.policy_class(name).__module__.split(".")[1]
        by_family.setdefault(family, []).append(name)
    lines = [
        "# Controllers",
        "",
        "The classical controllers, as policies with Stable-Baselines3's `predict`, built for an env by "
        'name: `vcnc_baselines.make("qft", env)` ({py:func}`vcnc_baselines.registry.make`).  They are grouped by '
        "the family folders of `baselines/`.  Generated from {py:data}`vcnc_baselines.registry.REGISTRY` and "
        "{py:data}`vcnc_baselines.registry.VARIANTS`.",
        "",
        "```python",
        "import gymnasium as gym",
        "import vcnc_baselines",
        "import vcnc_gym",
        "",
        'env = gym.make("VCNC-Heart-v1")',
        'policy = vcnc_baselines.make("qft", env)',
        "action, _ = policy.predict(env.reset(seed=0)[0])",
        "```",
        "",
    ]
    for family, names in by_family.items():
        if not names:
            continue
        package = importlib.import_module(f"vcnc_baselines.{family}")
        lines += [
            f"## {FAMILIES.get(family, family)}",
            "",
            _first_paragraph(package),
            "",
            "| name | class | what |",
            "|---|---|---|",
        ]
        for name in names:
            cls = registry.REGISTRY[name]
            lines.append(
                f"| `{name}` | {{py:class}}`~{cls.__module__}.{cls.__name__}` | {_md_cell(_first_paragraph(cls))} |"
            )
        lines.append("")
    lines += [
        "## Variants",
        "",
        "A registered controller with some of its parameters fixed, benchmarked under its own name.",
        "",
        "| name | controller | fixed parameters |",
        "|---|---|---|",
    ]
    for name, (base, fixed) in registry.VARIANTS.items():
        fixed_text = ", ".join(f"`{k}={v!r}`" for k, v in fixed.items())
        lines.append(f"| `{name}` | `{base}` | {_md_cell(fixed_text)} |")
    lines.append("")
    _write(docs / "controllers.md", "\n".join(lines))


# -- API reference ----------------------------------------------------------------------------------


def public_modules(package: str) -> list[str]:
    """``package`` and its modules and subpackages, none private (``_x``) nor ``__main__``, sorted."""
    pkg = importlib.import_module(package)
    names = [package]
    for info in pkgutil.walk_packages(pkg.__path__, prefix=package + "."):
        parts = info.name.split(".")
        if any(p.startswith("_") for p in parts):
            continue
        names.append(info.name)
    return sorted(names)


def write_api_pages(docs: Path) -> None:
    out = docs / "api"
    index = [
        "# API reference",
        "",
        "Generated from the numpydoc docstrings (autodoc and napoleon); one page per package, a section per module.",
        "",
        "```{toctree}",
        ":maxdepth: 1",
        "",
    ]
    for package, heading in API_PACKAGES.items():
        lines = [heading, "=" * len(heading), ""]
        for module in public_modules(package):
            lines += [f"``{module}``", "-" * (len(module) + 4), "", f".. automodule:: {module}", ""]
        _write(out / f"{package}.rst", "\n".join(lines))
        index.append(package)
    index += ["```", ""]
    _write(out / "index.md", "\n".join(index))


def _generate(app) -> None:
    import time

    docs = Path(app.srcdir)
    start = time.perf_counter()
    write_env_pages(docs)
    write_controllers_page(docs)
    write_api_pages(docs)
    print(f"vcnc_pages: env, controller and API pages generated in {time.perf_counter() - start:.1f} s")


def setup(app):
    app.connect("builder-inited", _generate)
    return {"version": "1", "parallel_read_safe": True, "parallel_write_safe": True}
