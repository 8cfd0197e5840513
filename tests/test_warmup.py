"""python -m vcnc_gym.warmup: compiles (or loads) an env's kernels in a fresh process, reports failures."""

from __future__ import annotations

import pytest

from vcnc_gym import warmup
from vcnc_gym.envs.registry import suite_env


def test_warmup_makes_resets_and_steps_each_env(monkeypatch, capsys):
    monkeypatch.setattr(warmup, "SUITE", (suite_env("VCNC-Heart-v1"), suite_env("VCNC-Step-v0")))
    assert warmup.main(["--jobs", "2"]) == 0
    out = capsys.readouterr().out
    assert "VCNC-Heart-v1" in out and "VCNC-Step-v0" in out and "FAILED" not in out


def test_warmup_reports_a_failing_env(monkeypatch, capsys):
    monkeypatch.setattr(warmup, "SUITE", (suite_env("VCNC-Heart-v1"),))
    monkeypatch.setattr(warmup, "_ONE", "raise SystemExit('kernel broke')")
    assert warmup.main(["--jobs", "1"]) == 1
    captured = capsys.readouterr()
    assert "FAILED" in captured.out and "kernel broke" in captured.err


@pytest.mark.parametrize("jobs", ["0", "-1"])
def test_warmup_refuses_bad_jobs(jobs):
    with pytest.raises(SystemExit):
        warmup.main(["--jobs", jobs])


def test_warmup_takes_some_ids_and_names_an_unknown_one(monkeypatch, capsys):
    monkeypatch.setattr(warmup, "SUITE", (suite_env("VCNC-Heart-v1"), suite_env("VCNC-Step-v0")))
    assert warmup.main(["--jobs", "1", "--ids", "VCNC-Step-v0"]) == 0
    out = capsys.readouterr().out
    assert "VCNC-Step-v0" in out and "VCNC-Heart-v1" not in out
    with pytest.raises(SystemExit):
        warmup.main(["--ids", "VCNC-Nope-v1"])
    assert "--ids: VCNC-Nope-v1 not among the current ids" in capsys.readouterr().err
