"""Path following: from a scenario to everything a run needs (`Setup`).

`MakeSetup` reads the scenario without changing it. It loads the hose (a named path, a
CSV file, or a seeded random path) in the arm's base frame B, checks it against the
workspace, builds the station's plant once and from it the IK on a controller plant of
the arm and what it carries (MakeMultibodyPlant), solves the start pose, and returns a
copy of the station scenario with what the task derives filled in: the hose's centerline
and frame, the ToF noise seed and target radius, the arm's start position, and with
motion `continuous` the arm's control period (the servo's; docs/path_following.md,
Settings). A scenario value that the task would have to change instead is refused with one
line naming both keys.
"""

from __future__ import annotations

import copy
import hashlib
import os
import tempfile
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from pydrake.geometry import SceneGraph
from pydrake.math import RigidTransform
from pydrake.multibody.plant import MultibodyPlant
from pydrake.systems.framework import DiagramBuilder

from guidedarm.diagrams.scenario_loading import load_typed, read_raw_scenario
from guidedarm.diagrams.station.scenario import StationScenario
from guidedarm.diagrams.station.station_plant import (
    ArmAndAttachments,
    ArmInitialPosition,
    FixedFramePose,
    GetArmInstance,
    MakeMultibodyPlant,
)
from guidedarm.diagrams.tasks.path_following.scenario import Motion, PathFollowingScenario
from guidedarm.diagrams.tasks.path_following.start_pose import ReachableRandomPath, StartPosition
from guidedarm.systems.config_checks import CheckConfig, CheckInstance
from guidedarm.systems.errors import ConfigurationError
from guidedarm.systems.path_following.continuous_follower_config import ContinuousConfig
from guidedarm.systems.path_following.hose_reach import (
    CalcArmReach,
    CheckHoseReachable,
    ToolClearance,
    ToolPoints,
)
from guidedarm.systems.path_following.joint_moves import MotionLimits
from guidedarm.systems.path_following.path_follower_math import Estimator, FollowerConfig, ToolMount
from guidedarm.systems.path_following.tool_pose_ik_math import ToolPoseIkConfig, ToolPoseSolver
from guidedarm.systems.path_following.workspace import WorkspaceConfig
from guidedarm.systems.planning.acceleration_planner_math import PlannerConfig
from guidedarm.systems.plant_frames import GetScopedFrame
from guidedarm.systems.scene.hose_geometry import (
    CheckSelfClearance,
    HoseConfig,
    ReadCenterline,
    ResolveCenterlinePath,
    WriteCenterline,
)
from guidedarm.systems.tof.detection_grid import DetectionGrid
from guidedarm.systems.tof.known_surfaces import KnownSurfaces
from guidedarm.systems.tof.tof_tool_sensor import MakeDetectionGrid


@dataclass
class Setup:
    """What a path-following run needs; frames: world W, the arm's base B, gripper G, tool T.

    station: the station scenario to build (hose, ToF seed and target radius, the arm's
        initial position = q_start filled in).
    arm, gripper_frame, tool_name: the arm's model instance, the gripper frame G (scoped
        name) and the ToF tool's key in station.tof_tools.
    base_frame, X_WB: the arm's base frame B (scoped name) and its pose in the world.
    workspace: the walls (m, frame B).
    estimator: the hose estimator, `grid` or `ranging`; follower: the follower's parameters
        (PathFollower resolves them for the estimator); limits: move limits; motion:
        `joint_trajectory`, `planner` (with `planner`) or `continuous` (with
        `continuous`); period: follower and IK tick (s); max_time (s).
    centerline_B, centerline: the hose's centerline (N, 3; m) in B and in W; hose_source:
        the CSV or named path it came from.
    solver: the IK (on the controller plant); mount: X_GT as the paper's l_e and angles;
        grid: the tool's detection grid; q_start: the arm's start joints (rad).
    tool_roll: the tool's roll about the hose (rad, the scenario's tool_roll_deg);
        known_surfaces: what the followers know is not hose (the table), or None.
    """

    station: StationScenario
    arm: str
    gripper_frame: str
    tool_name: str
    base_frame: str
    X_WB: RigidTransform
    workspace: WorkspaceConfig
    estimator: Estimator
    follower: FollowerConfig
    limits: MotionLimits
    motion: Motion
    planner: PlannerConfig
    continuous: ContinuousConfig
    period: float
    max_time: float
    centerline_B: np.ndarray
    centerline: np.ndarray
    hose_source: str
    solver: ToolPoseSolver
    mount: ToolMount
    grid: DetectionGrid
    q_start: np.ndarray
    tool_roll: float = 0.0
    known_surfaces: KnownSurfaces | None = None


