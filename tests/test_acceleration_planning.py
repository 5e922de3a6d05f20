"""The planner's mathematics (Pająk's law, Pająk), and its Table 2 reproduced without a
Diagram by the paper's mode (planner.robust: false)."""

import numpy as np
import pytest
from pydrake.math import RollPitchYaw, RotationMatrix

from guidedarm.diagrams.tasks.registry import LoadScenario
from guidedarm.diagrams.tasks.waypoints import MakePlannerSetup
from guidedarm.systems.errors import ConfigurationError
from guidedarm.systems.planning.acceleration_planner_kinematics import (
    EulerRateMatrix,
    EulerRateMatrixDotTimesRate,
    PlanningError,
    WrapAngle,
)
from guidedarm.systems.planning.acceleration_planner_limits import (
    AccelerationScaling,
    VelocityPenalty,
)
from guidedarm.systems.planning.acceleration_planner_math import (
    AccelerationPlanning,
    ClosestApproach,
    PlannerConfig,
    RunPlanning,
)

PI = np.pi
Q0_UR10E = np.array([-PI / 2, -PI / 2, -3 * PI / 4, -PI / 4, PI / 2, PI / 4])
SCENARIOS = ["ur10e_waypoints", "mz04d_waypoints", "rover_arm_waypoints"]
SEED_LAW = "planner.robust=false"
SEED_CONFIG = PlannerConfig(robust=False)


def _Setup(name: str = "ur10e_waypoints", *overrides: str):
    _, scenario, _ = LoadScenario(name, list(overrides))
    return scenario, MakePlannerSetup(scenario)


@pytest.fixture(scope="module")
def ur10e():
    return _Setup("ur10e_waypoints", SEED_LAW)[1]


def test_wrap_angle():
    np.testing.assert_allclose(WrapAngle([PI + 0.1, -PI - 0.1, 0.3]), [-PI + 0.1, PI - 0.1, 0.3])


def test_euler_rate_matrix_matches_finite_differences():
    rng = np.random.default_rng(1)
    for _ in range(20):
        rpy, rate = rng.uniform(-1.2, 1.2, 3), rng.uniform(-1, 1, 3)
        h = 1e-6
        R0 = RotationMatrix(RollPitchYaw(rpy)).matrix()
        R1 = RotationMatrix(RollPitchYaw(rpy + h * rate)).matrix()
        skew = (R1 - R0) / h @ R0.T
        omega = np.array([skew[2, 1], skew[0, 2], skew[1, 0]])
        np.testing.assert_allclose(EulerRateMatrix(rpy) @ rate, omega, atol=1e-5)
        dB = (EulerRateMatrix(rpy + h * rate) - EulerRateMatrix(rpy)) / h
        np.testing.assert_allclose(EulerRateMatrixDotTimesRate(rpy, rate), dB @ rate, atol=1e-5)


def test_ur10e_tcp_at_the_seeds_start(ur10e):
    p = ur10e.planning.kinematics.Position(Q0_UR10E)
    np.testing.assert_allclose(p[:3], [-0.17415, -0.52400, 0.27270], atol=1e-5)
    np.testing.assert_allclose(WrapAngle(p[3:] - [PI, 0, 3 * PI / 4]), 0, atol=1e-9)


@pytest.mark.parametrize("name", SCENARIOS)
def test_analytic_jacobian_and_bias_match_finite_differences(name):
    """J = d k / d q and Jdot qd = d(J qd)/dt along q + t qd, on each of the three arms."""
    setup = _Setup(name)[1]
    kinematics = setup.planning.kinematics
    rng = np.random.default_rng(2)
    h = 1e-6
    for _ in range(5):
        q = setup.q0 + rng.uniform(-0.3, 0.3, 6)
        qd = rng.uniform(-1, 1, 6)
        kin = kinematics.Evaluate(q, qd)
        J_fd = np.column_stack(
            [
                _Wrapped(kinematics.Position(q + h * e) - kinematics.Position(q - h * e)) / (2 * h)
                for e in np.eye(6)
            ]
        )
        np.testing.assert_allclose(kin.J, J_fd, atol=1e-6)
        later = kinematics.Evaluate(q + h * qd, qd)
        earlier = kinematics.Evaluate(q - h * qd, qd)
        jdot_fd = (later.J @ qd - earlier.J @ qd) / (2 * h)
        np.testing.assert_allclose(kin.Jdot_qdot, jdot_fd, atol=1e-5)


