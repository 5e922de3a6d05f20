"""The planner's robust mode (the default): rotation-vector error, damped inverse, speed
governor, step bounds, braking fallback and joint-space blend near singularities, on all
three arms and on seeded random reachable tasks (near-singular starts, steep targets)."""

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from pydrake.math import RollPitchYaw, RotationMatrix

from guidedarm.diagrams.cli.main import main
from guidedarm.diagrams.tasks.registry import LoadScenario
from guidedarm.diagrams.tasks.waypoints import MakePlannerSetup
from guidedarm.systems.planning.acceleration_planner_kinematics import (
    DampedSolve,
    DampingFactor,
    PlanningError,
    RotationFromVector,
    RotationVector,
)
from guidedarm.systems.planning.acceleration_planner_math import (
    AccelerationPlanning,
    PlannerConfig,
    RunPlanning,
)
from guidedarm.systems.planning.acceleration_planner_robust_limits import (
    AdmissibleScaling,
    BrakingAcceleration,
    CholeskySolve,
    GovernorDamping,
    JerkWindow,
    SaturatedLeastSquares,
    SaturationMetricFactor,
)
from guidedarm.systems.planning.random_waypoint_tasks import KINDS, MakeRandomWaypointTasks
from guidedarm.systems.planning.waypoint_ik import SolveWaypointIk

PI = np.pi
ARMS = {"ur10e": "ur10e_waypoints", "mz04d": "mz04d_waypoints", "rover_arm": "rover_arm_waypoints"}


@pytest.fixture(scope="module")
def setups():
    return {arm: _Setup(name) for arm, name in ARMS.items()}


def _Setup(name: str, *overrides: str):
    _, scenario, _ = LoadScenario(name, list(overrides))
    return MakePlannerSetup(scenario)


def _Run(setup, waypoints, q0, max_time=20.0, robust=True, **settings):
    planning = setup.planning
    joints = SolveWaypointIk(planning.kinematics, waypoints, q0) if robust else None
    config = PlannerConfig(robust=robust, **settings)
    law = AccelerationPlanning(
        planning.kinematics,
        waypoints,
        config,
        (-setup.velocity_limit, setup.velocity_limit),
        (-setup.acceleration_limit, setup.acceleration_limit),
        joints,
    )
    return RunPlanning(law, q0, max_time)


def _AssertFinishedWithinLimits(setup, trajectory, waypoints):
    assert trajectory.done_time > 0
    assert np.all(np.abs(trajectory.qd) <= setup.velocity_limit * (1 + 1e-9))
    assert np.all(np.abs(trajectory.qdd) <= setup.acceleration_limit * (1 + 1e-9))
    p_end = setup.planning.kinematics.Position(trajectory.q[-1])
    assert np.linalg.norm(p_end[:3] - waypoints[-1, :3]) <= 1e-3


def test_rotation_vector_inverts_rodrigues_up_to_pi():
    rng = np.random.default_rng(3)
    for angle in (0.0, 1e-9, 0.3, 2.0, PI - 1e-6, PI):
        axis = rng.normal(size=3)
        v = angle * axis / np.linalg.norm(axis)
        R = RotationFromVector(v)
        np.testing.assert_allclose(R @ R.T, np.eye(3), atol=1e-12)
        back = RotationVector(R)
        if angle < PI - 1e-3:
            np.testing.assert_allclose(back, v, atol=1e-9)
        else:  # +-v are the same rotation at pi
            np.testing.assert_allclose(RotationFromVector(back), R, atol=1e-6)


def test_damped_inverse_is_the_inverse_when_undamped_and_bounded_near_singularity():
    assert DampingFactor(0.05, 0.03, 0.01) == 0.0
    assert DampingFactor(0.0, 0.03, 0.01) == pytest.approx(1e-4)
    rng = np.random.default_rng(4)
    J = rng.normal(size=(6, 6))
    rhs = rng.normal(size=6)
    np.testing.assert_allclose(DampedSolve(J, rhs, 0.0), np.linalg.solve(J, rhs))
    U, _, Vt = np.linalg.svd(J)
    singular = U @ np.diag([3, 2, 1, 1, 0.5, 1e-6]) @ Vt
    # |J^# x| <= |x| / (2 lambda) for every x
    x = DampedSolve(singular, U[:, -1], 1e-4)
    assert np.linalg.norm(x) <= 1 / (2 * 1e-2) + 1e-9


