"""Nachi CFD controllers through the User Task line protocol, behind the ArmLink interface.

Requests are pipelined: a writer appends one pending reply per request line to a queue, in
the order the lines are sent, and a reader thread hands each reply line to the oldest
pending request. So a STOP goes out at once even while an earlier request waits for a
controller that has frozen, and a late reply can never be taken for the reply to a later
request. A poll thread sends the newest joint target as soon as one is pending, and
READ_JOINTS at least every `poll_period`. Targets go out as `SERVO <interval> <joints>`
(command mode `stream`: the controller tracks them within its limits and brakes by itself
when they stop coming) or as `SET_TARGET` + `MOVE` (mode `move`: the paper's User Task). The
poll thread it waits for its replies without a
deadline of its own: the ArmDriver's watchdog judges a link that went quiet.

Velocities are differences of successive joint readings over the controller's clock.
Malformed reply lines are counted in `rejected_lines` and skipped; the 1st, 10th, 100th, ...
are printed. A reply line without a pending request, or a well-formed reply to another kind
of request (`OK` to READ_JOINTS), means the controller and the link no longer agree which
reply answers which request (a duplicated or dropped reply): every later reply could be
taken for an earlier request's, so the link faults, and a STOP after that is sent but
cannot be confirmed. A controller that refuses a target or a move (`NG ...`, e.g. after a
STOP from its pendant) or a lost connection is a fault: streaming ends and the ArmDriver
fails the run. `stop` waits at most `stop_timeout` for the controller's OK. Connecting sends
RESET: starting a run is the deliberate act that clears an earlier STOP (or a streaming
timeout).

`lockstep_wait` (s) is for a controller whose clock advances by the SERVO intervals (the
emulator's lockstep mode): `latest` then asks for the joints and waits, at most that long,
for a reading requested after the call, which it hands over as fresh. Requests are served
in order, so that reading comes after every target sent before it: the arm at the time the
stream has reached, however late the OS ran either process. A wait that runs out returns
the older sample with its age, which the ArmDriver's watchdog judges.
"""

from __future__ import annotations

import collections
import contextlib
import socket
import struct
import threading
import time

import numpy as np

from guidedarm.systems.errors import ConfigurationError
from guidedarm.systems.hardware import nachi_protocol as nachi
from guidedarm.systems.hardware.arm_link import (
    JointSample,
    LatestSample,
    RegisterArmLink,
    UnregisterArmLink,
)
from guidedarm.systems.hardware.line_socket import LineSocket, PrintRejectedLine

COMMAND_MODES = ("stream", "move")
WAIT_SLICE = 0.05  # s; how often a wait for a reply checks whether the link died or closes
SEND_TIMEOUT = 1.0  # s; a controller that takes no bytes for this long is lost


class PendingReply:
    """The reply line to one request line, filled in by the reader thread."""

    def __init__(self, request: str) -> None:
        self.word = request.split(maxsplit=1)[0]
        self._done = threading.Event()
        self._line = ""
        self._error: str | None = None

    def Resolve(self, line: str | None, error: str | None = None) -> None:
        self._line, self._error = line or "", error
        self._done.set()

    def Wait(self, timeout: float | None) -> str:
        """The reply; TimeoutError after `timeout` s, ConnectionError if the link died."""
        if not self._done.wait(timeout):
            raise TimeoutError(f"no reply to {self.word} within {timeout} s")
        if self._error is not None:
            raise ConnectionError(f"{self.word} unanswered: {self._error}")
        return self._line


