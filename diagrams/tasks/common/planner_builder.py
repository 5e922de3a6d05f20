"""MakeAccelerationPlanner: the acceleration-level planner for one arm of a station, ready to
wire, on its own controller plant; and MakeControllerPlant, the plant it solves on.

    station = builder.AddSystem(MakeStation(scenario))
    planner = builder.AddSystem(MakeAccelerationPlanner(
        scenario, "mz04d", "mz04d::base", "tof_tool::tof_tool", waypoints))
    builder.Connect(station.GetOutputPort("mz04d.state_estimated"),
                    planner.GetInputPort("arm_state"))
    builder.Connect(planner.GetOutputPort("position_commanded"),
                    station.GetInputPort("mz04d.position_commanded"))

(examples/planner_on_mz04d.py runs this.) The controller plant holds the arm and the models
welded between it and the frames the planner uses (tools, grippers), made by the station's
own MakeMultibodyPlant, so the arm sits where the station has it and nothing else is in it.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from pydrake.multibody.plant import MultibodyPlant
from pydrake.multibody.tree import BodyIndex, JointIndex

from guidedarm.diagrams.station.scenario import StationScenario
from guidedarm.diagrams.station.station_plant import GetArmInstance, MakeMultibodyPlant
from guidedarm.systems.config_checks import CheckInstance, FieldError
from guidedarm.systems.errors import ConfigurationError
from guidedarm.systems.planning.acceleration_planner import AccelerationPlanner
from guidedarm.systems.planning.acceleration_planner_kinematics import ArmKinematics, PlanningError
from guidedarm.systems.planning.acceleration_planner_math import AccelerationPlanning, PlannerConfig
from guidedarm.systems.plant_frames import GetScopedFrame

DEFAULT_VELOCITY = [np.radians(60.0)]  # rad/s, the paper's 60 deg/s
DEFAULT_ACCELERATION = [np.radians(80.0)]  # rad/s^2, the paper's 80 deg/s^2


def MakeControllerPlant(
    scenario: StationScenario, arm: str, frame_names: Sequence[str]
) -> MultibodyPlant:
    """The arm as its controller knows it: MakeMultibodyPlant(scenario, instances) with the
    arm and every model on the kinematic chain from it to the scoped frames `frame_names`
    (e.g. the gripper between the MZ04D's flange and its ToF tool), nothing of the scene.
    The arm's default positions are its scenario initial position."""
    if arm not in scenario.arms:
        raise ConfigurationError(f"arm '{arm}' is not in station.arms {list(scenario.arms)}")
    whole = MakeMultibodyPlant(scenario)
    arm_instance = GetArmInstance(whole, arm)
    parents = {}
    for i in range(whole.num_joints()):
        joint = whole.get_joint(JointIndex(i))
        parents[joint.child_body().index()] = joint.parent_body().index()
    names = [arm]
    for scoped in frame_names:
        body = GetScopedFrame(whole, scoped, scoped).body().index()
        chain = []
        while whole.get_body(body).model_instance() != arm_instance:
            if body == BodyIndex(0):
                raise ConfigurationError(f"frame '{scoped}' is not carried by the arm '{arm}'")
            chain.append(whole.GetModelInstanceName(whole.get_body(body).model_instance()))
            body = parents[body]
        names += [name for name in chain if name not in names]
    return MakeMultibodyPlant(scenario, names)


def SymmetricLimit(values: float | Sequence[float], key: str) -> np.ndarray:
    """Six positive limits from one value for every joint or one per joint."""
    limit = np.atleast_1d(np.asarray(values, float))
    if limit.size == 1:
        limit = np.full(6, limit[0])
    if limit.size != 6 or not np.all(np.isfinite(limit)) or np.any(limit <= 0):
        raise ConfigurationError(f"{key} needs 1 or 6 positive values, got {values}")
    return limit


def MakeAccelerationPlanner(
    scenario: StationScenario,
    arm: str,
    base_frame: str,
    tool_frame: str,
    waypoints: np.ndarray | Sequence[Sequence[float]] | None = None,
    config: PlannerConfig | None = None,
    max_joint_velocity: float | Sequence[float] | None = DEFAULT_VELOCITY,
    max_joint_acceleration: float | Sequence[float] | None = DEFAULT_ACCELERATION,
) -> AccelerationPlanner:
    """The AccelerationPlanner LeafSystem moving the TCP `tool_frame` of `arm` through
    `waypoints`, checked before any motion.

    scenario: the station's scenario (the planner's plant is MakeControllerPlant of it).
    arm: a key of scenario.arms. base_frame, tool_frame: scoped frame names (e.g.
    `mz04d::base`, `tof_tool::tof_tool`) of the base B and the TCP T.
    waypoints: rows [x, y, z, roll, pitch, yaw] of T in B (m, rad, Z-Y-X Euler angles), the
    last one the final location; None makes a planner that takes tasks while running (input
    `task`, PlannerTask; output `done`).
    config: gains and settings (PlannerConfig(), the robust mode, by default).
    max_joint_velocity, max_joint_acceleration: symmetric joint limits (rad/s, rad/s^2), one
    value for all joints or one per joint; None switches that limit off.

    Refused with a ConfigurationError (one line) before anything runs: an unknown arm or
    frame, bad limits or settings, a waypoint out of reach of the arm (inverse kinematics
    within the joint limits from the arm's scenario initial position; the message names the
    waypoint), and in the paper's mode (config.robust False) a near-singular initial position.

    Ports of the returned system: input `arm_state` (12: q in rad, v in rad/s, read once at
    initialization; connect the station's `<arm>.state_estimated`); outputs
    `position_commanded` (6, rad; to the station's `<arm>.position_commanded`),
    `velocity_commanded` (rad/s), `acceleration_commanded` (rad/s^2), `scaling_coefficient`
    (c) and `planner_state` (the PlannerState vector); all updated every config.time_step.
    Its `planning` holds the law (kinematics on the controller plant, limits, waypoints and
    their joint solutions `planning.joint_waypoints`, rad).
    """
    CheckInstance("scenario", scenario, StationScenario)
    for name, value in (("arm", arm), ("base_frame", base_frame), ("tool_frame", tool_frame)):
        CheckInstance(name, value, str)
    CheckInstance("config", config, (PlannerConfig, type(None)))
    config = config if config is not None else PlannerConfig()
    plant = MakeControllerPlant(scenario, arm, [base_frame, tool_frame])
    kinematics = ArmKinematics(
        plant,
        GetArmInstance(plant, arm),
        GetScopedFrame(plant, base_frame, "base_frame"),
        GetScopedFrame(plant, tool_frame, "tool_frame"),
        config.min_singular_value,
    )
    velocity = acceleration = None
    if max_joint_velocity is not None:
        limit = SymmetricLimit(max_joint_velocity, "max_joint_velocity")
        velocity = (-limit, limit)
    if max_joint_acceleration is not None:
        limit = SymmetricLimit(max_joint_acceleration, "max_joint_acceleration")
        acceleration = (-limit, limit)
    q_start = plant.GetPositions(plant.CreateDefaultContext(), kinematics.instance)
    rows = _WaypointRows(waypoints) if waypoints is not None else None
    planning = AccelerationPlanning(
        kinematics,
        rows if rows is not None else kinematics.Position(q_start)[np.newaxis],
        config,
        velocity,
        acceleration,
    )
    if rows is not None:
        try:
            planning.InitialState(q_start)
        except PlanningError as e:
            raise ConfigurationError(
                f"{arm} initial position refused by the paper's law (planner.robust: false): {e}"
            ) from None
    return AccelerationPlanner(planning, accept_tasks=rows is None, q_guess=q_start)


def _WaypointRows(waypoints: np.ndarray | Sequence[Sequence[float]]) -> np.ndarray:
    """The waypoints as a 2-D float array, or a ConfigurationError naming them."""
    try:
        return np.atleast_2d(np.asarray(waypoints, float))
    except (TypeError, ValueError):
        why = f"expected rows [x, y, z, roll, pitch, yaw] of numbers, got {waypoints!r}"
        raise FieldError("waypoints", why) from None
