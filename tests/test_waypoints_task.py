"""Task `waypoints` end to end: `guidedarm run ur10e_waypoints` through the station, and
the planner on the MZ04D and the rover arm."""

import json

import numpy as np
import pytest

from guidedarm.diagrams.cli.main import main
from guidedarm.diagrams.studies.planner_comparison import ComparePlanners, TableRow
from guidedarm.diagrams.tasks.common.tracking import (
    MAX_TRACKING_DELAY,
    DelayedTrackingError,
    SampledCommands,
)
from guidedarm.diagrams.tasks.registry import GetTask, LoadScenario, NumericMetricNames
from guidedarm.diagrams.tasks.waypoints import MakePlannerSetup
from guidedarm.diagrams.tasks.waypoints.report import TrajectoryMetrics
from guidedarm.systems.planning.acceleration_planner_math import RunPlanning
from guidedarm.systems.planning.planner_baselines import TrapezoidProfile

SUMMARY_KEYS = {
    "T_s", "qd_max", "qd_min", "qdd_max", "qdd_min", "final_error_m", "c_min",
    "waypoint_distance_m", "sim_time_s", "failure", "tracking_error_max_rad",
    "tcp_tracking_error_max_m", "tracking_delay_s", "joint_limit_distance_min_rad",
    "oscillation_rate_max", "handover_time_s", "cell_contacts",
}  # fmt: skip
FIGURES = [
    "tcp_path", "joint_positions", "joint_velocities", "joint_accelerations",
    "scaling_coefficient",
]  # fmt: skip


def test_guidedarm_run_ur10e_waypoints_through_the_station(tmp_path):
    assert main(["run", "ur10e_waypoints", "--out", str(tmp_path)]) == 0
    summary = json.loads((tmp_path / "summary.json").read_text())
    assert summary.keys() >= SUMMARY_KEYS
    assert NumericMetricNames(summary) == set(GetTask("waypoints").KnownMetrics())
    assert summary["failure"] is None and summary["success"] is True
    assert summary["cell_contacts"] == 0 and summary["oscillation_rate_max"] < 2.0
    assert summary["joint_limit_distance_min_rad"] > 0.01
    rows = np.loadtxt(tmp_path / "trajectory.csv", delimiter=",", skiprows=1)
    header = (tmp_path / "trajectory.csv").read_text().splitlines()[0].split(",")
    assert header[:2] == ["t", "q_cmd_1"] and header[-1] == "q_meas_6" and rows.shape[1] == 25
    # one row per 2 ms control period; the commanded q, qd, qdd within their limits
    assert np.allclose(np.diff(rows[:, 0]), 0.002) and np.abs(rows[:, 13:19]).max() <= 1.3963
    # the robust mode's braking approach and per-joint saturation: 4.52 s where the paper's law
    # takes 5.41 s
    assert summary["T_s"] == pytest.approx(4.52, abs=0.05)
    assert summary["qdd_step_max"] <= 0.1 + 1e-9  # max_jerk * dt: continuous
    assert summary["final_error_m"] <= 1e-3
    assert max(summary["qdd_max"], -summary["qdd_min"]) <= 1.40
    assert max(summary["qd_max"], -summary["qd_min"]) <= 1.05
    assert summary["c_min"] == 0.0  # the smooth start
    assert all(d < 0.05 for d in summary["waypoint_distance_m"][:-1])
    # the station's servo tracks the 500 Hz commands to within about a millimetre, a
    # plant step or two behind
    assert summary["tcp_tracking_error_max_m"] < 3e-3
    assert summary["tracking_delay_s"] <= 0.004
    for name in FIGURES:
        assert (tmp_path / f"{name}.png").stat().st_size > 10_000
    assert (tmp_path / "replay.html").stat().st_size > 10_000


@pytest.mark.parametrize("name", ["mz04d_waypoints", "rover_arm_waypoints"])
def test_the_same_planner_drives_the_other_arms(name):
    _, scenario, _ = LoadScenario(name, [])
    setup = MakePlannerSetup(scenario)
    trajectory = RunPlanning(setup.planning, setup.q0, max_time=scenario.max_time)
    metrics = TrajectoryMetrics(setup, trajectory)
    assert metrics["T_s"] is not None and metrics["final_error_m"] <= 1e-3
    assert np.all(np.abs(trajectory.qd) <= setup.velocity_limit)
    assert np.all(np.abs(trajectory.qdd) <= setup.acceleration_limit * (1 + 1e-9))
    assert all(d < scenario.planner.neighbourhood_radius for d in metrics["waypoint_distance_m"])


def test_unknown_limits_choice_is_refused_at_load_before_any_output(capsys, tmp_path):
    out = tmp_path / "run"
    code = main(["run", "ur10e_waypoints", "--out", str(out), "--set", "limits=jerk"])
    assert code == 2
    printed = capsys.readouterr()
    assert "limits must be one of" in printed.err and "running" not in printed.out
    assert not out.exists()  # no scenario.yaml, no folder


