"""ToFDriver: the ToF tool's latest reading as the station's `ranges`, `valid` and
`measured_at` ports.

Every `period` seconds it copies the newest reading of a ToFLineCollector (fed by a serial or
BLE transport). No valid line for longer than `watchdog` (a silent tool, or one sending
only malformed lines) stops every arm and fails the run with a HardwareFaultError.

Time stamps: the collector notes the host's monotonic clock when a line arrives. The first
update that sees a line maps that receive time to diagram time (the update's context time
minus the line's age on the host clock) and subtracts `latency`, the time from the range's
measurement instant to its line's arrival: half the ranging time, the microcontroller's
readout and the link's transfer (MakeHardwareStation: ToFToolConfig.ranging_time / 2 +
ToFLinkSettings.latency). That is `measured_at`, the same for the six sensors of a line.

In lockstep with an emulator (`drain`), each update first reads what the link has delivered,
so the reading at a diagram time is the newest line the emulator wrote by then, and its line
counts as received at the update: its age on the host clock is the scheduling delay lockstep
exists to ignore.
"""

from __future__ import annotations

import time
from collections.abc import Callable

import numpy as np
from pydrake.systems.framework import BasicVector, Context, DiscreteValues, LeafSystem

from guidedarm.systems.config_checks import NON_NEGATIVE, POSITIVE, CheckArgument, CheckVector
from guidedarm.systems.hardware.arm_link import FailStoppingAllArms
from guidedarm.systems.hardware.tof_protocol import NUM_SENSORS, ToFLineCollector
from guidedarm.systems.tof.detection_grid import DetectionGrid
from guidedarm.systems.tof.tof_tool_sensor import DeclareGridOutputs
from guidedarm.systems.tof.tof_tool_sensor_math import CalibratedRanges

# The state: ranges (6, m), valid (6), measured_at (6, s), the held line's host receive time.
_RANGES, _VALID, _MEASURED_AT = (slice(k * NUM_SENSORS, (k + 1) * NUM_SENSORS) for k in range(3))
_RECEIVED = 3 * NUM_SENSORS


class ToFDriver(LeafSystem):
    """Outputs `ranges` (m, per sensor along its line of sight; `no_return_range` where the
    reading is not valid, as the simulated sensor does), `valid` (1 where the VL6180X
    status is 0, else 0) and `measured_at` (s, diagram time of the reading's measurement
    instant; see the module docstring). Before the first reading: no_return_range, valid 0,
    measured_at -1. With a `grid`, also `detections` and `detection_errors` as
    ToFToolSensor has them. latency: measurement instant to the host's receipt (s).
    calibration_offset: six offsets (m) subtracted from every valid range (the tool's
    calibration_file; None: none). drain: called at the start of every update to feed the
    collector what has arrived (lockstep; None: lines are taken as their thread feeds them)."""

    def __init__(
        self,
        collector: ToFLineCollector,
        period: float,
        watchdog: float,
        no_return_range: float = 0.1,
        grid: DetectionGrid | None = None,
        latency: float = 0.0,
        calibration_offset: np.ndarray | None = None,
        drain: Callable[[], None] | None = None,
    ) -> None:
        super().__init__()
        for name, value in (
            ("period", period),
            ("watchdog", watchdog),
            ("no_return_range", no_return_range),
        ):
            CheckArgument(name, value, POSITIVE)
        CheckArgument("latency", latency, NON_NEGATIVE)
        self._collector = collector
        self._watchdog = watchdog
        self._latency = latency
        self._drain = drain
        self._start: float | None = None
        self._no_return_range = no_return_range
        n = NUM_SENSORS
        self._calibration = CheckVector(
            "calibration_offset",
            np.zeros(n) if calibration_offset is None else calibration_offset,
            n,
        )
        self._state = self.DeclareDiscreteState(
            np.r_[np.full(n, no_return_range), np.zeros(n), np.full(n, -1.0), -np.inf]
        )
        self.DeclareVectorOutputPort("ranges", n, self._CalcSlice(_RANGES))
        self.DeclareVectorOutputPort("valid", n, self._CalcSlice(_VALID))
        self.DeclareVectorOutputPort("measured_at", n, self._CalcSlice(_MEASURED_AT))
        if grid is not None:
            DeclareGridOutputs(self, grid, self._Reading, {self.xd_ticket()})
        self.DeclarePeriodicDiscreteUpdateEvent(period, 0.0, self._Update)

    def _Reading(self, context: Context) -> tuple[np.ndarray, np.ndarray]:
        value = context.get_discrete_state(self._state).value()
        return value[_RANGES], value[_VALID] > 0.5

    def _CalcSlice(self, part: slice):
        def calc(context: Context, output: BasicVector) -> None:
            output.SetFromVector(context.get_discrete_state(self._state).value()[part])

        return calc

    def _Update(self, context: Context, state: DiscreteValues) -> None:
        if self._drain is not None:
            self._drain()
        now = time.monotonic()
        self._start = self._start or now
        latest = self._collector.latest()
        last_time = latest[1] if latest else self._start
        if now - last_time > self._watchdog:
            FailStoppingAllArms(
                self._collector.name,
                f"no valid line for {now - last_time:.2f} s (watchdog {self._watchdog} s, "
                f"{self._collector.rejected} lines rejected)",
                context.get_time(),
            )
        held = context.get_discrete_state(self._state).value()
        if latest is not None and latest[1] != held[_RECEIVED]:
            reading, received = latest
            valid = reading.valid > 0
            ranges = CalibratedRanges(
                np.where(valid, reading.ranges, self._no_return_range), valid, self._calibration
            )
            age = 0.0 if self._drain is not None else now - received
            measured_at = context.get_time() - age - self._latency
            state.set_value(
                self._state,
                np.r_[ranges, reading.valid, np.full(NUM_SENSORS, measured_at), received],
            )
