"""`guidedarm calibrate tof SCENARIO --out DIR [--hardware]` on a cell whose scenario places
the white target: the arm holds the ToF tool perpendicular over it at the procedure's
distances, the same steps on the simulated station and on the hardware one.

The target is a model instance `tof_target` of the station's directives (its link `target`:
origin at the centre of the face, +z out of it; models/calibration/tof_target.sdf), welded
where the real one lies: the procedure reads its pose from the scenario, never from a
sensor. From the scenario's initial position (home), for each group of parallel sensors
(sensors 1-3, then 4-6) the tool comes to CLEARANCE_M over the target, then to each of
TARGET_DISTANCES_M from the farthest in, resting SETTLE_S before READINGS_PER_DISTANCE new
readings are taken, back to CLEARANCE_M and home; every move is one cubic in joint space
at rest at both ends (cell_motion.py). Before anything moves every pose is solved by
inverse kinematics on the controller's model (a pose out of reach is refused, naming it)
and every move is checked against the scenario's models (CheckMovesClear).
"""

from __future__ import annotations

import dataclasses
import json
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from pydrake.math import RigidTransform, RotationMatrix
from pydrake.multibody.inverse_kinematics import InverseKinematics
from pydrake.multibody.plant import MultibodyPlant
from pydrake.solvers import Solve
from pydrake.systems.framework import Diagram
from pydrake.trajectories import PiecewisePolynomial

from guidedarm.diagrams.calibration.cell_motion import (
    ArmJointLimits,
    CheckMovesClear,
    MeasuredJoints,
    Schedule,
    StreamToArm,
    WriteCellSummary,
)
from guidedarm.diagrams.calibration.tof_calibration import (
    READINGS_PER_DISTANCE,
    SENSOR_GROUPS,
    TARGET_DISTANCES_M,
    TargetInTool,
    ToFTool,
    WriteToFOffsets,
)
from guidedarm.diagrams.run_preparation import WithErrorsDrawn
from guidedarm.diagrams.station.scenario import StationScenario
from guidedarm.diagrams.station.station import MakeStation
from guidedarm.diagrams.station.station_plant import (
    ArmAndAttachments,
    ArmInitialPosition,
    GetArmInstance,
    MakeMultibodyPlant,
)
from guidedarm.diagrams.task_run import InterruptedFailure
from guidedarm.systems.errors import ConfigurationError, RunFailedError
from guidedarm.systems.hardware.command_guard import JointLimits
from guidedarm.systems.plant_frames import GetScopedFrame
from guidedarm.systems.tof.tof_errors import ToFErrors

TARGET_MODEL = "tof_target"
TARGET_FRAME = f"{TARGET_MODEL}::target"
# m from the emitters to the target where the tool turns between the sensor groups: the
# tool's body (55 mm from the emitters to the tool frame) clears the target turning there.
CLEARANCE_M = 0.15
SETTLE_S = 0.5  # s at rest before the readings: the arm settles, the old lines pass
# Extra ranging periods held at each distance beyond READINGS_PER_DISTANCE: a line lost on
# the link (a pty without reader, a BLE interval) still leaves enough.
SPARE_PERIODS = 10
IK_POSITION_TOLERANCE = 1e-5  # m
IK_ANGLE_TOLERANCE = 1e-4  # rad
IK_RESTARTS = 8


@dataclass(frozen=True)
class Hold:
    """A rest of the arm at joints q (rad) from t_start to t_end (s); group and distance
    (m) of a measurement, group None for home or a clearance pose."""

    q: np.ndarray
    group: int | None
    distance: float
    t_start: float = 0.0
    t_end: float = 0.0


def HasTarget(station: StationScenario) -> bool:
    """Whether the station's directives (those they include too) add the `tof_target`
    model."""
    return MakeMultibodyPlant(station).HasModelInstanceNamed(TARGET_MODEL)


