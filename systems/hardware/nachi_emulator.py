"""An emulated Nachi CFD controller: the User Task line protocol served from a Drake
simulation of the arm (the station's MultibodyPlant and position servo).

`NachiControllerLogic` is the controller's bookkeeping (requests -> replies, target, the
servo loop of streamed SERVO targets with its timeout, stop and timeout latches, error log)
and runs without a simulation; `ServeConnection` answers one client's
lines with it; `NachiEmulator` steps the station in real time, feeds the logic the
simulated joints and flange pose, and serves TCP clients. With `lockstep`, the station's
time advances by the SERVO targets' intervals while a stream is tracked (LockstepClock)
instead of the host clock.

Any bytes a client sends (non-ASCII, binary, NUL, overlong lines) get a reply, `NG <code>
<text>` when they are not a request, and are counted; the connection keeps being served.
A request is executed when it is received, whether or not its reply can still be
delivered: a client that sent STOP and vanished has stopped the arm.
"""

from __future__ import annotations

import contextlib
import gc
import socket
import threading
import time
from collections.abc import Callable

import numpy as np
from pydrake.math import RollPitchYaw
from pydrake.systems.analysis import Simulator
from pydrake.systems.framework import Context

from guidedarm.systems.errors import ConfigurationError
from guidedarm.systems.hardware import nachi_protocol as nachi
from guidedarm.systems.hardware.line_socket import LineSocket
from guidedarm.systems.hardware.lockstep_clock import LockstepClock
from guidedarm.systems.hardware.servo_tracker import ServoTracker

SETTLED = 1e-3  # rad; the arm counts as MOVING while farther than this from its command
DEFAULT_SERVO_VELOCITY = np.pi  # rad/s per joint, where the emulator is given no limits
DEFAULT_SERVO_ACCELERATION = 10.0  # rad/s^2 per joint
DEFAULT_SERVO_TIMEOUT = 0.1  # s without a SERVO target: the arm brakes, TIMEOUT latched


