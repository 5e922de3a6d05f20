"""Ctrl-C and SIGTERM during a run: an interrupt Python drops (raised inside a finalizer)
still stops the run at its next progress report, and only until the run reports it."""

from __future__ import annotations

import os
import signal
import sys

import pytest

from guidedarm.diagrams.interrupts import InstallInterruptHandlers
from guidedarm.diagrams.run_context import RunContext
from guidedarm.diagrams.task_run import InterruptedFailure


@pytest.fixture
def handlers():
    saved = {s: signal.getsignal(s) for s in (signal.SIGINT, signal.SIGTERM)}
    hook = sys.unraisablehook
    InstallInterruptHandlers()
    yield
    for signum, handler in saved.items():
        signal.signal(signum, handler)
    sys.unraisablehook = hook


class _SignalsWhenCollected:
    def __init__(self, signum: int) -> None:
        self.signum = signum

    def __del__(self) -> None:
        os.kill(os.getpid(), self.signum)
        for _ in range(1000):  # the handler runs between two of these bytecodes
            pass


@pytest.mark.parametrize(
    "signum, failure",
    [(signal.SIGINT, "interrupted"), (signal.SIGTERM, "interrupted by SIGTERM")],
    ids=["ctrl-c", "sigterm"],
)
def test_an_interrupt_dropped_in_a_finalizer_stops_the_next_progress_report(
    handlers, tmp_path, capsys, signum, failure
):
    context = RunContext(out_dir=tmp_path)
    context.quiet = True
    _SignalsWhenCollected(signum)  # collected at once: its interrupt is dropped
    assert "KeyboardInterrupt" not in capsys.readouterr().err
    with pytest.raises(KeyboardInterrupt) as interrupt:
        context.progress("step 1")
    assert InterruptedFailure(interrupt.value) == failure
    context.progress("step 2")  # reported: the run may write its summary


def test_a_signal_while_interrupts_are_deferred_is_kept_for_later(handlers):
    """SIGTERM inside DeferredInterrupts (a run's summary being written, the cleanup at
    exit) raises nothing there; it stays pending until raised or taken."""
    from guidedarm.diagrams.interrupts import (
        DeferredInterrupts,
        RaiseIfInterrupted,
        TakeInterrupt,
    )

    with DeferredInterrupts():
        os.kill(os.getpid(), signal.SIGTERM)
        for _ in range(1000):  # the handler runs between two of these bytecodes
            pass
    with pytest.raises(KeyboardInterrupt, match="SIGTERM"):
        RaiseIfInterrupted()
    TakeInterrupt()
    RaiseIfInterrupted()  # taken: nothing left
    with pytest.raises(KeyboardInterrupt, match="SIGTERM"):
        os.kill(os.getpid(), signal.SIGTERM)
        for _ in range(1000):
            pass
    TakeInterrupt()


def test_an_error_raised_in_place_of_a_pending_interrupt_reports_the_interrupt(handlers, tmp_path):
    """A SIGTERM whose KeyboardInterrupt an extension turned into its own error (matplotlib's
    Agg, interrupted while drawing a figure, raises "Invalid affine transformation
    matrix") ends the run as interrupted, not as an internal error."""
    import dataclasses

    from guidedarm.diagrams.interrupts import DeferredInterrupts
    from guidedarm.diagrams.run_preparation import PreparedRun
    from guidedarm.diagrams.task_run import TRACEBACK_FILE, RunPrepared
    from guidedarm.diagrams.tasks.registry import LoadScenario

    def run(scenario, context, *prepared):
        with DeferredInterrupts():  # the interrupt is pending, as the extension caught it
            os.kill(os.getpid(), signal.SIGTERM)
            for _ in range(1000):
                pass
        raise ValueError("Invalid affine transformation matrix")

    task, scenario, _ = LoadScenario("ur10e_waypoints", [])
    task = dataclasses.replace(task, run=run, prepare=None)
    summary = RunPrepared(PreparedRun(task, scenario, None), RunContext(out_dir=tmp_path))
    assert summary["success"] is False
    assert summary["failure"] == "interrupted by SIGTERM"
    assert not (tmp_path / TRACEBACK_FILE).exists()

    def buggy(scenario, context, *prepared):
        raise ValueError("a bug")

    task = dataclasses.replace(task, run=buggy)
    summary = RunPrepared(PreparedRun(task, scenario, None), RunContext(out_dir=tmp_path))
    assert summary["failure"] == f"internal error ValueError: a bug (see {TRACEBACK_FILE})"
