"""The robust planner's joint position limits (viability bound) and its watch over its own
motion (oscillation measure, progress), on the plain functions, without a Diagram."""

import math

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from guidedarm.diagrams.tasks.registry import LoadScenario
from guidedarm.diagrams.tasks.waypoints import MakePlannerSetup
from guidedarm.systems.planning.acceleration_planner_kinematics import PlanningError
from guidedarm.systems.planning.acceleration_planner_math import RunPlanning
from guidedarm.systems.planning.acceleration_planner_position_limits import (
    PositionStepBounds,
    ViableSpeed,
)
from guidedarm.systems.planning.acceleration_planner_robust_limits import JerkWindow, StepBounds
from guidedarm.systems.planning.acceleration_planner_watch import (
    Progressed,
    ReversalRates,
    TargetError,
)
from guidedarm.systems.planning.random_waypoint_tasks import EXTRA_KINDS, MakeRandomWaypointTasks
from guidedarm.systems.planning.waypoint_ik import SolveWaypointIk

DT = 0.002
A, V, RATE, BRAKING, JERK = 1.4, 1.05, 25.0, 0.7, 50.0


def _DriveTowardsLimit(q0: float, qd0: float, q_upper: float, seconds: float):
    """One joint whose law asks for +A all the time, bounded by the acceleration, velocity
    and position step bounds and the jerk window as the robust step does: (q, qd, qdd)."""
    q, qd, qdd = q0, qd0, 0.0
    samples = []
    for _ in range(round(seconds / DT)):
        lower, upper = StepBounds(([-A], [A]), ([-V], [V]), [qd], RATE)
        lower, upper = PositionStepBounds(
            [q], [qd], lower, upper, [-10.0], [q_upper], [BRAKING], RATE
        )
        w_lo, w_hi, _ = JerkWindow([A], [qdd], JERK * DT, lower, upper)
        qdd = min(max(A, w_lo[0]), w_hi[0])
        qd_next = qd + qdd * DT
        q += 0.5 * (qd + qd_next) * DT
        qd = qd_next
        samples.append((q, qd, qdd))
    return np.array(samples)


def test_viable_speed_is_the_square_root_law_of_braking_smoothed_at_the_limit():
    c = 0.7 / RATE
    v, slope = ViableSpeed(0.5, 0.7, RATE)
    assert v == pytest.approx(math.sqrt(0.7 + c * c) - c) and slope == pytest.approx(0.7 / (v + c))
    assert abs(v - math.sqrt(0.7)) <= c  # the square-root law less at most c = 0.028 rad/s
    assert ViableSpeed(1e-9, 0.7, RATE)[1] == pytest.approx(RATE)  # a finite slope at it
    assert ViableSpeed(0.0, 0.7, RATE)[0] == 0.0 and ViableSpeed(-0.1, 0.7, RATE)[0] == 0.0


@pytest.mark.parametrize("distance", [0.02, 0.15, 1.0, 3.0])
def test_a_joint_pushed_at_its_limit_brakes_in_time_and_rests_there(distance):
    """From rest `distance` rad before the limit, a law that always asks for +A: the joint
    never passes the limit, never exceeds the acceleration, velocity or jerk limit, and
    comes to rest at the limit without chatter (its acceleration settles at 0)."""
    samples = _DriveTowardsLimit(0.0, 0.0, distance, 6.0)
    q, qd, qdd = samples.T
    assert q.max() <= distance + 1e-9
    assert np.abs(qdd).max() <= A + 1e-12 and np.abs(qd).max() <= V + 1e-12
    assert np.abs(np.diff(qdd)).max() <= JERK * DT * (1 + 1e-9)  # the bound moves smoothly
    assert q[-1] == pytest.approx(distance, abs=2e-3)
    assert np.abs(qd[-500:]).max() < 1e-3 and np.abs(qdd[-500:]).max() < 1e-3


def test_a_joint_arriving_at_full_speed_brakes_within_the_acceleration_limit():
    """At the velocity limit 1 rad before the limit (its braking distance at A/2 is 0.79
    rad): braking starts early enough to stop before it at the acceleration limit."""
    samples = _DriveTowardsLimit(0.0, V, 1.0, 4.0)
    q, _, qdd = samples.T
    assert q.max() <= 1.0 + 1e-9
    assert qdd.min() >= -A - 1e-12


def test_at_rest_on_the_limit_the_bound_neither_pushes_back_nor_lets_it_pass():
    lower, upper = PositionStepBounds(
        [1.0, -1.0], [0.0, 0.0], [-A, -A], [A, A], [-1.0, -1.0], [1.0, 1.0], [BRAKING] * 2, RATE
    )
    assert upper[0] == 0.0 and lower[0] == -A  # at the upper limit: may leave, not pass
    assert lower[1] == 0.0 and upper[1] == A  # at the lower limit likewise


def test_far_from_the_limits_the_bounds_are_unchanged_and_past_them_braking_is_full():
    far = PositionStepBounds([0.0], [0.5], [-A], [A], [-3.0], [3.0], [BRAKING], RATE)
    assert far == ([-A], [A])
    past = PositionStepBounds([1.01], [0.3], [-A], [A], [-3.0], [1.0], [BRAKING], RATE)
    assert past == ([-A], [-A])


