"""`guidedarm emulate nachi|tof|ur`: emulated devices served from a Drake simulation of a station.

`nachi` serves the Nachi User Task line protocol (docs/nachi_protocol.md) for an arm of the
station on TCP; every ToF tool of the station is streamed as well, each on its own
pseudo-terminal. `tof` streams the ToF tools only, the arm holding its initial position.
Without --scenario the station is the Wawrzyniak et al. cell (MZ04D, gripper, ToF tool `tof`).
`ur` (a UR controller for the ur_rtde client) is diagrams/cli/emulate_ur.py's.
"""

from __future__ import annotations

import argparse

import numpy as np
from pydrake.multibody.parsing import LoadModelDirectives
from pydrake.systems.framework import Context, Diagram

from guidedarm.diagrams.cli.command_run import LoadScenario
from guidedarm.diagrams.cli.emulate_ur import EmulateUr
from guidedarm.diagrams.station.hardware_config import (
    CheckPort,
    ListenHostProblem,
    ToFLinkSettings,
)
from guidedarm.diagrams.station.model_paths import MODELS_DIR
from guidedarm.diagrams.station.scenario import ArmConfig, StationScenario
from guidedarm.diagrams.station.station import MakeStation
from guidedarm.systems.errors import ConfigurationError
from guidedarm.systems.hardware.lockstep_clock import SAME_INSTANT
from guidedarm.systems.hardware.nachi_emulator import (
    DEFAULT_SERVO_ACCELERATION,
    DEFAULT_SERVO_TIMEOUT,
    NachiEmulator,
)
from guidedarm.systems.hardware.nachi_protocol import DEFAULT_PORT
from guidedarm.systems.hardware.tof_emulator import ToFEmulator
from guidedarm.systems.tof.tof_tool_sensor import ToFToolConfig

DEFAULT_TOF_LATENCY = ToFLinkSettings().latency  # s, as the driver assumes by default
NO_TARGET_STATUS = 11  # VL6180X "max signal to noise ratio": nothing returned in range
# The frames of an arm's model the Nachi emulator reads the flange pose from (X_BF).
NACHI_FRAMES = ("base", "flange")


def register(subparsers: argparse._SubParsersAction) -> None:
    parser = subparsers.add_parser("emulate", help="serve emulated hardware from a simulation")
    parser.add_argument("device", choices=["nachi", "tof", "ur"])
    parser.add_argument("--scenario", help="scenario name or YAML whose `station` to simulate")
    parser.add_argument("--set", dest="overrides", action="append", default=[], metavar="K=V")
    parser.add_argument("--arm", help="the arm served (nachi: default mz04d; ur: ur10e)")
    parser.add_argument(
        "--host", help="the address nachi or ur listens on (default 127.0.0.1; ur: any 127.x.y.z)"
    )
    parser.add_argument(
        "--port", type=int, help=f"TCP port of `nachi` (default {DEFAULT_PORT}; 0 = any free)"
    )
    parser.add_argument("--duration", type=float, default=np.inf, help="simulated seconds")
    parser.add_argument(
        "--servo-acceleration",
        type=float,
        help=f"joint acceleration limit of the SERVO loop, rad/s^2 (nachi; default "
        f"{DEFAULT_SERVO_ACCELERATION})",
    )
    parser.add_argument(
        "--servo-timeout",
        type=float,
        help=f"seconds without a SERVO target before the arm brakes (nachi; default "
        f"{DEFAULT_SERVO_TIMEOUT})",
    )
    parser.add_argument(
        "--lockstep",
        action="store_true",
        help="nachi, ur: while SERVO (servoJ) targets stream, advance the station by their "
        "intervals instead of real time (for tests; the run's arm driver sets `lockstep: true`)",
    )
    parser.add_argument(
        "--tof-latency",
        type=float,
        help="seconds from a range's end of ranging to its line leaving the tool (the "
        f"hardware ToF driver's `latency`; default {DEFAULT_TOF_LATENCY})",
    )
    parser.set_defaults(func=emulate_command)


def DefaultCell() -> StationScenario:
    """The Wawrzyniak et al. cell: MZ04D at home with its gripper and the ToF tool `tof`."""
    directives = LoadModelDirectives(str(MODELS_DIR / "directives/mz04d_cell.dmd.yaml"))
    return StationScenario(
        directives=directives.directives,
        arms={"mz04d": ArmConfig()},
        tof_tools={"tof": ToFToolConfig()},
    )


