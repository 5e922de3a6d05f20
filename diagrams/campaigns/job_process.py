"""Where a worker runs its jobs: a child process of its own, reused from job to job and
replaced once it holds too much memory or ends.

pydrake keeps each run's diagram alive in its process (0.25-0.3 GB per panel_operation
run, docs/campaigns.md "Memory"), and a native crash ends the process it happens in. In the
child, the first costs a new child every few panel jobs, the second one job's row
(`failure: the job's process ended by SIGSEGV`); the Dask worker itself stays small and
alive, and never needs its nanny.
"""

from __future__ import annotations

import argparse
import os
import pickle
import tempfile
import threading
from contextlib import ExitStack
from pathlib import Path
from typing import Any

from guidedarm.diagrams.campaigns.jobs import Job
from guidedarm.diagrams.run_context import RESOLVED_SCENARIO_FILE, RunContext
from guidedarm.diagrams.task_run import RunTask
from guidedarm.diagrams.tasks.registry import LoadScenario
from guidedarm.systems.child_process import (
    ChildChannels,
    EndChild,
    FollowParent,
    HowItEnded,
    SendOrExit,
    StartChild,
)
from guidedarm.systems.errors import GuidedArmError

# A child whose resident memory passes this after a job is replaced: room for two panel
# runs' diagrams beside pydrake (0.65 GB after the first), while a path_following child
# (0.23 GB, +10-15 MB per run) serves about a hundred jobs before it is replaced.
RECYCLE_RSS_BYTES = 1.5e9


class JobProcess:
    """A child that runs jobs one at a time (RunJobHere) and answers each with its
    metrics and its resident memory (bytes)."""

    def __init__(self) -> None:
        self.process, (self._connection,) = StartChild(__name__, [], channels=1)

    def Run(self, job: Job, runs_dir: str | None) -> tuple[dict[str, Any], int | None]:
        """The job's metrics and the child's memory after it (None: the child ended, and
        the metrics say how). What RunJobHere raised (outside the task) is raised here."""
        try:
            self._connection.send((job, runs_dir))
            metrics, error, resident = self._connection.recv()
        except (EOFError, OSError):
            failure = HowItEnded(self.process, "the job's process")
            return {"success": False, "failure": failure}, None
        if error is not None:
            raise error
        return metrics, resident

    def End(self) -> None:
        self._connection.close()
        EndChild(self.process)


_idle: list[JobProcess] = []  # children between jobs, of this worker process
_idle_lock = threading.Lock()


def RunInJobProcess(job: Job, runs_dir: str | None) -> dict[str, Any]:
    """The job's metrics, run in an idle child of this process (a new one if none is)."""
    with _idle_lock:
        child = _idle.pop() if _idle else None
    child = child or JobProcess()
    resident = None
    try:
        metrics, resident = child.Run(job, runs_dir)
    finally:
        if resident is not None and resident < RECYCLE_RSS_BYTES:
            with _idle_lock:
                _idle.append(child)
        else:
            child.End()
    return metrics


def ResidentBytes() -> int:
    """This process's resident memory (bytes), from /proc/self/statm."""
    with open("/proc/self/statm") as statm:
        return int(statm.read().split()[1]) * os.sysconf("SC_PAGE_SIZE")


def RunJobHere(job: Job, runs_dir: str | None = None) -> dict[str, Any]:
    """Runs `job` in this process and returns its metrics (a failure of its task is the
    metrics' `failure`). With `runs_dir` the run folder runs_dir/<job id> (scenario.yaml,
    summary.json, plots) is kept; without, the run writes to a temporary folder that is
    removed."""
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


def _Picklable(error: Exception) -> Exception:
    """`error`, or a RuntimeError with its type and text if it cannot be sent."""
    try:
        pickle.loads(pickle.dumps(error))
    except Exception:  # an exception class whose arguments do not round-trip
        return RuntimeError(f"{type(error).__name__}: {error}")
    return error


def _Main() -> None:
    parser = argparse.ArgumentParser(description="Runs a worker's jobs, one at a time.")
    parser.add_argument("--fds", required=True)
    (connection,) = ChildChannels(parser.parse_args().fds)
    FollowParent()
    while True:
        try:
            job, runs_dir = connection.recv()
        except (EOFError, OSError):
            os._exit(0)  # the worker is done with this child: no teardown of pydrake
        metrics, error = {}, None
        try:
            metrics = RunJobHere(job, runs_dir)
        except Exception as e:  # the worker raises it, as when it ran the job itself
            error = _Picklable(e)
        SendOrExit(connection, (metrics, error, ResidentBytes()))


if __name__ == "__main__":
    _Main()