def test_unreachable_waypoint_fails_before_any_motion(capsys, tmp_path):
    far = "waypoints=[[2.5, 0.0, 0.5, 3.14159, 0.0, 0.0]]"
    assert main(["run", "ur10e_waypoints", "--out", str(tmp_path), "--set", far]) == 2
    assert "waypoint 1" in capsys.readouterr().err
    assert not (tmp_path / "summary.json").exists()


def test_trapezoid_profile_reaches_the_limits_and_ends_at_rest():
    duration, profile = TrapezoidProfile(1.0, v_max=0.5, a_max=1.0)
    assert duration == pytest.approx(1.0 / 0.5 + 0.5 / 1.0)
    t = np.linspace(0, duration, 2001)
    s, ds, dds = profile(t)
    assert s[0] == 0 and s[-1] == pytest.approx(1.0)
    assert ds.max() == pytest.approx(0.5) and np.abs(dds).max() == pytest.approx(1.0)
    short, _ = TrapezoidProfile(0.1, v_max=0.5, a_max=1.0)  # triangular
    assert short == pytest.approx(2 * np.sqrt(0.1))


def test_compare_planners_table(capsys):
    assert main(["compare-planners"]) == 0
    lines = capsys.readouterr().out.strip().splitlines()
    assert lines[0].split()[0] == "planner" and len(lines) == 6
    _, scenario, _ = LoadScenario("ur10e_waypoints", [])
    setup = MakePlannerSetup(scenario)
    found = ComparePlanners(setup, setup.planning.waypoints, setup.q0, scenario.max_time)
    rows = {name: TableRow(setup, trajectory) for name, trajectory in found.items()}
    planner, seed, movej, toppra, ruckig = rows.values()
    limit_v, limit_a = setup.velocity_limit[0], setup.acceleration_limit[0]
    # movej keeps the speed limit but its blends add two segments' accelerations (the
    # seed's experiment 1: 4.29 s, up to 2.48 rad/s^2); only the planners are smooth
    assert movej["qd_abs_max"] <= limit_v + 1e-9 and movej["qdd_abs_max"] > 1.2 * limit_a
    assert movej["T_s"] == pytest.approx(4.29, rel=0.1)
    # Toppra is time-optimal on its path (limits met up to its grid discretisation)
    assert toppra["T_s"] < movej["T_s"] < planner["T_s"]
    assert toppra["qdd_abs_max"] <= 1.01 * limit_a and toppra["qd_abs_max"] <= 1.01 * limit_v
    for law in (planner, seed):
        assert law["qdd_abs_max"] <= limit_a * (1 + 1e-9)
        assert law["jerk_abs_max"] < 0.1 * min(movej["jerk_abs_max"], toppra["jerk_abs_max"])
    # Ruckig at the planner's own max jerk keeps every limit and passes the waypoints
    assert ruckig["jerk_abs_max"] <= planner["jerk_abs_max"] * (1 + 1e-6)
    assert ruckig["qdd_abs_max"] <= limit_a * (1 + 1e-9)
    assert ruckig["qd_abs_max"] <= limit_v * (1 + 1e-9)
    assert toppra["T_s"] - 0.01 <= ruckig["T_s"] < planner["T_s"]
    assert max(toppra["waypoint_deviation_mm"] + ruckig["waypoint_deviation_mm"]) < 1.0
    assert all(d < 50 for d in movej["waypoint_deviation_mm"] + planner["waypoint_deviation_mm"])


@pytest.mark.parametrize("lag, expected", [(0.0, 0.0), (0.03, 0.03), (0.25, 0.1)])
def test_delayed_tracking_error_finds_the_lag_of_a_delayed_arm(lag, expected):
    """A joint at 1 rad/s amplitude measured `lag` s behind its command: the delay found is
    the lag (up to MAX_TRACKING_DELAY), and the error at it is the lag's leftover only."""
    times = np.arange(0.0, 3.0, 0.002)
    command = SampledCommands(times, np.sin(times)[:, None])
    measured = command(times - lag)
    delay, error = DelayedTrackingError(times, command, measured, norm=np.inf)
    assert delay == pytest.approx(expected, abs=1e-9)
    assert error == pytest.approx(np.abs(measured - command(times - delay)).max())
    assert (error < 1e-12) == (lag <= MAX_TRACKING_DELAY)


def test_a_start_pose_in_collision_is_refused_in_one_line(capsys, tmp_path):
    """The MZ04D's ToF tool swung into the arm's own base: refused before any motion."""
    start = "[0.0, 0.0708, -0.25, 0.0, -1.5708, 0.0]"
    args = ["--set", f"station.arms.mz04d.initial_position={start}", "--out", str(tmp_path)]
    assert main(["run", "mz04d_waypoints", *args]) == 2
    error = capsys.readouterr().err.strip().splitlines()[-1]
    assert "start pose collides: mz04d::base and tof_tool::tof_tool overlap by" in error
    assert not (tmp_path / "summary.json").exists()
