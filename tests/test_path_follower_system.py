"""PathFollower as a LeafSystem with the real ToolPoseIk, the arm following its commands
exactly and sensors that never see the hose: lost steps, then retries that first retrace
the way back, every command within the joint speed and acceleration limits."""

import numpy as np
import pytest
from pydrake.systems.analysis import Simulator
from pydrake.systems.framework import DiagramBuilder
from pydrake.systems.primitives import ConstantVectorSource, VectorLogSink

from guidedarm.diagrams.cli.command_run import LoadScenario
from guidedarm.diagrams.tasks.path_following import MakeSetup
from guidedarm.diagrams.tasks.path_following_execution import MakeSolver
from guidedarm.systems.path_following.path_follower import DONE, PathFollower
from guidedarm.systems.path_following.tool_pose_ik import ToolPoseIk
from guidedarm.systems.planning.acceleration_planner_math import PlanningError

DT = 0.002


@pytest.fixture(scope="module")
def blind_setup(tmp_path_factory):
    _, scenario, _ = LoadScenario("path_following", [])
    return MakeSetup(scenario, tmp_path_factory.mktemp("follower"))


@pytest.fixture(scope="module")
def blind_run(blind_setup):
    return _BlindRun(blind_setup)


def _BlindRun(made_setup, plan_move=None):
    """Runs the follower for 30 s with nothing in sight: (setup, loop state, commands)."""
    setup, _, (mount, grid) = made_setup
    builder = DiagramBuilder()
    ik = builder.AddSystem(ToolPoseIk(MakeSolver(setup), setup.period))
    follower = builder.AddSystem(
        PathFollower(
            setup.params, mount, grid, setup.q_start, setup.motion, setup.period, plan_move
        )
    )
    ranges = builder.AddSystem(ConstantVectorSource(np.full(6, 0.1)))
    valid = builder.AddSystem(ConstantVectorSource(np.zeros(6)))
    builder.Connect(ranges.get_output_port(), follower.GetInputPort("ranges"))
    builder.Connect(valid.get_output_port(), follower.GetInputPort("valid"))
    command = follower.GetOutputPort("position_commanded")
    builder.Connect(command, follower.GetInputPort("position_measured"))
    builder.Connect(command, ik.GetInputPort("position_measured"))
    for source, sink in [
        ("X_WF_measured", "X_WF_measured"),
        ("status", "ik_status"),
        ("q_goal", "q_goal"),
        ("failure", "ik_failure"),
    ]:
        builder.Connect(ik.GetOutputPort(source), follower.GetInputPort(sink))
    builder.Connect(follower.GetOutputPort("X_WF_desired"), ik.GetInputPort("X_WF_desired"))
    builder.Connect(follower.GetOutputPort("request"), ik.GetInputPort("request"))
    log = builder.AddSystem(VectorLogSink(len(setup.q_start), DT))
    builder.Connect(command, log.get_input_port())
    diagram = builder.Build()
    simulator = Simulator(diagram)
    root = simulator.get_mutable_context()
    ik.SetInitialGoal(ik.GetMyMutableContextFromRoot(root), setup.q_start)
    simulator.AdvanceTo(30.0)
    loop = follower.Loop(follower.GetMyContextFromRoot(root))
    return setup, loop, log.FindLog(root).data().T


def _Stops(q: np.ndarray) -> list[int]:
    """Sample indices where the commanded arm rests (held for two or more ticks)."""
    still = np.flatnonzero(np.all(np.abs(np.diff(q, axis=0)) < 1e-12, axis=1))
    stops = [0]
    for k in still:
        if np.max(np.abs(q[k] - q[stops[-1]])) > 1e-6:
            stops.append(int(k))
    return stops


def test_blind_follower_retraces_and_ends(blind_run):
    setup, loop, q = blind_run
    assert loop.mode == DONE, loop.failure
    stops = _Stops(q)
    # Three lost short steps forward (lost_limit 3), then the first retry goes back
    # through them in reverse (passing each at rest) and turns at the start pose.
    np.testing.assert_allclose(q[stops[0]], setup.q_start, atol=1e-9)
    assert len(stops) >= 8
    way_back = q[stops[3] : stops[4]]
    passes = []
    for k in (2, 1, 0):
        distance = np.max(np.abs(way_back - q[stops[k]]), axis=1)
        assert distance.min() < 1e-4, (k, distance.min())
        passes.append(int(np.argmin(distance)))
    assert passes == sorted(passes)
    # The turn in place at the start pose moves the tool centre by at most the IK's 0.5 mm.
    solver = MakeSolver(setup)
    p_start = solver.ForwardKinematics(q[stops[0]]) @ solver.p_FQ
    p_retry = solver.ForwardKinematics(q[stops[4]]) @ solver.p_FQ
    assert np.linalg.norm(p_retry - p_start) < 0.001


def test_a_move_that_cannot_be_planned_while_lost_skips_to_the_next_retry(blind_setup):
    def refuse(waypoints, tool_points):
        raise PlanningError("near-singular arm configuration")

    _, loop, q = _BlindRun(blind_setup, refuse)
    # Every move refused: the first lost step and each retry are skipped, then the end.
    assert loop.mode == DONE and loop.failure == ""
    assert np.max(np.abs(q - q[0])) == 0.0


def test_commands_stay_within_speed_and_acceleration_limits(blind_run):
    setup, _, q = blind_run
    v = np.diff(q, axis=0) / DT
    a = np.diff(v, axis=0) / DT
    assert np.max(np.abs(v)) <= setup.motion.max_joint_speed + 1e-6
    assert np.max(np.abs(a)) <= setup.motion.max_joint_acceleration * 1.05