class ToFTap:
    """Writes each range of the station's `<tool>.ranges`/`valid` (m, status codes) as a
    ToFEmulator line `latency` s after it becomes available (every sensor `period` s, at
    k period; the end of its ranging): the tool's readout and transfer, which the hardware
    ToFDriver subtracts (ToFLinkSettings.latency) together with half the ranging time to
    recover the measurement instant. It runs in the simulation thread at every step, so
    the lines keep the emulated arm's time: the station steps in real time, within a step
    (2 ms) of the host clock while it keeps up."""

    def __init__(self, station, tool: str, period: float, emulator: ToFEmulator, latency: float):
        self._ranges = station.GetOutputPort(f"{tool}.ranges")
        self._valid = station.GetOutputPort(f"{tool}.valid")
        self._period = period
        self._emulator = emulator
        self._latency = latency
        self._tick = -1
        self._pending: list[tuple[float, np.ndarray, np.ndarray]] = []  # (due t, reading)

    def __call__(self, context: Context) -> None:
        t = context.get_time()
        tick = int(np.floor(t / self._period + 1e-9))
        if tick != self._tick:
            self._tick = tick
            valid = self._valid.Eval(context) > 0.5
            status = np.where(valid, 0, NO_TARGET_STATUS)
            due = tick * self._period + self._latency
            self._pending.append((due, self._ranges.Eval(context).copy(), status))
        while self._pending and self._pending[0][0] <= t + SAME_INSTANT:  # due now
            _, ranges, status = self._pending.pop(0)
            self._emulator.Write(ranges, status)


def EmulatedStation(
    station_scenario: StationScenario, arm: str, tof_latency: float
) -> tuple[Diagram, dict[str, ToFEmulator], tuple[ToFTap, ...]]:
    """The simulated station an emulator serves `arm` of, a ToF emulator per tool and the
    taps that write its lines (`tof_latency` s after each range's end of ranging)."""
    if arm not in station_scenario.arms:
        raise ConfigurationError(
            f"--arm {arm}: not an arm of the station {list(station_scenario.arms)}"
        )
    station = MakeStation(station_scenario)
    tools = station_scenario.tof_tools
    tofs = {name: ToFEmulator(None) for name in tools}
    taps = tuple(
        ToFTap(station, name, tool.period, tofs[name], tof_latency) for name, tool in tools.items()
    )
    return station, tofs, taps


def StartEmulators(
    station_scenario: StationScenario,
    arm: str,
    host: str,
    port: int,
    servo_acceleration: float = DEFAULT_SERVO_ACCELERATION,
    servo_timeout: float = DEFAULT_SERVO_TIMEOUT,
    tof_latency: float = DEFAULT_TOF_LATENCY,
    lockstep: bool = False,
) -> tuple[NachiEmulator, dict[str, ToFEmulator]]:
    """The Nachi emulator for `arm` (SERVO loop limits: the model's joint speeds and
    `servo_acceleration` rad/s^2; `servo_timeout` s; `lockstep`: NachiEmulator's) and a
    ToF emulator per tool, each line leaving `tof_latency` s after its range's end of
    ranging (on the station's clock, so in lockstep with the arm)."""
    station, tofs, taps = EmulatedStation(station_scenario, arm, tof_latency)
    plant = station.GetSubsystemByName("plant")
    instance = plant.GetModelInstanceByName(arm)
    missing = [f for f in NACHI_FRAMES if not plant.HasFrameNamed(f, instance)]
    if missing:
        raise ConfigurationError(
            f"arm {arm}: its model has no frame {' or '.join(map(repr, missing))}, which the "
            "Nachi emulator reports the flange pose with (an arm with base and flange frames: "
            "mz04d, ur10e)"
        )
    emulator = NachiEmulator(
        station,
        arm,
        host,
        port,
        observers=taps,
        servo_acceleration=servo_acceleration,
        servo_timeout=servo_timeout,
        lockstep=lockstep,
    )
    return emulator, tofs


