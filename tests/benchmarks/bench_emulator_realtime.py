"""The Nachi emulator in real time (its default, not lockstep): how far the host's
scheduling moves what the tests judge in lockstep. Figures depend on the machine's load;
they are printed, not judged.

1. The streamed sinusoid of tests/test_hardware_nachi_servo.py at wall-clock pace: the
   delay and error of the emulated arm behind the stream (diagram time mapped to the host
   clock both processes share), and how far the emulator's clock drifted from real time.
2. The ToF lines of `guidedarm emulate nachi`: their arrival on the host clock minus the
   timing model's k period + latency on the controller clock (READ_JOINTS ties the two).

    .venv/bin/python tests/benchmarks/bench_emulator_realtime.py [--rounds 3]
"""

from __future__ import annotations

import argparse
import socket
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
from hardware_doubles import StartNachiEmulator, StopServer
from test_hardware_nachi_servo import PrintFit, SinusoidFit, StreamSinusoid

from guidedarm.diagrams.emulation import DEFAULT_TOF_LATENCY
from guidedarm.systems.hardware.tof_protocol import ToFLineCollector
from guidedarm.systems.hardware.tof_transports import SerialTransport
from guidedarm.systems.tof.tof_tool_sensor import ToFToolConfig


def SinusoidAtWallClockPace() -> None:
    with tempfile.TemporaryDirectory() as directory:
        rows, clock, status = StreamSinusoid(Path(directory), lockstep=False)
    host, q = rows[:, 0], rows[:, 2:8]
    diagram_time, diagram_host = clock.T
    during = (host >= diagram_host[0]) & (host <= diagram_host[-1])
    drift = np.ptp(rows[during, 1] - host[during])
    t = np.interp(host[during], diagram_host, diagram_time)
    PrintFit("streamed sinusoid, real time", *SinusoidFit(t, q[during]))
    print(f"emulator clock drift from real time: {drift:.3f} s; emulator {status}")


def ToFLineArrival(seconds: float = 1.5) -> None:
    process, port, device = StartNachiEmulator("--duration", "20")
    collector = ToFLineCollector()
    transport = SerialTransport(collector, device, 115200)
    received, offsets = {}, []
    try:
        with socket.create_connection(("127.0.0.1", port)) as connection:
            replies = connection.makefile("r")
            time.sleep(0.5)  # the emulator's first steps catch up with the host clock
            end = time.monotonic() + seconds
            while time.monotonic() < end:
                connection.sendall(b"READ_JOINTS\n")
                controller_time = float(replies.readline().split()[1])
                now = time.monotonic()
                offsets.append((now, now - controller_time))
                latest = collector.latest()
                if latest is not None:
                    received.setdefault(latest[0].seq, latest[1])
                time.sleep(0.0005)
    finally:
        transport.close()
        StopServer(process)
    # READ_JOINTS reports the start of the current 2 ms step: the smallest offset near a
    # line is the host time of controller time 0 there, within about a step.
    offsets = np.array(offsets)
    period, latency = ToFToolConfig().period, DEFAULT_TOF_LATENCY
    errors = []
    for k, t in received.items():
        near = offsets[np.abs(offsets[:, 0] - t) < 0.03, 1]
        if len(near):
            errors.append(t - near.min() - (k * period + latency))
    errors = 1e3 * np.array(errors)
    print(
        f"ToF lines: {len(errors)}, arrival - (k period + latency) median "
        f"{np.median(errors):.2f} ms, p10 {np.percentile(errors, 10):.2f}, p90 "
        f"{np.percentile(errors, 90):.2f}, min {errors.min():.2f}; emulator clock drift "
        f"{np.ptp(offsets[:, 1]):.3f} s"
    )


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--rounds", type=int, default=3)
    args = parser.parse_args()
    for _ in range(args.rounds):
        SinusoidAtWallClockPace()
        ToFLineArrival()


if __name__ == "__main__":
    main()
