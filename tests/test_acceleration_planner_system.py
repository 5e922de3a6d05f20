"""AccelerationPlanner as a LeafSystem: ports, 500 Hz updates, same commands as its law."""

import numpy as np
import pytest
from pydrake.systems.analysis import Simulator
from pydrake.systems.framework import DiagramBuilder
from pydrake.systems.primitives import ConstantVectorSource, VectorLogSink

from guidedarm.diagrams.tasks.registry import LoadScenario
from guidedarm.diagrams.tasks.waypoints import MakePlannerSetup
from guidedarm.systems.errors import ConfigurationError
from guidedarm.systems.planning.acceleration_planner import AccelerationPlanner
from guidedarm.systems.planning.acceleration_planner_math import (
    AccelerationPlanning,
    PlannedTrajectory,
    PlannerConfig,
    PlannerState,
    PlanningError,
    RunPlanning,
)


@pytest.fixture(scope="module")
def setup():
    _, scenario, _ = LoadScenario("ur10e_waypoints", [])
    return MakePlannerSetup(scenario)


def _Simulate(planning: AccelerationPlanning, q0: np.ndarray, t_final: float):
    builder = DiagramBuilder()
    planner = builder.AddSystem(AccelerationPlanner(planning))
    measured = builder.AddSystem(ConstantVectorSource(np.concatenate([q0, np.zeros(6)])))
    builder.Connect(measured.get_output_port(), planner.get_input_port())
    log = builder.AddSystem(VectorLogSink(planner.GetOutputPort("planner_state").size()))
    builder.Connect(planner.GetOutputPort("planner_state"), log.get_input_port())
    diagram = builder.Build()
    simulator = Simulator(diagram)
    simulator.Initialize()
    simulator.AdvanceTo(t_final)
    context = planner.GetMyContextFromRoot(simulator.get_context())
    return planner, context, log.FindLog(simulator.get_context()).data()


def test_ports(setup):
    planner = AccelerationPlanner(setup.planning)
    assert planner.get_input_port().get_name() == "arm_state"
    assert planner.get_input_port().size() == 12
    for name in ("position_commanded", "velocity_commanded", "acceleration_commanded"):
        assert planner.GetOutputPort(name).size() == 6
    assert planner.GetOutputPort("scaling_coefficient").size() == 1
    assert planner.GetOutputPort("planner_state").size() == 18 + PlannerState.SIZE_EXTRA


def test_streams_the_law_at_500_hz_from_the_measured_start(setup):
    planner, context, data = _Simulate(setup.planning, setup.q0, 1.0)
    states = data[:, np.unique(data[PlannerState.TIME_ROW], return_index=True)[1]]
    logged = PlannedTrajectory.FromStateVectors(states)
    np.testing.assert_allclose(np.diff(logged.times), 0.002, atol=1e-12)
    np.testing.assert_array_equal(logged.q[0], setup.q0)
    reference = RunPlanning(setup.planning, setup.q0, max_time=1.0)
    np.testing.assert_allclose(logged.q, reference.q, atol=1e-12)
    np.testing.assert_allclose(logged.qdd, reference.qdd, atol=1e-9)
    # the outputs at t = 1 s are the state the update at t = 1 s produced
    assert context.get_time() == pytest.approx(1.0)
    np.testing.assert_allclose(
        planner.GetOutputPort("position_commanded").Eval(context), reference.q[-1], atol=1e-12
    )
    np.testing.assert_allclose(
        planner.GetOutputPort("velocity_commanded").Eval(context), reference.qd[-1], atol=1e-12
    )
    assert planner.GetOutputPort("scaling_coefficient").Eval(context)[0] == pytest.approx(
        reference.c[-1]
    )


def test_an_unreachable_waypoint_is_refused_at_construction_naming_it(setup):
    """In one's own diagram too: the LeafSystem solves every waypoint's IK before any
    motion, instead of failing mid-run."""
    waypoints = setup.planning.waypoints.copy()
    waypoints[2, :3] = [1.9, 0.0, 0.7]  # beyond the UR10e's 1.3 m reach
    with pytest.raises(
        ConfigurationError, match=r"^waypoint 3 \[1\.9, 0\.0, 0\.7, .* out of reach"
    ):
        AccelerationPlanner(setup.planning.WithWaypoints(waypoints))


def test_planning_errors_leave_the_simulator_as_planning_errors(setup):
    q0 = setup.q0.copy()
    q0[4] = 0.0  # wrist singularity: the paper's law refuses it
    planning = AccelerationPlanning(
        setup.planning.kinematics, setup.planning.waypoints, PlannerConfig(robust=False)
    )
    with pytest.raises(PlanningError, match="near-singular"):
        _Simulate(planning, q0, 0.01)
