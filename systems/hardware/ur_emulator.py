"""An emulated UR e-Series controller that the ur_rtde client drives as it would a real
one: a Drake simulation of the arm stepped in real time behind UrControllerLogic, served
on the three ports ur_rtde 1.6.5 connects to (fixed in the library, so each emulator
listens on its own loopback address, 127.0.0.0/8):

- 30004 RTDE (protocol version 2): output recipes streamed at their frequency from the
  controller's steps, input recipes written into the registers;
- 29999 the dashboard server (the lines ur_rtde and an operator use: PolyscopeVersion,
  get serial number, is in remote control, stop, running, programState, robotmode);
- 30003 the script port: a program received there starts (only ur_rtde's control script,
  whose register protocol UrControllerLogic runs).

Malformed RTDE packets are answered with a TEXT_MESSAGE, counted and printed; the session
goes on. A client that does not take its data for SEND_TIMEOUT is disconnected.
"""

from __future__ import annotations

import contextlib
import gc
import socket
import struct
import sys
import threading
from collections.abc import Callable

import numpy as np
from pydrake.systems.analysis import Simulator
from pydrake.systems.framework import Context

from guidedarm.systems.errors import ConfigurationError
from guidedarm.systems.hardware import rtde_protocol as rtde
from guidedarm.systems.hardware.ur_controller_logic import CONTROLLER_VERSION, UrControllerLogic

RTDE_PORT, DASHBOARD_PORT, SCRIPT_PORT = 30004, 29999, 30003
MAX_FREQUENCY = 500.0  # Hz
SEND_TIMEOUT = 0.5  # s
# lockstep: a stream that pauses this long on the host (s) has ended, and the station
# returns to real time; longer than a loaded host delays a PC's next target (0.1-0.5 s
# seen), shorter than the tests' patience.
LOCKSTEP_STALL = 2.0
DASHBOARD_WELCOME = "Connected: Universal Robots Dashboard Server"


class RtdeSession:
    """One RTDE client: its recipes, and the data packages it is due."""

    def __init__(self, connection: socket.socket, logic: UrControllerLogic) -> None:
        self.connection = connection
        self._logic = logic
        self._send_lock = threading.Lock()
        self._outputs: tuple[struct.Struct, list[str]] | None = None
        self._inputs: dict[int, tuple[struct.Struct, list[str], list[str]]] = {}
        self._period = 1.0 / MAX_FREQUENCY
        self._next_publish: float | None = None  # controller time; None: not started
        self.malformed = 0
        self.closed = False

    def Serve(self) -> None:
        """Reads the client's packets until it closes the connection."""
        buffer = bytearray()
        with contextlib.suppress(OSError):
            while data := self.connection.recv(65536):
                buffer += data
                try:
                    packets = rtde.SplitPackets(buffer)
                except rtde.RtdeProtocolError as e:
                    self._Reject(str(e))
                    continue
                for packet in packets:
                    self._Handle(packet)
        self.closed = True

    def _Handle(self, packet: rtde.Packet) -> None:
        reply = rtde.EncodePacket
        kind, payload = packet.type, packet.payload
        if kind == rtde.REQUEST_PROTOCOL_VERSION and len(payload) == 2:
            accepted = struct.unpack(">H", payload)[0] == rtde.PROTOCOL_VERSION
            self._Send(reply(kind, bytes([accepted])))
        elif kind == rtde.GET_URCONTROL_VERSION:
            self._Send(reply(kind, struct.pack(">IIII", *CONTROLLER_VERSION)))
        elif kind == rtde.CONTROL_PACKAGE_SETUP_OUTPUTS and len(payload) > 8:
            (frequency,) = struct.unpack_from(">d", payload)
            names = _Names(payload[8:])
            types = [rtde.VariableType(n) for n in names]
            accepted = "NOT_FOUND" not in types and 0 < frequency <= MAX_FREQUENCY
            if accepted:
                self._outputs = (rtde.RecipeFormat(types), names)
                self._period = 1.0 / frequency
            self._Send(reply(kind, bytes([int(accepted)]) + ",".join(types).encode()))
        elif kind == rtde.CONTROL_PACKAGE_SETUP_INPUTS and payload:
            names = _Names(payload)
            types = [rtde.VariableType(n, "input") for n in names]
            recipe_id = 0
            if "NOT_FOUND" not in types:
                recipe_id = len(self._inputs) + 1
                self._inputs[recipe_id] = (rtde.RecipeFormat(types), types, names)
            self._Send(reply(kind, bytes([recipe_id]) + ",".join(types).encode()))
        elif kind == rtde.CONTROL_PACKAGE_START:
            accepted = self._outputs is not None or bool(self._inputs)
            self._Send(reply(kind, bytes([int(accepted)])))
            if accepted:
                self._next_publish = self._logic.time
        elif kind == rtde.CONTROL_PACKAGE_PAUSE:
            self._next_publish = None
            self._Send(reply(kind, b"\x01"))
        elif kind == rtde.DATA_PACKAGE and payload and payload[0] in self._inputs:
            recipe, types, names = self._inputs[payload[0]]
            try:
                values = rtde.DecodeDataPackage(recipe, types, payload[1:])
            except rtde.RtdeProtocolError as e:
                self._Reject(str(e))
                return
            self._logic.WriteInputs(dict(zip(names, values, strict=True)))
        else:
            self._Reject(f"unexpected RTDE packet type {kind} ({len(payload)} B)")

    def Publish(self, t: float) -> None:
        """Sends the output recipe's data package if one is due at controller time t."""
        if self._next_publish is None or self._outputs is None or t < self._next_publish - 1e-9:
            return
        self._next_publish = max(self._next_publish + self._period, t)
        recipe, names = self._outputs
        row = [self._logic.Output(n) for n in names]
        self._Send(rtde.EncodeDataPackage(1, recipe, row))

    def _Reject(self, why: str) -> None:
        self.malformed += 1
        print(f"ur emulator: rejected RTDE packet #{self.malformed}: {why}", file=sys.stderr)
        text = why.encode()[:200]
        self._Send(rtde.EncodePacket(rtde.TEXT_MESSAGE, bytes([len(text)]) + text + b"\x00\x01"))

    def _Send(self, data: bytes) -> None:
        try:
            with self._send_lock:
                self.connection.sendall(data)
        except OSError:  # gone, or not reading for SEND_TIMEOUT: the controller drops it
            self.closed = True
            with contextlib.suppress(OSError):
                self.connection.shutdown(socket.SHUT_RDWR)


