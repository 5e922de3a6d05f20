"""What a Dask worker does with one job: load its scenario text, build, run, report.

The worker hands the job to a child process of its own, which runs it
(job_process.RunJobHere); guidedarm and pydrake must be installed in the worker's Python.
Whatever the task raises becomes the job's `failure`, as does the end of the child: a failed
job is a result, never the end of the campaign.
"""

from __future__ import annotations

import os
import socket
import time
from typing import Any

from guidedarm.diagrams.campaigns.job_process import RunInJobProcess
from guidedarm.diagrams.campaigns.jobs import Job


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