def CheckArguments(args: argparse.Namespace) -> None:
    """Refuses, before the station is built, a port outside 0..65535, a host that is not an
    address of this machine, a duration, servo acceleration or servo timeout that is not
    positive and finite (the duration may be infinite), a ToF latency that is negative or
    infinite, and --port, --host, --arm and the SERVO options for `tof` (which serves no
    arm), and --set without --scenario (the default cell has no scenario keys); fills in
    their defaults."""
    if args.overrides and not args.scenario:
        raise ConfigurationError("--set needs --scenario (the default cell has no scenario)")
    if args.lockstep and args.device != "nachi":
        raise ConfigurationError(
            "--lockstep applies to `emulate nachi` and `emulate ur` only (the targets set "
            "their clock)"
        )
    for option in ("port", "host", "arm"):
        if getattr(args, option) is not None and args.device != "nachi":
            raise ConfigurationError(f"--{option} applies to `emulate nachi` only")
    args.host = args.host or "127.0.0.1"
    CheckPort("--port", DEFAULT_PORT if args.port is None else args.port)
    problem = ListenHostProblem(args.host)
    if problem is not None:
        raise ConfigurationError(f"--host {args.host!r}: cannot listen there, {problem}")
    if not args.duration > 0:
        raise ConfigurationError(f"--duration {args.duration}: must be positive")
    for option, default in (
        ("servo_acceleration", DEFAULT_SERVO_ACCELERATION),
        ("servo_timeout", DEFAULT_SERVO_TIMEOUT),
    ):
        value = getattr(args, option)
        flag = "--" + option.replace("_", "-")
        if value is not None and args.device != "nachi":
            raise ConfigurationError(f"{flag} applies to `emulate nachi` only")
        if value is not None and not 0 < value < np.inf:
            raise ConfigurationError(f"{flag} {value}: must be positive and finite")
        setattr(args, option, default if value is None else value)
    if args.tof_latency is not None and not 0 <= args.tof_latency < np.inf:
        raise ConfigurationError(f"--tof-latency {args.tof_latency}: must be >= 0 and finite")


def ScenarioStation(args: argparse.Namespace, default) -> StationScenario:
    """The station of --scenario with its --set options, or `default()` without one."""
    if not args.scenario:
        return default()
    task, scenario, _ = LoadScenario(args.scenario, args.overrides)
    if task.station is None and not hasattr(scenario, "station"):
        raise ConfigurationError(
            f"--scenario {args.scenario}: task '{task.name}' builds no station (no arm or "
            "ToF tool to emulate)"
        )
    return task.Station(scenario)


def emulate_command(args: argparse.Namespace) -> int:
    if args.device == "ur":
        return EmulateUr(args)
    CheckArguments(args)
    station_scenario = ScenarioStation(args, DefaultCell)
    if args.tof_latency is not None and not station_scenario.tof_tools:
        raise ConfigurationError("--tof-latency: the station has no tof_tools to emulate")
    if args.device == "tof" and not station_scenario.tof_tools:
        raise ConfigurationError("the station has no tof_tools to emulate")
    latency = DEFAULT_TOF_LATENCY if args.tof_latency is None else args.tof_latency
    # `tof` serves no arm: the station's first holds its initial position
    arm = args.arm or ("mz04d" if args.device == "nachi" else next(iter(station_scenario.arms), ""))
    port = 0 if args.device != "nachi" else DEFAULT_PORT if args.port is None else args.port
    emulator, tofs = StartEmulators(
        station_scenario,
        arm,
        args.host,
        port,
        args.servo_acceleration,
        args.servo_timeout,
        latency,
        args.lockstep,
    )
    if args.device == "nachi":
        print(f"nachi: {arm} listening on {args.host}:{emulator.port}", flush=True)
    Serve(emulator, tofs, args.duration)
    return 0


def Serve(emulator, tofs: dict[str, ToFEmulator], duration: float, report=None) -> None:
    """Announces the ToF ptys, runs the emulator for `duration` s (or until interrupted),
    then closes it, calls `report()` and closes the ptys."""
    for name, tof in tofs.items():
        print(f"tof: {name} streaming on {tof.device}", flush=True)
    try:
        emulator.Run(duration)
    finally:
        emulator.Close()
        if report is not None:
            report()
        for tof in tofs.values():
            tof.close()