def _Names(payload: bytes) -> list[str]:
    return [n for n in payload.decode("ascii", "replace").split(",") if n]


class UrEmulator:
    """Serves `arm` of a station Diagram (see MakeStation, which must export
    `<arm>.position_commanded`, `.position_measured`, `.velocity_estimated`) on host's
    ports 30004, 29999, 30003. The controller steps every `period` s (the arm tracking
    servoJ targets within the model's joint speeds and `servo_acceleration` rad/s^2);
    after every step each observer gets the station's context."""

    def __init__(
        self,
        station,
        arm: str,
        host: str = "127.0.0.1",
        period: float = 0.002,
        observers: tuple[Callable[[Context], None], ...] = (),
        servo_acceleration: float = 10.0,
        lockstep: bool = False,
    ) -> None:
        self.station = station
        self.simulator = Simulator(station)
        self.context = self.simulator.get_mutable_context()
        self._command_port = station.GetInputPort(f"{arm}.position_commanded")
        self._measured_port = station.GetOutputPort(f"{arm}.position_measured")
        self._velocity_port = station.GetOutputPort(f"{arm}.velocity_estimated")
        plant = station.GetSubsystemByName("plant")
        instance = plant.GetModelInstanceByName(arm)
        plant_context = plant.GetMyContextFromRoot(self.context)
        q0 = plant.GetPositions(plant_context, instance)
        self.logic = UrControllerLogic(
            plant.GetPositionsFromArray(instance, plant.GetPositionLowerLimits()),
            plant.GetPositionsFromArray(instance, plant.GetPositionUpperLimits()),
            q0,
            plant.GetVelocitiesFromArray(instance, plant.GetVelocityUpperLimits()),
            np.full(len(q0), servo_acceleration),
            lockstep,
        )
        self._command_port.FixValue(self.context, q0)
        self._period = period
        self._observers = observers
        self._sessions: list[RtdeSession] = []
        self._sessions_lock = threading.Lock()
        self._closing = threading.Event()
        self._servers = []
        for port, serve in (
            (RTDE_PORT, self._ServeRtde),
            (DASHBOARD_PORT, self._ServeDashboard),
            (SCRIPT_PORT, self._ServeScript),
        ):
            try:
                server = socket.create_server((host, port))
            except (OSError, OverflowError) as e:
                self.Close()
                raise ConfigurationError(
                    f"ur emulator: cannot listen on {host}:{port}: {e}"
                ) from None
            self._servers.append(server)
            threading.Thread(target=self._Accept, args=(server, serve), daemon=True).start()
        self.host = host

    def Run(self, duration: float = np.inf, realtime_rate: float = 1.0) -> None:
        """Steps the simulation until `duration` (s) or Close(); the controller runs in the
        middle of each period of the station's discrete updates, as NachiEmulator.Run.
        In lockstep, each servoJ target received advances the station by its interval, as
        fast as the host allows (see _NextTarget)."""
        lockstep = self.logic.lockstep
        self.simulator.set_target_realtime_rate(0.0 if lockstep else realtime_rate)
        self.simulator.Initialize()
        gc.freeze()  # a full collection over the station's objects would stall real time
        self._start, self._k = self.context.get_time(), 0
        self._stalled = False  # lockstep: the stream paused longer than the watchdog period
        self.idle_steps = 0  # steps without a target (lockstep), or all steps
        while self.context.get_time() < duration and not self._closing.is_set():
            steps = 1
            self.idle_steps += 1
            if lockstep:
                target = self._NextTarget()
                if target is not None:
                    q, interval = target
                    with self.logic.lock:
                        self.logic.Servo(q, interval)
                    steps = max(1, round(interval / self._period))
                    self.idle_steps -= 1
            for _ in range(steps):
                self._Step()

    def _NextTarget(self) -> tuple[np.ndarray, float] | None:
        """The oldest servoJ target not yet run. While a stream is tracked the station waits
        for it (its clock is the stream's), at most LOCKSTEP_STALL of the host's clock;
        after that, and outside a stream, it waits one period and steps without one (real
        time: the arm holds or brakes, the program's watchdog runs)."""
        logic = self.logic
        with logic.lock:
            tracking = logic.running and logic.tracker is not None and not logic.tracker.braking
            streaming = tracking and not self._stalled
            period = LOCKSTEP_STALL
        if not logic.targets:
            # woken by any input: a command other than servoJ is run by the next step
            arrived = logic.target_arrived.wait(period if streaming else self._period)
            self._stalled = self._stalled or (streaming and not arrived)
        logic.target_arrived.clear()
        with logic.lock:
            if not logic.targets:
                return None
            self._stalled = False
            return logic.targets.popleft()

    def _Step(self) -> None:
        """One controller step: the program's cycle and servo loop at the current time,
        the data packages due, then the station advanced to the middle of the next period."""
        t = self.context.get_time()
        q = self._measured_port.Eval(self.context).copy()
        v = self._velocity_port.Eval(self.context).copy()
        self._command_port.FixValue(self.context, self.logic.Step(t, q, v))
        with self._sessions_lock:
            self._sessions = [s for s in self._sessions if not s.closed]
            sessions = list(self._sessions)
        for session in sessions:
            session.Publish(t)
        self.simulator.AdvanceTo(self._start + (self._k + 0.5) * self._period)
        self._k += 1
        for observer in self._observers:
            observer(self.context)

    def Close(self) -> None:
        """Ends Run and the servers."""
        self._closing.set()
        for server in self._servers:
            with contextlib.suppress(OSError):
                server.shutdown(socket.SHUT_RDWR)
            server.close()

    def _Accept(self, server: socket.socket, serve: Callable[[socket.socket], None]) -> None:
        while not self._closing.is_set():
            try:
                connection, _ = server.accept()
            except OSError:
                return
            connection.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
            threading.Thread(target=self._Serve, args=(connection, serve), daemon=True).start()

    @staticmethod
    def _Serve(connection: socket.socket, serve: Callable[[socket.socket], None]) -> None:
        with connection, contextlib.suppress(OSError):
            serve(connection)

    def _ServeRtde(self, connection: socket.socket) -> None:
        connection.settimeout(None)
        seconds, micro = int(SEND_TIMEOUT), int(1e6 * (SEND_TIMEOUT % 1))
        timeout = struct.pack("ll", seconds, micro)
        connection.setsockopt(socket.SOL_SOCKET, socket.SO_SNDTIMEO, timeout)
        session = RtdeSession(connection, self.logic)
        with self._sessions_lock:
            self._sessions.append(session)
        session.Serve()

    def _ServeDashboard(self, connection: socket.socket) -> None:
        connection.sendall(f"{DASHBOARD_WELCOME}\n".encode())
        for line in connection.makefile("r", encoding="ascii", errors="replace"):
            connection.sendall(f"{self.logic.Dashboard(line)}\n".encode())

    def _ServeScript(self, connection: socket.socket) -> None:
        """A program is complete at its closing `end` at the start of a line."""
        text = ""
        while data := connection.recv(65536):
            text += data.decode("ascii", "replace")
            while "\nend\n" in text:
                program, _, text = text.partition("\nend\n")
                started = self.logic.StartProgram(program)
                print(f"ur emulator: {started}", flush=True)
