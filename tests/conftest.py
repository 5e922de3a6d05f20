"""Shared fixtures: paths and a fast way to run the CLI in-process."""

from __future__ import annotations

import gc
import sys
import threading
import time
from pathlib import Path

import pytest

from guidedarm.systems.hardware.arm_link import CloseAllArmLinks

REPO = Path(__file__).resolve().parents[1]


def pytest_collection_modifyitems(items: list[pytest.Item]) -> None:
    """Modules with slow tests first, so that `make test` (xdist, a module per work unit,
    `--no-loadscope-reorder`) hands them out early and ends with the short ones, instead of
    one worker running a long module alone at the end."""
    slow_modules = {item.path for item in items if item.get_closest_marker("slow")}
    items.sort(key=lambda item: item.path not in slow_modules)


@pytest.fixture
def run_cli(capsys):
    """Runs `guidedarm ARGS...` in-process; returns (exit code, stdout, stderr)."""
    from guidedarm.diagrams.cli.main import main

    def run(*args: str) -> tuple[int, str, str]:
        code = main([str(a) for a in args])
        captured = capsys.readouterr()
        sys.stdout.flush()
        return code, captured.out, captured.err

    return run


@pytest.fixture(autouse=True, scope="module")
def collect_garbage_on_the_main_thread():
    """Frees each module's reference cycles on the main thread. Drake objects such as
    Meshcat must be destroyed on the thread that made them; a cycle left to the collector
    can otherwise be freed on whatever thread triggers a collection (an emulator or link
    thread of a later test), which aborts the process."""
    yield
    gc.collect()


@pytest.fixture(autouse=True)
def no_thread_outlives_its_test():
    """Fails a test that leaves one of guidedarm's threads (a link, emulator, transport or
    test double) running 2 s after it ended: a driver stops its threads when closed. A
    leaked thread also keeps allocating, and a collection it triggers frees the next
    test's Drake objects on the wrong thread."""
    before = set(threading.enumerate())
    yield
    CloseAllArmLinks()  # as the CLI does at the end of a run
    deadline = time.monotonic() + 2.0
    while (left := _OursStartedSince(before)) and time.monotonic() < deadline:
        time.sleep(0.02)
    assert not left, f"threads still running after the test: {sorted(left)}"


def _OursStartedSince(before: set[threading.Thread]) -> list[str]:
    """Names (and targets) of live threads not in `before` that run guidedarm or test code."""
    left = []
    for thread in threading.enumerate():
        target = getattr(thread, "_target", None)
        module = getattr(target, "__module__", "") or ""
        if thread not in before and thread.is_alive() and _IsOurs(module):
            left.append(f"{thread.name} ({module}.{getattr(target, '__qualname__', '?')})")
    return left


def _IsOurs(module: str) -> bool:
    return module.startswith(("guidedarm", "test_", "hardware_doubles"))
