"""`guidedarm emulate ur`: an emulated UR e-Series controller (systems/hardware/ur_emulator.py)
for an arm of a station, served on the ports ur_rtde connects to (30004 RTDE, 29999
dashboard, 30003 script) at `--host`, any loopback address (127.0.0.0/8) so that several
emulators and the tests can run side by side on the library's fixed ports. Every ToF tool of
the station is streamed on its own pseudo-terminal, as with `emulate nachi`. Without
--scenario the station is the UR10e alone.

Not a subcommand module of its own: `emulate` hands `ur` to EmulateUr.
"""

from __future__ import annotations

import argparse

import numpy as np

from guidedarm.diagrams.emulation import ScenarioStation, Serve, StartUrEmulator, UrCell
from guidedarm.diagrams.station.hardware_config import ListenHostProblem, ToFLinkSettings
from guidedarm.systems.errors import ConfigurationError
from guidedarm.systems.hardware.nachi_emulator import DEFAULT_SERVO_ACCELERATION

DEFAULT_ARM = "ur10e"
# Options of `emulate` that do not apply to `ur`, and why.
NOT_FOR_UR = {
    "port": "ur_rtde connects to the fixed ports 30004, 29999 and 30003: choose --host",
    "servo_timeout": "the UR's streaming timeout is the client's (station.hardware.arms."
    "<arm>.servo_timeout, sent with setWatchdog)",
}


def CheckUrArguments(args: argparse.Namespace) -> None:
    """Refuses the options `ur` does not read, --set without --scenario, a host this
    machine cannot listen on, a duration or servo acceleration that is not positive."""
    for option, why in NOT_FOR_UR.items():
        if getattr(args, option) is not None:
            raise ConfigurationError(f"--{option.replace('_', '-')}: not for `emulate ur`: {why}")
    if args.overrides and not args.scenario:
        raise ConfigurationError("--set needs --scenario (the default cell has no scenario)")
    args.host = args.host or "127.0.0.1"
    problem = ListenHostProblem(args.host)
    if problem is not None:
        raise ConfigurationError(f"--host {args.host!r}: cannot listen there, {problem}")
    if not args.duration > 0:
        raise ConfigurationError(f"--duration {args.duration}: must be positive")
    acceleration = args.servo_acceleration
    if acceleration is not None and not 0 < acceleration < np.inf:
        raise ConfigurationError(
            f"--servo-acceleration {acceleration}: must be positive and finite"
        )
    if args.tof_latency is not None and not 0 <= args.tof_latency < np.inf:
        raise ConfigurationError(f"--tof-latency {args.tof_latency}: must be >= 0 and finite")


def EmulateUr(args: argparse.Namespace) -> int:
    """`guidedarm emulate ur`."""
    CheckUrArguments(args)
    station_scenario = ScenarioStation(args.scenario, args.overrides, UrCell)
    emulator, tofs = StartUrEmulator(
        station_scenario,
        args.arm or DEFAULT_ARM,
        args.host,
        args.servo_acceleration or DEFAULT_SERVO_ACCELERATION,
        ToFLinkSettings().latency if args.tof_latency is None else args.tof_latency,
        args.lockstep,
    )
    print(f"ur: {args.arm or DEFAULT_ARM} listening on {args.host} (RTDE 30004, dashboard "
          "29999, script 30003)", flush=True)  # fmt: skip

    def report() -> None:
        logic = emulator.logic
        state = "running" if logic.running else f"stopped: {logic.stop_reason or 'not started'}"
        print(
            f"ur: {logic.servo_packages} servoJ received, {logic.servo_targets} tracked, "
            f"{emulator.idle_steps} steps without one, {logic.unsupported} unsupported "
            f"commands; program {state}",
            flush=True,
        )

    Serve(emulator, tofs, args.duration, report)
    return 0