def MakeSetup(scenario: PathFollowingScenario, out_dir: Path | None = None) -> Setup:
    """Checks the scenario (CheckConfig: its fields' types and bounds, then
    PathFollowingScenario.Validate), places the hose and solves the start pose (module
    docstring).
    out_dir receives the CSV of a random path (default: _RandomHoseFile's shared folder)."""
    CheckInstance("scenario", scenario, PathFollowingScenario)
    CheckConfig(scenario)
    station = copy.deepcopy(scenario.station)
    base_frame = scenario.base_frame or f"{scenario.arm}::base"
    plant = MakeMultibodyPlant(station)
    X_WB = FixedFramePose(plant, base_frame, "base_frame")
    workspace = _Workspace(scenario)
    tof = station.tof_tools[scenario.tof]
    _ResolveToF(scenario, station)
    if scenario.motion == "continuous":
        station.arms[scenario.arm].control_period = scenario.continuous.servo_period
    solver = MakeSolver(
        station,
        plant,
        scenario.arm,
        scenario.gripper_frame,
        scenario.tof,
        scenario.ik,
        workspace,
        X_WB,
    )
    mount = ToolMount.FromTransform(_ToolInGripper(solver.plant, scenario.gripper_frame, tof))
    q_home = ArmInitialPosition(solver.plant, scenario.arm, station.arms[scenario.arm])
    tool_frame = GetScopedFrame(solver.plant, tof.tool_frame, "tof tool_frame")
    tool_points = ToolPoints(solver.plant, solver.context, tool_frame)
    roll = float(np.radians(scenario.tool_roll_deg))
    centerline_B, source = _LoadHose(
        scenario, workspace, solver, mount, q_home, out_dir, tool_points
    )
    CheckHoseReachable(
        centerline_B,
        X_WB,
        workspace,
        CalcArmReach(
            solver.plant, GetArmInstance(solver.plant, scenario.arm), solver.frame, solver.p_FQ
        ),
        ToolClearance(solver.plant, tool_frame),
        scenario.arm,
        tool_points,
        roll,
    )
    _ResolveHose(scenario, station, source, base_frame)
    centerline = X_WB.multiply(centerline_B.T).T
    q_start = StartPosition(solver, mount, centerline, q_home, roll)
    grid = MakeDetectionGrid(solver.plant, tof)
    known = KnownSurfaces.Table(grid.X_TS, grid.cone_angle, tof.noise_std, tof.quantization)
    station.arms[scenario.arm].initial_position = q_start.tolist()
    return Setup(
        station=station,
        arm=scenario.arm,
        gripper_frame=scenario.gripper_frame,
        tool_name=scenario.tof,
        base_frame=base_frame,
        X_WB=X_WB,
        workspace=workspace,
        estimator=scenario.estimator,
        follower=scenario.follower,
        limits=MotionLimits(
            scenario.tool_speed,
            scenario.max_joint_speed,
            max_joint_acceleration=scenario.max_joint_acceleration,
        ),
        motion=scenario.motion,
        planner=scenario.planner,
        continuous=scenario.continuous,
        period=scenario.period,
        max_time=scenario.max_time,
        centerline_B=centerline_B,
        centerline=centerline,
        hose_source=source,
        solver=solver,
        mount=mount,
        grid=grid,
        q_start=q_start,
        tool_roll=roll,
        known_surfaces=known if scenario.ignore_table else None,
    )


