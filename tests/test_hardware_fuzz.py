"""Arbitrary bytes against the parsers of the Nachi, ToF and RTDE protocols, the Nachi
controller emulator's request handling and the RTDE double: each malformed input gets the
protocol's error reply (or is rejected and counted), nothing else raises, and the next good
input is served."""

from __future__ import annotations

import contextlib
import socket
import struct
import threading

import numpy as np
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from guidedarm.systems.hardware import nachi_protocol as nachi
from guidedarm.systems.hardware import rtde_protocol as rtde
from guidedarm.systems.hardware.line_socket import LineSocket
from guidedarm.systems.hardware.nachi_emulator import NachiControllerLogic, ServeConnection
from guidedarm.systems.hardware.rtde_double import RtdeDoubleSession
from guidedarm.systems.hardware.tof_protocol import (
    MAX_LINE,
    FormatTofLine,
    ParseTofLine,
    ToFLineCollector,
    ToFLineError,
)

FUZZ = settings(max_examples=150, deadline=None, suppress_health_check=[HealthCheck.too_slow])
# Bytes biased towards the protocols' own words and separators, so that the parsers get
# past their first check as often as they are stopped by it.
WORDS = [
    b"READ_JOINTS",
    b"SET_TARGET",
    b"MOVE",
    b"SERVO 0.01",
    b"STOP",
    b"RESET",
    b"STATUS",
    b"JOINTS",
    b"$TOF,",
]
PIECES = st.one_of(
    st.binary(max_size=12),
    st.sampled_from([*WORDS, b" ", b"\n", b"\r\n", b"\x00", b"\xff", b"1.5", b"-0", b"nan"]),
)
BYTES = st.lists(PIECES, max_size=40).map(b"".join)


def _Text(data: bytes) -> str:
    """What LineSocket makes of a line's bytes: one character per byte."""
    return data.decode("latin-1")


def _IsReplyText(line: str) -> bool:
    return all(" " <= c <= "~" for c in line)


@FUZZ
@given(BYTES)
def test_nachi_request_parser_raises_only_its_protocol_error(data):
    try:
        request = nachi.ParseRequest(_Text(data))
    except nachi.NachiProtocolError as e:
        assert _IsReplyText(str(e))
    else:
        assert request.word in data.decode("ascii")
        assert np.all(np.isfinite(request.values))


@FUZZ
@given(BYTES)
def test_nachi_reply_parsers_raise_only_their_protocol_error(data):
    for parse, sizes in ((nachi.ParseJoints, (1, 6)), (nachi.ParsePose, (3, 3))):
        try:
            values = parse(_Text(data))
        except nachi.NachiProtocolError as e:
            assert _IsReplyText(str(e))
        else:
            assert tuple(np.size(v) for v in values) == sizes
            assert np.all(np.isfinite(np.concatenate([np.ravel(v) for v in values])))
    try:
        nachi.CheckOk(_Text(data))
    except nachi.NachiProtocolError as e:
        assert _IsReplyText(str(e))


@FUZZ
@given(st.lists(BYTES, max_size=8))
def test_nachi_controller_answers_every_line_and_counts_its_errors(lines):
    # Between lines the servo loop runs (2 ms ticks): whatever was accepted, the joint
    # command stays finite, within the position range, and moves at most at the velocity
    # limit.
    logic = NachiControllerLogic(np.full(6, -1.0), np.full(6, 1.0), np.zeros(6))
    t, previous = 0.0, logic.commanded.copy()
    for data in lines:
        errors = logic.error_count
        reply = logic.Handle(_Text(data.replace(b"\n", b" ")))
        assert _IsReplyText(reply)
        assert logic.error_count == errors + reply.startswith("NG ")
        for _ in range(3):
            t += 0.002
            command = logic.Measure(t, logic.commanded, np.zeros(3), np.zeros(3))
            assert np.all(np.isfinite(command)) and np.all(np.abs(command) <= 1.0)
            if logic.tracker is not None:
                assert np.all(np.abs(command - previous) <= logic.velocity * 0.002 + 1e-12)
            previous = command


def _Exchange(serve, data: bytes) -> bytes:
    """Runs `serve(connection)` on one end of a socket pair, sends `data` from the other,
    closes it for writing and returns everything served back until the server closes."""
    ours, theirs = socket.socketpair()

    def server() -> None:
        with theirs:
            serve(theirs)

    thread = threading.Thread(target=server, daemon=True)
    thread.start()

    def send() -> None:
        with contextlib.suppress(OSError):  # a server that has finished closes its end
            ours.sendall(data)
            ours.shutdown(socket.SHUT_WR)

    sender = threading.Thread(target=send, daemon=True)
    sender.start()
    received = bytearray()
    ours.settimeout(10.0)
    while chunk := ours.recv(65536):
        received += chunk
    sender.join()
    thread.join(timeout=10.0)
    ours.close()
    return bytes(received)


@FUZZ
@given(BYTES)
def test_nachi_emulator_replies_once_per_line_and_keeps_serving(data):
    logic = NachiControllerLogic(np.full(6, -1.0), np.full(6, 1.0), np.zeros(6))
    # The LF ends whatever line the bytes left open; STATUS must still be served.
    stream = data + b"\nSTATUS\n"
    replies = _Exchange(lambda c: ServeConnection(c, logic), stream).decode("ascii")
    lines = replies.split("\n")
    assert lines.pop() == ""
    assert len(lines) == stream.count(b"\n")
    assert all(_IsReplyText(line) for line in lines)
    errors = sum(line.startswith("NG ") for line in lines)
    assert lines[-1] == f"STATUS {logic.State()} {logic.moves} {errors}"


