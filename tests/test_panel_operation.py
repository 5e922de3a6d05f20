"""Task `panel_operation` (Annusewicz-Mistal et al., section 2.4; Tables 4-6 in simulation)."""

from __future__ import annotations

import numpy as np
import pytest

from guidedarm.diagrams.run_context import RunContext
from guidedarm.diagrams.tasks.panel_operation import PanelOperationRun, PanelPlannerConfig
from guidedarm.diagrams.tasks.panel_operation.run import PlannerBaseFrame
from guidedarm.diagrams.tasks.registry import LoadScenario


def _run(tmp_path, overrides):
    _, scenario, _ = LoadScenario("panel_operation", overrides)
    return PanelOperationRun(scenario, RunContext(tmp_path, quiet=True))


@pytest.mark.slow
def test_joint_trajectory_runs_from_different_starts_press_the_chosen_switch(tmp_path):
    """The estimator and the sequence, moves as exact IK joint segments, on every switch from
    four of the press study's starts (the next test runs all ten through the planner)."""
    results = []
    for seed, switch in zip((0, 3, 6, 9), (1, 2, 3, 1), strict=True):
        run = _run(tmp_path, [f"switch={switch}", "operation.motion=joint_trajectory"])
        results.append(run.Run(run.SampleStart(seed)))
    start_distances = [r["measurements"][0]["distance_mm"] for r in results]
    assert max(start_distances) - min(start_distances) > 40  # really different starts
    for r in results:
        assert r["failure"] is None, r["failure"]
        assert r["success"] and r["switch_pressed"] == r["switch"]
        assert max(r["press_error_mm"].values()) <= 2.0, r["press_error_mm"]
        assert r["base_position_error_mm"] <= 2.0
        assert [m["point"] for m in r["measurements"]] == ["start", "base", "switch_point"]
        assert all(m["valid"] for m in r["measurements"])
        travel = r["switch_travel_mm"]
        assert travel[r["switch"] - 1] >= 4.0
        assert sum(t > 0.5 for t in travel) == 1  # no neighbour touched


@pytest.mark.slow
def test_the_planner_presses_from_the_ten_starts_of_the_press_study(tmp_path):
    """The default moves, through the acceleration-level planner, from the 10 starts of the
    press study (Table 5: switch 2, start seeds 0-9, `guidedarm marker-study press`)."""
    run = _run(tmp_path, ["switch=2"])
    assert run.scenario.operation.motion == "planner"
    for seed in range(10):
        r = run.Run(run.SampleStart(seed))
        assert r["failure"] is None, (seed, r["failure"])
        assert r["success"] and r["switch_pressed"] == 2
        assert max(r["press_error_mm"].values()) <= 2.0, (seed, r["press_error_mm"])
        assert r["base_position_error_mm"] <= 2.0
        assert sum(t > 0.5 for t in r["switch_travel_mm"]) == 1  # no neighbour touched


@pytest.mark.parametrize("policy", ["abort", "continue"])
def test_markers_covered_after_base_position(tmp_path, policy):
    run = _run(
        tmp_path,
        ["switch=3", "cover_markers_after_base=true", f"operation.on_marker_loss={policy}"],
    )
    result = run.Run(run.SampleStart(1))
    lost = result["measurements"][-1]
    assert lost["point"] == "switch_point" and not lost["valid"]
    assert result["marker_loss"] == policy and result["lost_measurements"] == 1
    if policy == "abort":
        assert result["failure"] == (
            "markers lost at the 'switch_point' point: aborted before pressing "
            "(on_marker_loss: abort)"
        )
        assert result["switch_pressed"] is None and max(result["switch_travel_mm"]) < 0.5
    else:
        assert lost["used_last_valid_estimate"] is True
        assert result["success"] and result["switch_pressed"] == 3
        assert max(result["press_error_mm"].values()) <= 2.0


