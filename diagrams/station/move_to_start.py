"""Bringing the hardware arms to a task's start pose at reduced speed (`guidedarm
move-to-start`), through the hardware station's drivers and their checks (links proved,
every command passing the command guard, watchdogs, stop on any fault).

Each arm moves on one cubic in joint space from where it is measured to its start pose,
with zero velocity at both ends, timed so that every joint stays within `speed_scale`
times its velocity limit (the model's) and acceleration limit (the command guard's).
"""

from __future__ import annotations

import numpy as np
from pydrake.systems.analysis import Simulator
from pydrake.systems.framework import Diagram, DiagramBuilder
from pydrake.systems.primitives import TrajectorySource
from pydrake.trajectories import PiecewisePolynomial

from guidedarm.diagrams.station.hardware_station import START_TOLERANCE
from guidedarm.systems.errors import ConfigurationError
from guidedarm.systems.hardware.command_guard import JointLimits

SETTLE = 0.5  # s held at the start pose before the final measurement
MIN_DURATION = 0.2  # s, the shortest move


def MoveDuration(
    q_from: np.ndarray, q_to: np.ndarray, limits: JointLimits, speed_scale: float
) -> float:
    """The duration (s) of the cubic from q_from to q_to (rad) whose peak speed
    (1.5 |dq| / T) and peak acceleration (6 |dq| / T^2) stay within speed_scale times the
    joints' velocity and acceleration limits."""
    if not 0 < speed_scale <= 1:
        raise ConfigurationError(f"--speed-scale {speed_scale}: must be in (0, 1]")
    distance = np.abs(np.asarray(q_to, float) - np.asarray(q_from, float))
    by_speed = 1.5 * distance / (speed_scale * limits.velocity)
    by_acceleration = np.sqrt(6.0 * distance / (speed_scale * limits.acceleration))
    return float(max(MIN_DURATION, np.max(by_speed), np.max(by_acceleration)))


def MoveTrajectory(q_from: np.ndarray, q_to: np.ndarray, duration: float) -> PiecewisePolynomial:
    """The cubic from q_from to q_to (rad) over `duration` s, at rest at both ends."""
    knots = np.column_stack([q_from, q_to])
    zero = np.zeros((len(q_from), 2))
    return PiecewisePolynomial.CubicHermite([0.0, duration], knots, zero)


def MoveArmsToStart(
    station: Diagram,
    starts: dict[str, np.ndarray],
    limits: dict[str, JointLimits],
    speed_scale: float,
) -> dict[str, tuple[np.ndarray, np.ndarray]]:
    """Moves every arm of the hardware `station` to its start pose (rad) in real time;
    returns each arm's joint offsets from it before and after the move (rad). A fault of
    any link raises HardwareFaultError with the arms stopped (as a run)."""
    builder = DiagramBuilder()
    builder.AddNamedSystem("station", station)
    context = station.CreateDefaultContext()
    durations = {}
    before = {}
    for arm, q_start in starts.items():
        q_now = station.GetOutputPort(f"{arm}.position_measured").Eval(context)
        before[arm] = q_now - q_start
        durations[arm] = MoveDuration(q_now, q_start, limits[arm], speed_scale)
        source = builder.AddNamedSystem(
            f"{arm}.move", TrajectorySource(MoveTrajectory(q_now, q_start, durations[arm]))
        )
        builder.Connect(source.get_output_port(), station.GetInputPort(f"{arm}.position_commanded"))
    for arm in starts:
        print(
            f"move-to-start: {arm} moves {np.max(np.abs(before[arm])):.4f} rad (largest "
            f"joint) in {durations[arm]:.2f} s",
            flush=True,
        )
    diagram = builder.Build()
    simulator = Simulator(diagram)
    simulator.set_target_realtime_rate(1.0)
    simulator.Initialize()
    simulator.AdvanceTo(max(durations.values(), default=0.0) + SETTLE)
    root = simulator.get_context()
    station_context = station.GetMyContextFromRoot(root)
    after = {
        arm: station.GetOutputPort(f"{arm}.position_measured").Eval(station_context) - q
        for arm, q in starts.items()
    }
    return {arm: (before[arm], after[arm]) for arm in starts}


def Reached(offset: np.ndarray) -> bool:
    """Whether joint offsets (rad) are within what a run accepts (START_TOLERANCE)."""
    return bool(np.max(np.abs(offset)) <= START_TOLERANCE)