def ToolArm(plant: MultibodyPlant, station: StationScenario, tool: str) -> str:
    """The arm of the station whose joints move the ToF tool (refused without one)."""
    body = GetScopedFrame(plant, station.tof_tools[tool].tool_frame, "tof tool_frame").body()
    for arm in station.arms:
        joints = plant.GetJointIndices(GetArmInstance(plant, arm))
        if body.index() in plant.GetBodiesKinematicallyAffectedBy(joints):
            return arm
    raise ConfigurationError(f"calibrate tof: no arm of the station carries the tool '{tool}'")


def PlanHolds(station: StationScenario, tool: str, arm: str, home: np.ndarray) -> list[Hold]:
    """The rests of the procedure (see the module docstring), their joints solved on the
    arm's controller plant (the arm and what it carries), the arm passing through `home`
    (rad) first, between the groups and last: a joint-space move between the two
    groups' poses, which turn the wrist by 90 degrees, could sweep through the cell."""
    whole = MakeMultibodyPlant(station)
    X_WP = GetScopedFrame(whole, TARGET_FRAME, "the ToF target").CalcPoseInWorld(
        whole.CreateDefaultContext()
    )
    plant = MakeMultibodyPlant(station, ArmAndAttachments(whole, arm), whole=whole)
    tool_frame = GetScopedFrame(plant, station.tof_tools[tool].tool_frame, "tof tool_frame")
    q = np.asarray(home, float)
    holds = [Hold(q, None, 0.0)]
    for group in range(len(SENSOR_GROUPS)):
        steps = [(None, CLEARANCE_M)]
        steps += [(group, d) for d in sorted(TARGET_DISTANCES_M, reverse=True)]
        steps.append((None, CLEARANCE_M))
        # The target is symmetric about its normal: the tool may face it either way round.
        for turn in (0.0, np.pi):
            X_WP_turned = X_WP @ RigidTransform(RotationMatrix.MakeZRotation(turn))
            group_holds = _GroupHolds(plant, tool_frame, X_WP_turned, group, steps, q)
            if group_holds is not None:
                break
        else:
            raise ConfigurationError(
                f"calibrate tof: {arm} cannot hold the tool over the target facing sensors "
                f"{[s + 1 for s in SENSOR_GROUPS[group]]} at {CLEARANCE_M * 1e3:g} to "
                f"{min(TARGET_DISTANCES_M) * 1e3:g} mm (target at "
                f"{np.round(X_WP.translation(), 3).tolist()} m): place {TARGET_MODEL} where "
                "the arm reaches it from above"
            )
        holds += [*group_holds, Hold(q, None, 0.0)]
    return holds


def _GroupHolds(
    plant: MultibodyPlant,
    tool_frame: Any,
    X_WP: RigidTransform,
    group: int,
    steps: list[tuple[int | None, float]],
    q: np.ndarray,
) -> list[Hold] | None:
    """The holds of one sensor group's steps (group or None, distance m), each solved from
    the one before (the first from q); None if one is out of reach."""
    holds = []
    for measured, distance in steps:
        q = SolveToolPose(plant, tool_frame, X_WP @ TargetInTool(group, distance).inverse(), q)
        if q is None:
            return None
        holds.append(Hold(q, measured, distance))
    return holds


def SolveToolPose(
    plant: MultibodyPlant, tool_frame: Any, X_WT: RigidTransform, q_guess: np.ndarray
) -> np.ndarray | None:
    """Joints (rad) putting tool_frame at X_WT, nearest q_guess; None if none is found."""
    ik = InverseKinematics(plant)
    p = X_WT.translation()
    tolerance = np.full(3, IK_POSITION_TOLERANCE)
    ik.AddPositionConstraint(
        tool_frame, np.zeros(3), plant.world_frame(), p - tolerance, p + tolerance
    )
    ik.AddOrientationConstraint(
        tool_frame,
        RigidTransform().rotation(),
        plant.world_frame(),
        X_WT.rotation(),
        IK_ANGLE_TOLERANCE,
    )
    prog = ik.get_mutable_prog()
    prog.AddQuadraticErrorCost(np.eye(len(q_guess)), q_guess, ik.q())
    # Restarts from seeded perturbations of the guess: a turn of the wrist by 90 degrees
    # (the second sensor group) is often not found from the first.
    rng = np.random.default_rng(0)
    lower, upper = plant.GetPositionLowerLimits(), plant.GetPositionUpperLimits()
    for attempt in range(IK_RESTARTS + 1):
        start = q_guess if attempt == 0 else q_guess + rng.normal(0.0, 0.5 * attempt, len(q_guess))
        result = Solve(prog, np.clip(start, lower, upper))
        if result.is_success():
            return result.GetSolution(ik.q())
    return None