def test_no_marker_in_view_at_start_fails_without_moving(tmp_path):
    run = _run(tmp_path, [])
    q_away = np.array([1.2, -1.5707963267948966, 1.5707963267948966, 0.0, 0.0, 0.0])
    result = run.Run(q_away)
    assert result["failure"] == "no marker of the panel in view at the 'start' point"
    assert not result["success"] and result["switch_pressed"] is None


def test_planner_motion_presses_the_switch_within_the_planner_limits(tmp_path):
    run = _run(tmp_path, ["switch=2", "operation.motion=planner"])
    result = run.Run(run.SampleStart(4))
    assert result["failure"] is None, result["failure"]
    assert result["success"] and result["switch_pressed"] == 2
    assert max(result["press_error_mm"].values()) <= 2.0, result["press_error_mm"]
    assert result["base_position_error_mm"] <= 2.0
    assert all(m["valid"] for m in result["measurements"])
    state = run.sequencer.GetSequencerState(
        run.sequencer.GetMyContextFromRoot(run.simulator.get_context())
    )
    # base, switch point, approach, press, release, retract: six planner tasks
    assert state.task.sequence == 5
    # the measured joints keep the planner's 0.5 rad/s (the joint segments peak at 0.75)
    log = run.joint_log.FindLog(run.simulator.get_context())
    speed = np.abs(np.diff(log.data(), axis=1)) / np.diff(log.sample_times())
    assert 0.2 < speed.max() <= 0.5 * 1.05
    # trajectory.csv: one row per 2 ms, the planner's qd within its limit; no contact with
    # the cell, no oscillation
    rows = np.loadtxt(tmp_path / "trajectory.csv", delimiter=",", skiprows=1)
    assert rows.shape[1] == 25 and np.allclose(np.diff(rows[:, 0]), 0.002)
    assert np.abs(rows[:, 7:13]).max() <= 0.5 * (1 + 1e-9)
    assert result["cell_contacts"] == 0 and result["oscillation_rate_max"] < 5.0
    # the press and its return run straight along the switch's axis: wherever the
    # commanded tip is within 10 mm of the cap's rest face, it is within 0.5 mm of the
    # axis (the long move before bends 7 mm sideways, clear of the caps)
    switch = np.array(run.panel.switches[1].position)
    X_PW = run.X_WP.inverse()
    p_PT = np.array([(X_PW @ run.kinematics.X_WT(q)).translation() for q in rows[::5, 1:7]])
    near = p_PT[:, 2] < switch[2] + 0.010
    assert near.sum() > 100 and p_PT[:, 2].min() < switch[2] - 0.0075  # pressed 8 mm
    assert np.linalg.norm(p_PT[near, :2] - switch[:2], axis=1).max() < 0.5e-3


@pytest.mark.slow
def test_the_start_that_drove_the_planner_into_a_limit_cycle_presses_its_switch(tmp_path):
    """Start seed 40, switch 1: the first move turned J1 by 3.3 rad, drove J2 and J6 into
    their limits and oscillated at 3 Hz until the 40 s time limit; with the position limits
    and the hand-over to joint space it presses the switch."""
    run = _run(tmp_path, ["switch=1"])
    result = run.Run(run.SampleStart(40))
    assert result["failure"] is None, result["failure"]
    assert result["success"] and result["switch_pressed"] == 1
    assert max(result["press_error_mm"].values()) <= 2.0
    assert result["sim_time_s"] < 25.0 and result["cell_contacts"] == 0
    assert result["joint_limit_distance_min_rad"] >= 0.01 and result["oscillation_rate_max"] < 5.0


