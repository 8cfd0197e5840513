"""A short run of tests/probes/fuzz_new_surfaces.py, a check that it can fail, and a kill and resume of the lean
trainer audited by tests/probes/kill_and_resume.py (the full runs: ``python tests/probes/fuzz_new_surfaces.py
--kill-resume``)."""

from __future__ import annotations

import sys

import numpy as np
import pytest
from benchmark_script import PROBES as _DIR
from benchmark_script import probe_script as _load

fuzz = _load("fuzz_new_surfaces")


@pytest.mark.slow  # ~30 s: programs through the reader, an override episode
def test_random_programs_settings_specs_and_override_actions_give_clear_errors_or_sound_results():
    rng = np.random.default_rng(1)
    failures: list = []
    programs = fuzz.fuzz_programs(40, rng, failures)
    settings = fuzz.fuzz_shop_floor(60, rng, failures)
    specs = fuzz.fuzz_specs(60, rng, failures)
    override = fuzz.fuzz_override(1, rng, failures)
    assert failures == []
    assert programs["read"] > 0 and programs["clear error"] > 0
    assert settings["built"] > 0 and settings["clear error"] > 0 and specs["clear error"] > 0
    assert override["steps"] > 100


def test_the_fuzz_counts_an_accepted_bad_setting_and_a_raw_exception(monkeypatch):
    """The check can fail: a shop floor that takes anything, a reader that raises something else."""
    import vcnc_gym.gcode
    import vcnc_gym.plants.shop_floor as sf

    monkeypatch.setattr(sf, "shop_floor", lambda plant, settings: None)
    failures: list = []
    fuzz.fuzz_shop_floor(30, np.random.default_rng(0), failures)
    assert any("accepted" in f[2] for f in failures)

    def broken(*args, **kwargs):
        raise RuntimeError("not a clear error")

    monkeypatch.setattr(vcnc_gym.gcode, "read_program", broken)
    failures = []
    fuzz.fuzz_programs(3, np.random.default_rng(0), failures)
    assert len(failures) == 3 and all("RuntimeError" in f[2] for f in failures)


@pytest.mark.slow  # two vcnc-train subprocesses, ~1 min
def test_a_killed_lean_run_resumes_with_no_row_lost_or_duplicated(tmp_path):
    sys.path.insert(0, str(_DIR))
    try:
        kill_and_resume = _load("kill_and_resume")
    finally:
        sys.path.remove(str(_DIR))
    report = kill_and_resume.kill_and_resume(tmp_path, timesteps=4096, kill_after=1024, trainer="lean")
    audit = report["audit"]
    assert report["pre_checkpoint_rows_unchanged"]
    for m in audit["monitor"].values():
        assert m["chain_breaks"] == 0 and m["duplicates"] == 0 and not m["tail_lost"], audit
    e = audit["evaluations"]
    assert e["increasing"] and e["duplicates"] == 0 and e["steps"][-1] == 4096