def ScheduleHolds(
    q_start: np.ndarray,
    holds: list[Hold],
    limits: JointLimits,
    speed_scale: float,
    reading_period: float,
) -> tuple[PiecewisePolynomial, list[Hold]]:
    """The arm's joint trajectory from q_start through every hold, and the holds with their
    times: measurement rests last SETTLE_S plus READINGS_PER_DISTANCE + SPARE_PERIODS
    reading periods, the others SETTLE_S."""
    spare = (READINGS_PER_DISTANCE + SPARE_PERIODS) * reading_period
    rests = [SETTLE_S + (spare if h.group is not None else 0.0) for h in holds]
    trajectory, windows = Schedule(q_start, [h.q for h in holds], rests, limits, speed_scale)
    timed = [
        dataclasses.replace(h, t_start=t0, t_end=t1)
        for h, (t0, t1) in zip(holds, windows, strict=True)
    ]
    return trajectory, timed


def MeasureOnStation(
    station: Diagram,
    arm: str,
    tool: str,
    trajectory: PiecewisePolynomial,
    holds: list[Hold],
    reading_period: float,
    hardware: bool,
) -> np.ndarray:
    """Streams `trajectory` to the arm of `station` (simulated or hardware: the same ports)
    and returns each sensor's mean of the first READINGS_PER_DISTANCE valid readings
    measured (`measured_at`) at each measurement hold after its SETTLE_S, per distance
    (TARGET_DISTANCES_M x 6, m; NaN where a sensor had too few)."""
    ports = [station.GetOutputPort(f"{tool}.{name}") for name in ("ranges", "valid", "measured_at")]
    readings: dict[int, list[np.ndarray]] = {}
    last = [-np.inf]

    def Observe(_: float, context) -> None:
        ranges, valid, measured_at = (np.array(p.Eval(context)) for p in ports)
        t = float(np.max(measured_at))
        if t <= last[0]:
            return
        last[0] = t
        for k, hold in enumerate(holds):
            if hold.group is not None and hold.t_start + SETTLE_S <= t <= hold.t_end:
                readings.setdefault(k, []).append(np.where(valid > 0.5, ranges, np.nan))

    StreamToArm(station, arm, trajectory, reading_period / 4, Observe, hardware)
    means = np.full((len(TARGET_DISTANCES_M), 6), np.nan)
    for k, hold in enumerate(holds):
        if hold.group is None:
            continue
        taken = np.array(readings.get(k, [np.full(6, np.nan)]))
        for j in SENSOR_GROUPS[hold.group]:
            column = taken[:, j][np.isfinite(taken[:, j])][:READINGS_PER_DISTANCE]
            if len(column) == READINGS_PER_DISTANCE:
                means[TARGET_DISTANCES_M.index(hold.distance), j] = column.mean()
    return means