def test_admissible_scaling_is_rule_a_or_b_and_detects_an_empty_interval():
    lower, upper = -np.ones(2), np.ones(2)
    # case (1) and (2) joints: c <= 0.4 and c <= 0.3: rule (a) picks 0.3
    c_lo, c_hi = AdmissibleScaling(np.array([0.2, -0.1]), np.array([2.0, -3.0]), lower, upper)
    assert c_lo == 0.0 and c_hi == pytest.approx(0.3)
    # a outside the limits with b = 0: nothing helps
    c_lo, c_hi = AdmissibleScaling(np.array([1.5, 0.0]), np.array([0.0, 1.0]), lower, upper)
    assert c_lo > c_hi
    # the paper's case (c) example: no c
    c_lo, c_hi = AdmissibleScaling(np.array([0.0, 3.0]), np.array([2.0, -2.0]), lower, upper)
    assert c_lo > c_hi


def test_saturation_holds_the_worst_joint_and_gives_the_others_their_full_share():
    """Metric I (joint by joint): a joint beyond its bound is held there, every other joint
    keeps exactly the law's acceleration, not a scaled one (scaling by c would give
    c = 0.5 / 2.0 = 0.25 and joint 2 a quarter of its 0.8)."""
    lower, upper = [-0.5, -1.0, -1.0], [0.5, 1.0, 1.0]
    x, held = SaturatedLeastSquares([2.0, 0.8, -0.3], lower, upper, None)
    assert x == [0.5, 0.8, -0.3] and held == [0]
    x, held = SaturatedLeastSquares([0.1, 0.8, -0.3], lower, upper, None)  # feasible
    assert x == [0.1, 0.8, -0.3] and held == []


def test_saturation_in_the_task_metric_makes_up_the_held_joints_part_of_the_task():
    """Metric J^T J: the free joints minimise |J (x - q''_d)|. Two joints driving the same
    task axis (J = [[1, 1], [0, 1]]): joint 1 wants 2.0 with bound 0.5, so the task's first
    row loses 1.5, and joint 2 is not throttled but raised, within its bound: the least
    squares over x_2 of (0.5 + x_2 - 2.5)^2 + (x_2 - 0.5)^2 gives x_2 = 1.25."""
    J = np.array([[1.0, 1.0], [0.0, 1.0]])
    factor = SaturationMetricFactor(J)
    np.testing.assert_allclose(factor @ factor.T, np.linalg.inv(J.T @ J))
    x, held = SaturatedLeastSquares([2.0, 0.5], [-0.5, -2.0], [0.5, 2.0], factor)
    assert held == [0] and x[0] == 0.5 and x[1] == pytest.approx(1.25)
    # the compensation is bounded too: joint 2 held at 1.0 as well, both at their bounds
    x, held = SaturatedLeastSquares([2.0, 0.5], [-0.5, -1.0], [0.5, 1.0], factor)
    assert held == [0, 1] and x == [0.5, 1.0]


def test_saturation_never_leaves_the_bounds_and_matches_the_bounded_least_squares():
    """Random 6-joint cases (task and joint metrics, narrow windows): x within the bounds,
    held joints exactly on a bound, exactly the law where it is feasible, and with one held
    joint the free ones stationary in the metric."""
    rng = np.random.default_rng(3)
    for case in range(300):
        J = rng.normal(size=(6, 6))
        factor = SaturationMetricFactor(J, np.linalg.inv(J) if case % 2 else None)
        M = J.T @ J
        np.testing.assert_allclose(factor @ factor.T @ M, np.eye(6), atol=1e-6)
        if case % 3 == 0:
            factor, M = None, np.eye(6)
        desired = rng.normal(scale=2.0, size=6)
        width = rng.uniform(0.01, 2.0, size=6)
        lower = rng.uniform(-1.0, 0.0, size=6)
        upper = lower + width
        x, held = SaturatedLeastSquares(desired.tolist(), lower.tolist(), upper.tolist(), factor)
        x = np.array(x)
        assert np.all(x >= lower) and np.all(x <= upper)
        for j in held:
            assert x[j] in (lower[j], upper[j])
        if np.all((desired >= lower) & (desired <= upper)):
            assert held == [] and np.array_equal(x, desired)
        if len(held) == 1:
            free = [i for i in range(6) if i not in held]
            gradient = M @ (x - desired)
            np.testing.assert_allclose(gradient[free], 0.0, atol=1e-8 * np.abs(M).max() * 10)


def test_cholesky_solve_and_jerk_window():
    A = np.array([[4.0, 1.0, 0.5], [1.0, 3.0, 0.2], [0.5, 0.2, 2.0]])
    y = [1.0, -2.0, 0.5]
    np.testing.assert_allclose(CholeskySolve(A.tolist(), y), np.linalg.solve(A, y))
    # within 0.1 of the previous acceleration and within the step bounds; where those do
    # not overlap (the step bound moved past the previous value), the step bound
    lower, upper, inside = JerkWindow([0.3, 0.0], [0.0, 1.2], 0.1, [-1.0, -1.0], [1.0, 1.0])
    assert lower == [-0.1, 1.0] and upper == [0.1, 1.0] and not inside
    assert JerkWindow([0.05, 1.0], [0.0, 1.2], 0.1, [-1.0, -1.0], [1.0, 1.0])[2]


