"""Emulated devices served from a Drake simulation of a station (`guidedarm emulate`): the
Nachi controller (systems/hardware/nachi_emulator.py), the UR controller
(systems/hardware/ur_emulator.py) and the ToF tools, each streamed on its own
pseudo-terminal from the station's `<tool>.ranges` (ToFTap)."""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
from pydrake.multibody.parsing import LoadModelDirectives
from pydrake.systems.framework import Context, Diagram

from guidedarm.diagrams.interrupts import StopOnSignal
from guidedarm.diagrams.station.hardware_config import ToFLinkSettings
from guidedarm.diagrams.station.model_paths import MODELS_DIR
from guidedarm.diagrams.station.scenario import ArmConfig, StationScenario
from guidedarm.diagrams.station.station import MakeStation
from guidedarm.diagrams.tasks.registry import LoadScenario
from guidedarm.systems.errors import ConfigurationError
from guidedarm.systems.hardware.lockstep_clock import SAME_INSTANT
from guidedarm.systems.hardware.nachi_emulator import (
    DEFAULT_SERVO_ACCELERATION,
    DEFAULT_SERVO_TIMEOUT,
    NachiEmulator,
)
from guidedarm.systems.hardware.tof_emulator import ToFEmulator
from guidedarm.systems.hardware.ur_emulator import UrEmulator
from guidedarm.systems.tof.tof_tool_sensor import ToFToolConfig

DEFAULT_TOF_LATENCY = ToFLinkSettings().latency  # s, as the driver assumes by default
NO_TARGET_STATUS = 11  # VL6180X "max signal to noise ratio": nothing returned in range
# The frames of an arm's model the Nachi emulator reads the flange pose from (X_BF).
NACHI_FRAMES = ("base", "flange")


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


def UrCell() -> StationScenario:
    """The UR10e alone at its model's home."""
    directives = LoadModelDirectives(str(MODELS_DIR / "directives/ur10e.dmd.yaml"))
    return StationScenario(directives=directives.directives, arms={"ur10e": ArmConfig()})


def StartUrEmulator(
    station_scenario: StationScenario,
    arm: str,
    host: str,
    servo_acceleration: float = DEFAULT_SERVO_ACCELERATION,
    tof_latency: float = ToFLinkSettings().latency,
    lockstep: bool = False,
) -> tuple[UrEmulator, dict[str, ToFEmulator]]:
    """The UR emulator for `arm` of the station (UrEmulator's `lockstep`) and a ToF
    emulator per tool."""
    station, tofs, taps = EmulatedStation(station_scenario, arm, tof_latency)
    emulator = UrEmulator(
        station,
        arm,
        host,
        observers=taps,
        servo_acceleration=servo_acceleration,
        lockstep=lockstep,
    )
    return emulator, tofs


def ScenarioStation(
    scenario_name: str | None, overrides: list[str], default: Callable[[], StationScenario]
) -> StationScenario:
    """The station of a scenario (a name or file, `--scenario`) with its `--set` overrides,
    or `default()` without one."""
    if not scenario_name:
        return default()
    task, scenario, _ = LoadScenario(scenario_name, overrides)
    if task.station is None and not hasattr(scenario, "station"):
        raise ConfigurationError(
            f"--scenario {scenario_name}: task '{task.name}' builds no station (no arm or "
            "ToF tool to emulate)"
        )
    return task.Station(scenario)


def Serve(emulator, tofs: dict[str, ToFEmulator], duration: float, report=None) -> None:
    """Announces the ToF ptys, runs the emulator for `duration` s or until SIGINT or
    SIGTERM closes it, then calls `report()` and closes the ptys."""
    for name, tof in tofs.items():
        print(f"tof: {name} streaming on {tof.device}", flush=True)
    try:
        with StopOnSignal(emulator.Close):
            emulator.Run(duration)
    finally:
        emulator.Close()
        if report is not None:
            report()
        for tof in tofs.values():
            tof.close()
