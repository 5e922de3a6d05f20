"""`guidedarm move-to-start SCENARIO --hardware [--speed-scale 0.1]`: brings every arm of
the scenario's hardware station to the start pose a run of the scenario streams from
(diagrams/station/move_to_start.py), at `--speed-scale` times its velocity and acceleration
limits, through the same drivers and checks as a run. Exit 0 when every arm ends within
the run's start tolerance; 1 when the move ended elsewhere or a link failed during it
(the arms stopped); 2 when a link is refused before any motion.
"""

from __future__ import annotations

import argparse

from guidedarm.diagrams.scenario_loading import AddOverridesArgument
from guidedarm.diagrams.station.hardware_check import FormatJoints
from guidedarm.diagrams.station.hardware_station import START_TOLERANCE
from guidedarm.diagrams.station.move_to_start import MoveArmsToStart, Reached
from guidedarm.diagrams.station.station import MakeStation
from guidedarm.diagrams.station.station_plant import GetArmInstance, MakeMultibodyPlant
from guidedarm.diagrams.tasks.common.start_pose import StartPoses
from guidedarm.diagrams.tasks.registry import LoadScenario
from guidedarm.systems.errors import ConfigurationError, HardwareFaultError
from guidedarm.systems.hardware.command_guard import JointLimits

DEFAULT_SPEED_SCALE = 0.1


def register(subparsers: argparse._SubParsersAction) -> None:
    parser = subparsers.add_parser(
        "move-to-start", help="bring the hardware arms to a task's start pose, slowly"
    )
    parser.add_argument("scenario", help="scenario name (see `guidedarm list`) or YAML file")
    parser.add_argument(
        "--hardware", action="store_true", help="required: this command drives the real arms"
    )
    parser.add_argument(
        "--speed-scale",
        type=float,
        default=DEFAULT_SPEED_SCALE,
        help=f"fraction of the joints' velocity and acceleration limits (default "
        f"{DEFAULT_SPEED_SCALE})",
    )
    AddOverridesArgument(parser, "override a scenario key, as for `guidedarm run --hardware`")
    parser.set_defaults(func=move_to_start_command)


def move_to_start_command(args: argparse.Namespace) -> int:
    if not args.hardware:
        raise ConfigurationError("move-to-start drives the real arms: add --hardware")
    if not 0 < args.speed_scale <= 1:
        raise ConfigurationError(f"--speed-scale {args.speed_scale}: must be in (0, 1]")
    task, scenario, name = LoadScenario(args.scenario, args.overrides)
    station_scenario = task.Station(scenario)
    if station_scenario is None or not station_scenario.arms:
        raise ConfigurationError(f"{name}: task '{task.name}' drives no arm")
    starts = StartPoses(task, scenario)
    plant = MakeMultibodyPlant(station_scenario, list(station_scenario.arms))
    limits = {}
    for arm in starts:
        fallback = station_scenario.hardware.arms.get(arm)
        try:
            limits[arm] = JointLimits.FromPlant(
                plant, GetArmInstance(plant, arm), fallback.acceleration_limits if fallback else []
            )
        except ConfigurationError as e:
            raise ConfigurationError(f"hardware.arms.{arm}.acceleration_limits: {e}") from None
    station = MakeStation(station_scenario, kind="hardware")
    try:
        offsets = MoveArmsToStart(station, starts, limits, args.speed_scale)
    except HardwareFaultError as e:
        print(f"move-to-start: {e}", flush=True)
        return 1
    reached = True
    for arm, (before, after) in offsets.items():
        print(f"move-to-start: {arm} offsets from the start pose before {FormatJoints(before)}")
        print(f"move-to-start: {arm} offsets after {FormatJoints(after)}", flush=True)
        reached = reached and Reached(after)
    if not reached:
        print(f"move-to-start: not within {START_TOLERANCE} rad of the start pose", flush=True)
        return 1
    print(f"move-to-start: at the start pose of '{name}' (within {START_TOLERANCE} rad)")
    return 0
