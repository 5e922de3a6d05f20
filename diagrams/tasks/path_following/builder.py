"""Public builders of path following: the follower loop wired to a station, and a kinematic
station that stands in for the simulated one.

The loop of Wawrzyniak et al.'s figure 10 as a Diagram:

    station `<tof>.ranges`, `<tof>.valid` ──> PathFollower ──X_WF_desired, request──> ToolPoseIk
    station `<arm>.position_measured` ──> PathFollower, ToolPoseIk
    ToolPoseIk `X_WF_measured`, `status`, `q_goal`, `failure` ──> PathFollower
    PathFollower `position_commanded` ──> station `<arm>.position_commanded`

Any Diagram exporting those four port names is a station: MakeStation's (simulated or
hardware) or MakeStation(..., kind="kinematic")'s (the arm is where it is commanded, no
dynamics).

A user's diagram (examples/tof_following_on_ur10e.py):

    setup = MakeSetup(scenario)                      # hose, workspace, start pose (IK)
    builder = DiagramBuilder()
    station = builder.AddNamedSystem("station", MakeStation(setup.station))
    follower, ik = AddPathFollowing(builder, station, setup)
    simulator = Simulator(builder.Build())
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
from pydrake.multibody.plant import MultibodyPlant
from pydrake.systems.framework import Diagram, DiagramBuilder

from guidedarm.diagrams.builder_checks import CheckStationWiring
from guidedarm.diagrams.station.station_plant import GetArmInstance
from guidedarm.diagrams.tasks.path_following.setup import Setup
from guidedarm.systems.config_checks import CheckInstance
from guidedarm.systems.path_following.continuous_follower import ContinuousFollower
from guidedarm.systems.path_following.differential_ik_servo import DifferentialIkServo
from guidedarm.systems.path_following.joint_moves import MovePlanner
from guidedarm.systems.path_following.path_follower import PathFollower
from guidedarm.systems.path_following.planner_moves import PlannerMoves
from guidedarm.systems.path_following.tool_pose_ik import ToolPoseIk
from guidedarm.systems.planning.acceleration_planner_math import AccelerationPlanning, ArmKinematics
from guidedarm.systems.plant_frames import GetScopedFrame


class PathFollowing(NamedTuple):
    """The systems AddPathFollowing adds: the follower and what turns its targets into
    joint commands (ToolPoseIk, or the DifferentialIkServo of `continuous`)."""

    follower: PathFollower | ContinuousFollower
    ik: ToolPoseIk | DifferentialIkServo


def AddPathFollowing(
    builder: DiagramBuilder,
    station: Diagram,
    setup: Setup,
    plan_move: MovePlanner | None = None,
) -> PathFollowing:
    """Adds a PathFollower ("path_follower") and a ToolPoseIk ("tool_pose_ik") to `builder`
    and wires them to `station`, a system already in `builder` with MakeStation's ports:

    inputs used   `<tof>.ranges` (6, m; max_range without a return), `<tof>.valid` (6, 0/1),
                  `<arm>.position_measured` (n, rad)
    input driven  `<arm>.position_commanded` (n, rad): rest-to-rest joint moves, or moves
                  of the acceleration-level planner when setup.motion is `planner`

    <arm> and <tof> are setup.arm and setup.tool_name. The IK works in the world frame W on
    setup.solver's controller plant; the gripper frame G is setup.gripper_frame, the tool
    centre O stays on target, the workspace walls are in the arm's base frame B. Both
    systems tick every setup.period s; the arm must start at setup.q_start (MakeSetup puts
    it in setup.station). plan_move: how moves are made (default as setup.motion says).

    Outputs for logging and stopping: follower `step_record` (RECORD_FIELDS of the latest
    step; world frame, m), `mode` ([mode, step]; DONE = 3, FAILED = 4), `failure` (str),
    `detections`/`detection_errors` (3 x 3 grid of the latest reading); ik `status`.

    With setup.motion `continuous` the follower is a ContinuousFollower (also reading
    `<tof>.measured_at`, 6, s) and a DifferentialIkServo streams its target to
    `<arm>.position_commanded` (AddContinuousFollowing).
    """
    CheckInstance("setup", setup, Setup)
    if setup.motion == "continuous":
        return AddContinuousFollowing(builder, station, setup)
    arm, tof = setup.arm, setup.tool_name
    CheckStationWiring(
        builder,
        station,
        inputs=[f"{arm}.position_commanded"],
        outputs=[f"{tof}.ranges", f"{tof}.valid", f"{arm}.position_measured"],
        new_systems=["tool_pose_ik", "path_follower"],
    )
    if plan_move is None and setup.motion == "planner":
        plan_move = MakePlannerMoves(setup)
    ik = builder.AddNamedSystem(
        "tool_pose_ik", ToolPoseIk(setup.solver, setup.period, setup.q_start)
    )
    follower = builder.AddNamedSystem(
        "path_follower",
        PathFollower(
            setup.follower,
            setup.estimator,
            setup.mount,
            setup.grid,
            setup.q_start,
            setup.limits,
            setup.period,
            plan_move,
            setup.tool_roll,
            setup.known_surfaces,
        ),
    )
    q_measured = station.GetOutputPort(f"{arm}.position_measured")
    builder.Connect(station.GetOutputPort(f"{tof}.ranges"), follower.GetInputPort("ranges"))
    builder.Connect(station.GetOutputPort(f"{tof}.valid"), follower.GetInputPort("valid"))
    builder.Connect(q_measured, follower.GetInputPort("position_measured"))
    builder.Connect(q_measured, ik.GetInputPort("position_measured"))
    for output, input_ in (
        ("X_WF_measured", "X_WF_measured"),
        ("status", "ik_status"),
        ("q_goal", "q_goal"),
        ("failure", "ik_failure"),
    ):
        builder.Connect(ik.GetOutputPort(output), follower.GetInputPort(input_))
    builder.Connect(follower.GetOutputPort("X_WF_desired"), ik.GetInputPort("X_WF_desired"))
    builder.Connect(follower.GetOutputPort("request"), ik.GetInputPort("request"))
    builder.Connect(
        follower.GetOutputPort("position_commanded"),
        station.GetInputPort(f"{arm}.position_commanded"),
    )
    return PathFollowing(follower, ik)


def AddContinuousFollowing(
    builder: DiagramBuilder, station: Diagram, setup: Setup
) -> PathFollowing:
    """Adds a ContinuousFollower ("path_follower") and a DifferentialIkServo
    ("differential_ik") on setup.solver's controller plant, the ToF tool frame T the
    controlled frame, both ticking every setup.continuous.servo_period, within the
    scenario's joint speed and acceleration limits and setup.workspace's walls:

    station `<tof>.ranges`, `<tof>.valid`, `<tof>.measured_at`, `<arm>.position_measured`
        ──> ContinuousFollower ──X_WT_desired──> DifferentialIkServo
        ──position_commanded──> station `<arm>.position_commanded`
    DifferentialIkServo `failure` ──> ContinuousFollower `servo_failure`
    """
    CheckInstance("setup", setup, Setup)
    arm, tof = setup.arm, setup.tool_name
    CheckStationWiring(
        builder,
        station,
        inputs=[f"{arm}.position_commanded"],
        # measured_at: the ToF readings' measurement instants, for motion compensation
        outputs=[f"{tof}.{port}" for port in ("ranges", "valid", "measured_at")]
        + [f"{arm}.position_measured"],
        new_systems=["path_follower", "differential_ik"],
    )
    plant = setup.solver.plant
    tool_frame = setup.station.tof_tools[tof].tool_frame
    tool = GetScopedFrame(plant, tool_frame, f"tof_tools.{tof}.tool_frame")
    config = setup.continuous
    follower = builder.AddNamedSystem(
        "path_follower",
        ContinuousFollower(
            config,
            plant,
            tool,
            setup.grid,
            setup.estimator,
            setup.q_start,
            setup.tool_roll,
            setup.known_surfaces,
        ),
    )
    servo = builder.AddNamedSystem(
        "differential_ik",
        DifferentialIkServo(
            plant,
            tool,
            setup.q_start,
            config.servo_period,
            setup.limits.max_joint_speed,
            setup.limits.max_joint_acceleration,
            config.servo_gain,
            config.ServoWeights(),
            config.servo_damping,
            setup.workspace,
            setup.X_WB,
            config.servo_feedforward,
        ),
    )
    for port in ("ranges", "valid", "measured_at"):
        builder.Connect(station.GetOutputPort(f"{tof}.{port}"), follower.GetInputPort(port))
    builder.Connect(
        station.GetOutputPort(f"{arm}.position_measured"),
        follower.GetInputPort("position_measured"),
    )
    builder.Connect(follower.GetOutputPort("X_WT_desired"), servo.GetInputPort("X_WT_desired"))
    builder.Connect(servo.GetOutputPort("failure"), follower.GetInputPort("servo_failure"))
    builder.Connect(
        servo.GetOutputPort("position_commanded"),
        station.GetInputPort(f"{arm}.position_commanded"),
    )
    return PathFollowing(follower, servo)


def MakePlannerMoves(setup: Setup, plant: MultibodyPlant | None = None) -> PlannerMoves:
    """Moves through the acceleration-level planner of Pajak et al. (on setup.solver's
    plant unless `plant` is given), its tool frame the ToF tool's T, its joint limits the
    scenario's motion limits."""
    plant = plant or setup.solver.plant
    tool_frame = setup.station.tof_tools[setup.tool_name].tool_frame
    tool = GetScopedFrame(plant, tool_frame, f"tof_tools.{setup.tool_name}.tool_frame")
    kinematics = ArmKinematics(
        plant,
        GetArmInstance(plant, setup.arm),
        plant.world_frame(),
        tool,
        setup.planner.min_singular_value,
    )
    speed = np.full(len(setup.q_start), setup.limits.max_joint_speed)
    accel = np.full(len(setup.q_start), setup.limits.max_joint_acceleration)
    planning = AccelerationPlanning(
        kinematics,
        kinematics.Position(setup.q_start)[np.newaxis],
        setup.planner,
        (-speed, speed),
        (-accel, accel),
    )
    return PlannerMoves(planning)
