"""Scenario schema of the hardware branch: which driver serves each arm, camera and the ToF
tool, and where to reach it. Loaded with `yaml_load_typed` as `StationScenario.hardware`;
each section checks itself in `Validate()` (comparisons written so that NaN fails).
"""

import socket
from dataclasses import dataclass, field

from guidedarm.systems.config_checks import (
    CheckFields,
    FieldError,
    InRange,
    NonNegative,
    Positive,
)
from guidedarm.systems.errors import ConfigurationError

ARM_DRIVERS = ("ur_rtde", "nachi_tcp")
COMMAND_MODES = ("stream", "move")
TOF_TRANSPORTS = ("serial", "ble")


def CheckPort(key: str, port: int) -> None:
    """A TCP port number, 0..65535 (0: any free port, or the driver's default)."""
    if isinstance(port, bool) or not isinstance(port, int) or not 0 <= port <= 65535:
        raise ConfigurationError(f"{key}: {port} is not a TCP port (0..65535)")


def ListenHostProblem(host: str) -> str | None:
    """Why a server cannot listen on `host` (a name or address), or None when it can: the
    name does not resolve, or no address it resolves to belongs to this machine. Checked
    with a socket bound to port 0, in well under a second (a server library given such a
    host may instead retry for minutes)."""
    try:
        addresses = socket.getaddrinfo(host, 0, type=socket.SOCK_STREAM)
    except (OSError, UnicodeError) as e:
        return f"it does not resolve ({e})"
    errors = []
    for family, kind, protocol, _, address in addresses:
        with socket.socket(family, kind, protocol) as probe:
            try:
                probe.bind(address)
                return None
            except OSError as e:
                errors.append(f"{address[0]}: {e.strerror}")
    return "no address of this machine (" + "; ".join(errors) + ")"


def _CheckChoice(key: str, value: str, choices: tuple[str, ...]) -> None:
    if value not in choices:
        raise FieldError(key, f"'{value}' is not one of {choices}")


def _CheckText(key: str, value: str) -> None:
    if not value.strip():
        raise FieldError(key, "must not be empty")


def _CheckHost(key: str, host: str) -> None:
    """A host name or address that name resolution can be asked about: not empty, and each
    dot-separated label of a name 1..63 characters (IDNA; longer labels made the socket
    library raise UnicodeError, not a connection error)."""
    _CheckText(key, host)
    try:
        host.encode("idna")
    except UnicodeError as e:
        raise FieldError(key, f"'{host}' is not a host name or address ({e})") from None


