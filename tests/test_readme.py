"""The README's quick start runs as printed (examples rot unless something runs them)."""

import pathlib
import re


def test_readme_quick_start_runs(capsys):
    text = (pathlib.Path(__file__).parents[1] / "README.md").read_text()
    code = re.findall(r"```python\n(.*?)```", text, re.S)[0]
    exec(compile(code, "README.md", "exec"), {})
    out = capsys.readouterr().out
    error_um = float(re.search(r"final contour error ([0-9.]+) um", out).group(1))
    assert error_um < 20.0
