"""Task `path_following`: follow a hose with the six-sensor ToF tool (seed 000).

The hose comes from a named path (`paper_path_1..4`), a CSV file (`path_csv`, also the
`--path-csv` flag), or a seeded random path (`random_<seed>`). The tool starts at the hose's
first point, its x axis along the hose; the arm's start joints come from the IK. The run
ends at the end of the hose (the follower loses it and every retry fails) or at the first
failure; the summary compares what the follower saw and did with the true centerline.
"""

import dataclasses
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from pydrake.math import RigidTransform

from guidedarm.diagrams.run_context import RunContext
from guidedarm.diagrams.station.scenario import StationScenario
from guidedarm.diagrams.station.station_plant import ArmInitialPosition
from guidedarm.diagrams.tasks.path_following_execution import (
    Execution,
    KinematicScene,
    MakeSolver,
    RunKinematic,
    RunStation,
    Setup,
    ToolGeometry,
)
from guidedarm.diagrams.tasks.path_following_report import (
    DetectedPath,
    Metrics,
    PlotDetectedPath,
    Repeatability,
)
from guidedarm.diagrams.tasks.registry import TaskDefinition
from guidedarm.systems.errors import ConfigurationError, GuidedArmError
from guidedarm.systems.path_following.hose_geometry import (
    HoseConfig,
    LoadPathLimits,
    PathLimits,
    RandomSmoothPath,
    ReadCenterline,
    WriteCenterline,
)
from guidedarm.systems.path_following.joint_moves import MotionLimits
from guidedarm.systems.path_following.path_follower_math import (
    RECORD_FIELDS,
    FollowerConfig,
    OrientationFromVector,
)
from guidedarm.systems.path_following.tool_pose_ik_math import IkLimits
from guidedarm.systems.planning.acceleration_planner_math import PlannerConfig

EXECUTORS = ("station", "kinematic")
MOVES = ("joint_trajectory", "planner")


@dataclass
class PathFollowingScenario:
    """path: `paper_path_N`, another name in models/hoses/, or `random_<seed>`;
    path_csv: a centerline CSV (overrides path); estimator: `grid` (the seed) or `ranging`;
    seed: ToF noise seed; repeat_seed: when set, a second run with this noise seed is
    overlaid (repeatability); executor: `station` or `kinematic`; motion: how the station
    moves between steps, `joint_trajectory` (rest-to-rest joint moves at tool_speed) or
    `planner` (seed 001's acceleration-level planner with the `planner` parameters; both
    within max_joint_speed and max_joint_acceleration); tool_speed (m/s); max_joint_speed
    (rad/s); max_joint_acceleration (rad/s^2); period: follower and IK tick (s); max_time:
    simulated time limit (s); min_coverage: success threshold; follower: the algorithm's parameters
    (estimator overrides follower.estimator); ik: IK tolerances (the cell walls come from
    the path: models/hoses/NAME.yaml); arm, gripper_frame, tof: names in the station."""

    task: str = "path_following"
    path: str = "paper_path_1"
    path_csv: str = ""
    estimator: str = "grid"
    seed: int = 0
    repeat_seed: int | None = None
    executor: str = "station"
    tool_speed: float = 0.05
    max_joint_speed: float = 1.0
    max_joint_acceleration: float = 5.0
    motion: str = "joint_trajectory"
    planner: PlannerConfig = field(default_factory=PlannerConfig)
    period: float = 0.01
    max_time: float = 400.0
    min_coverage: float = 0.95
    follower: FollowerConfig = field(default_factory=FollowerConfig)
    ik: IkLimits = field(default_factory=IkLimits)
    arm: str = "mz04d"
    gripper_frame: str = "gripper::gripper"
    tof: str = "tof"
    station: StationScenario = field(default_factory=StationScenario)


def LoadHose(scenario: PathFollowingScenario, out_dir: Path) -> tuple[np.ndarray, str, PathLimits]:
    """(centerline, CSV used, workspace limits) of the scenario's hose."""
    if scenario.path_csv:
        return ReadCenterline(scenario.path_csv), scenario.path_csv, PathLimits()
    if scenario.path.startswith("random_"):
        try:
            seed = int(scenario.path.removeprefix("random_"))
        except ValueError:
            raise ConfigurationError(f"path '{scenario.path}': expected random_<seed>") from None
        csv = out_dir / "hose.csv"
        WriteCenterline(ReachableRandomPath(scenario, seed), csv)
        return ReadCenterline(str(csv)), str(csv), PathLimits()
    return ReadCenterline(scenario.path), scenario.path, LoadPathLimits(scenario.path)