def CalibrateToFOnCell(
    station: StationScenario, tool: str, home: np.ndarray, speed_scale: float, hardware: bool
) -> np.ndarray:
    """Plans the holds through `home` (rad; refusals before motion), builds the station
    (`hardware`: its links prove themselves), runs the procedure; the mean readings per
    distance (m, 5 x 6)."""
    arm = ToolArm(MakeMultibodyPlant(station), station, tool)
    holds = PlanHolds(station, tool, arm, home)
    limits = ArmJointLimits(station, arm)
    period = station.tof_tools[tool].period
    # Checked before any link is connected, from home on; the move from where the arm is
    # measured to home once it is.
    planned, _ = ScheduleHolds(holds[0].q, holds, limits, speed_scale, period)
    CheckMovesClear(station, arm, planned, "calibrate tof")
    built = MakeStation(station, kind="hardware" if hardware else "simulation")
    q_start = MeasuredJoints(built, arm)
    CheckMovesClear(
        station, arm, Schedule(q_start, [holds[0].q], [0.0], limits, 1.0)[0], "calibrate tof"
    )
    trajectory, holds = ScheduleHolds(q_start, holds, limits, speed_scale, period)
    print(
        f"calibrate tof: {len(holds)} rests over the target in {trajectory.end_time():.1f} s",
        flush=True,
    )
    means = MeasureOnStation(built, arm, tool, trajectory, holds, period, hardware)
    if np.any(np.isnan(means)):
        sensors = sorted({int(j) + 1 for j in np.argwhere(np.isnan(means))[:, 1]})
        raise RunFailedError(
            f"sensors {sensors} gave fewer than {READINGS_PER_DISTANCE} valid readings at "
            "some distance: is the target where the scenario places it?"
        )
    return means


def RunToFCalibrationOnCell(
    task: Any, scenario: Any, out_dir: Path, hardware: bool, speed_scale: float, argv: list[str]
) -> tuple[bool, list[str]]:
    """The procedure on the scenario's cell (CheckCell first): writes DIR/tof_offsets.yaml
    and tof_report.json (WriteToFOffsets, beside the drawn truth in simulation) and always
    DIR/summary.json (`success`, `failure`, the command line); returns (success, lines to
    print). Refusals before motion raise ConfigurationError and write nothing."""
    tool = ToFTool(scenario)
    if not hardware:
        scenario = WithErrorsDrawn(scenario)
    station = task.Station(scenario)
    CheckCell(station, tool, hardware)
    # Home: the scenario's own initial position (a task's station may start elsewhere).
    plant = MakeMultibodyPlant(scenario.station, list(scenario.station.arms))
    arm = ToolArm(MakeMultibodyPlant(station), station, tool)
    home = ArmInitialPosition(plant, arm, scenario.station.arms[arm])
    summary: dict[str, Any] = {"tool": tool, "hardware": hardware}
    try:
        means = CalibrateToFOnCell(station, tool, home, speed_scale, hardware)
    except (RunFailedError, KeyboardInterrupt) as e:
        failure = InterruptedFailure(e) if isinstance(e, KeyboardInterrupt) else str(e)
        summary |= {"success": False, "failure": failure}
        WriteCellSummary(out_dir, summary, argv)
        return False, [f"calibrate tof failed: {failure}"]
    truth = None if hardware else station.errors.tof_tools.get(tool, ToFErrors()).Offsets()
    lines = WriteToFOffsets(out_dir, tool, means, truth)
    report = json.loads((out_dir / "tof_report.json").read_text())
    summary |= {"success": True, "failure": "", "offset_m": report["offset_m"]}
    WriteCellSummary(out_dir, summary, argv)
    return True, lines


def CheckCell(station: StationScenario, tool: str, hardware: bool) -> None:
    """Refuses, before anything is built: a station without the target, and on hardware
    simulated errors or an arm or the tool without its driver entry."""
    if not HasTarget(station):
        raise ConfigurationError(
            f"calibrate tof{' --hardware' if hardware else ''}: the station has no "
            f"'{TARGET_MODEL}' model; add the directive "
            "package://guidedarm/directives/tof_target.dmd.yaml with the target's pose "
            "(docs/calibration.md)"
        )
    if not hardware:
        return
    if station.HasErrors():
        raise ConfigurationError(
            "station.errors and station.errors_preset describe a simulated cell; "
            "calibrate tof --hardware measures the real one: remove them"
        )
    arm = ToolArm(MakeMultibodyPlant(station), station, tool)
    for section, name, kind in (("arms", arm, "arm"), ("tof_tools", tool, "ToF")):
        if name not in getattr(station.hardware, section):
            raise ConfigurationError(
                f"calibrate tof --hardware: no {kind} driver for '{name}' "
                f"(station.hardware.{section}.{name}, docs/hardware.md)"
            )
