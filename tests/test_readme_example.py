"""The README's Python example runs as written and does what it says."""

from __future__ import annotations

import re

from conftest import REPO


def test_readme_example_runs(capsys):
    readme = (REPO / "README.md").read_text()
    block = re.search(r"<!-- example:start -->\s*```python\n(.*?)```", readme, re.DOTALL)
    assert block, "README lost its example markers"
    exec(compile(block.group(1), "README.md", "exec"), {})
    out = capsys.readouterr().out
    low, high = map(float, re.search(r"between (\S+) and (\S+) rad", out).groups())
    # pi/4 +- 0.3 rad, tracked by the servo within a few milliradians.
    assert abs(low - (0.7854 - 0.3)) < 0.01 and abs(high - (0.7854 + 0.3)) < 0.01