def ReachableRandomPath(scenario: "PathFollowingScenario", seed: int) -> np.ndarray:
    """The first random path of the seed's sequence that the arm can trace with the tool
    on the centerline and along it (IK every 15 mm, no reconfiguration): the generator's
    region is only an annulus, the arm's reachable set with a downward tool is smaller."""
    # The tool exactly on and along the centerline: no orientation shortfall.
    setup = Setup(
        scenario.station,
        scenario.arm,
        scenario.gripper_frame,
        scenario.tof,
        FollowerConfig(),
        dataclasses.replace(scenario.ik, shortfall_tolerance_deg=0.0),
        MotionLimits(),
        scenario.period,
        np.zeros(0),
        scenario.max_time,
    )
    solver = MakeSolver(setup)
    tof = scenario.station.tof_tools[scenario.tof]
    mount, _ = ToolGeometry(solver.plant, scenario.gripper_frame, tof)
    for attempt in range(20):
        path = RandomSmoothPath(seed * 1000 + attempt)
        try:
            q = _StartPosition(scenario, solver, mount, path)
        except GuidedArmError:
            continue
        if all(
            (q := _Trace(solver, mount, a, b, q)) is not None
            for a, b in zip(path[:-3:3], path[3::3], strict=True)
        ):
            return path
    raise ConfigurationError(f"no reachable random path for seed {seed}")


def _Trace(solver, mount, a: np.ndarray, b: np.ndarray, q: np.ndarray) -> np.ndarray | None:
    result = solver.Solve(mount.GripperPose(RigidTransform(OrientationFromVector(b - a), a)), q)
    return result.q if result.success else None


def _CheckInsideWalls(centerline: np.ndarray, limits: PathLimits) -> None:
    x, y = centerline[:, 0], centerline[:, 1]
    outside = (
        (x < limits.x[0])
        | (x > limits.x[1])
        | (y < limits.y[0])
        | (y > limits.y[1])
        | (centerline[:, 2] < limits.z_min)
    )
    if outside.any():
        row = int(np.argmax(outside))
        raise ConfigurationError(
            f"centerline point {row} {np.round(centerline[row], 3).tolist()} is outside the "
            f"cell walls x {limits.x}, y {limits.y}, z >= {limits.z_min}"
        )


def MakeSetup(scenario: PathFollowingScenario, out_dir: Path) -> tuple[Setup, np.ndarray, Any]:
    """Validates the scenario, places the hose and solves the start pose."""
    if scenario.executor not in EXECUTORS:
        raise ConfigurationError(f"executor must be one of {EXECUTORS}, got '{scenario.executor}'")
    if scenario.motion not in MOVES:
        raise ConfigurationError(f"motion must be one of {MOVES}, got '{scenario.motion}'")
    rates = (scenario.tool_speed, scenario.period, scenario.max_joint_speed)
    if min(*rates, scenario.max_joint_acceleration) <= 0:
        raise ConfigurationError(
            "tool_speed, max_joint_speed, max_joint_acceleration and period must be positive"
        )
    scenario.planner.Validate()
    if scenario.arm not in scenario.station.arms or scenario.tof not in scenario.station.tof_tools:
        raise ConfigurationError(
            f"station must define arms.{scenario.arm} and tof_tools.{scenario.tof}"
        )
    centerline, csv, walls = LoadHose(scenario, out_dir)
    _CheckInsideWalls(centerline, walls)
    station = scenario.station
    station.hose = station.hose or HoseConfig()
    station.hose.centerline = str(Path(csv).resolve()) if Path(csv).is_file() else csv
    tof = station.tof_tools[scenario.tof]
    tof.seed = scenario.seed
    tof.target_radius = station.hose.diameter / 2
    params = dataclasses.replace(scenario.follower, estimator=scenario.estimator).Resolved()
    limits = scenario.ik
    limits.x, limits.y, limits.z_min = list(walls.x), list(walls.y), walls.z_min
    setup = Setup(
        station,
        scenario.arm,
        scenario.gripper_frame,
        scenario.tof,
        params,
        limits,
        MotionLimits(
            scenario.tool_speed,
            scenario.max_joint_speed,
            max_joint_acceleration=scenario.max_joint_acceleration,
        ),
        scenario.period,
        np.zeros(0),
        scenario.max_time,
        scenario.motion,
        scenario.planner,
    )
    solver = MakeSolver(setup)
    mount, grid = ToolGeometry(solver.plant, scenario.gripper_frame, tof)
    setup.q_start = _StartPosition(scenario, solver, mount, centerline)
    station.arms[scenario.arm].initial_position = setup.q_start.tolist()
    return setup, centerline, (mount, grid)


