"""The robustness probes of ``tests/probes/`` that no other test runs, in a short run (``tests/probes/README.md``)."""

from __future__ import annotations

from benchmark_script import probe_script


def test_the_largest_inputs_are_refused_within_a_second(capsys):
    """``tests/probes/refusal_times.py`` with a small zip bomb (0.05 GB inflated; the full run's is 4 GB): every case
    is refused, each within 1 s."""
    assert probe_script("refusal_times").main(["--bomb-gb", "0.05"]) == 0
    out = capsys.readouterr().out
    assert "OK: every case refused within 1 s" in out and "NOT refused" not in out
