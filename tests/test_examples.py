"""The examples in examples/ run as a user runs them: scripts as subprocesses (asserting the
numbers they print), pytest files through their own pytest run."""

from __future__ import annotations

import re
import subprocess
import sys

from conftest import REPO

EXAMPLES = REPO / "examples"


def _run(*args: str) -> str:
    result = subprocess.run(
        [sys.executable, *args], cwd=REPO, capture_output=True, text=True, timeout=300
    )
    assert result.returncode == 0, result.stdout + result.stderr
    return result.stdout


def test_marker_estimator_with_your_camera():
    out = _run(str(EXAMPLES / "marker_estimator_with_your_camera.py"))
    assert "markers [7, 42]" in out
    position_mm, rotation_deg = map(
        float, re.search(r"position error (\S+) mm, rotation error (\S+) deg", out).groups()
    )
    assert position_mm < 0.5 and rotation_deg < 0.3


def test_my_leaf_system_passes_its_own_pytest_run():
    out = _run(
        "-m", "pytest", "-q", "-p", "no:cacheprovider", str(EXAMPLES / "test_my_leaf_system.py")
    )
    assert re.search(r"\b2 passed\b", out), out
