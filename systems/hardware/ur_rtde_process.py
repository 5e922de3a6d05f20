"""The ur_rtde client in a process of its own, so that a crash of the vendor library is a
link fault that the run reports, not the end of the run.

ur_rtde runs threads of its own. When the controller's connection drops while a servoJ is
being sent, the library's reconnect races its receive thread, and the process can end by
SIGSEGV (about 1 in 15 runs whose controller is killed mid-stream). A run that ends that way
cannot stop its arm or write its summary.

The child process owns RTDEReceiveInterface and RTDEControlInterface. Over one socket it
answers the parent's vendor calls, one reply per request, in order; over another it pushes
every new controller sample (a later RTDE `timestamp`) as it polls the receive interface.
`RemoteRtdeReceive` and `RemoteRtdeControl` implement ur_rtde_link's RtdeReceive and
RtdeControl protocols on those sockets, so UrRtdeLink drives a remote client as it drove an
in-process one. A child that ends (a crash, a kill) closes both sockets: the receive side
reports the connection lost, and every later call raises RuntimeError naming how it ended.
"""

from __future__ import annotations

import argparse
import math
import os
import sys
import tempfile
import threading
import time
from multiprocessing.connection import Connection

from guidedarm.systems.child_process import (
    ChildChannels,
    EndChild,
    FollowParent,
    HowItEnded,
    SendOrExit,
    StartChild,
)
from guidedarm.systems.hardware.arm_link import DescribeError

POLL_PERIOD = 0.0005  # s, how often the child reads the receive interface
EXIT_TIMEOUT = 1.0  # s, for the child to end after the parent's last call
SAMPLE_FIELDS = ("timestamp", "actual_q", "actual_qd", "runtime_state")


class UrRtdeClientProcess:
    """Starts the child, which connects both vendor interfaces to the controller at `host`
    (ConnectionError with the vendor's own words if they fail, or if the child does not
    answer within `connect_timeout` s); `receive` and `control` then reach them.

    `register`: an output_int_register the samples carry as well (None: none)."""

    def __init__(
        self,
        host: str,
        frequency: float,
        register: int | None = None,
        connect_timeout: float = 30.0,
    ) -> None:
        args = [host, str(frequency)]
        if register is not None:
            args += ["--register", str(register)]
        self.process, (calls, samples) = StartChild(__name__, args, channels=2)
        self._calls = _CallChannel(calls, self._HowItEnded)
        said = self._calls.Wait(connect_timeout)
        if said != "connected":
            samples.close()
            self.End()
            raise ConnectionError(said)
        self.receive = RemoteRtdeReceive(samples, self._calls)
        self.control = RemoteRtdeControl(self._calls, self)

    def _HowItEnded(self) -> str:
        return HowItEnded(self.process, "the ur_rtde client process", EXIT_TIMEOUT)

    def End(self) -> None:
        """Asks the child to end; kills it if it has not within EXIT_TIMEOUT s (a vendor
        call it is still inside can wait minutes on a dead controller)."""
        self._calls.Close()
        EndChild(self.process, EXIT_TIMEOUT)


class _CallChannel:
    """Request and reply with the child, one call at a time across the parent's threads."""

    def __init__(self, connection: Connection, how_it_ended) -> None:
        self._connection = connection
        self._how_it_ended = how_it_ended
        self._lock = threading.Lock()

    def Wait(self, timeout: float):
        """The child's first message (its connection result) within `timeout` s."""
        try:
            if self._connection.poll(timeout):
                return self._connection.recv()
        except (EOFError, OSError):
            pass
        return self._how_it_ended()

    def Call(self, interface: str, method: str, *args):
        """`interface`.`method`(*args) in the child; its vendor error as RuntimeError."""
        with self._lock:
            try:
                self._connection.send((interface, method, args))
                ok, value = self._connection.recv()
            except (EOFError, OSError):
                raise RuntimeError(self._how_it_ended()) from None
        if not ok:
            raise RuntimeError(value)
        return value

    def Close(self) -> None:
        self._connection.close()


class RemoteRtdeReceive:
    """RtdeReceive of the child's receive interface: the newest sample it pushed. Before the
    first sample the timestamp is NaN, which no later timestamp is taken to follow."""

    def __init__(self, samples: Connection, calls: _CallChannel) -> None:
        self._samples = samples
        self._calls = calls
        self._sample = (math.nan, [], [], 0, 0)
        self._connected = True
        self._error: str | None = None
        self._thread = threading.Thread(target=self._Read, name="ur-rtde-samples", daemon=True)
        self._thread.start()

    def _Read(self) -> None:
        try:
            while True:
                kind, value = self._samples.recv()
                if kind == "sample":
                    self._sample = value
                elif kind == "error":
                    self._error = value
                else:  # "lost"
                    break
        except (EOFError, OSError):
            pass
        self._connected = False

    def _Newest(self) -> tuple:
        if self._error is not None:
            raise RuntimeError(self._error)
        return self._sample

    def getTimestamp(self) -> float:
        return self._Newest()[0]

    def getActualQ(self) -> list[float]:
        return self._Newest()[1]

    def getActualQd(self) -> list[float]:
        return self._Newest()[2]

    def getRuntimeState(self) -> int:
        return self._Newest()[3]

    def getOutputIntRegister(self, output_id: int) -> int:
        return self._Newest()[4]

    def isConnected(self) -> bool:
        return self._connected

    def disconnect(self) -> None:
        self._calls.Call("receive", "disconnect")


