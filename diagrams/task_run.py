"""Running one prepared task (run_preparation.PrepareRun) on its resolved scenario: what
`guidedarm run` and each campaign job do."""

from __future__ import annotations

import math
import time
import traceback
from typing import Any

from pydrake.common.yaml import yaml_dump_typed

from guidedarm.diagrams.interrupts import PendingInterrupt, RaiseIfInterrupted, TakeInterrupt
from guidedarm.diagrams.run_context import (
    RESOLVED_SCENARIO_FILE,
    SUMMARY_FILE,
    NonFiniteKeys,
    RunContext,
)
from guidedarm.diagrams.run_preparation import PreparedRun, PrepareRun
from guidedarm.diagrams.station.scenario import StationScenario
from guidedarm.diagrams.tasks.registry import ERRORS_KEY, RunFlags, TaskDefinition
from guidedarm.systems.cell_errors.camera_errors import CameraErrors
from guidedarm.systems.cell_errors.distributions import ErrorsAsData, IsZeroError
from guidedarm.systems.errors import DrakeCheckFailure, GuidedArmError, RunFailedError

# The `failure` of a run stopped by Ctrl-C.
INTERRUPTED = "interrupted"
# Where the traceback of an internal error goes, beside summary.json.
TRACEBACK_FILE = "traceback.txt"


def RunTask(task: TaskDefinition, scenario: Any, context: RunContext) -> dict[str, Any]:
    """RunPrepared(PrepareRun(...)) with the context's --hardware and live Meshcat flags:
    what a campaign job or a script runs. A refusal comes before anything is written."""
    flags = RunFlags(hardware=context.hardware, live=context.live)
    return RunPrepared(PrepareRun(task, scenario, flags), context)


def RunPrepared(run: PreparedRun, context: RunContext) -> dict[str, Any]:
    """Removes a previous run's DIR/summary.json and traceback.txt, writes DIR/scenario.yaml
    (the fully resolved scenario, its errors drawn), runs the task on what PrepareRun made
    and returns its metrics plus `success`, `wall_time_s` (s) and the drawn errors
    (ERRORS_KEY, when any), with `success` false and `failure` set when the run failed in
    any way once started: a RunFailedError, Ctrl-C, a non-finite metric (written as null),
    or a bug (its traceback in DIR/traceback.txt). Any other GuidedArmError (a refusal
    before any motion, e.g. a ConfigurationError) passes through."""
    task, scenario = run.task, run.scenario
    # A previous run's verdict in the same folder must not stand beside this run's files.
    for stale in (SUMMARY_FILE, TRACEBACK_FILE):
        (context.out_dir / stale).unlink(missing_ok=True)
    context.write_text(RESOLVED_SCENARIO_FILE, yaml_dump_typed(scenario))
    wall_start = time.perf_counter()
    try:
        given = () if task.prepare is None else (run.prepared,)
        metrics = dict(task.run(scenario, context, *given))
        RaiseIfInterrupted()  # one Python dropped, with no progress report after it
    except RunFailedError as e:
        metrics = {"success": False, "failure": str(e)}
    except KeyboardInterrupt as e:
        metrics = {"success": False, "failure": InterruptedFailure(e)}
    except GuidedArmError:
        raise
    except (Exception, SystemExit) as e:
        metrics = {"success": False, "failure": _ErrorFailure(e, context)}
    bad = NonFiniteKeys(metrics)
    if bad:
        metrics = _WithoutNonFinite(metrics)
        metrics["failure"] = metrics.get("failure") or f"non-finite values of {', '.join(bad)}"
        metrics["success"] = False
    if "success" not in metrics:  # a task whose metrics say only `failure`
        metrics = {"success": metrics.get("failure") is None, **metrics}
    metrics["wall_time_s"] = round(time.perf_counter() - wall_start, 3)
    drawn = DrawnErrors(scenario)
    if drawn:
        metrics[ERRORS_KEY] = drawn
    return metrics


def DrawnErrors(scenario: Any) -> dict[str, Any]:
    """The drawn errors of a scenario (WithErrorsDrawn) as summary.json's ERRORS_KEY: the
    station's, or marker_view's camera_errors under `camera`; {} for an exact cell."""
    station = getattr(scenario, "station", None)
    if isinstance(station, StationScenario):
        return ErrorsAsData(station.errors)
    camera_errors = getattr(scenario, "camera_errors", None)
    if isinstance(camera_errors, CameraErrors) and not IsZeroError(camera_errors):
        return {"camera": ErrorsAsData(camera_errors)}
    return {}


def _ErrorFailure(error: BaseException, context: RunContext) -> str:
    """The `failure` of a run that raised `error`: the interrupt it came from, when one is
    pending (an extension that caught the KeyboardInterrupt raised its own error instead:
    matplotlib's Agg drawing a figure, "Invalid affine transformation matrix"); else a bug
    or a failed Drake check (pydrake raises it as SystemExit), its traceback beside the
    summary, not on screen. Nothing in a task exits on purpose."""
    interrupt = PendingInterrupt()
    if interrupt is not None:
        return InterruptedFailure(interrupt)
    context.write_text(TRACEBACK_FILE, traceback.format_exc())
    first = str(error).strip().splitlines()[0] if str(error).strip() else ""
    cause = DrakeCheckFailure(error) or f"{type(error).__name__}: {first}"
    return f"internal error {cause} (see {TRACEBACK_FILE})"


def InterruptedFailure(interrupt: KeyboardInterrupt) -> str:
    """The `failure` of a run stopped by Ctrl-C (`interrupted`) or by a signal the CLI
    turns into a KeyboardInterrupt naming it (`interrupted by SIGTERM`); the interrupt
    counts as reported."""
    TakeInterrupt()
    return f"{INTERRUPTED} by {interrupt.args[0]}" if interrupt.args else INTERRUPTED


def _WithoutNonFinite(value: Any) -> Any:
    if isinstance(value, float):
        return value if math.isfinite(value) else None
    if isinstance(value, dict):
        return {key: _WithoutNonFinite(v) for key, v in value.items()}
    if isinstance(value, list | tuple):
        return [_WithoutNonFinite(v) for v in value]
    return value
