"""Shared fixtures: paths and a fast way to run the CLI in-process."""

from __future__ import annotations

import gc
import sys
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[1]


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
