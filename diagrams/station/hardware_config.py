"""Scenario schema of the hardware branch: which driver serves each arm, camera and the ToF
tool, and where to reach it. Loaded with `yaml_load_typed` as `StationScenario.hardware`.
"""

from dataclasses import dataclass, field

from guidedarm.systems.config_checks import InRange, Positive


@dataclass
class ArmDriverConfig:
    """One arm's controller link.

    driver: `ur_rtde` (UR RTDE, servoJ) or `nachi_tcp` (Nachi CFD User Task line protocol).
    host, port: controller address; port 0 = the driver's default (RTDE 30004, Nachi 48000).
    watchdog: a measurement older than this (s) stops the arm and fails the run.
    stale_after: a measurement older than this (s) is not acted on (no command sent).
    acceleration_limits: rad/s^2 per joint, used where the model has none.
    lookahead_time, gain: servoJ parameters (UR only; s, 1/s).
    """

    driver: str = "ur_rtde"
    host: str = "127.0.0.1"
    port: int = InRange(0, 65535, 0)
    watchdog: float = Positive(0.1)
    stale_after: float = Positive(0.02)
    acceleration_limits: list[float] = Positive(factory=list)
    lookahead_time: float = Positive(0.1)
    gain: float = Positive(300.0)


@dataclass
class CameraDriverConfig:
    """An OpenCV VideoCapture source: a device index ("0"), a video file or a stream URL.
    Image size comes from the scenario's CameraConfig; frames of another size fail the run.

    watchdog: no new frame for this long (s) fails the run.
    """

    source: str = "0"
    watchdog: float = Positive(2.0)


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
    baudrate: int = Positive(115200)
    watchdog: float = Positive(0.5)


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
