"""Scenario schema of the hardware branch: which driver serves each arm, camera and the ToF
tool, and where to reach it. Loaded with `yaml_load_typed` as `StationScenario.hardware`.

Each device's driver is one of a few typed variants chosen by a YAML tag, as Drake's
hardware_sim names its model drivers: an arm is `!UrRtdeDriver {...}` or
`!NachiDriver {...}`, a ToF tool `!ToFSerialDriver {...}` or `!ToFBleDriver {...}` (an
entry without a tag is the first of its union). Each variant has only the fields its
driver reads, so a setting another driver would ignore cannot be written. Each checks
itself in `Validate()` (comparisons written so that NaN fails).
"""

import socket
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import ClassVar, Literal, Union

from guidedarm.systems.config_checks import (
    CheckFields,
    FieldError,
    InRange,
    NonNegative,
    Positive,
    TextChoices,
)
from guidedarm.systems.errors import ConfigurationError
from guidedarm.systems.hardware.tof_protocol import ToFLineCollector
from guidedarm.systems.hardware.tof_transports import BleTransport, SerialTransport


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
class ArmLinkSettings:
    """What every arm driver reads (the fields of UrRtdeDriver and NachiDriver).

    host: the controller's address.
    watchdog: a measurement older than this (s) stops the arm and fails the run.
    stale_after: a measurement older than this (s, at most `watchdog`) is not acted on (no
    command sent).
    acceleration_limits: rad/s^2 per joint, used where the model has none.
    lockstep: streaming to `guidedarm emulate nachi --lockstep` or `emulate ur --lockstep`
    only: the emulated controller's clock advances by the SERVO (servoJ) intervals, and
    each control period waits (at most `watchdog`) for the joints read after the previous
    target, so that the run does not depend on how the OS schedules the two processes
    (docs/hardware.md). Never on a real controller, whose clock does not wait.
    """

    host: str = "127.0.0.1"
    watchdog: float = Positive(0.5)
    stale_after: float = Positive(0.05)
    acceleration_limits: list[float] = Positive(factory=list)
    lockstep: bool = False

    # The driver's name in reports (hardware-check).
    KIND: ClassVar[str] = ""

    def Validate(self) -> None:
        """Raises ConfigurationError naming the first bad field."""
        CheckFields(self)
        _CheckHost("host", self.host)
        if not self.stale_after <= self.watchdog:
            raise FieldError(
                "stale_after", f"{self.stale_after} s exceeds the watchdog {self.watchdog} s"
            )


@dataclass
class UrRtdeDriver(ArmLinkSettings):
    """A UR arm over RTDE (ur_rtde), streaming servoJ targets (the RTDE port is always
    30004). Besides ArmLinkSettings:

    servo_timeout: no servoJ for this long (s) and the controller stops the robot by
    itself (the RTDE control watchdog at 1 / servo_timeout Hz).
    lookahead_time, gain: servoJ parameters (s in [0.03, 0.2], 1/s in [100, 2000]).
    """

    servo_timeout: float = Positive(0.1)
    # URScript servoJ admits lookahead_time in [0.03, 0.2] s and gain in [100, 2000].
    lookahead_time: float = InRange(0.03, 0.2, 0.1)
    gain: float = InRange(100.0, 2000.0, 300.0)

    KIND: ClassVar[str] = "ur_rtde"


@TextChoices
@dataclass
class NachiDriver(ArmLinkSettings):
    """A Nachi arm over the CFD User Task line protocol (TCP). Besides ArmLinkSettings:

    port: the User Task's port; 0 = its default 48000.
    command_mode: how each control period's target reaches the controller. `stream`: the
    controller tracks the stream within its limits and brakes by itself when it stops
    (`SERVO`). `move`: `SET_TARGET` + `MOVE`, each target a move of the controller's main
    program, as the paper's User Task. The controller's streaming timeout is its own
    setting (`guidedarm emulate nachi --servo-timeout`).
    """

    port: int = InRange(0, 65535, 0)
    command_mode: Literal["stream", "move"] = "stream"

    KIND: ClassVar[str] = "nachi_tcp"

    def Validate(self) -> None:
        """Raises ConfigurationError naming the first bad field."""
        super().Validate()
        if self.lockstep and self.command_mode != "stream":
            raise FieldError("lockstep", "applies to command_mode 'stream' only")


# An arm's driver; an entry without a YAML tag is a UrRtdeDriver.
ArmDriverConfig = Union[UrRtdeDriver, NachiDriver]  # noqa: UP007 (yaml_load_typed reads typing.Union)


