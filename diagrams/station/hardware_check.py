"""Read-only checks of a hardware station's links (`guidedarm hardware-check`): each arm's
joints and sample rate, each ToF tool's readings and line rate, each camera's frame rate.
Nothing is commanded and no controller state is changed: a Nachi controller is asked
STATUS and READ_JOINTS only (no RESET, no STOP), a UR controller is read over RTDE only
(its control interface, which uploads a program, is not opened).

Each check returns the lines it reports, or raises ConfigurationError naming the link.
"""

from __future__ import annotations

import contextlib
import socket
import time

import numpy as np

from guidedarm.diagrams.station.hardware_config import (
    ArmDriverConfig,
    NachiDriver,
    ToFDriverConfig,
    UrRtdeDriver,
)
from guidedarm.diagrams.station.link_checks import ProveCamera, ProveToFTool
from guidedarm.systems.errors import ConfigurationError
from guidedarm.systems.hardware import nachi_protocol as nachi
from guidedarm.systems.hardware.command_guard import ImplausibleMeasurement, JointLimits
from guidedarm.systems.hardware.line_socket import LineSocket
from guidedarm.systems.hardware.opencv_camera import FrameGrabber
from guidedarm.systems.hardware.tof_protocol import RANGE_STATUS, ToFLineCollector
from guidedarm.systems.hardware.ur_rtde_link import ProbeUrController
from guidedarm.systems.hardware.ur_rtde_process import CapturedStderr

LISTEN = 1.0  # s each link is watched for its rates


def FormatJoints(q: np.ndarray) -> str:
    """Joint positions as rad (4 decimals) and degrees (2), no negative zeros."""
    radians = np.round(np.asarray(q, float), 4) + 0.0
    degrees = np.round(np.degrees(q), 2) + 0.0
    return (
        "[" + ", ".join(f"{x:+.4f}" for x in radians) + "] rad ("
        + ", ".join(f"{x:+.2f}" for x in degrees) + " deg)"
    )  # fmt: skip


def CheckArm(
    name: str, config: ArmDriverConfig, limits: JointLimits, q_start: np.ndarray | None
) -> tuple[list[str], np.ndarray]:
    """Reads the arm's joints for LISTEN s; returns the report lines and the last joints.
    Refuses an arm that does not answer or whose joints the model cannot have."""
    if isinstance(config, NachiDriver):
        q, rate, state = _ReadNachi(name, config)
    else:
        q, rate, state = _ReadUr(name, config)
    implausible = ImplausibleMeasurement(limits, q, np.zeros_like(q))
    if implausible:
        raise ConfigurationError(f"{name}: {implausible}")
    lines = [
        f"arm {name} ({config.KIND} {config.host}): {state}, {rate:.0f} samples/s",
        f"  joints {FormatJoints(q)}",
    ]
    if q_start is not None:
        offset = q - q_start
        lines.append(f"  from the task's start pose {FormatJoints(offset)}")
    return lines, q


def _ReadNachi(name: str, config: NachiDriver) -> tuple[np.ndarray, float, str]:
    port = config.port or nachi.DEFAULT_PORT
    try:
        connection = socket.create_connection((config.host, port), timeout=1.0)
    except (OSError, OverflowError, ValueError) as e:
        raise ConfigurationError(f"{name}: cannot reach {config.host}:{port}: {e}") from None
    with connection:
        lines = LineSocket(connection, nachi.MAX_LINE)
        try:
            lines.WriteLines(nachi.STATUS)
            status = lines.ReadLine()
            times, q = [], None
            end = time.monotonic() + LISTEN
            while time.monotonic() < end:
                lines.WriteLines(nachi.READ_JOINTS)
                t, q = nachi.ParseJoints(lines.ReadLine())
                times.append(t)
        except (OSError, nachi.NachiProtocolError) as e:
            raise ConfigurationError(f"{name}: {config.host}:{port}: {e}") from None
    samples = len(set(times))
    return q, samples / LISTEN, status


def _ReadUr(name: str, config: UrRtdeDriver) -> tuple[np.ndarray, float, str]:
    import rtde_receive

    try:
        said = ProbeUrController(config.host)
    except ConnectionError as e:
        raise ConfigurationError(f"{name}: cannot connect to the UR controller: {e}") from None
    variables = ["timestamp", "actual_q", "runtime_state", "robot_mode", "safety_mode"]
    with CapturedStderr():
        try:
            receive = rtde_receive.RTDEReceiveInterface(config.host, 500.0, variables)
        except RuntimeError as e:
            raise ConfigurationError(f"{name}: RTDE: {e}") from None
    try:
        stamps = set()
        end = time.monotonic() + LISTEN
        while time.monotonic() < end:
            stamps.add(receive.getTimestamp())
            time.sleep(0.0005)
        q = np.array(receive.getActualQ())
        state = (
            f"{said['dashboard server']}, robot mode {receive.getRobotMode()}, safety mode "
            f"{receive.getSafetyMode()}, runtime state {receive.getRuntimeState()}"
        )
    finally:
        with contextlib.suppress(Exception):
            receive.disconnect()
    return q, len(stamps) / LISTEN, state


def CheckToFTool(name: str, config: ToFDriverConfig) -> list[str]:
    """Reads the tool for LISTEN s after its first valid line: line rate, the newest
    ranges and status codes in sensor order r1..r6, lines rejected."""
    collector = ToFLineCollector(name)
    transport = config.Open(collector)
    try:
        ProveToFTool(collector, config.Where(), config.watchdog)
        first = collector.accepted
        time.sleep(LISTEN)
        reading, _ = collector.latest()
        rate = (collector.accepted - first) / LISTEN
    finally:
        transport.close()
    ranges = ", ".join(
        f"r{i + 1} {1e3 * r:.0f} mm" + ("" if s == 0 else f" ({RANGE_STATUS[int(s)]})")
        for i, (r, s) in enumerate(zip(reading.ranges, reading.status, strict=True))
    )
    return [
        f"tof {name} ({config.Label()}): {rate:.0f} lines/s, {collector.rejected} rejected",
        f"  {ranges}",
    ]


def CheckCamera(name: str, source: str, width: int, height: int, watchdog: float) -> list[str]:
    """Reads the camera for LISTEN s after its first frame: frame rate and size."""
    grabber = FrameGrabber(source)
    try:
        ProveCamera(name, grabber, width, height, watchdog)
        first = grabber.frames
        time.sleep(LISTEN)
        rate = (grabber.frames - first) / LISTEN
    finally:
        grabber.close()
    return [f"camera {name} ('{source}'): {rate:.1f} frames/s, {width}x{height}"]