@pytest.mark.parametrize("name", SCENARIOS)
def test_geometric_jacobian_and_bias_match_finite_differences(name):
    """The robust mode's kinematics (one context update per evaluation): rows [x; omega],
    J the derivative of the TCP position and of the rotation (omega from R' R^T), and
    Jdot qd = d(J qd)/dt along q + t qd, on each of the three arms."""
    kinematics = _Setup(name)[1].planning.kinematics
    rng = np.random.default_rng(5)
    h = 1e-6
    for _ in range(5):
        q = rng.uniform(-2, 2, 6)
        qd = rng.uniform(-1, 1, 6)
        kin = kinematics.Evaluate(q, qd, analytic=False)
        later = kinematics.Evaluate(q + h * qd, qd, analytic=False)
        earlier = kinematics.Evaluate(q - h * qd, qd, analytic=False)
        np.testing.assert_allclose(
            kin.J[:3] @ qd, np.subtract(later.x, earlier.x) / (2 * h), atol=1e-7
        )
        skew = (later.R - earlier.R) / (2 * h) @ kin.R.T
        omega = [skew[2, 1], skew[0, 2], skew[1, 0]]
        np.testing.assert_allclose(kin.J[3:] @ qd, omega, atol=1e-7)
        jdot_fd = (later.J @ qd - earlier.J @ qd) / (2 * h)
        np.testing.assert_allclose(kin.Jdot_qdot, jdot_fd, atol=1e-6)


def _Wrapped(difference: np.ndarray) -> np.ndarray:
    difference[3:] = WrapAngle(difference[3:])
    return difference


def test_velocity_penalty_is_zero_inside_and_pushes_away_from_the_near_limit():
    penalty = VelocityPenalty(-np.ones(6), np.ones(6), theta=0.1, rho=0.003)
    np.testing.assert_array_equal(penalty.Perturbation(np.full(6, 0.59)), 0.0)
    qd = np.array([0.9, -0.9, 0.95, -0.95, 0.0, 0.7])
    dq = penalty.Perturbation(qd)
    d = (1 - np.abs(qd[:4])) / 2
    np.testing.assert_allclose(np.abs(dq[:4]), 0.003 / d**2 / 2)
    assert dq[0] < 0 < dq[1] and dq[2] < 0 < dq[3] and dq[4] == dq[5] == 0


def test_scaling_cases_one_to_four_and_rules_a_b():
    scaling = AccelerationScaling(-np.ones(2), np.ones(2))
    # (1) qdd > max, b > 0 and (2) qdd < min, b < 0: upper bounds, rule (a) takes the least.
    c, limited = scaling.Select(np.array([0.2, -0.1]), np.array([2.0, -3.0]), 1.0, 0.5)
    assert limited and c == pytest.approx(min(0.8 / 2.0, -0.9 / -3.0))
    # (3) qdd > max, b < 0 and (4) qdd < min, b > 0: lower bounds, rule (b) the greatest.
    c, limited = scaling.Select(np.array([3.0, -2.0]), np.array([-1.0, 0.5]), 1.0, 1.0)
    assert limited and c == pytest.approx(max((1 - 3.0) / -1.0, (-1 + 2.0) / 0.5))
    c, limited = scaling.Select(np.array([0.1, 0.1]), np.array([0.5, 0.5]), 1.0, 0.3)
    assert not limited and c == 1.0


def test_scaling_rule_c_without_admissible_c_is_reported():
    """Joint 1 violates its maximum with b > 0 (case 1: c <= 0.5), joint 2 its maximum with
    b < 0 (case 3: c >= 1): no c satisfies both, and the planner says so."""
    scaling = AccelerationScaling(-np.ones(2), np.ones(2))
    a, b = np.array([0.0, 3.0]), np.array([2.0, -2.0])
    with pytest.raises(PlanningError, match=r"case \(c\) has no admissible c \(joints 1, 2"):
        scaling.Select(a, b, 0.8, 0.4)


