"""The Python examples of README.md and docs/api.md (the blocks between
`<!-- example:start -->` and `<!-- example:end -->`) run as written and do what they say."""

from __future__ import annotations

import re

from conftest import REPO

from guidedarm.diagrams.panel.panel_files import DEFAULT_PANEL_FILE, LoadPanelSpec


def _examples(relative_path: str) -> list[str]:
    text = (REPO / relative_path).read_text()
    blocks = re.findall(r"<!-- example:start -->\s*```python\n(.*?)```", text, re.DOTALL)
    assert blocks, f"{relative_path} lost its example markers"
    return blocks


def _run(block: str, name: str, capsys) -> str:
    exec(compile(block, name, "exec"), {})
    return capsys.readouterr().out


def test_readme_example_presses_the_switch(capsys):
    (block,) = _examples("README.md")
    code = [line for line in block.splitlines() if line.strip()]
    assert len([line for line in code if not line.startswith("from ")]) <= 22  # stays short
    out = _run(block, "README.md", capsys)
    travel_mm = float(re.search(r"switch 2 pressed in by (\S+) mm", out).group(1))
    switch = LoadPanelSpec(DEFAULT_PANEL_FILE).switches[1]
    assert 1000 * switch.on_travel_m <= travel_mm <= 1000 * switch.travel_m


def test_api_doc_examples_run(capsys):
    station, plant = _examples("docs/api.md")
    out = _run(station, "docs/api.md", capsys)
    low, high = map(float, re.search(r"between (\S+) and (\S+) rad", out).groups())
    # pi/4 +- 0.3 rad, tracked by the servo within a few milliradians.
    assert abs(low - (0.7854 - 0.3)) < 0.01 and abs(high - (0.7854 + 0.3)) < 0.01
    out = _run(plant, "docs/api.md", capsys)
    count, *p_WT = re.findall(r"-?\d+\.?\d*(?:e-?\d+)?", out)
    assert int(count) == 6  # the arm's joints only: the gripper is welded, the rover dropped
    assert 0.5 < float(p_WT[0]) < 1.5 and float(p_WT[2]) > 0.3  # ahead of and above the rover