def _ResolveToF(scenario: PathFollowingScenario, station: StationScenario) -> None:
    """Fills in the ToF tool's noise seed (the scenario's `random_seed`) and target radius
    (the hose's), or refuses a seed set in the station that differs."""
    tof = station.tof_tools[scenario.tof]
    key = f"station.tof_tools.{scenario.tof}.seed"
    if tof.seed is not None and tof.seed != scenario.random_seed:
        raise ConfigurationError(
            f"{key} ({tof.seed}) conflicts with the scenario's 'random_seed' "
            f"({scenario.random_seed}): set that only"
        )
    if tof.seed is not None and scenario.repeat_random_seed not in (None, tof.seed):
        raise ConfigurationError(
            f"{key} fixes the noise of both runs, repeat_random_seed "
            f"({scenario.repeat_random_seed}) needs another: set 'random_seed' only"
        )
    station.hose = station.hose or HoseConfig()
    tof.seed = scenario.random_seed
    tof.target_radius = tof.target_radius or station.hose.diameter / 2
    tof.Validate()


def _Workspace(scenario: PathFollowingScenario) -> WorkspaceConfig:
    """The scenario's workspace; unset: the hose's own (its NAME.yaml), or the paper's cell."""
    if scenario.workspace is not None:
        return scenario.workspace
    if IsRandomHose(scenario):
        return WorkspaceConfig()
    return LoadHoseWorkspace(scenario.path_csv or scenario.path) or WorkspaceConfig()


def IsRandomHose(scenario: PathFollowingScenario) -> bool:
    """Whether the hose is a seeded random path (path random_<seed>, no path_csv)."""
    return not scenario.path_csv and scenario.path.startswith("random_")


def LoadHoseWorkspace(name_or_file: str) -> WorkspaceConfig | None:
    """The workspace a hose was laid out for (its sidecar NAME.yaml beside NAME.csv, read
    like a scenario file), or None when it has none."""
    sidecar = ResolveCenterlinePath(name_or_file).with_suffix(".yaml")
    if not sidecar.is_file():
        return None
    return load_typed(WorkspaceConfig, read_raw_scenario(sidecar), str(sidecar))


def _LoadHose(
    scenario, workspace, solver, mount, q_home, out_dir, tool_points
) -> tuple[np.ndarray, str]:
    """(centerline in B, the CSV or named path it came from); refuses a hose that passes
    through itself or leaves the workspace."""
    if not IsRandomHose(scenario):
        source = scenario.path_csv or scenario.path
        centerline_B = ReadCenterline(source)
        if Path(source).suffix.lower() == ".csv" or Path(source).is_file():
            source = str(ResolveCenterlinePath(source).resolve())
    else:
        digits = scenario.path.removeprefix("random_")
        if not (digits.isascii() and digits.isdigit()):
            raise ConfigurationError(
                f"path '{scenario.path}': expected random_<seed>, a seed of digits 0-9"
            )
        seed = int(digits)
        centerline_B = ReachableRandomPath(
            scenario, seed, workspace, solver, mount, q_home, tool_points
        )
        source = str(_RandomHoseFile(centerline_B, out_dir).resolve())
    CheckSelfClearance(centerline_B, scenario.station.hose.diameter, source)
    row = workspace.FirstOutside(centerline_B)
    if row is not None:
        raise ConfigurationError(
            f"hose point {row} {np.round(centerline_B[row], 3).tolist()} (m, base frame) is "
            f"outside the workspace ({workspace.Describe()}); widen `workspace` or move the hose"
        )
    return centerline_B, source


