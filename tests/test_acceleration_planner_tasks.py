"""AccelerationPlanner with tasks given while it runs (the `task` input port, `done` output)."""

import numpy as np
import pytest
from pydrake.systems.analysis import Simulator
from pydrake.systems.framework import DiagramBuilder
from pydrake.systems.primitives import ConstantVectorSource, VectorLogSink

from guidedarm.diagrams.tasks.registry import LoadScenario
from guidedarm.diagrams.tasks.waypoints import MakePlannerSetup
from guidedarm.systems.planning.acceleration_planner import AccelerationPlanner
from guidedarm.systems.planning.acceleration_planner_kinematics import WrapAngle
from guidedarm.systems.planning.acceleration_planner_math import (
    PlannedTrajectory,
    PlannerState,
    PlannerTask,
    PlanningError,
    RunPlanning,
)


@pytest.fixture(scope="module")
def setup():
    _, scenario, _ = LoadScenario("ur10e_waypoints", [])
    return MakePlannerSetup(scenario)


class TaskedPlanner:
    """A task-driven planner in a Diagram, its task fixed on the input port."""

    def __init__(self, setup) -> None:
        builder = DiagramBuilder()
        self.planner = builder.AddSystem(AccelerationPlanner(setup.planning, accept_tasks=True))
        measured = builder.AddSystem(ConstantVectorSource(np.concatenate([setup.q0, np.zeros(6)])))
        builder.Connect(measured.get_output_port(), self.planner.GetInputPort("arm_state"))
        self.log = builder.AddSystem(
            VectorLogSink(self.planner.GetOutputPort("planner_state").size())
        )
        builder.Connect(self.planner.GetOutputPort("planner_state"), self.log.get_input_port())
        self.simulator = Simulator(builder.Build())
        self.context = self.planner.GetMyMutableContextFromRoot(
            self.simulator.get_mutable_context()
        )
        self.SetTask(PlannerTask())
        self.simulator.Initialize()

    def SetTask(self, task: PlannerTask) -> None:
        self.planner.GetInputPort("task").FixValue(self.context, task)

    def Done(self) -> bool:
        return self.planner.GetOutputPort("done").Eval(self.context)[0] == 1.0

    def Trajectory(self) -> PlannedTrajectory:
        data = self.log.FindLog(self.simulator.get_context()).data()
        steps = np.unique(data[PlannerState.TIME_ROW], return_index=True)[1]
        return PlannedTrajectory.FromStateVectors(data[:, steps])


def test_holds_still_without_a_task(setup):
    tasked = TaskedPlanner(setup)
    tasked.simulator.AdvanceTo(0.2)
    trajectory = tasked.Trajectory()
    np.testing.assert_array_equal(trajectory.q, np.tile(setup.q0, (trajectory.q.shape[0], 1)))
    assert tasked.Done()


def test_a_task_from_rest_equals_the_fixed_task_law(setup):
    tasked = TaskedPlanner(setup)
    tasked.SetTask(PlannerTask(0, setup.planning.waypoints))
    tasked.simulator.AdvanceTo(1.0)
    reference = RunPlanning(setup.planning, setup.q0, max_time=1.0)
    np.testing.assert_allclose(tasked.Trajectory().q, reference.q, atol=1e-12)
    assert not tasked.Done()


def test_re_planning_restarts_smoothly_and_signals_done(setup):
    tasked = TaskedPlanner(setup)
    final = setup.planning.waypoints[-1]
    tasked.SetTask(PlannerTask(0, setup.planning.waypoints))
    t = 0.0
    while not tasked.Done():
        t += 0.1
        assert t < 10.0, "first task did not end"
        tasked.simulator.AdvanceTo(t)
    first_end = tasked.Trajectory().done_time
    assert 0 < first_end <= t
    tasked.simulator.AdvanceTo(t + 1.0)  # come to rest
    t_switch = tasked.simulator.get_context().get_time()
    moved = final + np.array([0.0, 0.1, -0.1, 0.0, 0.0, 0.1])
    tasked.SetTask(PlannerTask(1, moved[np.newaxis]))
    assert not tasked.Done()  # the new task is not the ended one
    while not tasked.Done():
        t_switch += 0.1
        assert t_switch < t + 12.0, "second task did not end"
        tasked.simulator.AdvanceTo(t_switch)
    trajectory = tasked.Trajectory()
    # the same limits as the fixed task (the paper's 60 deg/s, 80 deg/s^2), a continuous
    # restart (c from 0 again) and the end within 1 mm of the new target
    assert np.abs(trajectory.qd).max() <= setup.velocity_limit[0] + 1e-9
    assert np.abs(trajectory.qdd).max() <= setup.acceleration_limit[0] + 1e-9
    # continuous: every step within max_jerk * dt (0.1 rad/s^2)
    assert np.abs(np.diff(trajectory.qdd, axis=0)).max() <= 0.1 + 1e-9
    after = trajectory.times > t + 1.0
    assert trajectory.c[after][0] < 0.01
    p_end = setup.planning.kinematics.Position(trajectory.q[-1])
    assert np.linalg.norm(p_end[:3] - moved[:3]) <= 1e-3
    assert np.abs(WrapAngle(p_end[3:] - moved[3:])).max() <= 1e-3  # roll pi is roll -pi


def test_an_unreachable_task_is_refused_before_moving(setup):
    tasked = TaskedPlanner(setup)
    far = setup.planning.waypoints[-1] + np.array([3.0, 0.0, 0.0, 0.0, 0.0, 0.0])
    tasked.SetTask(PlannerTask(4, far[np.newaxis]))
    with pytest.raises(PlanningError, match=r"planner task 4 refused: waypoint 1 .* out of reach"):
        tasked.simulator.AdvanceTo(0.01)
    np.testing.assert_array_equal(tasked.Trajectory().q[-1], setup.q0)