class NachiControllerLogic:
    """Replies to requests. Joints within [lower, upper] (rad) are accepted as targets.

    MOVE sets the joint command to the stored target. SERVO streams: a ServoTracker moves
    the command towards the latest target within `velocity` and `acceleration` (rad/s,
    rad/s^2 per joint) at every `Measure`; no SERVO for `servo_timeout` s brakes it and
    latches TIMEOUT. STOP holds the arm (braking within the limits while streaming) and
    latches STOPPED. A latch refuses motion requests until RESET.

    With `lockstep`, a SERVO returns once the simulation has advanced by its interval
    (`clock`, stepped by `WaitForClock` in the simulation thread). Time stands still
    between targets then, the streaming timeout's too: a client that stops streaming
    without STOP leaves the arm where the last interval ended."""

    def __init__(
        self,
        lower: np.ndarray,
        upper: np.ndarray,
        q0: np.ndarray,
        velocity: np.ndarray | None = None,
        acceleration: np.ndarray | None = None,
        servo_timeout: float = DEFAULT_SERVO_TIMEOUT,
        lockstep: bool = False,
    ) -> None:
        self.lower, self.upper = lower, upper
        n = len(lower)
        self.velocity = np.full(n, DEFAULT_SERVO_VELOCITY) if velocity is None else velocity
        self.acceleration = (
            np.full(n, DEFAULT_SERVO_ACCELERATION) if acceleration is None else acceleration
        )
        self.servo_timeout = servo_timeout
        self.lock = threading.Lock()
        self.clock = LockstepClock(self.lock) if lockstep else None
        self.commanded = np.array(q0, float)
        self.measured = np.array(q0, float)
        self.time = 0.0
        self.pose = (np.zeros(3), np.zeros(3))
        self.target: np.ndarray | None = None
        self.tracker: ServoTracker | None = None  # while streaming or braking from a stream
        self.last_servo_time = -np.inf  # controller clock of the latest accepted SERVO (s)
        self.standstill_time: float | None = None  # when the latest braking ended (s)
        self.stopped = False
        self.timed_out = False
        self.moves = 0
        self.stops = 0
        self.timeouts = 0
        self.error_count = 0
        self.last_error: tuple[str, str] | None = None

    def Measure(self, t: float, q: np.ndarray, xyz: np.ndarray, rpy: np.ndarray) -> np.ndarray:
        """Records the simulated state at controller time t (s) and runs the servo loop;
        returns the joint command for the next step."""
        with self.lock:
            self.time, self.measured, self.pose = t, q, (xyz, rpy)
            tracker = self.tracker
            if tracker is not None:
                if not tracker.braking and t - self.last_servo_time > self.servo_timeout:
                    self._Brake()
                    self.timed_out = True
                    self.timeouts += 1
                self.commanded = tracker.Step(t)
                if tracker.braking and tracker.Standstill():
                    self.tracker, self.standstill_time = None, t
            return self.commanded.copy()

    def WaitForClock(self, t_next: float) -> bool:
        """Lockstep, from the simulation thread: blocks until the simulation may step to
        t_next (s); True when the host clock paces that step (no stream is tracked)."""
        with self.lock:
            while self.clock.Blocks(t_next):
                self.clock.changed.wait()
            return self.clock.granted is None

    def Close(self) -> None:
        """Releases requests waiting for the lockstep clock (the simulation ends)."""
        if self.clock is not None:
            with self.lock:
                self.clock.Close()

    def _Brake(self) -> None:
        self.tracker.Brake()
        if self.clock is not None:
            self.clock.Release()

    def Handle(self, line: str) -> str:
        """The reply line to one request line (ASCII, without its LF)."""
        with self.lock:
            try:
                request = nachi.ParseRequest(line)
            except nachi.NachiProtocolError as e:
                code = nachi.E_UNKNOWN if "unknown request" in str(e) else nachi.E_MALFORMED
                return self._Error(code, str(e))
            return self._Reply(request)

    def _Reply(self, request: nachi.Request) -> str:
        word = request.word
        if word == nachi.READ_JOINTS:
            return nachi.FormatJoints(self.time, self.measured)
        if word == nachi.READ_POSE:
            return nachi.FormatPose(*self.pose)
        if word == nachi.SET_TARGET:
            refused = self._CheckRange(request.values)
            if refused:
                return refused
            self.target = request.values
            return "OK"
        if word == nachi.MOVE:
            refused = self._CheckMayMove(word)
            if refused:
                return refused
            if self.tracker is not None:
                return self._Error(nachi.E_STREAMING, "MOVE while streaming; send STOP first")
            if self.target is None:
                return self._Error(nachi.E_NO_TARGET, "MOVE without SET_TARGET")
            self.commanded = self.target
            self.moves += 1
            return "OK"
        if word == nachi.SERVO:
            return self._Servo(request.values, request.interval)
        if word == nachi.STOP:
            if self.tracker is not None:
                self._Brake()
            else:
                self.commanded = self.measured.copy()
            self.target = None
            self.stopped = True
            self.stops += 1
            return "OK"
        if word == nachi.RESET:
            self.stopped = self.timed_out = False
            return "OK"
        if word == nachi.STATUS:
            return f"STATUS {self.State()} {self.moves} {self.error_count}"
        last = f" {self.last_error[0]} {self.last_error[1]}" if self.last_error else ""
        return f"ERRORS {self.error_count}{last}"

    def _Servo(self, q: np.ndarray, interval: float) -> str:
        """A streamed target: checked against the latches, the interval, the position range
        and the velocity it implies from the previous target (the held command when a
        stream starts), then tracked."""
        refused = self._CheckMayMove(nachi.SERVO) or self._CheckRange(q)
        if refused:
            return refused
        if self.tracker is not None and self.tracker.braking:
            return self._Error(nachi.E_STREAMING, "SERVO while the arm still brakes")
        if not 0.0 < interval <= nachi.MAX_SERVO_INTERVAL:
            return self._Error(
                nachi.E_SERVO_STEP,
                f"SERVO interval {interval:g} s outside (0, {nachi.MAX_SERVO_INTERVAL:g}] s",
            )
        previous = self.commanded if self.tracker is None else self.tracker.target
        speed = np.abs(q - previous) / interval
        too_fast = speed > self.velocity
        if np.any(too_fast):
            j = int(np.argmax(too_fast))
            return self._Error(
                nachi.E_SERVO_STEP,
                f"joint{j + 1} SERVO step implies {speed[j]:.4g} rad/s, beyond its "
                f"limit {self.velocity[j]:.4g}",
            )
        if self.clock is not None:  # the arm tracks the previous target for `interval` first
            self.clock.Grant(self.time, interval)
            refused = self._CheckMayMove(nachi.SERVO)  # a STOP or timeout meanwhile
            if refused:
                return refused
        if self.tracker is None:
            self.tracker = ServoTracker(self.commanded, self.velocity, self.acceleration, self.time)
        self.tracker.SetTarget(q, interval, self.time)
        self.last_servo_time = self.time
        self.moves += 1
        return "OK"

    def _CheckMayMove(self, word: str) -> str | None:
        if self.stopped:
            return self._Error(nachi.E_STOPPED, f"stopped; send RESET before {word}")
        if self.timed_out:
            return self._Error(nachi.E_TIMEOUT, f"servo timeout; send RESET before {word}")
        return None

    def _CheckRange(self, q: np.ndarray) -> str | None:
        outside = (q < self.lower) | (q > self.upper)
        if np.any(outside):
            joint = int(np.argmax(outside)) + 1
            return self._Error(nachi.E_LIMIT, f"joint{joint} target beyond its limits")
        return None

    def State(self) -> str:
        if self.stopped:
            return "STOPPED"
        if self.timed_out:
            return "TIMEOUT"
        if self.tracker is not None:
            return "STOPPING" if self.tracker.braking else "SERVO"
        moving = np.max(np.abs(self.commanded - self.measured)) > SETTLED
        return "MOVING" if moving else "IDLE"

    def _Error(self, code: str, text: str) -> str:
        self.error_count += 1
        self.last_error = (code, text)
        return f"NG {code} {text}"