def _ResolveHose(scenario, station: StationScenario, source: str, base_frame: str) -> None:
    """Points the station's hose at the task's centerline in the base frame, or refuses a
    hose centerline or frame set in the station that differs."""
    hose = station.hose
    if hose.centerline and not _SameHose(hose.centerline, source):
        raise ConfigurationError(
            f"station.hose.centerline '{hose.centerline}' conflicts with the task's hose "
            f"'{source}': set the hose with the keys 'path' or 'path_csv' only"
        )
    if hose.frame not in ("", base_frame):
        raise ConfigurationError(
            f"station.hose.frame '{hose.frame}' conflicts with base_frame '{base_frame}': "
            "path following reads hoses in the arm's base frame"
        )
    hose.centerline, hose.frame = source, base_frame


def _SameHose(a: str, b: str) -> bool:
    return ResolveCenterlinePath(a).resolve() == ResolveCenterlinePath(b).resolve()


def _RandomHoseFile(centerline_B: np.ndarray, out_dir: Path | None) -> Path:
    """The CSV the station reads a random hose from: out_dir/hose.csv, or without out_dir
    a file named by the centerline's content in one folder of the user's under the
    temporary directory (the same hose, the same file: repeated setups add no files)."""
    if out_dir is not None:
        path = Path(out_dir) / "hose.csv"
        WriteCenterline(centerline_B, path)
        return path
    folder = Path(tempfile.gettempdir()) / f"guidedarm_hoses_{os.getuid()}"
    folder.mkdir(mode=0o700, exist_ok=True)
    path = folder / f"hose_{hashlib.sha256(centerline_B.tobytes()).hexdigest()[:16]}.csv"
    if not path.is_file():
        # Written aside, then renamed: a parallel setup of the same hose never reads half.
        partial = path.with_name(f"{path.stem}.{os.getpid()}.partial")
        WriteCenterline(centerline_B, partial)
        os.replace(partial, path)
    return path


def MakeSolver(
    station: StationScenario,
    plant: MultibodyPlant,
    arm: str,
    gripper_frame: str,
    tool_name: str,
    ik: ToolPoseIkConfig,
    workspace: WorkspaceConfig,
    X_WB: RigidTransform,
) -> ToolPoseSolver:
    """The IK of the gripper frame G holding the ToF tool's centre O on target, on a
    controller plant of the arm and what it carries (MakeMultibodyPlant, no hose; `plant`:
    the station's, MakeMultibodyPlant(station)) with its SceneGraph (the IK keeps the arm
    from touching itself), with the workspace walls in the base frame B (pose X_WB)."""
    names = ArmAndAttachments(plant, arm)
    builder = DiagramBuilder()
    scene_graph = builder.AddSystem(SceneGraph())
    plant = builder.AddSystem(
        MakeMultibodyPlant(station, names, scene_graph=scene_graph, whole=plant)
    )
    source_pose = scene_graph.get_source_pose_port(plant.get_source_id())
    builder.Connect(plant.get_geometry_pose_output_port(), source_pose)
    builder.Connect(scene_graph.get_query_output_port(), plant.get_geometry_query_input_port())
    diagram = builder.Build()
    gripper = GetScopedFrame(plant, gripper_frame, "gripper_frame")
    tof = station.tof_tools[tool_name]
    tool = GetScopedFrame(plant, tof.tool_frame, f"station.tof_tools.{tool_name}.tool_frame")
    p_GO = tool.CalcPose(plant.CreateDefaultContext(), gripper).translation()
    instance = GetArmInstance(plant, arm)
    return ToolPoseSolver(plant, instance, gripper, ik, p_GO, workspace, X_WB, diagram)


def _ToolInGripper(plant: MultibodyPlant, gripper_frame: str, tof) -> RigidTransform:
    """X_GT, the tool frame T in the gripper frame G."""
    T = GetScopedFrame(plant, tof.tool_frame, "tof tool_frame")
    G = GetScopedFrame(plant, gripper_frame, "gripper_frame")
    return T.CalcPose(plant.CreateDefaultContext(), G)