def test_governor_brakes_above_the_margin_only_and_keeps_c_zero_admissible():
    lower, upper = -np.ones(3), np.ones(3)
    qd = np.array([0.5, -0.4, 0.2])
    assert GovernorDamping(np.array([0.4, 0.0, 0.1]), qd, lower, upper, 0.5, 5.0) == 0.0
    a = np.array([0.9, -0.2, 0.0])
    braking = -GovernorDamping(a, qd, lower, upper, 0.5, 5.0) * qd
    assert np.all(braking * qd <= 0) and np.any(braking != 0)  # slows every moving joint
    assert np.all(a + braking <= upper) and np.all(a + braking >= lower)


def test_braking_fallback_slows_every_joint_within_the_limits_from_the_last_acceleration():
    qd = np.array([1.0, -0.5, 0.0, 0.2, -2.0, 0.01])
    lower, upper = -np.full(6, 1.4), np.full(6, 1.4)
    qdd = np.asarray(BrakingAcceleration(qd, np.zeros(6), lower, upper, 0.002, np.inf))
    assert np.all(qdd >= lower) and np.all(qdd <= upper)
    assert np.all(qdd * qd <= 0) and np.abs(qdd).max() == pytest.approx(1.4)
    np.testing.assert_allclose(qdd / np.abs(qdd).max(), -qd / np.abs(qd).max())  # direction kept
    # from the last acceleration, at most max_change per step towards full braking
    previous = np.full(6, 0.5)
    ramped = np.asarray(BrakingAcceleration(qd, previous, lower, upper, 0.002, 0.07))
    np.testing.assert_allclose(ramped, previous + np.clip(qdd - previous, -0.07, 0.07))


def test_on_the_seeds_task_faster_than_the_seeds_law_and_continuous(setups):
    """The braking approach, the per-joint saturation and the faster return of c shorten
    the paper's task by more than 5 % (4.52 s vs 5.41 s); with a weak braking approach
    (approach_acceleration 0.05) the robust mode stays within 5 % of the paper's law
    (5.30 s). Both keep q'' continuous: no step beyond max_jerk * dt = 0.1 rad/s^2."""
    setup = setups["ur10e"]
    waypoints = setup.planning.waypoints
    robust = _Run(setup, waypoints, setup.q0)
    paper_timed = _Run(setup, waypoints, setup.q0, approach_acceleration=0.05)
    seed = _Run(setup, waypoints, setup.q0, robust=False)
    for trajectory in (robust, paper_timed):
        _AssertFinishedWithinLimits(setup, trajectory, waypoints)
        assert trajectory.qdd[0].tolist() == [0.0] * 6 and trajectory.c[0] == 0  # smooth start
        assert np.abs(np.diff(trajectory.qdd, axis=0)).max() <= 0.1 + 1e-9
    assert robust.done_time == pytest.approx(4.52, abs=0.05)
    assert robust.done_time < 0.9 * seed.done_time
    assert paper_timed.done_time == pytest.approx(seed.done_time, rel=0.05)


def test_the_seeds_case_c_task_finishes_in_the_robust_mode(setups):
    """The task with which the paper's law stops in case (c) (test_acceleration_planning)."""
    setup = setups["ur10e"]
    kinematics = setup.planning.kinematics
    q_goal = setup.joint_waypoints[0] + np.array([0, 0.25, 0, 0, 0, 0])
    target = kinematics.Position(q_goal)[np.newaxis]
    with pytest.raises(PlanningError, match=r"case \(c\)"):
        _Run(setup, target, setup.q0, robust=False)
    _AssertFinishedWithinLimits(setup, _Run(setup, target, setup.q0), target)


@pytest.mark.parametrize("pitch", [PI / 2, -PI / 2])
def test_a_target_at_pitch_90_deg(setups, pitch):
    """At the Z-Y-X Euler singularity: the robust mode arrives, with the orientation exact
    (the rotation, not the ambiguous angles); the paper's law stops on the way (its analytic
    Jacobian blows up near pitch 90 deg: case (c), or the singularity itself)."""
    setup = setups["ur10e"]
    kinematics = setup.planning.kinematics
    start = kinematics.Position(setup.q0)
    target = np.array([[*(start[:3] + [0.05, -0.1, 0.1]), 0.3, pitch, -0.4]])
    trajectory = _Run(setup, target, setup.q0)
    _AssertFinishedWithinLimits(setup, trajectory, target)
    R_end = RotationMatrix(RollPitchYaw(kinematics.Position(trajectory.q[-1])[3:])).matrix()
    R_target = RotationMatrix(RollPitchYaw(target[0, 3:])).matrix()
    assert np.linalg.norm(RotationVector(R_end @ R_target.T)) <= 1e-3
    with pytest.raises(PlanningError, match=r"Euler-angle singularity|case \(c\)"):
        _Run(setup, target, setup.q0, robust=False)