@pytest.mark.parametrize(
    "override, message",
    [
        ("switch=9", "switch must be 1 .. 3, got 9"),
        ("degradation.supersampling=2", "set the camera's supersampling (>= 1) with the top-level"),
        (
            "operation.on_marker_loss=ignore",
            "key 'operation.on_marker_loss': 'ignore' is not one of 'abort', 'continue'",
        ),
        (
            "operation.motion=teleport",
            "key 'operation.motion': 'teleport' is not one of 'joint_trajectory', 'planner'",
        ),
        ("start.distance_m=near", "key 'start.distance_m': expected a list"),
    ],
)
def test_bad_scenario_values_are_one_line(run_cli, tmp_path, override, message):
    code, _, err = run_cli("run", "panel_operation", "--out", tmp_path, "--set", override)
    assert code == 2
    lines = err.strip().splitlines()
    assert len(lines) == 1 and message in lines[0], err


def test_the_shipped_scenario_loads_with_either_motion():
    """The shipped file sets no planner key (the planner's defaults are the panel's), so
    `--set operation.motion=joint_trajectory` loads it; the planner's base defaults to the
    arm's base and its moves end within 0.1 mm and 0.1 mrad (the sequencer presses where a
    move ends)."""
    for motion in ("planner", "joint_trajectory"):
        _, scenario, _ = LoadScenario("panel_operation", [f"operation.motion={motion}"])
        assert scenario.operation.motion == motion
        assert scenario.planner == PanelPlannerConfig()
    assert PanelPlannerConfig().parameters.position_tolerance == 1e-4
    assert PanelPlannerConfig().parameters.orientation_tolerance == 1e-4
    assert PlannerBaseFrame(scenario) == "rover_arm::base"


def test_estimator_camera_file_is_the_estimators_model(tmp_path, run_cli):
    """estimator_camera_file replaces the model derived from the station's CameraConfig;
    a file for another image size is refused at load."""
    camera = tmp_path / "calibrated.yaml"
    camera.write_text(
        "width: 1920\nheight: 1080\nfx: 1362.5\nfy: 1361.0\ncx: 961.0\ncy: 538.0\n"
        "distortion: [-0.2, 0.07, 0.0, 0.0, 0.0]\n"
    )
    mount = tmp_path / "hand_eye.yaml"
    mount.write_text(
        "X_PC:\n  translation: [0.001, -0.002, 0.003]\n  rotation: !Rpy { deg: [0.5, 0, 0] }\n"
        "  base_frame: rover_gripper::camera\n"
    )
    run = _run(tmp_path, [f"estimator_camera_file={camera}", f"camera_mount_file={mount}"])
    estimator = run.diagram.GetSubsystemByName("marker_pose_estimator")
    assert estimator.solver.intrinsics.fx == 1362.5
    assert estimator.solver.intrinsics.distortion == [-0.2, 0.07, 0.0, 0.0, 0.0]
    # The controller's camera sits where the mount file says, in the mount frame.
    q = run.kinematics.plant.GetPositions(run.kinematics.plant.CreateDefaultContext())
    X_WF = run.kinematics.camera_frame.CalcPoseInWorld(run.kinematics.plant.CreateDefaultContext())
    X_FC = X_WF.inverse() @ run.kinematics.X_WC(q)
    np.testing.assert_allclose(X_FC.translation(), [0.001, -0.002, 0.003], atol=1e-12)
    small = tmp_path / "small.yaml"
    small.write_text("width: 640\nheight: 480\nfx: 500\nfy: 500\ncx: 319.5\ncy: 239.5\n")
    other = tmp_path / "other_mount.yaml"
    other.write_text(mount.read_text().replace("rover_gripper::camera", "world"))
    for key, path, message in (
        ("estimator_camera_file", small, "is for 640 x 480 px images, camera 'camera' renders"),
        ("estimator_camera_file", tmp_path / "missing.yaml", "file not found"),
        ("camera_mount_file", other, "X_PC is in world, the camera's X_PB in rover_gripper"),
        ("camera_mount_file", tmp_path / "missing.yaml", "file not found"),
    ):
        code, _, err = run_cli(
            "run", "panel_operation", "--out", tmp_path / "out", "--set", f"{key}={path}"
        )
        assert code == 2 and message in err and len(err.strip().splitlines()) == 1, err
