"""Shared fixtures: paths and a fast way to run the CLI in-process."""

from __future__ import annotations

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
