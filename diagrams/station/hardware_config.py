"""Scenario schema of the hardware branch: which driver serves each arm, camera and the ToF
tool, and where to reach it. Loaded with `yaml_load_typed` as `StationScenario.hardware`;
each section checks itself in `Validate()` (comparisons written so that NaN fails).
"""

import math
from dataclasses import dataclass, field

from guidedarm.systems.errors import ConfigurationError

ARM_DRIVERS = ("ur_rtde", "nachi_tcp")
TOF_TRANSPORTS = ("serial", "ble")
# URScript servoJ: lookahead_time in [0.03, 0.2] s, gain in [100, 2000].
LOOKAHEAD_RANGE = (0.03, 0.2)
GAIN_RANGE = (100.0, 2000.0)


def _CheckPositive(key: str, value: float) -> None:
    if not (math.isfinite(value) and value > 0):
        raise ConfigurationError(f"{key}: {value} must be a positive finite number")


def _CheckText(key: str, value: str) -> None:
    if not value.strip():
        raise ConfigurationError(f"{key}: must not be empty")


def CheckPort(key: str, port: int) -> None:
    """A TCP port number, 0..65535 (0: any free port, or the driver's default)."""
    if isinstance(port, bool) or not isinstance(port, int) or not 0 <= port <= 65535:
        raise ConfigurationError(f"{key}: {port} is not a TCP port (0..65535)")


@dataclass
class ArmDriverConfig:
    """One arm's controller link.

    driver: `ur_rtde` (UR RTDE, servoJ) or `nachi_tcp` (Nachi CFD User Task line protocol).
    host, port: controller address; port 0 = the driver's default (RTDE 30004, Nachi 48000).
    watchdog: a measurement older than this (s) stops the arm and fails the run.
    stale_after: a measurement older than this (s, at most `watchdog`) is not acted on (no
    command sent).
    acceleration_limits: rad/s^2 per joint, used where the model has none.
    lookahead_time, gain: servoJ parameters (UR only; s in [0.03, 0.2], 1/s in [100, 2000]).
    """

    driver: str = "ur_rtde"
    host: str = "127.0.0.1"
    port: int = 0
    watchdog: float = 0.1
    stale_after: float = 0.02
    acceleration_limits: list[float] = field(default_factory=list)
    lookahead_time: float = 0.1
    gain: float = 300.0

    def Validate(self, key: str = "arm") -> None:
        """Raises ConfigurationError naming the first bad field (prefixed with `key`)."""
        if self.driver not in ARM_DRIVERS:
            raise ConfigurationError(f"{key}.driver: '{self.driver}' is not one of {ARM_DRIVERS}")
        _CheckText(f"{key}.host", self.host)
        CheckPort(f"{key}.port", self.port)
        _CheckPositive(f"{key}.watchdog", self.watchdog)
        _CheckPositive(f"{key}.stale_after", self.stale_after)
        if not self.stale_after <= self.watchdog:
            raise ConfigurationError(
                f"{key}.stale_after: {self.stale_after} s exceeds the watchdog {self.watchdog} s"
            )
        for i, limit in enumerate(self.acceleration_limits):
            _CheckPositive(f"{key}.acceleration_limits[{i}]", limit)
        low, high = LOOKAHEAD_RANGE
        if not low <= self.lookahead_time <= high:
            raise ConfigurationError(
                f"{key}.lookahead_time: {self.lookahead_time} s is outside [{low}, {high}]"
            )
        low, high = GAIN_RANGE
        if not low <= self.gain <= high:
            raise ConfigurationError(f"{key}.gain: {self.gain} is outside [{low}, {high}]")


@dataclass
class CameraDriverConfig:
    """An OpenCV VideoCapture source: a device index ("0"), a video file or a stream URL.
    Image size comes from the scenario's CameraConfig; frames of another size fail the run.

    watchdog: no new frame for this long (s) fails the run.
    """

    source: str = "0"
    watchdog: float = 2.0

    def Validate(self, key: str = "camera") -> None:
        """Raises ConfigurationError naming the first bad field (prefixed with `key`)."""
        _CheckText(f"{key}.source", self.source)
        _CheckPositive(f"{key}.watchdog", self.watchdog)


@dataclass
class ToFDriverConfig:
    """A ToF tool's microcontroller link (keyed like StationScenario.tof_tools).

    transport: `serial` (USB or classic-Bluetooth serial port) or `ble` (BLE UART).
    device: serial device path (e.g. /dev/rfcomm0) or BLE address.
    baudrate: serial only.
    watchdog: no valid line for this long (s) stops the arms and fails the run.
    """

    transport: str = "serial"
    device: str = ""
    baudrate: int = 115200
    watchdog: float = 0.5

    def Validate(self, key: str = "tof") -> None:
        """Raises ConfigurationError naming the first bad field (prefixed with `key`)."""
        if self.transport not in TOF_TRANSPORTS:
            raise ConfigurationError(
                f"{key}.transport: '{self.transport}' is not one of {TOF_TRANSPORTS}"
            )
        _CheckText(f"{key}.device", self.device)
        if isinstance(self.baudrate, bool) or not self.baudrate > 0:
            raise ConfigurationError(f"{key}.baudrate: {self.baudrate} must be positive")
        _CheckPositive(f"{key}.watchdog", self.watchdog)


@dataclass
class HardwareConfig:
    """Drivers of the hardware station, keyed like StationScenario.arms, .cameras and
    .tof_tools."""

    arms: dict[str, ArmDriverConfig] = field(default_factory=dict)
    cameras: dict[str, CameraDriverConfig] = field(default_factory=dict)
    tof_tools: dict[str, ToFDriverConfig] = field(default_factory=dict)

    def Validate(self, key: str = "hardware") -> None:
        """Raises ConfigurationError naming the first bad field as a dotted key."""
        for section in ("arms", "cameras", "tof_tools"):
            for name, config in getattr(self, section).items():
                config.Validate(f"{key}.{section}.{name}")
