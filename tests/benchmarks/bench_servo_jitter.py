"""Timing jitter of the 500 Hz servo loop (ArmDriver under the Simulator at real-time rate 1).

The UR link reads the loopback RTDE double (a separate process, RTDE v2 on 127.0.0.1:30004)
through the vendor's RTDEReceiveInterface; servoJ goes to a recording control side that
stamps each call with the host clock. The figures are the errors of the periods between
successive servoJ calls against 2 ms, and the age of the measurement each command used.

    .venv/bin/python tests/benchmarks/bench_servo_jitter.py [--seconds 10]
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np
import rtde_receive
from pydrake.multibody.plant import MultibodyPlant
from pydrake.systems.analysis import Simulator

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
from hardware_doubles import RecordingRtdeControl, StartServer, StopServer

from guidedarm.diagrams.station.model_paths import MakeParser
from guidedarm.systems.hardware.arm_driver import ArmDriver
from guidedarm.systems.hardware.command_guard import JointLimits
from guidedarm.systems.hardware.ur_rtde_link import RTDE_FREQUENCY, UrRtdeLink

PERIOD = 0.002
Q = [-1.5708, -1.5708, -2.3562, -0.7854, 1.5708, 0.7854]


class AgeRecordingControl(RecordingRtdeControl):
    """Also records how old the link's newest measurement is at each servoJ (s)."""

    link: UrRtdeLink

    def __init__(self) -> None:
        super().__init__()
        self.ages: list[float] = []

    def servoJ(self, q, speed, acceleration, time_, lookahead_time, gain) -> bool:
        self.ages.append(time.monotonic() - self.link.latest().host_time)
        return super().servoJ(q, speed, acceleration, time_, lookahead_time, gain)


def main() -> None:
    parser = argparse.ArgumentParser()
    parser.add_argument("--seconds", type=float, default=10.0)
    seconds = parser.parse_args().seconds
    process, _ = StartServer("guidedarm.systems.hardware.rtde_double", "--q", *map(str, Q))
    receive = rtde_receive.RTDEReceiveInterface(
        "127.0.0.1", RTDE_FREQUENCY, ["timestamp", "actual_q", "actual_qd"]
    )
    control = AgeRecordingControl()
    link = UrRtdeLink("ur10e", receive, control)
    control.link = link
    plant = MultibodyPlant(0.0)
    (instance,) = MakeParser(plant).AddModelsFromUrl("package://guidedarm/ur10e/ur10e.urdf")
    plant.Finalize()
    limits = JointLimits.FromPlant(plant, instance, [10.0] * 6)
    driver = ArmDriver(link, limits, PERIOD, watchdog=0.1, stale_after=0.02)
    simulator = Simulator(driver)
    driver.get_input_port().FixValue(simulator.get_mutable_context(), Q)
    simulator.set_target_realtime_rate(1.0)
    try:
        simulator.Initialize()
        simulator.AdvanceTo(seconds)
    finally:
        link.close()
        StopServer(process)
    times = np.array([c[2] for c in control.calls if c[0] == "servoJ"])
    error = np.abs(np.diff(times) - PERIOD) * 1e3
    print(f"servo loop at 500 Hz for {seconds:g} s (loopback RTDE double, realtime rate 1.0)")
    print(f"  commands sent: {times.size}, stale skips: {driver.stale_skips}")
    print(
        f"  period error |dt - 2 ms|: median {np.median(error):.3f} ms, "
        f"p99 {np.percentile(error, 99):.3f} ms, max {error.max():.3f} ms"
    )
    ages = 1e3 * np.array(control.ages)
    print(
        f"  measurement age at servoJ: median {np.median(ages):.3f} ms, "
        f"p99 {np.percentile(ages, 99):.3f} ms"
    )


if __name__ == "__main__":
    main()
