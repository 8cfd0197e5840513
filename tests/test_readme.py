"""The README: its code runs as printed, its tables are the registry's and the shipped leaderboard's, it stays short,
and its links to the glossary land on a definition.  Examples and tables rot unless something checks them."""

from __future__ import annotations

import json
import math
import re
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
README = ROOT / "README.md"
GLOSSARY = ROOT / "docs" / "glossary.md"
LEADERBOARD = ROOT / "docs" / "leaderboard.json"

#: An env id as the README writes it.
_ID = re.compile(r"VCNC-[A-Za-z0-9]+-v\d+")


def _text() -> str:
    return README.read_text()


def _python_blocks() -> list[str]:
    return re.findall(r"```python\n(.*?)```", _text(), re.S)


def _table(heading: str) -> list[str]:
    """The rows (lines) of the first Markdown table under the section ``## heading``, header and rule left out."""
    section = _text().split(f"\n## {heading}\n", 1)[1].split("\n## ", 1)[0]
    rows = [line for line in section.splitlines() if line.startswith("|")]
    return rows[2:]


def slug(heading: str) -> str:
    """The anchor GitHub and MyST give a heading: lower case, punctuation dropped, spaces as hyphens."""
    return re.sub(r"[^\w\- ]", "", heading.strip().lower()).replace(" ", "-")


def test_the_readme_reads_in_ten_minutes():
    text = _text()
    assert len(text.splitlines()) <= 200, "README.md: at most 200 lines"
    assert len(text) <= 16_000, "README.md: at most 16 000 characters"


def test_the_quick_start_runs(capsys):
    exec(compile(_python_blocks()[0], "README.md", "exec"), {})
    out = capsys.readouterr().out
    error_um = float(re.search(r"max contour error ([0-9.]+) um", out).group(1))
    assert error_um < 3.0, out


@pytest.mark.slow  # a PPO rollout of 4 x 2 048 decisions and an episode of the heart: minutes on 2 busy cores
def test_the_stable_baselines3_snippet_trains(capsys):
    import gymnasium as gym

    import vcnc_gym  # noqa: F401  (registers the ids)

    if "VCNC-Heart-v2" not in gym.registry:
        pytest.skip("VCNC-Heart-v2 (the learnable heart) is not registered in this tree")
    code = _python_blocks()[1]
    assert "total_timesteps=300_000" in code
    exec(compile(code.replace("total_timesteps=300_000", "total_timesteps=2_048"), "README.md", "exec"), {})
    out = capsys.readouterr().out
    error_um = float(re.search(r"PPO: max contour error ([0-9.a-z]+) um", out).group(1))
    assert math.isfinite(error_um), out


def test_the_catalogue_is_the_registry():
    """Every current id once, and nothing else: the table cannot drift from ``vcnc_gym.envs.registry``."""
    from vcnc_gym.envs import registry

    current = {e.id for e in registry.SUITE} | {e.id for e in getattr(registry, "LEARNABLE", ())}
    named = [i for row in _table("The environments") for i in _ID.findall(row)]
    assert len(named) == len(set(named)), "an id named twice in the catalogue"
    assert set(named) == current, (
        f"missing from the README's catalogue: {sorted(current - set(named))}; "
        f"not current ids: {sorted(set(named) - current)}"
    )


def _fig(x: float) -> str:
    return f"{x:.3g}"


def results_row(env_id: str, rows: list[dict]) -> str:
    """The README's results row of ``env_id`` from the leaderboard's rows: the strongest causal controller, the best
    learned controller and the non-causal lower bound on the nominal plant (max contour error, um), and the learned
    controller's verdicts over the plants."""
    ran = [r for r in rows if r["env"] == env_id and r["max_um"] is not None]

    def best(role: str) -> dict:
        return min((r for r in ran if r["role"] == role), key=lambda r: (r["max_um"], r["rms_um"]))

    classical, learned, bound = best("classical"), best("learned or yours"), best("floor")
    seeds = re.search(r"\((\d+) seeds\)", learned["policy"])
    k = int(seeds.group(1)) if seeds else 1
    verdicts = "; ".join(
        f"{label}: {learned['verdicts'][key]['outcome']} against `{learned['verdicts'][key]['opponent']}`"
        for key, label in (("max", "max"), ("rms", "RMS"))
    )
    return (
        f"| `{env_id}` | `{classical['policy']}` {_fig(classical['max_um'])} | {_fig(learned['max_um'])} "
        f"({k} seed{'s' if k > 1 else ''}) | {_fig(bound['max_um'])} | {verdicts} |"
    )


def test_the_results_are_the_shipped_leaderboards():
    """The results table says what ``docs/leaderboard.json`` holds; on a mismatch the message is the table to paste."""
    rows = json.loads(LEADERBOARD.read_text())["rows"]
    table = _table("Results")
    assert table, "README.md has no results table"
    expected = [results_row(_ID.search(row).group(0), rows) for row in table]
    assert table == expected, "README.md's results table should read:\n" + "\n".join(expected)


def test_the_field_s_words_link_to_their_definition():
    text = _text()
    anchors = {slug(h) for h in re.findall(r"^###? (.+)$", GLOSSARY.read_text(), re.M)}
    links = re.findall(r"\]\(docs/glossary\.md#([\w-]+)\)", text)
    assert set(links) <= anchors, f"README links to glossary anchors that do not exist: {set(links) - anchors}"
    for term in ("non-causal-lower-bound", "parameter-uncertainty-set", "commissioned-per-machine", "feed-override"):
        assert term in links, f"README.md does not link {term!r} to the glossary"


def test_the_readme_tells_no_history():
    text = _text()
    assert not re.search(r"\bissues? #?\d+", text, re.I), "README.md names an issue number"
    assert "superseded" not in text.lower(), "README.md keeps a superseded result"
