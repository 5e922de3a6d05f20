"""`guidedarm emulate nachi|tof|ur`: emulated devices served from a Drake simulation of a station.

`nachi` serves the Nachi User Task line protocol (docs/nachi_protocol.md) for an arm of the
station on TCP; every ToF tool of the station is streamed as well, each on its own
pseudo-terminal. `tof` streams the ToF tools only, the arm holding its initial position.
Without --scenario the station is the Wawrzyniak et al. cell (MZ04D, gripper, ToF tool `tof`).
`ur` (a UR controller for the ur_rtde client) is diagrams/cli/emulate_ur.py's. The stations
and emulators they serve are diagrams/emulation.py's.
"""

from __future__ import annotations

import argparse

import numpy as np

from guidedarm.diagrams.cli.emulate_ur import EmulateUr
from guidedarm.diagrams.emulation import (
    DEFAULT_TOF_LATENCY,
    DefaultCell,
    ScenarioStation,
    Serve,
    StartEmulators,
)
from guidedarm.diagrams.station.hardware_config import (
    CheckPort,
    ListenHostProblem,
)
from guidedarm.systems.errors import ConfigurationError
from guidedarm.systems.hardware.nachi_emulator import (
    DEFAULT_SERVO_ACCELERATION,
    DEFAULT_SERVO_TIMEOUT,
)
from guidedarm.systems.hardware.nachi_protocol import DEFAULT_PORT


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


def emulate_command(args: argparse.Namespace) -> int:
    if args.device == "ur":
        return EmulateUr(args)
    CheckArguments(args)
    station_scenario = ScenarioStation(args.scenario, args.overrides, DefaultCell)
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