def test_a_near_singular_start_is_handled_in_the_robust_mode(setups):
    setup = setups["ur10e"]
    q0 = setup.q0.copy()
    q0[4] = 0.008  # wrist 2 almost straight: smallest singular value about 0.008
    assert setup.planning.kinematics.MinSingularValue(q0) < 0.01
    waypoints = setup.planning.waypoints
    _AssertFinishedWithinLimits(setup, _Run(setup, waypoints, q0), waypoints)


def test_a_near_singular_start_is_refused_in_one_line_in_the_seeds_mode(capsys, tmp_path):
    start = "[-1.5707963, -1.5707963, -2.3561945, -0.7853982, 0.0001, 0.7853982]"
    code = main(
        [
            "run", "ur10e_waypoints", "--out", str(tmp_path), "--set", "planner.robust=false",
            "--set", f"station.arms.ur10e.initial_position={start}",
        ]
    )  # fmt: skip
    err = capsys.readouterr().err.strip().splitlines()
    assert code == 2 and len(err) == 1
    assert "initial position refused by the paper's law" in err[0] and "near-singular" in err[0]


@pytest.mark.parametrize("arm", list(ARMS))
def test_random_reachable_tasks_of_every_kind(setups, arm):
    """One task of each kind (regular, near-singular start, steep target) per arm; the
    benchmark and `guidedarm compare-planners --random 50 --arm ARM` run 50 or more."""
    setup = setups[arm]
    tasks = MakeRandomWaypointTasks(setup.planning.kinematics, len(KINDS), seed=7)
    assert [task.kind for task in tasks] == list(KINDS)
    assert tasks[1].start_sigma <= 0.03 and np.degrees(np.abs(tasks[2].waypoints[:, 4])).max() > 70
    for task in tasks:
        trajectory = _Run(setup, task.waypoints, task.q0)
        _AssertFinishedWithinLimits(setup, trajectory, task.waypoints)


@settings(
    max_examples=9,
    deadline=None,
    derandomize=True,
    suppress_health_check=[HealthCheck.function_scoped_fixture],
)
@given(arm=st.sampled_from(list(ARMS)), kind=st.integers(0, 2), seed=st.integers(100, 10_000))
def test_property_random_tasks_end_within_1_mm_and_keep_every_limit(setups, arm, kind, seed):
    """Any seeded random reachable task of any kind on any arm: the robust planner ends
    within 1 mm and no commanded sample exceeds a velocity or acceleration limit."""
    setup = setups[arm]
    task = MakeRandomWaypointTasks(setup.planning.kinematics, kind + 1, seed)[kind]
    trajectory = _Run(setup, task.waypoints, task.q0)
    _AssertFinishedWithinLimits(setup, trajectory, task.waypoints)


def test_compare_planners_random_table(capsys):
    assert main(["compare-planners", "--random", "2", "--arm", "rover_arm"]) == 0
    lines = capsys.readouterr().out.strip().splitlines()
    assert lines[0] == "2 random reachable tasks on rover_arm"
    rows = {line[:22].strip(): line[22:].split() for line in lines[2:]}
    assert list(rows) == [
        "acceleration planner", "paper's law", "movej blend 0.05 m", "toppra", "ruckig",
    ]  # fmt: skip
    assert rows["acceleration planner"][0] == "100%" and rows["acceleration planner"][7] == "0"
    assert float(rows["ruckig"][2]) == pytest.approx(1.0)  # T/ruckig of ruckig itself


def test_compare_planners_random_applies_set(capsys):
    """--set changes the arm's scenario of every random task: a max jerk of 10 rad/s^3
    bounds the robust planner's and Ruckig's jerk columns (the approach to the rover arm's
    velocity limit too, where the step bound's rate is capped at 10 / 1 rad/s^2)."""
    args = ["compare-planners", "--random", "1", "--arm", "rover_arm", "--seed", "3"]
    assert main([*args, "--set", "planner.max_jerk=10"]) == 0
    lines = capsys.readouterr().out.strip().splitlines()
    rows = {line[:22].strip(): line[22:].split() for line in lines[2:]}
    assert float(rows["acceleration planner"][6]) <= 10.0 + 1e-6
    assert float(rows["ruckig"][6]) <= 10.0 + 1e-6
