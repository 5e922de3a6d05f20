"""The planner of a `waypoints` scenario (MakePlannerSetup) and the checks of the cell before
any motion."""

from dataclasses import dataclass

import numpy as np
from pydrake.multibody.plant import MultibodyPlant

from guidedarm.diagrams.tasks.common.cell_collisions import CellCollisions, ModelNames
from guidedarm.diagrams.tasks.common.planner_builder import MakeAccelerationPlanner, SymmetricLimit
from guidedarm.diagrams.tasks.common.planner_route import RouteClearOfCell
from guidedarm.diagrams.tasks.waypoints.scenario import WaypointsScenario
from guidedarm.systems.config_checks import CheckConfig, CheckInstance
from guidedarm.systems.planning.acceleration_planner import AccelerationPlanner
from guidedarm.systems.planning.acceleration_planner_math import AccelerationPlanning


@dataclass
class PlannerSetup:
    """The planner of a waypoints scenario (MakeAccelerationPlanner's LeafSystem), its law,
    controller plant, start q0 (rad), the waypoints' IK solutions (rad) and the symmetric
    limits (rad/s, rad/s^2; the scenario's even when a limit is switched off)."""

    planner: AccelerationPlanner
    plant: MultibodyPlant
    planning: AccelerationPlanning
    q0: np.ndarray
    joint_waypoints: np.ndarray
    velocity_limit: np.ndarray
    acceleration_limit: np.ndarray


def MakePlannerSetup(scenario: WaypointsScenario) -> PlannerSetup:
    """The scenario's planner through MakeAccelerationPlanner, which refuses bad input
    before any motion: unknown arm or frames, bad limits or gains, waypoints out of reach,
    and a near-singular start in the paper's mode; before those, the scenario's own checks
    (WaypointsScenario.Validate)."""
    CheckInstance("scenario", scenario, WaypointsScenario)
    CheckConfig(scenario)
    velocity = SymmetricLimit(scenario.max_joint_velocity, "max_joint_velocity")
    acceleration = SymmetricLimit(scenario.max_joint_acceleration, "max_joint_acceleration")
    planner = MakeAccelerationPlanner(
        scenario.station,
        scenario.arm,
        scenario.base_frame,
        scenario.tool_frame,
        scenario.waypoints,
        scenario.planner,
        velocity if scenario.limits != "none" else None,
        acceleration if scenario.limits == "velocity,acceleration" else None,
    )
    planning = planner.planning
    plant = planning.kinematics.plant
    q0 = plant.GetPositions(plant.CreateDefaultContext(), planning.kinematics.instance)
    return PlannerSetup(
        planner, plant, planning, q0, planning.joint_waypoints, velocity, acceleration
    )


def CheckCellBeforeMotion(scenario: WaypointsScenario, setup: PlannerSetup) -> CellCollisions:
    """Refuses (ConfigurationError, one line naming the bodies) a start pose or a
    waypoint's joint solution that collides with the cell or the arm itself and, in the
    robust mode, chooses the law's route by kinematic dry runs (RouteClearOfCell: the
    Cartesian law, or the task through joint space, towards the planner's or other IK
    solutions, where the Cartesian motion collides or oscillates; refused when no route is
    clear or can finish). The planner, setup.planning and setup.joint_waypoints then run
    that route. Returns the CellCollisions for the run's contact count."""
    collisions = CellCollisions(scenario.station, scenario.arm, ModelNames(setup.plant))
    collisions.Refuse(setup.q0, f"the {scenario.arm} start pose")
    for i, q in enumerate(setup.joint_waypoints):
        collisions.Refuse(q, f"the joint solution of waypoint {i + 1}")
    if scenario.planner.robust:
        route = RouteClearOfCell(setup.planning, setup.q0, scenario.max_time, collisions)
        if route.joint_space_from is not None:
            joints = route.planning.joint_waypoints
            setup.planner.RouteThroughJointSpaceFrom(route.joint_space_from, joints)
            setup.planning, setup.joint_waypoints = setup.planner.planning, joints
    return collisions


def PrepareWaypoints(scenario: WaypointsScenario) -> tuple[PlannerSetup, CellCollisions]:
    """Every check of a waypoints run before it starts, and what the run reuses: the
    planner (MakePlannerSetup) and the cell's collision checks (CheckCellBeforeMotion)."""
    setup = MakePlannerSetup(scenario)
    return setup, CheckCellBeforeMotion(scenario, setup)
