"""The ur_rtde client in a process of its own (ur_rtde_process), against `guidedarm emulate
ur`: samples and servoJ pass through it, and when it crashes (as the vendor library can
when a connection drops) the link reports a fault and every call names how it ended."""

from __future__ import annotations

import os
import signal
import time

import numpy as np
import pytest
from test_hardware_ur_emulator import UrCell

from guidedarm.systems.hardware.ur_rtde_link import RTDE_FREQUENCY, UrRtdeLink
from guidedarm.systems.hardware.ur_rtde_process import UrRtdeClientProcess

pytest.importorskip("rtde_control")


def _FirstSample(link: UrRtdeLink, timeout: float = 10.0):
    deadline = time.monotonic() + timeout
    while (sample := link.latest()) is None and time.monotonic() < deadline:
        time.sleep(0.01)
    return sample


def _Fault(link: UrRtdeLink, timeout: float = 10.0) -> str | None:
    deadline = time.monotonic() + timeout
    while link.fault() is None and time.monotonic() < deadline:
        time.sleep(0.01)
    return link.fault()


@pytest.fixture
def cell():
    cell = UrCell("ur10e_joint_tour")
    yield cell
    cell.Close()


def test_samples_and_servoj_pass_through_the_client_process(cell):
    client = UrRtdeClientProcess(cell.host, RTDE_FREQUENCY)
    link = UrRtdeLink("ur10e", client.receive, client.control)
    try:
        sample = _FirstSample(link)
        assert sample is not None and sample.q.shape == (6,)
        target = sample.q + np.array([0.01, 0, 0, 0, 0, 0])
        for _ in range(100):  # 0.2 s of 2 ms targets
            link.send_position(target, 0.002)
            time.sleep(0.002)
        deadline = time.monotonic() + 10.0
        while abs(link.latest().q[0] - target[0]) > 1e-3 and time.monotonic() < deadline:
            link.send_position(target, 0.002)
            time.sleep(0.002)
        assert link.latest().q[0] == pytest.approx(target[0], abs=1e-3)
        assert link.fault() is None
        link.stop()
    finally:
        link.close()
    assert client.process.wait(5.0) == 0


def test_a_crash_of_the_client_process_is_a_link_fault_naming_it(cell):
    client = UrRtdeClientProcess(cell.host, RTDE_FREQUENCY)
    link = UrRtdeLink("ur10e", client.receive, client.control)
    try:
        assert _FirstSample(link) is not None
        os.kill(client.process.pid, signal.SIGSEGV)
        assert _Fault(link) == "RTDE connection lost"
        with pytest.raises(RuntimeError, match=r"^the ur_rtde client process ended by SIGSEGV$"):
            link.send_position(link.latest().q, 0.002)
        with pytest.raises(RuntimeError, match="ended by SIGSEGV"):
            link.stop()
    finally:
        link.close()  # returns: nothing is left waiting on the dead process
    assert client.process.returncode == -signal.SIGSEGV
