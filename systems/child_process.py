"""A Python child process of guidedarm's, talking to its parent over local socket pairs
(pickled messages: multiprocessing.connection).

Work that can end its process (a vendor library that crashes, runs that leave memory
behind) runs in such a child: when it ends, the parent reads how, and goes on. The child is
started with `python -m MODULE ARGS --fds F1,F2,...` (no multiprocessing start method:
Dask's worker processes are daemons, which multiprocessing does not let have children).
"""

from __future__ import annotations

import os
import signal
import socket
import subprocess
import sys
import threading
import time
from multiprocessing.connection import Connection

FDS_OPTION = "--fds"


def StartChild(
    module: str, args: list[str], channels: int
) -> tuple[subprocess.Popen, list[Connection]]:
    """Starts `python -m module *args` with `channels` socket pairs; returns the process
    and the parent's ends (the child's: ChildChannels)."""
    pairs = [socket.socketpair() for _ in range(channels)]
    fds = [there.fileno() for _, there in pairs]
    command = [sys.executable, "-m", module, *args, FDS_OPTION, ",".join(map(str, fds))]
    process = subprocess.Popen(command, pass_fds=fds)
    for _, there in pairs:
        there.close()
    return process, [Connection(here.detach()) for here, _ in pairs]


def ChildChannels(fds: str) -> list[Connection]:
    """The child's ends of its socket pairs, from the value of its `--fds` option."""
    return [Connection(int(fd)) for fd in fds.split(",")]


def HowItEnded(process: subprocess.Popen, what: str, timeout: float = 1.0) -> str:
    """One line on how `process` ended, for a parent whose socket to it has closed (it
    closes as the child exits, a moment before the exit status can be read)."""
    try:
        code = process.wait(timeout)
    except subprocess.TimeoutExpired:
        return f"{what} stopped answering"
    if code < 0:
        return f"{what} ended by {signal.Signals(-code).name}"
    return f"{what} ended with exit code {code}"


def EndChild(process: subprocess.Popen, timeout: float = 1.0) -> None:
    """Waits `timeout` s for a child asked to end (its parent's socket closed), then kills
    it (it may be inside a call that waits minutes)."""
    try:
        process.wait(timeout)
    except subprocess.TimeoutExpired:
        process.kill()
        process.wait()


def FollowParent(period: float = 0.5) -> None:
    """In the child: ignores Ctrl-C (a terminal sends it to the whole process group; the
    parent decides when its child ends) and ends (os._exit, no teardown) once the parent is
    gone, even while the child's main thread is inside a call that does not return."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    parent = os.getppid()

    def watch() -> None:
        while os.getppid() == parent:
            time.sleep(period)
        os._exit(0)

    threading.Thread(target=watch, name="follow-parent", daemon=True).start()


def SendOrExit(connection: Connection, message) -> None:
    """In the child: sends `message`; a parent that is gone ends the child at once."""
    try:
        connection.send(message)
    except OSError:
        os._exit(0)
