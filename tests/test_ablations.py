"""``experiments/ablations/ablations.py`` (issue 33, item 5): every family's variants change one thing of the agent's recipe, and
the stored table's figures are the IQM an independent computation (scipy's trimmed mean) gives."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from benchmark_script import study_script

ROOT = Path(__file__).resolve().parents[1]
FAMILIES = [
    ("specialists.yml", "VCNC-OmegaLookahead-v1"),
    ("generalists.yml", "VCNC-RandomContour-v1"),
    ("override.yml", "VCNC-OmegaOverride-v1"),
]


def _ablations():
    return study_script("ablations", "ablations")


def _differences(a, b, path=()):
    """The key paths where two nested entries differ (written here, not the module's)."""
    if isinstance(a, dict) and isinstance(b, dict):
        return [d for k in sorted(set(a) | set(b)) for d in _differences(a.get(k), b.get(k), path + (k,))]
    if isinstance(a, list) and isinstance(b, list) and len(a) == len(b):
        return [d for i, (x, y) in enumerate(zip(a, b)) for d in _differences(x, y, path + (i,))]
    return [] if a == b else [path]


@pytest.mark.parametrize("recipe, env_id", FAMILIES)
def test_each_variant_changes_one_thing_of_the_recipe(recipe, env_id):
    """Per family: the agent is its recipe's entry; ``no-preview`` changes only the env's two preview arguments,
    ``direct`` only the action mode (the same decision period), ``repeat-R`` only the decision period (half and twice)
    and ``correction-C`` only the bound (a quarter and five times, at most 1)."""
    from vcnc_agents.config import load_hyperparameters

    module = _ablations()
    entry = load_hyperparameters(env_id, ROOT / "agents" / "hyperparams" / recipe)
    out = module.variants(entry)
    assert out["agent"] == entry
    wrapper = entry["env_wrapper"][0]["vcnc_agents.action_modes.ResidualAction"]
    repeat, bound = wrapper["action_repeat"], wrapper["correction"]
    assert set(out) == {
        "agent",
        "direct",
        "no-preview",
        f"repeat-{max(1, repeat // 2)}",
        f"repeat-{2 * repeat}",
        f"correction-{bound / 4:g}",
        f"correction-{min(1.0, 5 * bound):g}",
    }
    assert _differences(entry, out["no-preview"]) == [("env_kwargs", "contour_ahead"), ("env_kwargs", "preview_steps")]
    for name, variant in out.items():
        changed = _differences(entry, variant)
        if name.startswith(("repeat-", "correction-")):
            key = "action_repeat" if name.startswith("repeat-") else "correction"
            assert changed == [("env_wrapper", 0, "vcnc_agents.action_modes.ResidualAction", key)], name
        elif name == "direct":
            # the env itself holds the amplifier command for the agent's decision period; no residual wrapper
            assert set(changed) <= {("env_kwargs", "action_repeat"), ("env_wrapper",)}, changed
            assert variant["env_kwargs"].get("action_repeat", 1) == repeat
            assert "ResidualAction" not in json.dumps(variant.get("env_wrapper") or [])


def test_a_direct_entry_is_refused_by_name():
    from vcnc_agents.action_modes import ActionMode
    from vcnc_agents.config import load_hyperparameters, with_action_mode

    module = _ablations()
    entry = load_hyperparameters("VCNC-OmegaLookahead-v1", ROOT / "agents" / "hyperparams" / "specialists.yml")
    with pytest.raises(ValueError, match="direct"):
        module.variants(with_action_mode(entry, ActionMode("direct", action_repeat=10)))


def test_the_stored_table_gives_the_iqm_of_the_seeds_records():
    """The omega's stored ablation run: each variant's row in the printed table is the IQM (25 % trimmed mean) of
    its seeds' sampled-plant figures, as scipy computes it."""
    from scipy.stats import trim_mean

    module = _ablations()
    data = json.loads((ROOT / "experiments" / "ablations" / "data" / "VCNC-OmegaLookahead-v1.json").read_text())
    lines = module.table(data)
    rows = {
        (c[1].strip(), c[3].split(",")[0].strip()): c
        for line in lines
        if line.startswith("| ")
        for c in [line.split("|")]
        if len(c) > 5
    }
    for name, group in data["ablations"].items():
        records = [r for r in data["robust"] if r.get("group") == group]
        for figure in ("max", "rms"):
            values = np.concatenate(
                [
                    [v for v, kind in zip(r["per_plant"][f"{figure}_um"], r["per_plant"]["kind"]) if kind == "sample"]
                    for r in records
                ]
            )
            iqm = float(rows[(name, figure)][4].split("[")[0])
            assert iqm == pytest.approx(trim_mean(values, 0.25), rel=1e-3), (name, figure)


def test_the_override_family_is_judged_on_its_final_agents_and_on_cycle_time():
    """``--which final`` hands the bench every seed's ``final`` agent (the bench's ``ppo`` kind expands
    ``FOLDER/final``), and an override id adds the cycle time to the figures; a contouring id does not."""
    from vcnc_bench.kinds.ppo import KIND

    module = _ablations()
    folder = ROOT / "experiments" / "ablations" / "seeds" / "override_1M" / "VCNC-OmegaOverride-v1"
    spec = module.agents_spec(folder, "final")
    agents = KIND.expand(spec.split(":", 1)[1])
    assert [Path(a).parent.name for a in agents] == ["seed0", "seed1", "seed2"]
    assert all(Path(a).name == "final" for a in agents)
    assert module.agents_spec(folder) == f"ppo:{folder}"
    assert module.without_agent(folder, "final") is None
    assert module.figures_of("VCNC-OmegaOverride-v1") == ["max", "rms", "cycle"]
    assert module.figures_of("VCNC-Heart-v1") == ["max", "rms"]
