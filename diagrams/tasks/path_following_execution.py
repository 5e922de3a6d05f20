"""Running the path follower: through the simulated station, or kinematically.

station     the loop of the seed's figure 10 as a Diagram: the station (plant, servos, ToF
            tool), ToolPoseIk and PathFollower; moves are simulated by the station's
            computed-torque servos at 2 ms steps.
kinematic   the same algorithm code (estimators, FollowStep, ToolPoseSolver) and the same
            ToFToolSensor reading the same QueryObject, but each IK solution is written
            straight into the plant context instead of being driven there. About 30 times
            faster; used for the random-path suite, where the physics of a 15 mm move at
            50 mm/s adds nothing to what the follower sees.
Both return the per-step records (path_following.RECORD_FIELDS) and the joint samples used
for the contact check.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from pydrake.geometry import QueryObject
from pydrake.multibody.plant import AddMultibodyPlant, MultibodyPlant, MultibodyPlantConfig
from pydrake.systems.analysis import ApplySimulatorConfig, Simulator
from pydrake.systems.framework import Diagram, DiagramBuilder, EventStatus
from pydrake.systems.primitives import VectorLogSink

from guidedarm.diagrams.overlays.path_following_overlays import AddPathFollowingOverlays
from guidedarm.diagrams.run_context import RunContext
from guidedarm.diagrams.station.scenario import StationScenario
from guidedarm.diagrams.station.station import MakeStation
from guidedarm.diagrams.station.station_plant import AddStationModels
from guidedarm.systems.path_following.joint_moves import MotionLimits
from guidedarm.systems.path_following.path_follower import DONE, FAILED, PathFollower
from guidedarm.systems.path_following.path_follower_math import (
    RECORD_FIELDS,
    EstimateHose,
    FollowerConfig,
    FollowerMemory,
    FollowStep,
    GiveUpDirection,
    IsExploring,
    MakeRecord,
    ToolMount,
)
from guidedarm.systems.path_following.planner_moves import PlannerMoves
from guidedarm.systems.path_following.tool_pose_ik import ToolPoseIk
from guidedarm.systems.path_following.tool_pose_ik_math import IkLimits, ToolPoseSolver
from guidedarm.systems.planning.acceleration_planner_math import (
    AccelerationPlanning,
    ArmKinematics,
    PlannerConfig,
)
from guidedarm.systems.plant_frames import GetScopedFrame
from guidedarm.systems.tof.tof_tool_sensor import MakeDetectionGrid, ToFToolConfig, ToFToolSensor
from guidedarm.systems.tof.tof_tool_sensor_math import AverageReadings

# Nominal duration of one kinematic step (s): only sets the ToF noise tick.
_KINEMATIC_STEP_TIME = 0.5


@dataclass
class Execution:
    """What a run produced: step records (steps x RECORD_FIELDS), joint samples (times,
    q rows) for the contact check, the simulated time (s) and a failure line or None."""

    records: np.ndarray
    sample_times: np.ndarray
    q_samples: np.ndarray
    sim_time: float
    failure: str | None
    collisions: int = 0


@dataclass
class Setup:
    """Everything both executors share."""

    station: StationScenario
    arm: str
    gripper_frame: str
    tool_name: str
    params: FollowerConfig
    limits: IkLimits
    motion: MotionLimits
    period: float
    q_start: np.ndarray
    max_time: float
    moves: str = "joint_trajectory"
    planner: PlannerConfig = field(default_factory=PlannerConfig)


class KinematicScene:
    """A plant and SceneGraph of the station's models (hose included) with the ToF sensor,
    posed by writing joint positions; also answers contact queries."""

    def __init__(self, station: StationScenario, tof: ToFToolConfig) -> None:
        builder = DiagramBuilder()
        self.plant, self.scene_graph = AddMultibodyPlant(
            MultibodyPlantConfig(time_step=0.0), builder
        )
        AddStationModels(station, self.plant)
        self.plant.Finalize()
        self.sensor = builder.AddSystem(ToFToolSensor(self.plant, tof))
        builder.Connect(self.scene_graph.get_query_output_port(), self.sensor.get_input_port())
        self.diagram: Diagram = builder.Build()
        self.context = self.diagram.CreateDefaultContext()
        self.plant_context = self.plant.GetMyContextFromRoot(self.context)
        self.sensor_context = self.sensor.GetMyContextFromRoot(self.context)

    def Read(self, q: np.ndarray, t: float) -> tuple[np.ndarray, np.ndarray]:
        """(ranges, valid) with the arm at q at time t."""
        self.plant.SetPositions(self.plant_context, q)
        self.context.SetTime(t)
        ranges = self.sensor.GetOutputPort("ranges").Eval(self.sensor_context)
        valid = self.sensor.GetOutputPort("valid").Eval(self.sensor_context) > 0.5
        return ranges.copy(), valid

    def HosePenetration(self, q: np.ndarray) -> bool:
        """Whether any robot geometry penetrates a hose geometry at q."""
        self.plant.SetPositions(self.plant_context, q)
        query: QueryObject = self.scene_graph.get_query_output_port().Eval(
            self.scene_graph.GetMyContextFromRoot(self.context)
        )
        inspector = query.inspector()
        for pair in query.ComputePointPairPenetration():
            names = (inspector.GetName(pair.id_A), inspector.GetName(pair.id_B))
            if any("hose_" in n and "bracket" not in n for n in names):
                return True
        return False


def MakeSolver(setup: Setup, plant: MultibodyPlant | None = None) -> ToolPoseSolver:
    """The IK of the gripper frame on a plant of the station's models without the hose,
    holding the ToF tool's centre on target."""
    if plant is None:
        plant = MultibodyPlant(0.0)
        bare = StationScenario(directives=setup.station.directives)
        AddStationModels(bare, plant)
        plant.Finalize()
    gripper = GetScopedFrame(plant, setup.gripper_frame, "gripper_frame")
    tool_frame = setup.station.tof_tools[setup.tool_name].tool_frame
    tool = GetScopedFrame(plant, tool_frame, f"tof_tools.{setup.tool_name}.tool_frame")
    p_GO = tool.CalcPose(plant.CreateDefaultContext(), gripper).translation()
    instance = plant.GetModelInstanceByName(setup.arm)
    return ToolPoseSolver(plant, instance, gripper, setup.limits, p_GO)