@dataclass
class OpenCvCameraDriver:
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
class ToFLinkSettings:
    """What every ToF tool driver reads (keyed like StationScenario.tof_tools).

    watchdog: no valid line for this long (s) stops the arms and fails the run.
    latency: time from the end of a range's ranging to its line's arrival at the host (s):
        the microcontroller's readout and the link's transfer (a 50-character line takes
        4.3 ms at 115200 baud); a reading's `measured_at` is its arrival in diagram time
        minus this and half the tool's ranging_time.
    """

    watchdog: float = Positive(0.5)
    latency: float = NonNegative(0.005)


@dataclass
class ToFSerialDriver(ToFLinkSettings):
    """A ToF tool on a serial port (USB, or classic Bluetooth's RFCOMM).

    device: the serial device (e.g. /dev/rfcomm0, /dev/ttyACM0).
    baudrate: the port's rate (bit/s).
    lockstep: reading `guidedarm emulate nachi|ur --lockstep` (tests, CI): the driver reads
        the port at every update, so its reading is the newest line the emulator wrote by
        that diagram time, whatever the host's scheduling (docs/hardware.md).
    """

    device: str = ""
    baudrate: int = Positive(115200)
    lockstep: bool = False

    def Validate(self) -> None:
        """Raises ConfigurationError naming the first bad field."""
        CheckFields(self)
        _CheckText("device", self.device)

    def Open(self, collector: ToFLineCollector) -> SerialTransport:
        """Opens the port; its bytes go to `collector`."""
        return SerialTransport(collector, self.device, self.baudrate)

    def Drain(self, transport: SerialTransport) -> Callable[[], None] | None:
        """What the driver calls at every update to read the port (lockstep), else None."""
        return transport.Drain if self.lockstep else None

    def Where(self) -> str:
        """Where the tool is reached: its device."""
        return self.device

    def Label(self) -> str:
        """The link in reports: `serial DEVICE`."""
        return f"serial {self.device}"


@dataclass
class ToFBleDriver(ToFLinkSettings):
    """A ToF tool on BLE (Nordic UART TX notifications).

    address: the tool's BLE address (e.g. AA:BB:CC:DD:EE:FF).
    """

    address: str = ""

    def Validate(self) -> None:
        """Raises ConfigurationError naming the first bad field."""
        CheckFields(self)
        _CheckText("address", self.address)

    def Open(self, collector: ToFLineCollector) -> BleTransport:
        """Subscribes to the tool's notifications; their bytes go to `collector`."""
        return BleTransport(collector, self.address)

    def Drain(self, _transport: BleTransport) -> None:
        """None: notifications are taken as they arrive (no lockstep over BLE)."""
        return None

    def Where(self) -> str:
        """Where the tool is reached: its address."""
        return self.address

    def Label(self) -> str:
        """The link in reports: `ble ADDRESS`."""
        return f"ble {self.address}"


# A ToF tool's driver; an entry without a YAML tag is a ToFSerialDriver.
ToFDriverConfig = Union[ToFSerialDriver, ToFBleDriver]  # noqa: UP007 (yaml_load_typed reads typing.Union)

# Keys the tags replaced: each old value and the tag that now names it.
REPLACED_BY_TAG = {
    "arms": ("driver", {"ur_rtde": "!UrRtdeDriver", "nachi_tcp": "!NachiDriver"}),
    "tof_tools": ("transport", {"serial": "!ToFSerialDriver", "ble": "!ToFBleDriver"}),
}


def RefuseReplacedDriverKeys(hardware: object, key: str) -> None:
    """Refuses (FieldError) an untyped hardware section whose arm has a `driver` or whose
    ToF tool has a `transport` key, naming the tag that replaced it."""
    if not isinstance(hardware, dict):
        return
    for section, (old, tags) in REPLACED_BY_TAG.items():
        entries = hardware.get(section)
        for name, entry in entries.items() if isinstance(entries, dict) else ():
            if isinstance(entry, dict) and old in entry:
                tag = tags.get(entry[old], " or ".join(tags.values()))
                raise FieldError(
                    f"{key}.{section}.{name}.{old}",
                    f"replaced by the entry's YAML tag: write `{name}: {tag} {{...}}` "
                    "without it (docs/migration.md)",
                )


@dataclass
class HardwareConfig:
    """Drivers of the hardware station.

    arms: each arm's controller link, keyed like StationScenario.arms.
    cameras: each camera's video source, keyed like StationScenario.cameras.
    tof_tools: each ToF tool's link, keyed like StationScenario.tof_tools.
    """

    arms: dict[str, ArmDriverConfig] = field(default_factory=dict)
    cameras: dict[str, OpenCvCameraDriver] = field(default_factory=dict)
    tof_tools: dict[str, ToFDriverConfig] = field(default_factory=dict)