class NachiLink:
    """ArmLink of a Nachi arm at (host, port)."""

    def __init__(
        self,
        name: str,
        host: str,
        port: int,
        poll_period: float = 0.002,
        connect_timeout: float = 1.0,
        stop_timeout: float = 0.25,
        command_mode: str = "stream",
        lockstep_wait: float | None = None,
    ) -> None:
        if command_mode not in COMMAND_MODES:
            raise ConfigurationError(f"{name}: command mode {command_mode!r}, not {COMMAND_MODES}")
        if lockstep_wait is not None and command_mode != "stream":
            raise ConfigurationError(f"{name}: lockstep needs command mode 'stream'")
        self.name = name
        self._streaming = command_mode == "stream"
        self.rejected_lines = 0
        self._fault: str | None = None
        self._dead: str | None = None  # why nothing more can be sent or received
        self._out_of_step: str | None = None  # why replies can no longer be matched
        self._stop_timeout = stop_timeout
        try:
            connection = socket.create_connection((host, port), timeout=connect_timeout)
        except (OSError, OverflowError, ValueError) as e:  # ValueError: a name IDNA refuses
            raise ConfigurationError(f"{name}: cannot reach {host}:{port}: {e}") from None
        connection.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
        # Reads block (close() shuts the socket down); sends give up after SEND_TIMEOUT.
        connection.settimeout(None)
        seconds = int(SEND_TIMEOUT)
        microseconds = int(1e6 * (SEND_TIMEOUT - seconds))
        connection.setsockopt(
            socket.SOL_SOCKET, socket.SO_SNDTIMEO, struct.pack("ll", seconds, microseconds)
        )
        self._socket = LineSocket(connection, nachi.MAX_LINE)
        self._send_lock = threading.Lock()
        self._pending_replies: collections.deque[PendingReply] = collections.deque()
        self._closing = threading.Event()
        self._wake = threading.Event()  # before RESET: close() sets it when RESET fails
        self._reader = threading.Thread(target=self._Read, name=f"{name}-nachi-read", daemon=True)
        self._reader.start()
        try:
            (reply,) = self.Request(nachi.RESET, timeout=connect_timeout)
            nachi.CheckOk(reply)
        except (OSError, nachi.NachiProtocolError) as e:
            self.close()
            raise ConfigurationError(f"{name}: {host}:{port} did not accept RESET: {e}") from None
        # The newest target not yet sent and the time since the last one sent (SERVO's
        # interval); their own lock, since a send may block (SEND_TIMEOUT) under _send_lock.
        self._target_lock = threading.Lock()
        self._target: np.ndarray | None = None
        self._interval = 0.0
        # READ_JOINTS requests numbered (_target_lock), and the newest one read (_reads).
        self._lockstep_wait = lockstep_wait
        self._reads = threading.Condition()
        self._reads_sent = self._reads_done = 0
        self._stopped = False
        self._poll_period = poll_period
        self._latest = LatestSample()
        self._previous: tuple[float, np.ndarray] | None = None
        self._poller = threading.Thread(target=self._Poll, name=f"{name}-nachi-poll", daemon=True)
        self._poller.start()
        RegisterArmLink(self)

    def Request(self, *lines: str, timeout: float | None = None) -> list[str]:
        """Sends request lines and returns their replies (thread-safe); TimeoutError when a
        reply does not come within `timeout` s (its late reply is then discarded)."""
        return [reply.Wait(timeout) for reply in self._Send(lines)]

    def _Send(self, lines: list[str] | tuple[str, ...]) -> list[PendingReply]:
        with self._send_lock:
            return self._SendLocked(lines)

    def _SendLocked(self, lines: list[str] | tuple[str, ...]) -> list[PendingReply]:
        replies = [PendingReply(line) for line in lines]
        if self._dead is not None:  # the reason is the link's fault, reported already
            raise ConnectionError(f"{replies[0].word} not sent: the link is down")
        self._pending_replies.extend(replies)
        try:
            self._socket.WriteLines(*lines)
        except OSError as e:
            self._Lost(f"connection lost: {e}")
            raise ConnectionError(f"{replies[0].word} not sent: connection lost: {e}") from None
        return replies

    def _Read(self) -> None:
        try:
            while True:
                line = self._socket.ReadLine()
                try:
                    reply = self._pending_replies.popleft()
                except IndexError:
                    self._OutOfStep(f"a reply without a request: {nachi.Quote(line)}")
                    continue
                if self._out_of_step is None and nachi.RepliesOutOfStep(reply.word, line):
                    self._OutOfStep(f"{nachi.Quote(line)} answered {reply.word}")
                if self._out_of_step is not None:
                    reply.Resolve(None, self._out_of_step)
                else:
                    reply.Resolve(line)
        except OSError as e:
            self._Lost("link closed" if self._closing.is_set() else f"connection lost: {e}")

    def _OutOfStep(self, what: str) -> None:
        """Replies can no longer be matched to requests: the link faults (once)."""
        if self._out_of_step is None:
            self._out_of_step = f"replies out of step with requests: {what}"
            self._fault = self._fault or self._out_of_step
            print(f"{self.name}: {self._out_of_step}", flush=True)

    def _Lost(self, reason: str) -> None:
        """Marks the link dead: every pending and later request fails with `reason`."""
        self._dead = self._dead or reason
        self._fault = self._fault or reason
        while self._pending_replies:
            with contextlib.suppress(IndexError):
                self._pending_replies.popleft().Resolve(None, reason)

    def _Poll(self) -> None:
        while not self._closing.is_set():
            self._wake.wait(self._poll_period)
            self._wake.clear()
            try:
                with self._send_lock:
                    target_lines, read = self._TargetLines()
                    replies = self._SendLocked([*target_lines, nachi.READ_JOINTS])
                for reply in replies[:-1]:
                    nachi.CheckOk(self._Await(reply))
                if self._Check(self._Measured, self._Await(replies[-1])):
                    with self._reads:
                        self._reads_done = read
                        self._reads.notify_all()
            except (nachi.NachiProtocolError, OSError) as e:
                self._fault = self._fault or str(e)
                with self._reads:  # a `latest` waiting in lockstep returns at once
                    self._reads.notify_all()
                return

    def _TargetLines(self) -> tuple[list[str], int]:
        """The request lines of the pending target, none if there is none or the link was
        stopped (called with the send lock held, which `stop` takes too), and the number of
        the READ_JOINTS that follows them: counted as the target is taken, so that a
        reading numbered after a `latest` call follows every target queued before it."""
        with self._target_lock:
            target, interval = self._target, self._interval
            if target is not None:
                self._target, self._interval = None, 0.0
            self._reads_sent += 1
            read = self._reads_sent
        if target is None or self._stopped:
            return [], read
        if not self._streaming:
            return [nachi.FormatSetTarget(target), nachi.MOVE], read
        return [nachi.FormatServo(target, interval)], read

    def _Await(self, reply: PendingReply) -> str:
        """The reply, however long the controller takes, unless the link dies or closes."""
        while True:
            try:
                return reply.Wait(WAIT_SLICE)
            except TimeoutError:
                if self._dead is not None or self._closing.is_set():
                    raise ConnectionError(self._dead or "link closed") from None

    def _Check(self, parse, reply: str) -> bool:
        """Whether `parse` accepted the reply (else it is rejected and counted)."""
        try:
            parse(reply)
        except nachi.NachiProtocolError as e:
            self._Reject(str(e))
            return False
        return True

    def _Reject(self, why: str) -> None:
        self.rejected_lines += 1
        PrintRejectedLine(self.name, "reply", self.rejected_lines, why)

    def _Measured(self, reply: str) -> None:
        t, q = nachi.ParseJoints(reply)
        if self._previous is not None and t <= self._previous[0]:
            return  # the controller has not produced a new sample yet
        v = (
            np.zeros_like(q)
            if self._previous is None
            else (q - self._previous[1]) / (t - self._previous[0])
        )
        self._previous = (t, q)
        self._latest.put(q, v)

    def latest(self) -> JointSample | None:
        if self._lockstep_wait is None:
            return self._latest.get()
        with self._target_lock:
            wanted = self._reads_sent + 1
        self._wake.set()
        with self._reads:
            read = self._reads.wait_for(
                lambda: self._reads_done >= wanted or self._fault is not None,
                self._lockstep_wait,
            )
        sample = self._latest.get()
        if not read or sample is None or self._fault is not None or self._stopped:
            return sample
        return JointSample(sample.q, sample.v, time.monotonic())

    def fault(self) -> str | None:
        return self._fault

    def send_position(self, q: np.ndarray, period: float) -> None:
        """Queues q (rad), meant `period` s after the previous target; a target replaced
        before it was sent lends its period to the next (SERVO intervals add up to the time
        between the targets the controller receives)."""
        with self._target_lock:
            self._target = np.array(q, float)
            self._interval += period
        self._wake.set()

    def stop(self) -> None:
        """Sends STOP at once (no target follows it) and waits `stop_timeout` for its OK.
        A STOP left unanswered marks the link dead: stopping again fails at once. With
        replies out of step, no reply can confirm it: the STOP is sent, then this raises."""
        with self._send_lock:
            self._stopped = True
            (reply,) = self._SendLocked([nachi.STOP])
        if self._out_of_step is not None:
            raise ConnectionError("STOP sent, unconfirmed: replies out of step with requests")
        try:
            line = reply.Wait(self._stop_timeout)
        except TimeoutError as e:
            self._dead = self._dead or str(e)
            raise
        nachi.CheckOk(line)

    def close(self) -> None:
        self._closing.set()
        self._wake.set()
        UnregisterArmLink(self)
        with contextlib.suppress(OSError):
            self._socket.connection.shutdown(socket.SHUT_RDWR)
        for thread in (getattr(self, "_poller", None), self._reader):
            if thread is not None and thread is not threading.current_thread():
                thread.join(timeout=2 * WAIT_SLICE)
        self._socket.connection.close()
