"""An emulated Nachi CFD controller: the User Task line protocol served from a Drake
simulation of the arm (the station's MultibodyPlant and position servo).

`NachiControllerLogic` is the controller's bookkeeping (requests -> replies, target, stop
latch, error log) and runs without a simulation; `ServeConnection` answers one client's
lines with it; `NachiEmulator` steps the station in real time, feeds the logic the
simulated joints and flange pose, and serves TCP clients.

Any bytes a client sends (non-ASCII, binary, NUL, overlong lines) get a reply, `NG <code>
<text>` when they are not a request, and are counted; the connection keeps being served.
A request is executed when it is received, whether or not its reply can still be
delivered: a client that sent STOP and vanished has stopped the arm.
"""

from __future__ import annotations

import contextlib
import socket
import threading
from collections.abc import Callable

import numpy as np
from pydrake.math import RollPitchYaw
from pydrake.systems.analysis import Simulator
from pydrake.systems.framework import Context

from guidedarm.systems.errors import ConfigurationError
from guidedarm.systems.hardware import nachi_protocol as nachi
from guidedarm.systems.hardware.line_socket import LineSocket

SETTLED = 1e-3  # rad; the arm counts as MOVING while farther than this from its command


class NachiControllerLogic:
    """Replies to requests. Joints within [lower, upper] (rad) are accepted as targets; STOP
    holds the arm where it is and refuses MOVE until RESET."""

    def __init__(self, lower: np.ndarray, upper: np.ndarray, q0: np.ndarray) -> None:
        self.lower, self.upper = lower, upper
        self.lock = threading.Lock()
        self.commanded = np.array(q0, float)
        self.measured = np.array(q0, float)
        self.time = 0.0
        self.pose = (np.zeros(3), np.zeros(3))
        self.target: np.ndarray | None = None
        self.stopped = False
        self.moves = 0
        self.stops = 0
        self.error_count = 0
        self.last_error: tuple[str, str] | None = None

    def Measure(self, t: float, q: np.ndarray, xyz: np.ndarray, rpy: np.ndarray) -> np.ndarray:
        """Records the simulated state; returns the joint command for the next step."""
        with self.lock:
            self.time, self.measured, self.pose = t, q, (xyz, rpy)
            return self.commanded.copy()

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
            q = request.values
            outside = (q < self.lower) | (q > self.upper)
            if np.any(outside):
                joint = int(np.argmax(outside)) + 1
                return self._Error(nachi.E_LIMIT, f"joint{joint} target beyond its limits")
            self.target = q
            return "OK"
        if word == nachi.MOVE:
            if self.stopped:
                return self._Error(nachi.E_STOPPED, "stopped; send RESET before MOVE")
            if self.target is None:
                return self._Error(nachi.E_NO_TARGET, "MOVE without SET_TARGET")
            self.commanded = self.target
            self.moves += 1
            return "OK"
        if word == nachi.STOP:
            self.commanded = self.measured.copy()
            self.target = None
            self.stopped = True
            self.stops += 1
            return "OK"
        if word == nachi.RESET:
            self.stopped = False
            return "OK"
        if word == nachi.STATUS:
            return f"STATUS {self.State()} {self.moves} {self.error_count}"
        last = f" {self.last_error[0]} {self.last_error[1]}" if self.last_error else ""
        return f"ERRORS {self.error_count}{last}"

    def State(self) -> str:
        if self.stopped:
            return "STOPPED"
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
        self.logic = NachiControllerLogic(
            plant.GetPositionsFromArray(instance, plant.GetPositionLowerLimits()),
            plant.GetPositionsFromArray(instance, plant.GetPositionUpperLimits()),
            q0,
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
        """Steps the simulation until `duration` (s) or Close()."""
        self.simulator.set_target_realtime_rate(realtime_rate)
        self.simulator.Initialize()
        t = self.context.get_time()
        while t < duration and not self._closing.is_set():
            X_BF = self._plant.CalcRelativeTransform(self._plant_context, self._base, self._flange)
            q = self._measured_port.Eval(self.context)
            rpy = RollPitchYaw(X_BF.rotation()).vector()
            command = self.logic.Measure(t, q.copy(), X_BF.translation(), rpy)
            self._command_port.FixValue(self.context, command)
            t += self._period
            self.simulator.AdvanceTo(t)
            for observer in self._observers:
                observer(self.context)

    def Close(self) -> None:
        self._closing.set()
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
