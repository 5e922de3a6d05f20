"""Benchmark of `guidedarm sweep`: speed-up on 2 workers and the per-job overhead.

Run: .venv/bin/python tests/benchmarks/bench_sweep.py
Goals (issue 15): 16 short jobs on 2 workers >= 1.8x faster than on 1 (2 cores); the
engine's cost per job <= 5 % of a 5 s job.

Speed-up: 16 ur10e_joint_tour jobs (max_speed 1.5-3.0 rad/s, about 1 s each) on an
embedded cluster of 1, then 2 worker processes; the workers are warmed up first (pydrake
imported, one job run), so the figure is the jobs' phase, cluster start-up excluded (it is
printed apart). Overhead: 4 jobs of about 5 s (max_speed 0.3 rad/s) run one after the other
in this process with worker.RunJob (the job alone), then on a 1-worker cluster; the
difference per job is the engine's cost (submission, scheduling, results, the CSV row).
The machine's load average is printed before and after: other work on the cores shows
in every figure.
"""

from __future__ import annotations

import os
import tempfile
import time
from pathlib import Path

import numpy as np

from guidedarm.diagrams.campaigns.campaign import CampaignConfig
from guidedarm.diagrams.campaigns.engine import OpenClient, RunJobs
from guidedarm.diagrams.campaigns.jobs import ExpandJobs, Job
from guidedarm.diagrams.campaigns.results import ResultsTable
from guidedarm.diagrams.campaigns.worker import RunJob

SCENARIO = "ur10e_joint_tour"


def Jobs(grid: dict[str, list]) -> list[Job]:
    campaign = CampaignConfig(name="bench", scenario=SCENARIO, source="bench", grid=grid)
    return ExpandJobs(campaign)


def TimeJobs(workers: int, jobs: list[Job], warm_up: Job) -> tuple[float, float]:
    """(start-up of the cluster, wall time of the jobs) on `workers` local workers (s)."""
    with tempfile.TemporaryDirectory() as folder:
        start = time.perf_counter()
        with OpenClient(workers, None) as client:
            client.wait_for_workers(workers)
            startup = time.perf_counter() - start
            # Every worker imports pydrake and builds one diagram before the clock starts.
            client.run(RunJob, warm_up)
            table = ResultsTable(Path(folder) / "results.csv", list(jobs[0].axes))
            start = time.perf_counter()
            outcome = RunJobs(client, jobs, table, None, progress=lambda line: None)
            wall = time.perf_counter() - start
    assert outcome.ran == len(jobs) and outcome.failed == 0, outcome
    return startup, wall


def main() -> None:
    print(f"load average before: {' '.join(f'{v:.2f}' for v in os.getloadavg())}")
    warm_up = Jobs({"max_speed": [3.5]})[0]

    short = Jobs({"max_speed": np.round(np.linspace(1.5, 3.0, 16), 3).tolist()})
    startup_1, one = TimeJobs(1, short, warm_up)
    startup_2, two = TimeJobs(2, short, warm_up)
    print(
        f"16 short jobs: 1 worker {one:.1f} s ({one / 16:.2f} s/job), 2 workers {two:.1f} s"
        f" -> speed-up {one / two:.2f} (goal >= 1.8); cluster start-up {startup_1:.1f} s"
        f" (1 worker), {startup_2:.1f} s (2 workers)"
    )

    long = Jobs({"max_speed": [0.3], "settle_time": [0.50, 0.51, 0.52, 0.53]})
    RunJob(warm_up)
    start = time.perf_counter()
    for job in long:
        RunJob(job)
    alone = (time.perf_counter() - start) / len(long)
    _, campaign = TimeJobs(1, long, warm_up)
    overhead = campaign / len(long) - alone
    print(
        f"{len(long)} jobs of {alone:.2f} s alone: {campaign / len(long):.2f} s each on a "
        f"1-worker cluster -> overhead {overhead * 1e3:.0f} ms/job = "
        f"{100 * overhead / alone:.1f} % (goal <= 5 %)"
    )
    print(f"load average after: {' '.join(f'{v:.2f}' for v in os.getloadavg())}")


if __name__ == "__main__":
    main()
