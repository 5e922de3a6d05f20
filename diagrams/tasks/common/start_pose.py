"""The start pose of a task's run on hardware: each arm's start pose (StartPoses, what
`move-to-start` and `hardware-check` compare with), and the check every task makes before
its first command (CheckArmAtStart)."""

from __future__ import annotations

import numpy as np
from pydrake.systems.framework import Context, Diagram

from guidedarm.diagrams.station.hardware_station import START_TOLERANCE
from guidedarm.diagrams.station.station_plant import ArmInitialPosition, MakeMultibodyPlant
from guidedarm.systems.errors import ConfigurationError


def CheckArmAtStart(station: Diagram, root: Context, arm: str, q_start: np.ndarray) -> None:
    """Raises ConfigurationError, before any command is sent, unless the joints of `arm`
    measured by the (hardware) `station` in the diagram's context `root` are within
    START_TOLERANCE of the task's start pose q_start (rad): a task streams from that pose,
    and its first command would jump from anywhere else (a jump the arm driver's command
    guard refuses). The refusal names every joint's offset and the command that moves the
    arm there."""
    port = station.GetOutputPort(f"{arm}.position_measured")
    q_measured = port.Eval(station.GetMyContextFromRoot(root))
    offset = np.asarray(q_measured, float) - np.asarray(q_start, float)
    if np.max(np.abs(offset)) > START_TOLERANCE:
        offsets = ", ".join(f"{x:+.4f}" for x in np.round(offset, 4) + 0.0)  # no -0.0000
        raise ConfigurationError(
            f"{arm} is not at the task's start pose: joint offsets [{offsets}] rad "
            f"(tolerance {START_TOLERANCE} rad); bring it there with `guidedarm "
            "move-to-start SCENARIO --hardware` and the run's --set options (an emulator: "
            "start it with --scenario and the run's --set options)"
        )


def StartPoses(task, scenario) -> dict[str, np.ndarray]:
    """Each arm's start pose (rad) in a run of `scenario` by `task` (its TaskDefinition):
    the initial positions of the station the run builds (path following's IK solution of
    the hose's start, a tour's start, the planner's q(0)), the model's defaults where the
    scenario gives none."""
    station = task.Station(scenario)
    plant = MakeMultibodyPlant(station, list(station.arms))
    return {name: ArmInitialPosition(plant, name, arm) for name, arm in station.arms.items()}
