"""PathFollower as a LeafSystem with the real ToolPoseIk, wired by AddPathFollowing to a
station whose arm follows its commands exactly and whose sensors never see the hose: lost
steps, then retries that first retrace the way back, every command within the joint speed
and acceleration limits."""

import numpy as np
import pytest
from pydrake.systems.analysis import Simulator
from pydrake.systems.framework import DiagramBuilder
from pydrake.systems.primitives import ConstantVectorSource, LogVectorOutput, PassThrough

from guidedarm.diagrams.tasks.path_following.builder import AddPathFollowing
from guidedarm.diagrams.tasks.path_following.setup import MakeSetup
from guidedarm.diagrams.tasks.registry import LoadScenario
from guidedarm.systems.path_following.path_follower import DONE
from guidedarm.systems.planning.acceleration_planner_math import PlanningError

DT = 0.002


@pytest.fixture(scope="module")
def blind_setup(tmp_path_factory):
    _, scenario, _ = LoadScenario("path_following", [])
    return MakeSetup(scenario, tmp_path_factory.mktemp("follower"))


@pytest.fixture(scope="module")
def blind_run(blind_setup):
    return _BlindRun(blind_setup)


def _BlindStation(setup):
    """A station whose arm is where it is commanded and whose ToF tool sees nothing."""
    builder = DiagramBuilder()
    command = builder.AddSystem(PassThrough(len(setup.q_start)))
    builder.ExportInput(command.get_input_port(), f"{setup.arm}.position_commanded")
    builder.ExportOutput(command.get_output_port(), f"{setup.arm}.position_measured")
    for port, value in (("ranges", np.full(6, 0.1)), ("valid", np.zeros(6))):
        source = builder.AddSystem(ConstantVectorSource(value))
        builder.ExportOutput(source.get_output_port(), f"{setup.tool_name}.{port}")
    return builder.Build()


def _BlindRun(setup, plan_move=None):
    """Runs the follower for 30 s with nothing in sight: (setup, loop state, commands)."""
    builder = DiagramBuilder()
    station = builder.AddSystem(_BlindStation(setup))
    follower, _ = AddPathFollowing(builder, station, setup, plan_move)
    log = LogVectorOutput(follower.GetOutputPort("position_commanded"), builder, DT)
    simulator = Simulator(builder.Build())
    simulator.AdvanceTo(30.0)
    root = simulator.get_context()
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
    solver = setup.solver
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
    assert np.max(np.abs(v)) <= setup.limits.max_joint_speed + 1e-6
    assert np.max(np.abs(a)) <= setup.limits.max_joint_acceleration * 1.05
