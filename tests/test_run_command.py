"""`guidedarm run` end to end on the station smoke-test scenario, and `show`/`picture`."""

from __future__ import annotations

import json

import cv2
import numpy as np

from guidedarm.diagrams.tasks.registry import GetTask, NumericMetricNames


def test_joint_tour_writes_summary_plot_and_replay(tmp_path, run_cli):
    code, out, _ = run_cli("run", "ur10e_joint_tour", "--out", tmp_path)
    assert code == 0
    summary = json.loads((tmp_path / "summary.json").read_text())
    assert summary["task"] == "joint_tour" and summary["failure"] is None
    assert summary["sim_time_s"] > 3.0 and summary["wall_time_s"] > 0
    # The servo tracks the smooth tour closely and ends on the last waypoint.
    assert summary["tracking_error_max_rad"] < 0.01
    assert summary["final_error_rad"] < 1e-4
    assert NumericMetricNames(summary) == set(GetTask("joint_tour").KnownMetrics())
    replay = (tmp_path / "replay.html").read_text()
    assert "<html" in replay.lower() and len(replay) > 100_000
    assert (tmp_path / "joints.png").stat().st_size > 10_000
    assert "summary.json" in out


def test_override_changes_the_run(tmp_path, run_cli):
    code, _, _ = run_cli("run", "ur10e_joint_tour", "--out", tmp_path, "--set", "max_speed=2.0")
    assert code == 0
    fast = json.loads((tmp_path / "summary.json").read_text())
    assert fast["sim_time_s"] < 3.0


def test_joint_tour_fails_when_the_arm_lags_the_tour(tmp_path, run_cli):
    # A soft servo (kp = 1/s^2) ends near the start, where the tour ends too: the final
    # error alone would pass it; the tracking error along the tour fails it.
    code, _, err = run_cli(
        "run", "ur10e_joint_tour", "--out", tmp_path, "--set", "station.arms.ur10e.kp=1"
    )
    summary = json.loads((tmp_path / "summary.json").read_text())
    assert code == 1 and summary["success"] is False
    assert summary["tracking_error_max_rad"] > 0.05
    assert "max_tracking_error 0.05 rad" in summary["failure"]
    assert "max_tracking_error" in err


def test_show_writes_an_offline_page(tmp_path, run_cli):
    page = tmp_path / "mz04d.html"
    code, _, _ = run_cli("show", "mz04d", "--html", page)
    assert code == 0 and page.stat().st_size > 100_000


def test_show_unknown_arm_is_one_line(run_cli):
    code, _, err = run_cli("show", "kuka")
    assert code == 2 and "unknown arm or scene 'kuka'" in err


def test_picture_renders_three_arms(tmp_path, run_cli):
    path = tmp_path / "arms.png"
    code, _, _ = run_cli("picture", path, "--width", "160", "--height", "120")
    assert code == 0
    image = cv2.imread(str(path))
    assert image.shape == (120, 480, 3)
    for view in np.split(image, 3, axis=1):
        background = view[0, 0].astype(float)
        assert (np.linalg.norm(view - background, axis=2) > 30).mean() > 0.01