@FUZZ
@given(BYTES, st.integers(min_value=1, max_value=64))
def test_line_socket_returns_bounded_lines(data, max_line):
    def serve(connection: socket.socket) -> None:
        lines = LineSocket(connection, max_line)
        try:
            while True:
                line = lines.ReadLine()
                assert len(line) <= max_line + 1
                connection.sendall(b"%d\n" % len(line))
        except ConnectionError:
            return

    # One line per LF, and an overlong line as soon as it is overlong, even unterminated.
    unterminated = data.rsplit(b"\n", 1)[-1]
    expected = data.count(b"\n") + (len(unterminated) > max_line)
    assert _Exchange(serve, data).count(b"\n") == expected


@FUZZ
@given(BYTES)
def test_tof_parser_raises_only_its_line_error(data):
    try:
        reading = ParseTofLine(_Text(data))
    except ToFLineError as e:
        assert _IsReplyText(str(e))
    else:
        assert reading.ranges.shape == (6,) and 0 <= reading.seq <= 65535


# A good line with a sequence number to give: the stream numbers its lines in order (a
# line that does not advance the number is stale).
GOOD_LINE = st.builds(
    lambda ranges, status: lambda seq: FormatTofLine(seq, np.array(ranges), np.array(status)),
    st.lists(st.integers(0, 255), min_size=6, max_size=6),
    st.lists(st.sampled_from([0, 6, 7, 11]), min_size=6, max_size=6),
)
# Garbage lines: no LF (it would end the line) and no `$` (it starts a new one).
GARBAGE_LINE = BYTES.map(lambda b: b.replace(b"\n", b"").replace(b"$", b"")[: MAX_LINE - 2])


@FUZZ
@given(
    st.lists(st.tuples(st.booleans(), GOOD_LINE, GARBAGE_LINE), max_size=12),
    st.lists(st.integers(1, 40), min_size=1, max_size=20),
)
def test_tof_collector_keeps_good_lines_between_garbage_however_chunked(lines, chunk_sizes):
    stream = b"".join(
        (good(seq).encode() if is_good else garbage) + b"\r\n"
        for seq, (is_good, good, garbage) in enumerate(lines)
    )
    collector = ToFLineCollector()
    position, k = 0, 0
    while position < len(stream):
        size = chunk_sizes[k % len(chunk_sizes)]
        collector.Feed(stream[position : position + size])
        position, k = position + size, k + 1
    assert collector.accepted == sum(is_good for is_good, _, _ in lines)
    garbage = [g for is_good, _, g in lines if not is_good and _Text(g).strip()]
    assert collector.rejected == len(garbage)


@FUZZ
@given(BYTES)
def test_rtde_split_packets_consumes_whole_packets_or_raises_its_error(data):
    buffer = bytearray(data)
    try:
        packets = rtde.SplitPackets(buffer)
    except rtde.RtdeProtocolError:
        assert buffer == bytearray()
        return
    consumed = b"".join(rtde.EncodePacket(p.type, p.payload) for p in packets)
    assert data == consumed + bytes(buffer)
    if len(buffer) >= rtde.HEADER.size:
        assert rtde.HEADER.unpack_from(buffer)[0] > len(buffer)


@FUZZ
@given(st.integers(0, 255), st.binary(max_size=64))
def test_rtde_double_answers_every_packet(packet_type, payload):
    def serve(connection: socket.socket) -> None:
        session = RtdeDoubleSession(connection, [0.0] * 6, quiet_after=0.0)
        session._Handle(rtde.Packet(packet_type, payload))

    replies = bytearray(_Exchange(serve, b""))
    (reply,) = rtde.SplitPackets(replies)
    assert replies == bytearray()
    assert reply.type in (packet_type, rtde.TEXT_MESSAGE)


@FUZZ
@given(BYTES)
def test_rtde_double_survives_any_bytes_and_serves_the_next_request(data):
    # A size field that declares more than arrives would swallow the request after it:
    # the test sends whole packets of arbitrary type and payload, then a good request.
    payload = data[: 65535 - rtde.HEADER.size]
    stream = rtde.EncodePacket(data[0] if data else 0, payload)
    stream += rtde.EncodePacket(rtde.REQUEST_PROTOCOL_VERSION, struct.pack(">H", 2))

    def serve(connection: socket.socket) -> None:
        RtdeDoubleSession(connection, [0.0] * 6, quiet_after=0.0).Run()

    packets = rtde.SplitPackets(bytearray(_Exchange(serve, stream)))
    assert packets[-1] == rtde.Packet(rtde.REQUEST_PROTOCOL_VERSION, b"\x01")


@FUZZ
@given(word=st.sampled_from(WORDS), data=BYTES)
def test_replies_out_of_step_never_raises_and_accepts_ng(word, data):
    request = _Text(word).split()[0]
    line = _Text(data)
    nachi.RepliesOutOfStep(request, line)  # any text: a bool, no exception
    assert not nachi.RepliesOutOfStep(request, "NG " + line)


def test_tof_lines_that_repeat_or_go_back_are_stale():
    collector = ToFLineCollector()
    ranges, status = np.full(6, 40), np.zeros(6, int)
    accepted = []
    for seq in [65534, 65535, 65535, 0, 65530, 0, 1, 5, 4, 40000]:
        before = collector.accepted
        collector.Feed((FormatTofLine(seq, ranges, status) + "\r\n").encode())
        accepted.append(collector.accepted > before)
    # the repeat, 6 behind, the repeat of 0, 1 behind: stale; a wrap and a restart are new
    assert accepted == [True, True, False, True, False, False, True, True, False, True]
    assert collector.rejected == 4 and collector.latest()[0].seq == 40000