def test_scaling_rechecks_joints_pushed_past_a_limit_by_the_new_c():
    """c = 0.4 fixes joint 1 (case 1) but drives joint 2 below its minimum (case 4, c >= 0.6):
    the collected bounds are inconsistent and reported, never silently violated."""
    scaling = AccelerationScaling(-np.ones(2), np.ones(2))
    a, b = np.array([0.0, -2.2]), np.array([2.5, 2.0])
    with pytest.raises(PlanningError, match=r"case \(c\)"):
        scaling.Select(a, b, 1.0, 1.0)
    c, limited = scaling.Select(np.array([0.0, -1.2]), np.array([2.5, 2.0]), 1.0, 1.0)
    assert limited and c == pytest.approx(0.4)
    assert np.all(np.abs(np.array([0.0, -1.2]) + c * np.array([2.5, 2.0])) <= 1.0 + 1e-12)


def test_scaling_cannot_fix_an_unscaled_violation():
    scaling = AccelerationScaling(-np.ones(1), np.ones(1))
    with pytest.raises(PlanningError, match="joint 1 cannot be met"):
        scaling.Select(np.array([2.0]), np.array([0.0]), 1.0, 1.0)


@pytest.mark.parametrize(
    "change",
    [{"gain_p": 0.0}, {"gain_v": -1.0}, {"time_step": 0.0}, {"penalty_strength": 0.0}],
)
def test_non_positive_gains_are_configuration_errors(ur10e, change):
    with pytest.raises(ConfigurationError, match=next(iter(change))):
        AccelerationPlanning(
            ur10e.planning.kinematics, ur10e.planning.waypoints, PlannerConfig(**change)
        )


def test_non_positive_limits_are_configuration_errors(ur10e):
    with pytest.raises(ConfigurationError, match="velocity limits"):
        VelocityPenalty(-np.ones(6), np.zeros(6), 0.1, 0.003)
    with pytest.raises(ConfigurationError, match="acceleration limits"):
        AccelerationScaling(np.ones(6), 2 * np.ones(6))
    with pytest.raises(ConfigurationError, match="max_joint_velocity"):
        _Setup("ur10e_waypoints", "max_joint_velocity=[-1.0]")


def test_unreachable_waypoint_is_refused_naming_it():
    with pytest.raises(ConfigurationError, match=r"waypoint 2 .* out of reach of ur10e"):
        _Setup(
            "ur10e_waypoints",
            "waypoints=[[-0.175, -0.525, 0.73, 3.14159, 0, 2.35619],[1.9, 0, 0.7, 3.14159, 0, 0]]",
        )


def test_near_singular_start_is_a_clear_error_in_the_seeds_mode(ur10e):
    q = Q0_UR10E.copy()
    q[4] = 1e-4  # wrist 2 straight: wrist singularity of the UR10e
    with pytest.raises(PlanningError, match="near-singular"):
        ur10e.planning.InitialState(q)


def test_near_singular_motion_stops_with_an_error_instead_of_huge_accelerations(ur10e):
    """A target that needs the wrist to straighten (q5 -> 0) drives the arm into the
    singularity; the planner stops before its accelerations blow up."""
    kinematics = ur10e.planning.kinematics
    q_target = Q0_UR10E.copy()
    q_target[4] = 0.0
    target = kinematics.Position(q_target)
    start = Q0_UR10E.copy()
    start[4] = 0.3
    planning = AccelerationPlanning(kinematics, target[None, :], SEED_CONFIG)
    with pytest.raises(PlanningError, match="near-singular"):
        RunPlanning(planning, start, max_time=10.0)


TABLE_2 = {  # the paper's Table 2: T (s), max qd, min qd, max qdd, min qdd
    "none": (4.98, 0.91, -1.62, 19.77, -22.63),
    "velocity": (5.22, 0.86, -0.97, 19.77, -22.63),
    "velocity,acceleration": (5.32, 0.69, -0.93, 1.40, -1.40),
}


@pytest.fixture(scope="module")
def table2():
    runs = {}
    for limits in TABLE_2:
        setup = _Setup("ur10e_waypoints", f"limits={limits}", SEED_LAW)[1]
        trajectory = RunPlanning(setup.planning, setup.q0, max_time=15.0)
        runs[limits] = (setup, trajectory)
    return runs


