"""ToFDriver: the ToF tool's latest reading as the station's `ranges` and `valid` ports.

Every `period` seconds it copies the newest reading of a ToFLineCollector (fed by a serial or
BLE transport). No valid line for longer than `watchdog` (a silent tool, or one sending
only malformed lines) stops every arm and fails the run with a HardwareFaultError.
"""

from __future__ import annotations

import time

import numpy as np
from pydrake.systems.framework import BasicVector, Context, DiscreteValues, LeafSystem

from guidedarm.systems.hardware.arm_link import FailStoppingAllArms
from guidedarm.systems.hardware.tof_protocol import NUM_SENSORS, ToFLineCollector
from guidedarm.systems.tof.tof_tool_sensor import DeclareGridOutputs
from guidedarm.systems.tof.tof_tool_sensor_math import DetectionGrid


class ToFDriver(LeafSystem):
    """Outputs `ranges` (m, per sensor along its line of sight; `no_return_range` where the
    reading is not valid, as the simulated sensor does) and `valid` (1 where the VL6180X
    status is 0, else 0). Before the first reading: no_return_range, valid 0. With a
    `grid`, also `detections` and `detection_errors` as ToFToolSensor has them."""

    def __init__(
        self,
        collector: ToFLineCollector,
        period: float,
        watchdog: float,
        no_return_range: float = 0.1,
        grid: DetectionGrid | None = None,
    ) -> None:
        super().__init__()
        self._collector = collector
        self._watchdog = watchdog
        self._start: float | None = None
        self._no_return_range = no_return_range
        n = NUM_SENSORS
        self._state = self.DeclareDiscreteState(np.r_[np.full(n, no_return_range), np.zeros(n)])
        self.DeclareVectorOutputPort("ranges", n, self._CalcSlice(0, n))
        self.DeclareVectorOutputPort("valid", n, self._CalcSlice(n, 2 * n))
        if grid is not None:
            DeclareGridOutputs(self, grid, self._Reading, {self.xd_ticket()})
        self.DeclarePeriodicDiscreteUpdateEvent(period, 0.0, self._Update)

    def _Reading(self, context: Context) -> tuple[np.ndarray, np.ndarray]:
        value = context.get_discrete_state(self._state).value()
        return value[:NUM_SENSORS], value[NUM_SENSORS:] > 0.5

    def _CalcSlice(self, start: int, stop: int):
        def calc(context: Context, output: BasicVector) -> None:
            output.SetFromVector(context.get_discrete_state(self._state).value()[start:stop])

        return calc

    def _Update(self, context: Context, state: DiscreteValues) -> None:
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
        if latest is not None:
            valid = latest[0].valid
            ranges = np.where(valid > 0, latest[0].ranges, self._no_return_range)
            state.set_value(self._state, np.concatenate([ranges, valid]))
