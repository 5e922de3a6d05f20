"""Checks every link of a hardware station makes before anything moves: each hardware entry
names a device of the scenario, each ToF tool delivers valid lines, each camera a frame of
the scenario's size, each within FirstDeliveryWait. A link that does not is refused with one
line naming it (ConfigurationError: exit 2, no run). The arms prove themselves in
ArmDriver (a plausible joint sample within the watchdog).
"""

from __future__ import annotations

import time
from collections.abc import Callable
from typing import TypeVar

from guidedarm.diagrams.station.hardware_config import HardwareConfig
from guidedarm.diagrams.station.scenario import StationScenario
from guidedarm.systems.config_checks import CheckConfig
from guidedarm.systems.errors import ConfigurationError
from guidedarm.systems.hardware.opencv_camera import FrameGrabber
from guidedarm.systems.hardware.tof_protocol import ToFLineCollector, ToFReading

HARDWARE_SECTIONS = ("arms", "cameras", "tof_tools")
POLL = 0.002  # s between looks at a link that has not delivered yet
# s: the least a link check waits for a device's first line or frame, whatever its
# watchdog (which bounds the gaps between deliveries during a run). A device may start
# later than it opens: a BLE tool streams once its notifications are subscribed, a
# microcontroller board that resets when its serial port opens boots first, a camera
# settles its exposure; and a host briefly busy elsewhere must not refuse a good link.
FIRST_DELIVERY_WAIT = 2.0


def FirstDeliveryWait(watchdog: float) -> float:
    """How long (s) a link check waits for a device's first delivery."""
    return max(watchdog, FIRST_DELIVERY_WAIT)


T = TypeVar("T")


def CheckHardwareEntries(scenario: StationScenario, hardware: HardwareConfig) -> None:
    """Every arm, camera and ToF tool of the scenario needs a valid driver entry, and every
    entry must name one of them (an entry for a device the scenario does not have would be
    ignored): refused before connecting."""
    for section in HARDWARE_SECTIONS:
        devices, entries = set(getattr(scenario, section)), set(getattr(hardware, section))
        if devices - entries:
            raise ConfigurationError(
                f"hardware.{section}: no driver for {sorted(devices - entries)}"
            )
        if entries - devices:
            raise ConfigurationError(
                f"hardware.{section}.{sorted(entries - devices)[0]}: the scenario has no such "
                f"{section.removesuffix('s').replace('_', ' ')} (its {section}: "
                f"{sorted(devices)}); remove the entry"
            )
    CheckConfig(hardware, "hardware")


def WaitFor(latest: Callable[[], T | None], deadline: float) -> T | None:
    """The first non-None value of `latest()` within `deadline` seconds, else None."""
    end = time.monotonic() + deadline
    value = latest()
    while value is None and time.monotonic() < end:
        time.sleep(POLL)
        value = latest()
    return value


def ProveToFTool(collector: ToFLineCollector, device: str, watchdog: float) -> ToFReading:
    """The first valid line (six sensors, checksum, ranges and status codes in range) of
    the tool within FirstDeliveryWait(watchdog) s, else ConfigurationError naming the tool
    and its device."""
    wait = FirstDeliveryWait(watchdog)
    first = WaitFor(collector.latest, wait)
    if first is None:
        raise ConfigurationError(
            f"{collector.name}: {device} opened, but no valid line within {wait} s "
            f"({collector.rejected} lines rejected): is the tool powered and "
            "streaming on that device?"
        )
    return first[0]


def ProveCamera(name: str, grabber: FrameGrabber, width: int, height: int, watchdog: float):
    """The first frame (RGBA array) of the camera within FirstDeliveryWait(watchdog) s and
    of the scenario's size, else ConfigurationError naming the camera and its source."""
    wait = FirstDeliveryWait(watchdog)
    first = WaitFor(grabber.latest, wait)
    if first is None:
        raise ConfigurationError(
            f"{name}: camera '{grabber.source}' opened, but no frame within {wait} s"
        )
    frame = first[0]
    if (frame.shape[1], frame.shape[0]) != (width, height):
        raise ConfigurationError(
            f"{name}: camera '{grabber.source}' delivers {frame.shape[1]}x{frame.shape[0]} "
            f"frames, the scenario expects {width}x{height}"
        )
    return frame