@pytest.mark.parametrize("limits", list(TABLE_2))
def test_table2_time_and_final_error(table2, limits):
    setup, trajectory = table2[limits]
    T = TABLE_2[limits][0]
    assert trajectory.done_time == pytest.approx(T, rel=0.07)
    p_end = setup.planning.kinematics.Position(trajectory.q[-1])
    assert np.linalg.norm(p_end[:3] - setup.planning.waypoints[-1, :3]) <= 1e-3
    # the TCP passes through every intermediate neighbourhood and ends at p_f
    distances = ClosestApproach(
        np.array([setup.planning.kinematics.Position(q)[:3] for q in trajectory.q]),
        setup.planning.waypoints,
    )
    assert np.all(distances[:-1] < 0.05) and distances[-1] <= 1e-3


def test_table2_variant_1_extrema(table2):
    _, trajectory = table2["none"]
    _, qd_max, qd_min, _, qdd_min = TABLE_2["none"]
    assert trajectory.qdd.min() == pytest.approx(qdd_min, abs=0.5)
    assert trajectory.qd.max() == pytest.approx(qd_max, abs=0.05)
    assert trajectory.qd.min() == pytest.approx(qd_min, abs=0.05)


def test_table2_variant_2_keeps_velocity_limits(table2):
    setup, trajectory = table2["velocity"]
    assert np.all(np.abs(trajectory.qd) <= setup.velocity_limit)
    assert trajectory.qdd.min() == pytest.approx(-22.63, abs=0.5)  # at t = 0, penalty idle


def test_table2_variant_3_limits_at_every_step_and_continuous_accelerations(table2):
    setup, trajectory = table2["velocity,acceleration"]
    assert np.all(np.abs(trajectory.qdd) <= 1.40)
    assert np.all(np.abs(trajectory.qdd) <= setup.acceleration_limit * (1 + 1e-9))
    assert np.all(np.abs(trajectory.qd) <= 1.05)
    # Continuity: c(0) = 0 starts at qdd = 0, and no step changes an acceleration by more
    # than c's exponential return (dc <= dt per step, times |b| <= 23 rad/s^2 here) and
    # the smooth dynamics add: 0.1 rad/s^2 per 2 ms step (7 % of the limit).
    assert np.all(trajectory.qdd[0] == 0) and trajectory.c[0] == 0
    assert np.abs(np.diff(trajectory.qdd, axis=0)).max() <= 0.1
    assert np.all(np.abs(np.diff(trajectory.c)) <= 0.05)


def test_stop_at_every_waypoint_mode(ur10e):
    _, scenario_setup = _Setup("ur10e_waypoints", "planner.stop_at_waypoints=true", SEED_LAW)
    planning = scenario_setup.planning
    trajectory = RunPlanning(planning, scenario_setup.q0, max_time=20.0)
    assert trajectory.done_time > 0
    switches = np.flatnonzero(np.diff(trajectory.index)) + 1
    assert len(switches) == len(planning.waypoints) - 1
    kinematics = planning.kinematics
    for k, waypoint in zip(switches, planning.waypoints, strict=False):
        assert np.linalg.norm(kinematics.Position(trajectory.q[k])[:3] - waypoint[:3]) <= 1e-3
        assert np.linalg.norm(trajectory.qd[k]) < 0.015  # at rest at each waypoint
    assert np.all(np.abs(trajectory.qdd) <= scenario_setup.acceleration_limit * (1 + 1e-9))
    assert np.all(np.abs(trajectory.qd) <= scenario_setup.velocity_limit)


def test_infeasible_scaling_in_a_run_is_reported_by_the_seeds_law(ur10e):
    """Found by a property test with joint-space offsets: moving joint 2 of the first IK
    solution by 0.25 rad makes c rise to 4.4 (rule (b)) and then the unscalable part a of
    joint 2 exceeds its limit while b vanishes: the paper's law stops naming case (c).
    (tests/test_acceleration_planner_robust.py runs the same task in the robust mode.)"""
    kinematics = ur10e.planning.kinematics
    q_goal = ur10e.joint_waypoints[0] + np.array([0, 0.25, 0, 0, 0, 0])
    planning = AccelerationPlanning(
        kinematics,
        kinematics.Position(q_goal)[None, :],
        SEED_CONFIG,
        (-ur10e.velocity_limit, ur10e.velocity_limit),
        (-ur10e.acceleration_limit, ur10e.acceleration_limit),
    )
    with pytest.raises(PlanningError, match=r"case \(c\) has no admissible c"):
        RunPlanning(planning, Q0_UR10E, max_time=10.0)
