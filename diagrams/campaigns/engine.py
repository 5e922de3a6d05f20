"""Runs a campaign's jobs on Dask distributed and records each result as it arrives.

By default an embedded LocalCluster: N worker processes with one thread each, scheduler
and workers listening on 127.0.0.1 only, no dashboard. With a scheduler address the same
jobs go to an existing cluster (`dask scheduler` / `dask worker`, dask-jobqueue, ...).
A worker that dies takes its running job with it; the scheduler gives that job to another
worker, up to `distributed.scheduler.allowed-failures` times (ALLOWED_FAILURES on the
embedded cluster), after which the job's row says the workers were lost.
"""

from __future__ import annotations

import logging
import sys
import time
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import dask
from distributed import Client, LocalCluster, as_completed

from guidedarm.diagrams.campaigns.jobs import DescribeAxes, Job
from guidedarm.diagrams.campaigns.results import LOST_PREFIX, ResultsTable, RowOf
from guidedarm.diagrams.campaigns.worker import RunJob
from guidedarm.diagrams.interrupts import InterruptsAllowed, TakeInterrupt
from guidedarm.diagrams.task_run import INTERRUPTED
from guidedarm.systems.errors import ConfigurationError

# How often a job may be on a worker that dies before the job counts as lost.
ALLOWED_FAILURES = 2
# The embedded cluster's settings. Jobs are seconds long and single-threaded: Dask's
# statistical profiler (a stack sample of the job's thread every 10 ms, under the GIL) and
# its 20-100 ms monitors cost the jobs several per cent for figures nobody looks at here.
EMBEDDED_CONFIG = {
    "distributed.scheduler.allowed-failures": ALLOWED_FAILURES,
    "distributed.worker.profile.enabled": False,
    "distributed.admin.tick.interval": "1s",
    "distributed.admin.system-monitor.interval": "2s",
    "distributed.worker.memory.monitor-interval": "1s",
    # Each run leaves its diagram in the worker (pydrake keeps it alive), so a worker's
    # memory only grows. A paused worker would wait for memory that never comes back and
    # stall the campaign; without pausing, the nanny restarts a worker past its terminate
    # fraction and its job runs again on the fresh one. The results are small: no spilling.
    "distributed.worker.memory.pause": False,
    "distributed.worker.memory.target": False,
    "distributed.worker.memory.spill": False,
}
CONNECT_TIMEOUT_S = 10.0


@contextmanager
def OpenClient(workers: int | None, scheduler: str | None) -> Iterator[Client]:
    """A Dask client: of an embedded LocalCluster of `workers` processes on 127.0.0.1, or
    of the scheduler at `scheduler` (tcp://host:port). Refuses (ConfigurationError) a
    scheduler it cannot reach."""
    if scheduler is not None:
        try:
            client = Client(scheduler, timeout=CONNECT_TIMEOUT_S)
        except (OSError, TimeoutError, ValueError) as e:
            raise ConfigurationError(
                f"--scheduler {scheduler}: cannot reach a Dask scheduler there ({e})"
            ) from None
        with client:
            yield client
        return
    with (
        dask.config.set(EMBEDDED_CONFIG),
        LocalCluster(
            n_workers=workers,
            threads_per_worker=1,
            processes=True,
            host="127.0.0.1",
            dashboard_address=None,
            worker_dashboard_address=None,
            # The scheduler's HTTP endpoints (health, metrics; no dashboard) on a free
            # loopback port rather than 8787, which another cluster may hold.
            scheduler_kwargs={"dashboard": False, "dashboard_address": "127.0.0.1:0"},
            # A worker whose heartbeat meets the scheduler already closed (the command
            # stopping on Ctrl-C or SIGTERM while the workers shut down) logs the closed
            # stream's traceback at ERROR; what a job's failure is reaches its row instead.
            silence_logs=logging.CRITICAL,
        ) as cluster,
        Client(cluster) as client,
    ):
        yield client


@dataclass
class Outcome:
    """What one call of RunJobs did."""

    ran: int = 0
    failed: int = 0
    lost: int = 0
    interrupted: bool = False


def RunJobs(
    client: Client,
    jobs: list[Job],
    table: ResultsTable,
    metrics: list[str] | None,
    runs_dir: Path | None = None,
    progress: Callable[[str], None] | None = None,
) -> Outcome:
    """Submits `jobs` (in order) and adds each one's row to `table` as it finishes. A job
    whose workers were all lost gets a row with failure `engine: ...`. Ctrl-C stops
    collecting (also one recorded before the call, inside DeferredInterrupts): rows already
    written stay, the rest are cancelled."""
    by_key = {_Key(job): job for job in jobs}
    meter = ProgressMeter(len(jobs), progress)
    outcome = Outcome()
    seen: set[str] = set()
    futures = []
    try:
        with InterruptsAllowed():
            futures = [
                client.submit(RunJob, job, str(runs_dir) if runs_dir else None, key=key)
                for key, job in by_key.items()
            ]
            for future, result in as_completed(futures, with_results=True, raise_errors=False):
                job = by_key[future.key]
                if job.id in seen:
                    continue
                if future.status == "error":
                    result = _LostResult(job, future.exception())
                elif result["metrics"].get("failure") == INTERRUPTED:  # SIGINT on its worker
                    result = _LostResult(job, KeyboardInterrupt("the job was interrupted"))
                failure = str(result["metrics"].get("failure") or "")
                outcome.lost += failure.startswith(LOST_PREFIX)
                seen.add(job.id)
                row = RowOf(job.axes, result, metrics)
                table.Add(row)
                outcome.ran += 1
                outcome.failed += not row["success"]
                meter.Done(job, row)
    except KeyboardInterrupt:
        TakeInterrupt()
        outcome.interrupted = True
        client.cancel(futures)
    return outcome


class ProgressMeter:
    """One line per finished job: count, failures, elapsed time and the ETA, to stderr."""

    def __init__(self, total: int, sink: Callable[[str], None] | None = None) -> None:
        self.total = total
        self.done = 0
        self.failed = 0
        self.start = time.monotonic()
        self.sink = sink or (lambda line: print(line, file=sys.stderr, flush=True))

    def Done(self, job: Job, row: dict[str, Any]) -> None:
        self.done += 1
        self.failed += not row["success"]
        elapsed = time.monotonic() - self.start
        eta = elapsed / self.done * (self.total - self.done)
        state = "ok" if row["success"] else f"FAILED: {row['failure'][:80]}"
        self.sink(
            f"  [{self.done}/{self.total}] {DescribeAxes(job.axes)}: {state} "
            f"({row['wall_time_s']:.1f} s) | {self.failed} failed, "
            f"elapsed {_Clock(elapsed)}, ETA {_Clock(eta)}"
        )


def _LostResult(job: Job, error: BaseException) -> dict[str, Any]:
    lines = str(error).strip().splitlines()
    why = f"{LOST_PREFIX}{type(error).__name__}: {lines[0] if lines else ''}"
    return {
        "job_id": job.id,
        "metrics": {"success": False, "failure": why},
        "wall_time_s": 0.0,
        "worker": "",
    }


def _Key(job: Job) -> str:
    """The Dask key of a job: one key per resolved scenario, on any cluster."""
    return f"guidedarm-job-{job.id}"


def _Clock(seconds: float) -> str:
    seconds = round(seconds)
    hours, rest = divmod(seconds, 3600)
    return f"{hours}:{rest // 60:02d}:{rest % 60:02d}" if hours else f"{rest // 60}:{rest % 60:02d}"
