"""vcnc_agents.run_folder.check_writable: a run folder that cannot be written is refused before a resume writes."""

from __future__ import annotations

import os

import pytest

from vcnc_agents.run_folder import check_writable


def test_a_run_folder_that_cannot_be_written_is_named(tmp_path, monkeypatch):
    (tmp_path / "checkpoints").mkdir()
    check_writable(tmp_path)
    locked = tmp_path / "checkpoints"
    real = os.access
    monkeypatch.setattr(os, "access", lambda p, mode: False if str(p) == str(locked) else real(p, mode))
    with pytest.raises(ValueError, match=f"{locked} is not writable"):
        check_writable(tmp_path)
