"""The env pages of the learnable ids and of the v0 ids (docs/_ext/vcnc_env_pages.py), and their training snippet.

The pages are generated at build time (``make docs``); here the generator runs on its own: the v2 heart's page has
Gymnasium's sections with this id's figures, the v0 heart's page says what to use instead, and the page's
Stable-Baselines3 snippet runs (with few steps).
"""

from __future__ import annotations

import re
import sys
from pathlib import Path

import gymnasium as gym
import pytest

import vcnc_gym  # noqa: F401  (registers the ids)
from vcnc_gym.envs.registry import LEARNABLE, LEGACY, SUITE

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "docs" / "_ext"))

import vcnc_env_pages  # noqa: E402
import vcnc_pages  # noqa: E402

IDS = {e.id: e for e in SUITE + LEARNABLE + LEGACY}
SECTIONS = (
    "Description",
    "Action Space",
    "Observation Space",
    "Rewards",
    "Starting State",
    "Episode End",
    "Arguments",
    "Rendering",
    "Training with Stable-Baselines3",
    "Version History",
)


def _page(env_id: str) -> tuple[str, object]:
    env = gym.make(env_id).unwrapped
    v1 = IDS[env_id.replace("-v2", "-v1")].kwargs
    return vcnc_env_pages.learnable_page(IDS[env_id], env, v1, IDS, vcnc_pages._parameter_table, True), env


def test_the_v2_heart_page_has_gymnasiums_sections_with_this_ids_figures():
    page, env = _page("VCNC-Heart-v2")
    headings = re.findall(r"^## (.+)$", page, re.M)
    assert [h for h in headings if h in SECTIONS] == list(SECTIONS)
    assert f"`setpoint_range` = {env.task.setpoint_range:.6g} mm" in page
    assert "_img/VCNC-Heart-v2-frame.png" in page
    for f in env.layout.fields:  # every field with its scale and unit, as layout.describe() gives them
        assert f"| {f.name} | {f.unit} | {f.scale:g} |" in page
    assert 'base="ff-pid"' in page and 'action="voltage"' in page
    assert "[VCNC-Heart-v1](VCNC-Heart-v1.md)" in page and "[VCNC-Heart-v0](VCNC-Heart-v0.md)" in page
    history = page.split("## Version History", 1)[1]
    assert "1 603" in history and "**v2**" in history and "**v1**" in history and "**v0**" in history
    assert "between -10 and 0" in page and "3222 decisions" in page


def test_a_shop_floor_page_names_its_commissioned_servo_and_has_no_v0():
    page, env = _page("VCNC-HeartShop-v2")
    assert env.task.servo_gains.key in page and "a notch at the structural mode" in page
    assert "no v0" in page and "shop_floor" in page.split("## Version History", 1)[1]


def test_the_v0_heart_page_says_what_to_use_instead_without_inverted_ranges():
    env = gym.make("VCNC-Heart-v0").unwrapped
    page = vcnc_env_pages.legacy_page(IDS["VCNC-Heart-v0"], env, IDS)
    assert "[VCNC-Heart-v2](VCNC-Heart-v2.md)" in page and "[VCNC-Heart-v1](VCNC-Heart-v1.md)" in page
    ranges = [(int(a), int(b)) for a, b in re.findall(r"^\| (\d+)-(\d+) \|", page, re.M)]
    assert ranges and all(a < b for a, b in ranges)
    assert "contour_preview" not in env.layout.describe() and "| 19-20 | previous_action |" in page


def test_the_index_has_the_learnable_ids_and_a_v1_page_points_to_its_v2(tmp_path, monkeypatch):
    """The generator's own pages (every learnable id, the v0 contouring ids) are written by ``make docs``."""
    from vcnc_gym.envs import registry

    calls = []
    monkeypatch.setattr(vcnc_pages, "_learnable_and_legacy_pages", lambda out: calls.append(out) or ([], []))
    monkeypatch.setattr(registry, "SUITE", (IDS["VCNC-Heart-v1"],))  # one v1 page
    vcnc_pages.write_env_pages(tmp_path)  # the v1 page and the index, the learnable pages stubbed
    assert calls == [tmp_path / "envs"]
    index = (tmp_path / "envs" / "index.md").read_text()
    assert "## Learnable ids (v2)" in index
    heart_v1 = (tmp_path / "envs" / "VCNC-Heart-v1.md").read_text()
    assert "[VCNC-Heart-v2](VCNC-Heart-v2.md)" in heart_v1


def test_the_frame_is_a_png_of_the_render(tmp_path):
    path = tmp_path / "frame.png"
    vcnc_env_pages.write_frame("VCNC-Circle-v2", path)
    import matplotlib.image

    assert matplotlib.image.imread(path).shape[:2] == (360, 800)
    mtime = path.stat().st_mtime_ns
    vcnc_env_pages.write_frame("VCNC-Circle-v2", path)  # kept: the build's cache
    assert path.stat().st_mtime_ns == mtime


def test_the_training_snippet_is_ten_lines_of_code():
    code = [line for line in vcnc_env_pages.training_snippet("VCNC-Heart-v2").splitlines() if line.strip()]
    assert len(code) <= 13 and sum(not line.startswith(("import", "from")) for line in code) <= 8


@pytest.fixture
def one_torch_thread():
    torch = pytest.importorskip("torch")
    threads = torch.get_num_threads()
    torch.set_num_threads(1)  # two shared cores: torch's second thread waits for the other processes
    yield
    torch.set_num_threads(threads)


def _run_snippet(env_id: str, steps: int, capsys, fast: bool) -> str:
    pytest.importorskip("stable_baselines3")
    code = vcnc_env_pages.training_snippet(env_id, steps)
    if fast:  # one short rollout instead of SB3's default 2048 steps per env
        code = code.replace('PPO("MlpPolicy", env, seed=0)', 'PPO("MlpPolicy", env, seed=0, n_steps=32, batch_size=64)')
        assert "n_steps=32" in code
    exec(compile(code, "training_snippet", "exec"), {"__name__": "snippet"})
    return capsys.readouterr().out


def test_the_training_snippet_runs(capsys, one_torch_thread):
    out = _run_snippet("VCNC-Circle-v2", 128, capsys, fast=True)
    assert "'contour_error_max'" in out and "'completed'" in out


@pytest.mark.slow  # one rollout of SB3's defaults (4 x 2048 steps), its update and an episode: minutes on 2 cores
def test_the_training_snippet_runs_as_written(capsys, one_torch_thread):
    out = _run_snippet("VCNC-Circle-v2", 8192, capsys, fast=False)
    assert "'diverged'" in out
