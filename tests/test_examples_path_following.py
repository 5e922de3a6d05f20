"""examples/tof_following_on_ur10e.py runs as a user would run it, and follows its hose."""

import re
import subprocess
import sys

import pytest
from conftest import REPO


@pytest.mark.slow
def test_tof_following_on_ur10e_example():
    example = REPO / "examples" / "tof_following_on_ur10e.py"
    run = subprocess.run(
        [sys.executable, str(example)], capture_output=True, text=True, timeout=300, cwd=REPO
    )
    assert run.returncode == 0, run.stdout + run.stderr
    coverage = float(re.search(r"^coverage: ([0-9.]+)$", run.stdout, re.M).group(1))
    tracking = re.search(r"^tracking error mean / max: ([0-9.]+) / ([0-9.]+) mm$", run.stdout, re.M)
    assert coverage >= 0.95
    assert float(tracking.group(2)) <= 25.0  # within the 25 mm the coverage counts
    assert "failure: none" in run.stdout
