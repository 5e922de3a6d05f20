"""The replay page opens offline in headless Chromium and shows the robot."""

from __future__ import annotations

import shutil
import subprocess

import cv2
import numpy as np
import pytest
from pydrake.geometry import Meshcat

CHROMIUM = shutil.which("chromium")

pytestmark = pytest.mark.skipif(
    CHROMIUM is None, reason="Debian chromium missing: `make test` installs it"
)


def screenshot(page, tmp_path, name: str) -> np.ndarray:
    png = tmp_path / f"{name}.png"
    subprocess.run(
        [
            CHROMIUM,
            "--headless",
            "--no-sandbox",
            "--disable-gpu",
            "--use-angle=swiftshader",
            "--enable-unsafe-swiftshader",
            "--disable-background-networking",
            "--disable-component-update",
            "--disable-sync",
            "--no-first-run",
            f"--user-data-dir={tmp_path / name}",
            "--window-size=800,600",
            "--virtual-time-budget=8000",
            f"--screenshot={png}",
            page.as_uri(),
        ],
        check=True,
        capture_output=True,
        timeout=120,
    )
    return cv2.imread(str(png)).astype(float)


def test_replay_page_shows_the_robot_offline(tmp_path, run_cli):
    code, _, _ = run_cli("run", "ur10e_joint_tour", "--out", tmp_path / "run")
    assert code == 0
    empty = tmp_path / "empty.html"
    empty.write_text(Meshcat().StaticHtml())
    with_robot = screenshot(tmp_path / "run" / "replay.html", tmp_path, "replay")
    without_robot = screenshot(empty, tmp_path, "empty")
    changed = np.linalg.norm(with_robot - without_robot, axis=2) > 25
    # The page is not a blank canvas: the arm (about 1 % of an 800 x 600 view from
    # Meshcat's default camera) differs from the empty scene.
    assert with_robot.std() > 5
    assert changed.mean() > 0.004, f"only {changed.mean():.4f} of the pixels show the arm"
