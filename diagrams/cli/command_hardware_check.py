"""`guidedarm hardware-check SCENARIO`: connects to every link of the scenario's hardware
station and reports what it reads (diagrams/station/hardware_check.py); commands nothing.

Each arm's joints (and their offsets from the task's start pose), each ToF tool's line rate
and readings in sensor order r1..r6, each camera's frame rate. A link that does not answer
is reported in the same way a run refuses it; the command then ends with one line naming
every failed link (exit 2).
"""

from __future__ import annotations

import argparse

from guidedarm.diagrams.scenario_loading import AddOverridesArgument
from guidedarm.diagrams.station.hardware_check import CheckArm, CheckCamera, CheckToFTool
from guidedarm.diagrams.station.link_checks import CheckHardwareEntries
from guidedarm.diagrams.station.station_plant import GetArmInstance, MakeMultibodyPlant
from guidedarm.diagrams.tasks.common.start_pose import StartPoses
from guidedarm.diagrams.tasks.registry import LoadScenario
from guidedarm.systems.errors import ConfigurationError
from guidedarm.systems.hardware.command_guard import JointLimits


def register(subparsers: argparse._SubParsersAction) -> None:
    parser = subparsers.add_parser(
        "hardware-check", help="connect to every hardware link and report it; moves nothing"
    )
    parser.add_argument("scenario", help="scenario name (see `guidedarm list`) or YAML file")
    AddOverridesArgument(parser, "override a scenario key, as for `guidedarm run --hardware`")
    parser.set_defaults(func=hardware_check_command)


def hardware_check_command(args: argparse.Namespace) -> int:
    task, scenario, name = LoadScenario(args.scenario, args.overrides)
    station = task.Station(scenario)
    if station is None or not (station.arms or station.tof_tools or station.cameras):
        raise ConfigurationError(f"{name}: task '{task.name}' uses no hardware")
    hardware = station.hardware
    CheckHardwareEntries(station, hardware)
    plant = MakeMultibodyPlant(station, list(station.arms))
    starts = StartPoses(task, scenario)
    failed = []

    def report(device: str, check) -> None:
        try:
            lines = check()
        except ConfigurationError as e:
            failed.append(device)
            lines = [f"FAILED: {e}"]
        for line in lines:
            print(line, flush=True)

    print(f"hardware-check '{name}': reading every link, commanding nothing", flush=True)
    for arm, config in hardware.arms.items():

        def check(arm=arm, config=config):
            limits = JointLimits.FromPlant(
                plant, GetArmInstance(plant, arm), config.acceleration_limits
            )
            return CheckArm(arm, config, limits, starts.get(arm))[0]

        report(arm, check)
    for tool, config in hardware.tof_tools.items():
        report(tool, lambda tool=tool, config=config: CheckToFTool(tool, config))
    for camera, config in hardware.cameras.items():
        size = station.cameras[camera]
        report(
            camera,
            lambda camera=camera, config=config, size=size: CheckCamera(
                camera, config.source, size.width, size.height, config.watchdog
            ),
        )
    if failed:
        raise ConfigurationError(f"hardware-check: {', '.join(failed)} failed (see above)")
    print("hardware-check: every link answered", flush=True)
    return 0
