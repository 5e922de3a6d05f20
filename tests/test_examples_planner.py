"""examples/planner_on_mz04d.py runs as a user runs it, its planner ends within 1 mm and
its replay page holds the waypoint overlays and the arm's motion."""

from __future__ import annotations

import re
import subprocess
import sys

from conftest import REPO
from replay_commands import Replay


def test_planner_on_mz04d_example_ends_within_1_mm(tmp_path):
    script = REPO / "examples" / "planner_on_mz04d.py"
    page = tmp_path / "replay.html"
    result = subprocess.run(
        [sys.executable, str(script), str(page)],
        cwd=REPO,
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert result.returncode == 0, result.stdout + result.stderr
    error_mm = float(re.search(r"final TCP error \(measured arm\): (\S+) mm", result.stdout)[1])
    task_end_s = float(re.search(r"task ended at T = (\S+) s", result.stdout)[1])
    assert error_mm < 1.0
    assert 0 < task_end_s < 5.0  # ended, and the arm then settled until 5 s
    replay = Replay(page)
    assert len(replay.Paths("/overlays/waypoints/")) >= 3
    assert any(path.startswith("/drake/") and "mz04d" in path for path, _ in replay.tracks)