def test_the_oscillation_measure_counts_a_limit_cycle_and_not_a_move():
    """A 3 Hz swing between the acceleration limits exceeds the default bound 5 /s
    within 4 s; a rest-to-rest bang-bang move (accelerate, brake) reverses once."""
    times = np.arange(0.0, 5.0, DT)
    cycle = A * np.sign(np.sin(2 * np.pi * 3.0 * times))[:, None]
    rates = ReversalRates(cycle, np.array([A]), DT)[:, 0]
    first = times[np.argmax(rates > 5.0)]
    assert rates.max() > 5.0 and first < 4.0
    move = np.where(times < 1.0, A, np.where(times < 2.0, -A, 0.0))[:, None]
    assert ReversalRates(move, np.array([A]), DT).max() == pytest.approx(0.5, abs=1e-9)
    small = 0.4 * cycle  # swings within 50 % of the limit do not count
    assert ReversalRates(small, np.array([A]), DT).max() == 0.0


def test_progress_is_a_smaller_error_or_more_waypoint_progress():
    assert TargetError([0.03, 0.0, 0.04, 0.0, 0.0, 0.2]) == pytest.approx(0.07)
    assert Progressed(0.098, 0.0, 0.1, 0.0) == (True, 0.098, 0.0)
    assert Progressed(0.0995, 0.0, 0.1, 0.0) == (False, 0.1, 0.0)
    assert Progressed(0.2, 1.5, 0.1, 1.0) == (True, 0.2, 1.5)


@pytest.fixture(scope="module")
def setups():
    names = {"ur10e": "ur10e_waypoints", "mz04d": "mz04d_waypoints"}
    names["rover_arm"] = "rover_arm_waypoints"
    return {arm: MakePlannerSetup(LoadScenario(name, [])[1]) for arm, name in names.items()}


@settings(
    max_examples=4,
    deadline=None,
    derandomize=True,
    suppress_health_check=[HealthCheck.function_scoped_fixture],
)
@given(
    arm=st.sampled_from(["ur10e", "mz04d", "rover_arm"]),
    kind=st.sampled_from(EXTRA_KINDS),
    seed=st.integers(0, 10_000),
)
def test_property_near_limit_and_large_tasks_end_within_1_mm_inside_every_limit(
    setups, arm, kind, seed
):
    """Any seeded random task starting 0.02-0.15 rad from a joint limit, or moving
    0.2-0.5 m and up to 90 deg, on any arm, the planner alone: it ends within 1 mm, the
    commanded q stays within the limits less the margin, qd and qdd within theirs, and no
    joint's acceleration reverses more often than the oscillation bound."""
    setup = setups[arm]
    planning = setup.planning
    task = MakeRandomWaypointTasks(planning.kinematics, 1, seed, kind)[0]
    margin = planning.parameters.joint_limit_margin
    joints = SolveWaypointIk(planning.kinematics, task.waypoints, task.q0, margin=margin)
    trajectory = RunPlanning(planning.WithWaypoints(task.waypoints, joints), task.q0, 20.0)
    assert trajectory.done_time > 0
    p_end = planning.kinematics.Position(trajectory.q[-1])
    assert np.linalg.norm(p_end[:3] - task.waypoints[-1, :3]) <= 1e-3
    lower, upper = planning.kinematics.PositionLimits()
    # a start inside the margin may stay there; the command never goes further out
    inner_lower = np.minimum(lower + margin, task.q0) - 1e-9
    inner_upper = np.maximum(upper - margin, task.q0) + 1e-9
    assert np.all(trajectory.q >= inner_lower) and np.all(trajectory.q <= inner_upper)
    assert np.all(np.abs(trajectory.qd) <= setup.velocity_limit * (1 + 1e-9))
    assert np.all(np.abs(trajectory.qdd) <= setup.acceleration_limit * (1 + 1e-9))
    rates = ReversalRates(trajectory.qdd, setup.acceleration_limit, planning.parameters.time_step)
    assert rates.max() <= planning.parameters.max_reversal_rate


def test_a_target_past_a_joint_limit_stops_with_a_no_progress_failure_within_seconds(setups):
    """The rover arm's TCP sent where J2 would be 0.4 rad past its upper limit, without
    joint solutions to hand over to: the law holds J2 within its margin, makes no progress
    and stops with a PlanningError naming the waypoint stall_time (3 s) after its last
    progress, well before the 20 s time limit."""
    setup = setups["rover_arm"]
    planning = setup.planning
    lower, upper = planning.kinematics.PositionLimits()
    q_goal = setup.q0.copy()
    q_goal[1] = upper[1] + 0.4
    target = planning.kinematics.Position(q_goal)[np.newaxis]
    law = planning.WithWaypoints(target)
    state = law.InitialState(setup.q0)
    with pytest.raises(PlanningError, match=r"no progress towards waypoint 1 for 3\.0 s"):
        while state.t < 20.0:
            state = law.Step(state)
            assert lower[1] + 0.01 - 1e-9 <= state.q[1] <= upper[1] - 0.01 + 1e-9
    assert state.t < 12.0  # 9.5 s: it creeps closer until about 6.5 s, then 3 s stalled
