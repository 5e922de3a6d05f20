"""The replay page opens offline in headless Chromium and shows the robot."""

from __future__ import annotations

import numpy as np
import pytest
from browser import CHROMIUM, MISSING, Screenshot
from pydrake.geometry import Meshcat

pytestmark = pytest.mark.skipif(CHROMIUM is None, reason=MISSING)


def test_replay_page_shows_the_robot_offline(tmp_path, run_cli):
    code, _, _ = run_cli("run", "ur10e_joint_tour", "--out", tmp_path / "run")
    assert code == 0
    empty = tmp_path / "empty.html"
    empty.write_text(Meshcat().StaticHtml())
    with_robot = Screenshot(tmp_path / "run" / "replay.html", tmp_path / "replay")
    without_robot = Screenshot(empty, tmp_path / "empty")
    changed = np.linalg.norm(with_robot - without_robot, axis=2) > 25
    # The page is not a blank canvas: the arm (about 1 % of an 800 x 600 view from
    # Meshcat's default camera) differs from the empty scene.
    assert with_robot.std() > 5
    assert changed.mean() > 0.004, f"only {changed.mean():.4f} of the pixels show the arm"
