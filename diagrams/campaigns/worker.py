"""What a Dask worker does with one job: load its scenario text, build, run, report.

The worker hands the job to a child process of its own (job_process), which runs it with
RunJobHere; guidedarm and pydrake must be installed in the worker's Python. Whatever the task
raises becomes the job's `failure`, as does the end of the child: a failed job is a result,
never the end of the campaign.
"""

from __future__ import annotations

import os
import socket
import tempfile
import time
from contextlib import ExitStack
from pathlib import Path
from typing import Any

from guidedarm.diagrams.campaigns.job_process import RunInJobProcess
from guidedarm.diagrams.campaigns.jobs import Job
from guidedarm.diagrams.run_context import RESOLVED_SCENARIO_FILE, RunContext
from guidedarm.diagrams.task_run import RunTask
from guidedarm.diagrams.tasks.registry import LoadScenario
from guidedarm.systems.errors import GuidedArmError


def RunJob(job: Job, runs_dir: str | None = None) -> dict[str, Any]:
    """Runs `job` in this worker's job process and returns {job_id, metrics, wall_time_s,
    worker}. With `runs_dir` the run folder runs_dir/<job id> (scenario.yaml, summary.json,
    plots) is kept; without, the run writes to a temporary folder that is removed."""
    start = time.perf_counter()
    metrics = RunInJobProcess(job, runs_dir)
    return {
        "job_id": job.id,
        "metrics": metrics,
        "wall_time_s": round(time.perf_counter() - start, 3),
        "worker": f"{socket.gethostname()}:{os.getpid()}",
    }


def RunJobHere(job: Job, runs_dir: str | None = None) -> dict[str, Any]:
    """Runs `job` in this process; returns its metrics (see RunJob)."""
    with ExitStack() as stack:
        if runs_dir is None:
            out_dir = Path(stack.enter_context(tempfile.TemporaryDirectory(prefix="guidedarm-")))
        else:
            out_dir = Path(runs_dir) / job.id
        out_dir.mkdir(parents=True, exist_ok=True)
        path = out_dir / RESOLVED_SCENARIO_FILE
        path.write_text(job.scenario_yaml)
        context = RunContext(out_dir=out_dir, quiet=True)
        metrics: dict[str, Any] = {}
        try:
            task, scenario, _ = LoadScenario(str(path), [])
            metrics = RunTask(task, scenario, context)
            metrics.pop("wall_time_s", None)
            # Also refuses a NaN or infinite metric: the job then fails, naming it.
            context.write_summary({"job_id": job.id, "axes": job.axes, **metrics})
        except GuidedArmError as e:
            metrics = {**metrics, "success": False, "failure": str(e)}
        except Exception as e:  # a bug in one job is that job's failure, not the campaign's
            first = str(e).strip().splitlines()[0] if str(e).strip() else ""
            metrics = {**metrics, "success": False, "failure": f"{type(e).__name__}: {first}"}
    return metrics