class RemoteRtdeControl:
    """RtdeControl of the child's control interface. stopScript, the last call a link
    makes, also ends the child."""

    def __init__(self, calls: _CallChannel, client: UrRtdeClientProcess) -> None:
        self._calls = calls
        self._client = client

    def servoJ(
        self,
        q: list[float],
        speed: float,
        acceleration: float,
        time: float,
        lookahead_time: float,
        gain: float,
    ) -> bool:
        return self._calls.Call(
            "control", "servoJ", q, speed, acceleration, time, lookahead_time, gain
        )

    def servoStop(self, a: float) -> bool:
        return self._calls.Call("control", "servoStop", a)

    def setWatchdog(self, min_frequency: float) -> bool:
        return self._calls.Call("control", "setWatchdog", min_frequency)

    def kickWatchdog(self) -> bool:
        return self._calls.Call("control", "kickWatchdog")

    def stopScript(self) -> None:
        try:
            self._calls.Call("control", "stopScript")
        finally:
            self._client.End()


def _ServeCalls(calls: Connection, interfaces: dict) -> None:
    """Answers the parent's calls until it closes its socket."""
    while True:
        try:
            interface, method, args = calls.recv()
        except (EOFError, OSError):
            return
        try:
            reply = (True, getattr(interfaces[interface], method)(*args))
        except Exception as e:  # the vendor's error, handed to the parent
            reply = (False, DescribeError(e))
        SendOrExit(calls, reply)


def _PushSamples(receive, register: int | None, samples: Connection) -> None:
    """Sends each sample with a later timestamp; "lost" once the connection is."""
    last = -math.inf
    try:
        while receive.isConnected():
            timestamp = receive.getTimestamp()
            if timestamp > last:
                last = timestamp
                value = receive.getOutputIntRegister(register) if register is not None else 0
                sample = (
                    timestamp,
                    list(receive.getActualQ()),
                    list(receive.getActualQd()),
                    receive.getRuntimeState(),
                    value,
                )
                SendOrExit(samples, ("sample", sample))
            time.sleep(POLL_PERIOD)
        SendOrExit(samples, ("lost", None))
    except Exception as e:  # the vendor raises RuntimeError; any error ends the stream
        SendOrExit(samples, ("error", f"RTDE receive failed: {DescribeError(e)}"))


class CapturedStderr:
    """Within `with`, what is written to file descriptor 2 (also by C++ libraries, which
    print their connection errors themselves) goes to `text` instead of the terminal."""

    def __enter__(self) -> CapturedStderr:
        self.text = ""
        sys.stderr.flush()
        self._saved = os.dup(2)
        self._capture = tempfile.TemporaryFile()
        os.dup2(self._capture.fileno(), 2)
        return self

    def __exit__(self, *_) -> None:
        os.dup2(self._saved, 2)
        os.close(self._saved)
        self._capture.seek(0)
        self.text = self._capture.read().decode("utf-8", "replace")
        self._capture.close()


def _Main() -> None:
    parser = argparse.ArgumentParser(description="The ur_rtde client of one UR controller.")
    parser.add_argument("host")
    parser.add_argument("frequency", type=float)
    parser.add_argument("--register", type=int)
    parser.add_argument("--fds", required=True)
    args = parser.parse_args()
    FollowParent()
    calls, samples = ChildChannels(args.fds)

    variables = list(SAMPLE_FIELDS)
    if args.register is not None:
        variables.append(f"output_int_register_{args.register}")
    receive = control = None
    error = ""
    with CapturedStderr() as vendor:
        try:
            import rtde_control
            import rtde_receive

            receive = rtde_receive.RTDEReceiveInterface(args.host, args.frequency, variables)
            control = rtde_control.RTDEControlInterface(args.host, args.frequency)
        except (ImportError, RuntimeError) as e:
            error = DescribeError(e)
    if control is None:
        said = "; ".join(line for line in [*vendor.text.splitlines(), error] if line.strip())
        SendOrExit(calls, said)
        os._exit(0)
    sys.stderr.write(vendor.text)
    SendOrExit(calls, "connected")
    pusher = threading.Thread(target=_PushSamples, args=(receive, args.register, samples))
    pusher.daemon = True
    pusher.start()
    _ServeCalls(calls, {"receive": receive, "control": control})
    sys.stderr.flush()
    os._exit(0)  # the vendor's destructors may wait on a dead controller


if __name__ == "__main__":
    _Main()
