"""A loopback RTDE controller double: speaks RTDE protocol version 2 on a TCP port and streams
data packages of a fixed joint configuration at the recipe's frequency.

Run it as its own process (the vendor client holds the Python GIL while it connects):
    python -m guidedarm.systems.hardware.rtde_double --port 30004 --q 0 -1.57 ... [--quiet-after S]
It prints `listening HOST PORT` once bound. `--quiet-after` stops the data stream after S
seconds of streaming (the link stays open), for watchdog tests; `--backwards-after` keeps
streaming after S seconds with the `timestamp` running backwards (stale samples).
Malformed client packets are answered with a text message, counted, and printed on stderr.
"""

from __future__ import annotations

import argparse
import contextlib
import socket
import struct
import sys
import time

from guidedarm.systems.hardware import rtde_protocol as rtde

CONTROLLER_VERSION = (5, 15, 0, 0)  # major, minor, bugfix, build: an e-Series controller
MAX_FREQUENCY = 500.0  # Hz; an output recipe asking for more (or NaN) is refused


class RtdeDoubleSession:
    """One client connection: answers requests, streams data packages once started."""

    def __init__(
        self,
        connection: socket.socket,
        q: list[float],
        quiet_after: float,
        backwards_after: float = float("inf"),
    ) -> None:
        self._connection = connection
        self._q = q
        self._quiet_after = quiet_after
        self._backwards_after = backwards_after
        self._recipe: struct.Struct | None = None
        self._names: list[str] = []
        self._period = 0.002
        self._start_time: float | None = None
        self.malformed = 0

    def Run(self) -> None:
        buffer = bytearray()
        next_send = time.monotonic()
        self._connection.settimeout(0.0005)
        while True:
            try:
                data = self._connection.recv(4096)
                if not data:
                    return
                buffer += data
            except TimeoutError:
                pass
            try:
                packets = rtde.SplitPackets(buffer)
            except rtde.RtdeProtocolError as e:
                self._Reject(str(e))
                packets = []
            for packet in packets:
                self._Handle(packet)
            now = time.monotonic()
            if self._start_time is not None and now >= next_send:
                next_send = max(next_send + self._period, now)
                if now - self._start_time < self._quiet_after:
                    self._SendData(now - self._start_time)

    def _Handle(self, packet: rtde.Packet) -> None:
        reply = rtde.EncodePacket
        if packet.type == rtde.REQUEST_PROTOCOL_VERSION and len(packet.payload) == 2:
            (version,) = struct.unpack(">H", packet.payload)
            accepted = version == rtde.PROTOCOL_VERSION
            self._Send(reply(packet.type, bytes([accepted])))
        elif packet.type == rtde.GET_URCONTROL_VERSION:
            self._Send(reply(packet.type, struct.pack(">IIII", *CONTROLLER_VERSION)))
        elif packet.type == rtde.CONTROL_PACKAGE_SETUP_OUTPUTS and len(packet.payload) > 8:
            (frequency,) = struct.unpack_from(">d", packet.payload)
            names = [n for n in packet.payload[8:].decode("ascii", "replace").split(",") if n]
            types = [rtde.OUTPUT_TYPES.get(n, "NOT_FOUND") for n in names]
            if "NOT_FOUND" not in types and 0 < frequency <= MAX_FREQUENCY:
                self._recipe, self._names = rtde.RecipeFormat(types), names
                self._period = 1.0 / frequency
            recipe_id = 1 if self._recipe is not None else 0
            self._Send(reply(packet.type, bytes([recipe_id]) + ",".join(types).encode()))
        elif packet.type == rtde.CONTROL_PACKAGE_START:
            accepted = self._recipe is not None
            self._Send(reply(packet.type, bytes([accepted])))
            if accepted:
                self._start_time = time.monotonic()
        elif packet.type == rtde.CONTROL_PACKAGE_PAUSE:
            self._start_time = None
            self._Send(reply(packet.type, b"\x01"))
        else:
            self._Reject(f"unexpected RTDE packet type {packet.type} ({len(packet.payload)} B)")

    def _SendData(self, t: float) -> None:
        if t > self._backwards_after:
            t = 2 * self._backwards_after - t
        values = {"timestamp": t, "actual_q": self._q, "target_q": self._q}
        row = [values.get(n, _Zero(rtde.OUTPUT_TYPES[n])) for n in self._names]
        self._Send(rtde.EncodeDataPackage(1, self._recipe, row))

    def _Reject(self, why: str) -> None:
        self.malformed += 1
        print(f"rtde_double: rejected packet #{self.malformed}: {why}", file=sys.stderr, flush=True)
        text = why.encode()[:200]
        self._Send(rtde.EncodePacket(rtde.TEXT_MESSAGE, bytes([len(text)]) + text + b"\x00\x01"))

    def _Send(self, data: bytes) -> None:
        self._connection.sendall(data)


def _Zero(type_name: str):
    count = {"VECTOR3D": 3, "VECTOR6D": 6, "VECTOR6INT32": 6, "VECTOR6UINT32": 6}.get(type_name)
    return [0] * count if count else 0


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--host", default="127.0.0.1")
    parser.add_argument("--port", type=int, default=30004)
    parser.add_argument("--q", type=float, nargs=6, default=[0.0] * 6, help="joints (rad)")
    parser.add_argument("--quiet-after", type=float, default=float("inf"))
    parser.add_argument("--backwards-after", type=float, default=float("inf"))
    args = parser.parse_args(argv)
    server = socket.socket()
    server.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
    server.bind((args.host, args.port))
    server.listen()
    print(f"listening {args.host} {server.getsockname()[1]}", flush=True)
    while True:
        connection, _ = server.accept()
        connection.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
        with contextlib.suppress(ConnectionError, OSError):
            RtdeDoubleSession(connection, args.q, args.quiet_after, args.backwards_after).Run()
        connection.close()


if __name__ == "__main__":
    main()