@dataclass
class ArmDriverConfig:
    """One arm's controller link.

    driver: `ur_rtde` (UR RTDE, servoJ) or `nachi_tcp` (Nachi CFD User Task line protocol).
    host, port: controller address; port 0 = the driver's default (RTDE 30004, Nachi 48000).
    watchdog: a measurement older than this (s) stops the arm and fails the run.
    stale_after: a measurement older than this (s, at most `watchdog`) is not acted on (no
    command sent).
    acceleration_limits: rad/s^2 per joint, used where the model has none.
    command_mode: how each control period's target reaches the controller. `stream`: the
    controller tracks the stream within its limits and brakes by itself when it stops
    (Nachi `SERVO`, UR servoJ). `move` (nachi_tcp only): `SET_TARGET` + `MOVE`, each target a
    move of the controller's main program, as the paper's User Task.
    servo_timeout: ur_rtde only: no servoJ for this long (s) and the controller stops the
    robot by itself (the RTDE control watchdog at 1 / servo_timeout Hz). A Nachi
    controller's streaming timeout is its own setting (`guidedarm emulate nachi
    --servo-timeout`).
    lookahead_time, gain: servoJ parameters (UR only; s in [0.03, 0.2], 1/s in [100, 2000]).
    lockstep: streaming to `guidedarm emulate nachi --lockstep` or `emulate ur --lockstep`
    only: the emulated controller's clock advances by the SERVO (servoJ) intervals, and
    each control period waits (at most `watchdog`) for the joints read after the previous
    target, so that the run does not depend on how the OS schedules the two processes
    (docs/hardware.md). Never on a real controller, whose clock does not wait.
    """

    driver: str = "ur_rtde"
    host: str = "127.0.0.1"
    port: int = InRange(0, 65535, 0)
    watchdog: float = Positive(0.5)
    stale_after: float = Positive(0.05)
    acceleration_limits: list[float] = Positive(factory=list)
    command_mode: str = "stream"
    servo_timeout: float = Positive(0.1)
    # URScript servoJ admits lookahead_time in [0.03, 0.2] s and gain in [100, 2000].
    lookahead_time: float = InRange(0.03, 0.2, 0.1)
    gain: float = InRange(100.0, 2000.0, 300.0)
    lockstep: bool = False

    def Validate(self) -> None:
        """Raises ConfigurationError naming the first bad field."""
        CheckFields(self)
        _CheckChoice("driver", self.driver, ARM_DRIVERS)
        _CheckHost("host", self.host)
        _CheckChoice("command_mode", self.command_mode, COMMAND_MODES)
        if self.driver == "ur_rtde" and self.command_mode != "stream":
            raise FieldError("command_mode", "ur_rtde streams servoJ targets: only 'stream'")
        if self.driver != "ur_rtde":
            defaults = type(self)()
            for name in ("servo_timeout", "lookahead_time", "gain"):
                if getattr(self, name) != getattr(defaults, name):
                    raise FieldError(name, f"applies to the ur_rtde driver only, not {self.driver}")
        if self.lockstep and self.command_mode != "stream":
            raise FieldError("lockstep", "applies to command_mode 'stream' only")
        if not self.stale_after <= self.watchdog:
            raise FieldError(
                "stale_after", f"{self.stale_after} s exceeds the watchdog {self.watchdog} s"
            )


@dataclass
class CameraDriverConfig:
    """An OpenCV VideoCapture source: a device index ("0"), a video file or a stream URL.
    Image size comes from the scenario's CameraConfig; frames of another size fail the run.

    watchdog: no new frame for this long (s) fails the run.
    """

    source: str = "0"
    watchdog: float = Positive(2.0)

    def Validate(self) -> None:
        """Raises ConfigurationError naming the first bad field."""
        CheckFields(self)
        _CheckText("source", self.source)


@dataclass
class ToFDriverConfig:
    """A ToF tool's microcontroller link (keyed like StationScenario.tof_tools).

    transport: `serial` (USB or classic-Bluetooth serial port) or `ble` (BLE UART).
    device: serial device path (e.g. /dev/rfcomm0) or BLE address.
    baudrate: serial only.
    watchdog: no valid line for this long (s) stops the arms and fails the run.
    latency: time from the end of a range's ranging to its line's arrival at the host (s):
        the microcontroller's readout and the link's transfer (a 50-character line takes
        4.3 ms at 115200 baud); a reading's `measured_at` is its arrival in diagram time
        minus this and half the tool's ranging_time.
    """

    transport: str = "serial"
    device: str = ""
    baudrate: int = Positive(115200)
    watchdog: float = Positive(0.5)
    latency: float = NonNegative(0.005)

    def Validate(self) -> None:
        """Raises ConfigurationError naming the first bad field."""
        CheckFields(self)
        _CheckChoice("transport", self.transport, TOF_TRANSPORTS)
        _CheckText("device", self.device)


@dataclass
class HardwareConfig:
    """Drivers of the hardware station.

    arms: each arm's controller link, keyed like StationScenario.arms.
    cameras: each camera's video source, keyed like StationScenario.cameras.
    tof_tools: each ToF tool's link, keyed like StationScenario.tof_tools.
    """

    arms: dict[str, ArmDriverConfig] = field(default_factory=dict)
    cameras: dict[str, CameraDriverConfig] = field(default_factory=dict)
    tof_tools: dict[str, ToFDriverConfig] = field(default_factory=dict)
