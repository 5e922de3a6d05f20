"""The DifferentialIkServo's cost-saving pieces keep its results: the reach bound of the
wall check's memo holds on the MZ04D controller plant and its outputs are cached state
(its compiled kernel: test_differential_ik_servo_kernel.py)."""

import numpy as np
import pytest
from pydrake.math import RigidTransform

from guidedarm.diagrams.tasks.path_following.setup import MakeSetup
from guidedarm.diagrams.tasks.registry import LoadScenario
from guidedarm.systems.path_following.differential_ik_servo import DifferentialIkServo
from guidedarm.systems.path_following.differential_ik_servo_math import ReachBound
from guidedarm.systems.path_following.workspace import WorkspaceConfig
from guidedarm.systems.plant_frames import GetScopedFrame


@pytest.fixture(scope="module")
def setup():
    _, scenario, _ = LoadScenario("path_following", ["motion=continuous"])
    return MakeSetup(scenario)


def test_no_body_origin_moves_farther_than_the_reach_bound(setup):
    """|p(q + dq) - p(q)| <= R sum |dq| for every moved body, random q and dq (rad)."""
    plant = setup.solver.plant
    moved = plant.GetBodiesKinematicallyAffectedBy(list(plant.GetJointIndices()))
    bodies = [plant.get_body(b) for b in moved]
    reach = ReachBound(plant, bodies)
    assert 0.5 < reach < 2.0  # m: the MZ04D with gripper and tool, not a loose bound
    context = plant.CreateDefaultContext()
    rng = np.random.default_rng(0)

    def Origins(q):
        plant.SetPositions(context, q)
        return np.array([plant.EvalBodyPoseInWorld(context, b).translation() for b in bodies])

    worst = 0.0
    for _ in range(300):
        q = setup.q_start + rng.normal(0.0, 0.5, 6)
        dq = rng.normal(0.0, 0.05, 6) * rng.integers(0, 2, 6)
        moved_by = np.linalg.norm(Origins(q + dq) - Origins(q), axis=1).max()
        worst = max(worst, moved_by / (reach * np.abs(dq).sum() + 1e-300))
    assert worst <= 1.0
    assert worst > 0.3  # the bound is attained to within a factor of about 3


def test_workspace_margin_is_the_distance_to_the_nearest_wall():
    walls = WorkspaceConfig(x=[-0.5, 0.5], y=[-0.4, 0.4], z=[0.0, np.inf])
    points = np.array([[0.1, 0.0, 0.3], [0.45, -0.2, 0.2]])
    assert walls.Margin(points) == pytest.approx(0.05)


def test_servo_outputs_are_its_state(setup):
    """position_commanded and velocity_commanded are the servo's q and v state (Drake state
    outputs: no Python call when the station's interpolator reads them every plant step),
    and follow a change of that state."""
    plant = setup.solver.plant
    tool = GetScopedFrame(plant, setup.station.tof_tools["tof"].tool_frame, "tool")
    servo = DifferentialIkServo(plant, tool, setup.q_start, 0.004, 1.0, 5.0, 20.0, np.ones(6), 0.02)
    context = servo.CreateDefaultContext()
    servo.GetInputPort("X_WT_desired").FixValue(context, RigidTransform())
    position = servo.GetOutputPort("position_commanded")
    velocity = servo.GetOutputPort("velocity_commanded")
    np.testing.assert_array_equal(position.Eval(context), setup.q_start)
    np.testing.assert_array_equal(velocity.Eval(context), np.zeros(6))
    q = setup.q_start + 0.1
    context.SetDiscreteState(0, q)
    context.SetDiscreteState(1, np.full(6, 0.2))
    np.testing.assert_array_equal(position.Eval(context), q)
    np.testing.assert_array_equal(velocity.Eval(context), np.full(6, 0.2))
    assert servo.GetOutputPort("failure").Eval(context) == ""