def _StartPosition(scenario, solver, mount, centerline: np.ndarray) -> np.ndarray:
    ahead = centerline[min(4, len(centerline) - 1)]
    X_WT = RigidTransform(OrientationFromVector(ahead - centerline[0]), centerline[0])
    q_home = ArmInitialPosition(solver.plant, scenario.arm, scenario.station.arms[scenario.arm])
    start_limits = solver.limits
    solver.limits = dataclasses.replace(
        start_limits, max_step_rotation_deg=180.0, max_swing=np.inf, shortfall_tolerance_deg=0.0
    )
    result = solver.Solve(mount.GripperPose(X_WT), q_home)
    solver.limits = start_limits
    if not result.success:
        raise GuidedArmError(
            f"start pose out of reach: tool at {np.round(centerline[0], 3).tolist()} along the "
            f"hose ({result.reason})"
        )
    return result.q


def Execute(
    scenario: PathFollowingScenario, context: RunContext, seed: int
) -> tuple[Execution, np.ndarray]:
    """One run with ToF noise seed `seed`: (execution, centerline)."""
    scenario.seed = seed
    setup, centerline, (mount, grid) = MakeSetup(scenario, context.out_dir)
    if scenario.executor == "kinematic":
        scene = KinematicScene(setup.station, setup.station.tof_tools[setup.tool_name])
        execution = RunKinematic(setup, scene, mount, grid, context)
    else:
        execution = RunStation(setup, mount, grid, context)
        scene = KinematicScene(setup.station, setup.station.tof_tools[setup.tool_name])
    execution.collisions = _CountCollisions(execution, scene)
    return execution, centerline


def _CountCollisions(execution: Execution, scene: KinematicScene) -> int:
    """Steps during which some robot geometry penetrated the hose (sampled joint states)."""
    step_times = execution.records[:, 1] if len(execution.records) else np.zeros(0)
    hit_steps = set()
    for t, q in zip(execution.sample_times, execution.q_samples, strict=True):
        if scene.HosePenetration(q):
            hit_steps.add(int(np.searchsorted(step_times, t, side="right")))
    return len(hit_steps)


def RunPathFollowing(scenario: PathFollowingScenario, context: RunContext) -> dict[str, Any]:
    """Runs the follower (twice with repeat_seed) and returns the summary metrics."""
    repeat_seed = scenario.repeat_seed
    execution, centerline = Execute(scenario, context, scenario.seed)
    metrics = Metrics(execution.records, centerline)
    failure = execution.failure
    if failure is None and execution.collisions:
        failure = f"the robot touched the hose during {execution.collisions} step(s)"
    if failure is None and metrics["coverage"] < scenario.min_coverage:
        failure = (
            f"hose lost after step {metrics['steps'] - 1}: coverage "
            f"{metrics['coverage']:.2f} < {scenario.min_coverage}"
        )
    runs = {f"detected (seed {scenario.seed})": DetectedPath(execution.records)}
    summary = {
        "success": failure is None,
        **metrics,
        "collisions": execution.collisions,
        "estimator": scenario.estimator,
        "executor": scenario.executor,
        "failure": failure,
        "sim_time_s": round(execution.sim_time, 3),
    }
    context.headline = summary  # the figures below print its headline figures
    if repeat_seed is not None:
        second, _ = Execute(scenario, context, repeat_seed)
        runs[f"detected (seed {repeat_seed})"] = DetectedPath(second.records)
        first_path, second_path = runs.values()
        mean, worst = Repeatability(first_path, second_path)
        summary["repeatability_mean_mm"], summary["repeatability_max_mm"] = mean, worst
        context.save_figure(
            PlotDetectedPath(centerline, runs, "two runs overlaid"), "repeatability"
        )
    first = dict(list(runs.items())[:1])
    context.save_figure(
        PlotDetectedPath(
            centerline,
            first,
            f"{scenario.path_csv or scenario.path}: {scenario.estimator} estimator",
        ),
        "detected_path",
    )
    context.write_csv("steps", RECORD_FIELDS, execution.records.tolist())
    return summary


TASK = TaskDefinition(
    name="path_following",
    scenario_type=PathFollowingScenario,
    run=RunPathFollowing,
    description="follow a hose with the six-sensor ToF tool on the MZ04D (seed 000)",
)