def ToolGeometry(plant: MultibodyPlant, gripper_frame: str, tof: ToFToolConfig):
    """(ToolMount, DetectionGrid) read from the plant's frames."""
    T = GetScopedFrame(plant, tof.tool_frame, "tof tool_frame")
    X_GT = T.CalcPose(
        plant.CreateDefaultContext(), GetScopedFrame(plant, gripper_frame, "gripper_frame")
    )
    return ToolMount.FromTransform(X_GT), MakeDetectionGrid(plant, tof)


def RunKinematic(
    setup: Setup, scene: KinematicScene, mount, grid, context: RunContext
) -> Execution:
    """The follower loop with IK solutions applied directly (see the module docstring)."""
    solver = MakeSolver(setup)
    params = setup.params
    q = setup.q_start.copy()
    memory = None
    records, qs = [], [q.copy()]
    failure = None
    for step in range(params.max_steps):
        t = step * _KINEMATIC_STEP_TIME
        context.progress(f"step {step}")
        readings = [scene.Read(q, t + k * params.reading_period) for k in range(params.readings)]
        ranges, valid = AverageReadings(readings)
        X_WT = mount.ToolPose(solver.ForwardKinematics(q))
        memory = memory or FollowerMemory.Start(X_WT, params)
        S_T, centre_only = EstimateHose(grid, params.estimator, ranges, valid)
        result = FollowStep(X_WT, S_T, centre_only, memory, params)
        ik_time = 0.0
        solved = None
        while not result.ended:
            solved = solver.Solve(mount.GripperPose(result.X_WT_next), q)
            ik_time += solved.solve_time
            if solved.success or not IsExploring(result.memory):
                break
            result = GiveUpDirection(X_WT, result.memory, params)
        records.append(MakeRecord(step, t, X_WT, result, ranges, valid, ik_time))
        if result.ended:
            break
        if not solved.success:
            failure = f"IK failed at step {step}: {solved.reason}"
            break
        memory, q = result.memory, solved.q
        qs.append(q.copy())
    else:
        failure = f"step limit ({params.max_steps}) reached"
    times = np.arange(len(qs)) * _KINEMATIC_STEP_TIME
    return Execution(
        np.array(records), times, np.array(qs), len(records) * _KINEMATIC_STEP_TIME, failure
    )