def ServeConnection(connection: socket.socket, logic: NachiControllerLogic) -> None:
    """Answers the client's request lines until it closes the connection. Once replies can
    no longer be delivered, the requests already received are still executed."""
    lines = LineSocket(connection, nachi.MAX_LINE)
    replying = True
    while True:
        try:
            line = lines.ReadLine()
        except OSError:
            return
        reply = logic.Handle(line)
        if replying:
            try:
                lines.WriteLines(reply)
            except OSError:
                replying = False


class NachiEmulator:
    """Serves `arm` of a station Diagram (see MakeStation) on host:port (0 = any free port).

    The station must export `<arm>.position_commanded` and `<arm>.position_measured`; the
    flange pose is read from its plant (`plant` system), frames `<arm>::base`, `<arm>::flange`.
    The controller steps every `period` (s), its servo loop too: SERVO targets are tracked
    within the model's joint velocity limits and `servo_acceleration` (rad/s^2, every
    joint); `servo_timeout` (s) without a SERVO brakes the arm. `lockstep`: while a stream
    is tracked, the station steps by the SERVO intervals (see NachiControllerLogic), else
    in real time.
    After every step each observer is called with the station's context (e.g. to sample
    sensor ports for other emulated devices; they run in the stepping thread).
    """

    def __init__(
        self,
        station,
        arm: str,
        host: str = "127.0.0.1",
        port: int = nachi.DEFAULT_PORT,
        period: float = 0.002,
        observers: tuple[Callable[[Context], None], ...] = (),
        servo_acceleration: float = DEFAULT_SERVO_ACCELERATION,
        servo_timeout: float = DEFAULT_SERVO_TIMEOUT,
        lockstep: bool = False,
    ) -> None:
        self._observers = observers
        self.station = station
        self.simulator = Simulator(station)
        self.context = self.simulator.get_mutable_context()
        self._command_port = station.GetInputPort(f"{arm}.position_commanded")
        self._measured_port = station.GetOutputPort(f"{arm}.position_measured")
        plant = station.GetSubsystemByName("plant")
        self._plant = plant
        self._plant_context = plant.GetMyContextFromRoot(self.context)
        instance = plant.GetModelInstanceByName(arm)
        self._base = plant.GetFrameByName("base", instance)
        self._flange = plant.GetFrameByName("flange", instance)
        q0 = plant.GetPositions(self._plant_context, instance)
        velocity = plant.GetVelocitiesFromArray(instance, plant.GetVelocityUpperLimits())
        self.logic = NachiControllerLogic(
            plant.GetPositionsFromArray(instance, plant.GetPositionLowerLimits()),
            plant.GetPositionsFromArray(instance, plant.GetPositionUpperLimits()),
            q0,
            velocity,
            np.full(len(q0), servo_acceleration),
            servo_timeout,
            lockstep,
        )
        self._command_port.FixValue(self.context, q0)
        self._period = period
        try:
            self._server = socket.create_server((host, port), reuse_port=False)
        except (OSError, OverflowError) as e:
            message = f"nachi emulator: cannot listen on {host}:{port}: {e}"
            raise ConfigurationError(message) from None
        self.port = self._server.getsockname()[1]
        self._closing = threading.Event()
        threading.Thread(target=self._Accept, name="nachi-accept", daemon=True).start()

    def Run(self, duration: float = np.inf, realtime_rate: float = 1.0) -> None:
        """Steps the simulation until `duration` (s) or Close(). The controller runs in the
        middle of each period of the station's discrete updates (plant, command sampling),
        so every step holds exactly one of them: stepping to their very instants would let
        rounding decide whether a command is sampled now or a period later. In lockstep
        the steps outside a stream are paced here at `realtime_rate`."""
        lockstep = self.logic.clock is not None
        self.simulator.set_target_realtime_rate(0.0 if lockstep else realtime_rate)
        self.simulator.Initialize()
        # A full garbage collection over the station's objects would stall the controller
        # (and the ToF lines written from this thread) in real time: freeze what is built.
        gc.freeze()
        start = t = self.context.get_time()
        k, origin = 0, None
        while t < duration and not self._closing.is_set():
            X_BF = self._plant.CalcRelativeTransform(self._plant_context, self._base, self._flange)
            q = self._measured_port.Eval(self.context)
            rpy = RollPitchYaw(X_BF.rotation()).vector()
            command = self.logic.Measure(t, q.copy(), X_BF.translation(), rpy)
            self._command_port.FixValue(self.context, command)
            t = start + (k + 0.5) * self._period
            k += 1
            if lockstep:
                real_time = self.logic.WaitForClock(t)
                origin = self._Pace(t, realtime_rate, origin if real_time else None)
            self.simulator.AdvanceTo(t)
            for observer in self._observers:
                observer(self.context)
        self.logic.Close()

    def _Pace(
        self, t: float, rate: float, origin: tuple[float, float] | None
    ) -> tuple[float, float]:
        """Waits until host time reaches t (s) at `rate` from `origin` (simulated, host time;
        None: from now, the host clock taking over after a lockstep stream); returns the
        origin."""
        now = time.monotonic()
        if origin is None:
            return self.context.get_time(), now
        if rate > 0:
            self._closing.wait(max(0.0, origin[1] + (t - origin[0]) / rate - now))
        return origin

    def Close(self) -> None:
        """Ends Run and the accept thread. On Linux, closing a listening socket does not
        wake a thread blocked in accept(); shutting it down does."""
        self._closing.set()
        self.logic.Close()
        with contextlib.suppress(OSError):
            self._server.shutdown(socket.SHUT_RDWR)
        self._server.close()

    def _Accept(self) -> None:
        while not self._closing.is_set():
            try:
                connection, _ = self._server.accept()
            except OSError:
                return
            threading.Thread(target=self._Serve, args=(connection,), daemon=True).start()

    def _Serve(self, connection: socket.socket) -> None:
        with connection, contextlib.suppress(OSError):  # a client gone before it was served
            connection.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
            ServeConnection(connection, self.logic)
