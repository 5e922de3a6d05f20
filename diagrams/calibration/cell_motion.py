"""How the calibrations on a cell move its arm: rest-to-rest cubics in joint space through a
list of poses, streamed to the arm's `position_commanded` of a station, simulated or
hardware (the same ports), while an observer reads the station's outputs.

Each move is timed as `guidedarm move-to-start` times its one (MoveDuration: every joint
within `speed_scale` times its velocity and acceleration limits); against hardware the
diagram keeps real time and every command passes the drivers' command guard and
watchdogs, a link's fault raising HardwareFaultError with the arms stopped. Before any
motion CheckMovesClear refuses a plan that sweeps the arm through the cell's models.
"""

from __future__ import annotations

import gc
import importlib.metadata
import itertools
import json
import shlex
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np
from pydrake.systems.analysis import Simulator
from pydrake.systems.framework import Context, Diagram, DiagramBuilder
from pydrake.systems.primitives import TrajectorySource
from pydrake.trajectories import PiecewisePolynomial

from guidedarm.diagrams.interrupts import DeferredInterrupts
from guidedarm.diagrams.station.move_to_start import MoveDuration
from guidedarm.diagrams.station.scenario import StationScenario
from guidedarm.diagrams.station.station_plant import (
    ArmAndAttachments,
    GetArmInstance,
    MakeMultibodyPlant,
)
from guidedarm.diagrams.tasks.common.cell_collisions import CellCollisions
from guidedarm.systems.errors import ConfigurationError
from guidedarm.systems.hardware.arm_link import ReportStopErrors, StopAllArms
from guidedarm.systems.hardware.command_guard import JointLimits

CLEARANCE_STEP_RAD = 0.02  # rad of the largest joint's travel between collision checks


def ArmJointLimits(
    station: StationScenario, arm: str, fallback: float | None = None
) -> JointLimits:
    """The arm's velocity limits (its model's) and acceleration limits (its model's, else
    its hardware entry's acceleration_limits, else `fallback` rad/s^2 for every joint), as
    the command guard takes them."""
    plant = MakeMultibodyPlant(station, [arm])
    instance = GetArmInstance(plant, arm)
    entry = station.hardware.arms.get(arm)
    given = list(entry.acceleration_limits) if entry else []
    if not given and fallback is not None:
        given = [fallback] * plant.num_positions(instance)
    try:
        return JointLimits.FromPlant(plant, instance, given)
    except ConfigurationError as e:
        raise ConfigurationError(f"hardware.arms.{arm}.acceleration_limits: {e}") from None


def Schedule(
    q_start: np.ndarray,
    poses: list[np.ndarray],
    rests: list[float],
    limits: JointLimits,
    speed_scale: float,
) -> tuple[PiecewisePolynomial, list[tuple[float, float]]]:
    """The joint trajectory (rad) from q_start through each of `poses`, resting rests[i] s
    (>= 0) at pose i, and each rest's (start, end) time (s)."""
    times, knots, windows = [0.0], [np.asarray(q_start, float)], []
    for q, rest in zip(poses, rests, strict=True):
        t_arrive = times[-1] + MoveDuration(knots[-1], q, limits, speed_scale)
        windows.append((t_arrive, t_arrive + rest))
        ends = [t_arrive, t_arrive + rest] if rest > 0 else [t_arrive]
        times += ends
        knots += [np.asarray(q, float)] * len(ends)
    q = np.column_stack(knots)
    return PiecewisePolynomial.CubicHermite(times, q, np.zeros_like(q)), windows


def CheckMovesClear(
    station: StationScenario, arm: str, trajectory: PiecewisePolynomial, what: str
) -> None:
    """Refuses (ConfigurationError, one line) a trajectory of the arm's joints along which
    the arm or what it carries enters the cell's models or itself (CellCollisions: the
    scenario's models, not the hose), sampled every CLEARANCE_STEP_RAD of the largest
    joint's travel; `what` names the procedure in the message."""
    collisions = CellCollisions(station, arm, ArmAndAttachments(MakeMultibodyPlant(station), arm))
    times = trajectory.get_segment_times()
    for t0, t1 in itertools.pairwise(times):
        travel = np.max(np.abs(trajectory.value(t1) - trajectory.value(t0)))
        for t in np.linspace(t0, t1, int(np.ceil(travel / CLEARANCE_STEP_RAD)) + 1):
            contacts = collisions.Contacts(trajectory.value(t).ravel())
            if contacts:
                a, b, depth = contacts[0]
                raise ConfigurationError(
                    f"{what}: at t = {t:.2f} s of the planned moves {a} and {b} overlap by "
                    f"{1e3 * depth:.1f} mm: move the target or the scenario's initial "
                    "position (the moves are straight in joint space)"
                )


def StreamToArm(
    station: Diagram,
    arm: str,
    trajectory: PiecewisePolynomial,
    step: float,
    observe: Callable[[float, Context], None],
    hardware: bool,
) -> None:
    """Streams `trajectory` to `<arm>.position_commanded` of `station` to its end, calling
    observe(t, station context) every `step` s of diagram time; in real time against
    hardware. A KeyboardInterrupt (Ctrl-C, SIGTERM) stops every hardware arm, then goes
    on."""
    builder = DiagramBuilder()
    builder.AddNamedSystem("station", station)
    source = builder.AddNamedSystem("calibration_moves", TrajectorySource(trajectory))
    builder.Connect(source.get_output_port(), station.GetInputPort(f"{arm}.position_commanded"))
    simulator = Simulator(builder.Build())
    if hardware:
        simulator.set_target_realtime_rate(1.0)
        gc.freeze()  # as a hardware run: no full collection stalls the link threads
    simulator.Initialize()
    context = station.GetMyContextFromRoot(simulator.get_context())
    try:
        for k in range(1, int(np.ceil(trajectory.end_time() / step)) + 1):
            simulator.AdvanceTo(k * step)
            observe(k * step, context)
    except KeyboardInterrupt:
        # Ctrl-C or SIGTERM: the hardware arms stop now, not at the end of the command.
        with DeferredInterrupts():
            ReportStopErrors(StopAllArms(), "after the interrupt")
        raise


def MeasuredJoints(station: Diagram, arm: str) -> np.ndarray:
    """The arm's joints (rad) as the station measures them before anything moves (a
    hardware station's drivers hold the first sample of their link)."""
    context = station.CreateDefaultContext()
    return np.array(station.GetOutputPort(f"{arm}.position_measured").Eval(context))


def WriteCellSummary(out_dir: Path, summary: dict[str, Any], argv: list[str]) -> None:
    """out_dir/summary.json of a calibration on a cell: `summary` (`success`, `failure`,
    results) with the command line (`argv`, the arguments given to `guidedarm`) and the
    version."""
    summary["command"] = " ".join(shlex.quote(a) for a in ["guidedarm", *argv])
    summary["version"] = importlib.metadata.version("guidedarm")
    (out_dir / "summary.json").write_text(json.dumps(summary, indent=2) + "\n")