def RunStation(setup: Setup, mount, grid, context: RunContext) -> Execution:
    """The follower loop through the simulated station (see the module docstring)."""
    builder = DiagramBuilder()
    station = builder.AddNamedSystem(
        "station", MakeStation(setup.station, context.meshcat, context.hardware)
    )
    solver = MakeSolver(setup)
    ik = builder.AddNamedSystem("tool_pose_ik", ToolPoseIk(solver, setup.period))
    plan_move = MakePlannerMoves(setup, solver.plant) if setup.moves == "planner" else None
    follower = builder.AddNamedSystem(
        "path_follower",
        PathFollower(
            setup.params, mount, grid, setup.q_start, setup.motion, setup.period, plan_move
        ),
    )
    arm, tof = setup.arm, setup.tool_name
    q_measured = station.GetOutputPort(f"{arm}.position_measured")
    builder.Connect(station.GetOutputPort(f"{tof}.ranges"), follower.GetInputPort("ranges"))
    builder.Connect(station.GetOutputPort(f"{tof}.valid"), follower.GetInputPort("valid"))
    builder.Connect(q_measured, follower.GetInputPort("position_measured"))
    builder.Connect(q_measured, ik.GetInputPort("position_measured"))
    builder.Connect(ik.GetOutputPort("X_WF_measured"), follower.GetInputPort("X_WF_measured"))
    builder.Connect(ik.GetOutputPort("status"), follower.GetInputPort("ik_status"))
    builder.Connect(ik.GetOutputPort("q_goal"), follower.GetInputPort("q_goal"))
    builder.Connect(ik.GetOutputPort("failure"), follower.GetInputPort("ik_failure"))
    builder.Connect(follower.GetOutputPort("X_WF_desired"), ik.GetInputPort("X_WF_desired"))
    builder.Connect(follower.GetOutputPort("request"), ik.GetInputPort("request"))
    builder.Connect(
        follower.GetOutputPort("position_commanded"),
        station.GetInputPort(f"{arm}.position_commanded"),
    )
    AddPathFollowingOverlays(
        builder, context.meshcat, station, follower, solver.plant, setup.station, arm, tof
    )
    record_log = builder.AddSystem(VectorLogSink(len(RECORD_FIELDS), setup.period))
    builder.Connect(follower.GetOutputPort("step_record"), record_log.get_input_port())
    q_log = builder.AddSystem(VectorLogSink(len(setup.q_start), 0.02))
    builder.Connect(q_measured, q_log.get_input_port())
    diagram = builder.Build()
    simulator = Simulator(diagram)
    ApplySimulatorConfig(setup.station.simulator_config, simulator)
    if context.hardware:
        simulator.set_target_realtime_rate(1.0)
    context.pace(simulator, setup.max_time)
    root = simulator.get_mutable_context()
    ik.SetInitialGoal(ik.GetMyMutableContextFromRoot(root), setup.q_start)
    follower_context = follower.GetMyContextFromRoot(root)

    def monitor(_):
        loop = follower.Loop(follower_context)
        context.progress(f"step {loop.step}, t = {root.get_time():.1f} s")
        if loop.mode in (DONE, FAILED):
            return EventStatus.ReachedTermination(follower, "follower stopped")
        return EventStatus.DidNothing()

    simulator.set_monitor(monitor)
    simulator.Initialize()
    context.start_recording()
    simulator.AdvanceTo(setup.max_time)
    context.write_replay()
    loop = follower.Loop(follower_context)
    failure = loop.failure or None
    if loop.mode not in (DONE, FAILED):
        failure = f"time limit ({setup.max_time} s) reached at step {loop.step}"
    log = record_log.FindLog(root)
    qlog = q_log.FindLog(root)
    return Execution(
        _LastPerStep(log.data().T), qlog.sample_times(), qlog.data().T, root.get_time(), failure
    )


def MakePlannerMoves(setup: Setup, plant: MultibodyPlant) -> PlannerMoves:
    """Moves through seed 001's planner, its tool frame the ToF tool's T, its joint limits
    the scenario's motion limits."""
    tool_frame = setup.station.tof_tools[setup.tool_name].tool_frame
    tool = GetScopedFrame(plant, tool_frame, f"tof_tools.{setup.tool_name}.tool_frame")
    kinematics = ArmKinematics(
        plant,
        plant.GetModelInstanceByName(setup.arm),
        plant.world_frame(),
        tool,
        setup.planner.min_singular_value,
    )
    speed = np.full(6, setup.motion.max_joint_speed)
    accel = np.full(6, setup.motion.max_joint_acceleration)
    q = setup.q_start
    planning = AccelerationPlanning(
        kinematics,
        kinematics.Position(q)[np.newaxis],
        setup.planner,
        (-speed, speed),
        (-accel, accel),
    )
    return PlannerMoves(planning)


def _LastPerStep(samples: np.ndarray) -> np.ndarray:
    """The last logged record of each step (a step's IK time arrives after its reading)."""
    steps = samples[:, 0]
    keep = [
        i
        for i in range(len(samples))
        if steps[i] >= 0 and (i + 1 == len(samples) or steps[i + 1] != steps[i])
    ]
    return samples[keep]
