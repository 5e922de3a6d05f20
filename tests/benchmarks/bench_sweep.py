"""Benchmark of `guidedarm sweep`: speed-up on 2 workers and the per-job overhead.

Run: .venv/bin/python tests/benchmarks/bench_sweep.py  (about 3 min on 2 quiet cores)
Goals (issue 15): 16 short jobs on 2 workers >= 1.8x faster than on 1 (2 cores); the
engine's cost per job <= 5 % of a 5 s job.

Speed-up: 16 ur10e_joint_tour jobs (max_speed 1.5-3.0 rad/s, about 1 s each) on an
embedded cluster of 1, then 2 worker processes; the workers are warmed up first (pydrake
imported, one job run), so the figure is the jobs' phase, cluster start-up excluded (it is
printed apart). Overhead: 4 jobs of about 5 s (max_speed 0.1 rad/s) run one after the other
in this process with job_process.RunJobHere (the job alone), then on a 1-worker cluster; the
difference per job is the engine's cost (submission, scheduling, results, the CSV row).
The overhead is split into the engine's own cost (campaign time per job minus the job's
time inside its worker) and the job running slower inside the worker process than alone.
Each figure is the fastest of two interleaved measurements; the load average and a control
(two processes spinning in pure Python against one: 2.0 on two idle cores) are printed
along: other work on the shared cores shows in every figure.
"""

from __future__ import annotations

import multiprocessing
import os
import tempfile
import time
from pathlib import Path

import numpy as np
import psutil

from guidedarm.diagrams.campaigns.campaign import CampaignConfig
from guidedarm.diagrams.campaigns.engine import OpenClient, RunJobs
from guidedarm.diagrams.campaigns.job_process import RunJobHere
from guidedarm.diagrams.campaigns.jobs import ExpandJobs, Job
from guidedarm.diagrams.campaigns.results import ResultsTable
from guidedarm.diagrams.campaigns.worker import RunJob

SCENARIO = "ur10e_joint_tour"


def Jobs(grid: dict[str, list]) -> list[Job]:
    campaign = CampaignConfig(name="bench", scenario=SCENARIO, source="bench", grid=grid)
    return ExpandJobs(campaign)


def TimeJobs(workers: int, jobs: list[Job], warm_up: Job) -> tuple[float, float, float, float]:
    """(start-up of the cluster, wall time of the jobs, mean time of a job inside its
    worker, CPU time of every process of the cluster during the jobs) on `workers` local
    workers (s). The processes: this one (client and scheduler), the nannies, the
    workers and their job processes."""
    with tempfile.TemporaryDirectory() as folder:
        start = time.perf_counter()
        with OpenClient(workers, None) as client:
            client.wait_for_workers(workers)
            startup = time.perf_counter() - start
            # Every worker imports pydrake and builds one diagram before the clock starts.
            client.run(RunJob, warm_up)
            table = ResultsTable(Path(folder) / "results.csv", list(jobs[0].axes))
            workers = [psutil.Process(pid) for pid in client.run(os.getpid).values()]
            job_processes = [child for w in workers for child in w.children()]
            processes = [psutil.Process(), *workers, *job_processes]
            processes += [w.parent() for w in workers]
            cpu = -_Cpu(processes)
            start = time.perf_counter()
            outcome = RunJobs(client, jobs, table, None, progress=lambda line: None)
            wall = time.perf_counter() - start
            cpu += _Cpu(processes)
            in_worker = float(np.mean([r["wall_time_s"] for r in table.rows]))
    assert outcome.ran == len(jobs) and outcome.failed == 0, outcome
    return startup, wall, in_worker, cpu


def _Cpu(processes: list[psutil.Process]) -> float:
    """User + system CPU time of the processes (s)."""
    return sum(sum(p.cpu_times()[:2]) for p in processes)


def _Spin(count: int) -> None:
    x = 0
    for i in range(count):
        x += i * i


def Parallelism(count: int = 10_000_000) -> float:
    """What two processes get done against one in the same time, on pure Python work:
    2.0 on two idle cores, less while other work shares them (the control figure)."""
    times = []
    for processes in (1, 2):
        workers = [multiprocessing.Process(target=_Spin, args=(count,)) for _ in range(processes)]
        start = time.perf_counter()
        for w in workers:
            w.start()
        for w in workers:
            w.join()
        times.append(time.perf_counter() - start)
    return 2 * times[0] / times[1]


def Load() -> str:
    return " ".join(f"{v:.2f}" for v in os.getloadavg())


def main(repeats: int = 2) -> None:
    """Each measurement `repeats` times, interleaved, keeping the fastest: other work on
    the shared cores comes and goes, and it only ever slows a measurement down."""
    print(f"load average before: {Load()}")
    warm_up = Jobs({"max_speed": [3.5]})[0]
    short = Jobs({"max_speed": np.round(np.linspace(1.5, 3.0, 16), 3).tolist()})
    long = Jobs({"max_speed": [0.1], "settle_time": [0.50, 0.51, 0.52, 0.53]})
    one, two, control, alone, campaign, in_worker = [], [], [], [], [], []
    alone_cpu, campaign_cpu, busy = [], [], []
    RunJobHere(warm_up)
    for _ in range(repeats):
        control.append(Parallelism())
        startup_1, wall, _, _ = TimeJobs(1, short, warm_up)
        one.append(wall)
        startup_2, wall, inside, _ = TimeJobs(2, short, warm_up)
        two.append(wall)
        busy.append(inside * len(short) / wall)
        start, start_cpu = time.perf_counter(), time.process_time()
        for job in long:
            RunJobHere(job)
        alone.append((time.perf_counter() - start) / len(long))
        alone_cpu.append((time.process_time() - start_cpu) / len(long))
        _, wall, inside, cpu = TimeJobs(1, long, warm_up)
        campaign.append(wall / len(long))
        in_worker.append(inside)
        campaign_cpu.append(cpu / len(long))
        print(f"  load average: {Load()}")
    one, two, alone = min(one), min(two), min(alone)
    best = int(np.argmin(campaign))
    print(
        f"16 short jobs: 1 worker {one:.1f} s ({one / 16:.2f} s/job), 2 workers {two:.1f} s"
        f" -> speed-up {one / two:.2f} (goal >= 1.8); control (2 spinning processes against"
        f" 1 at the same time): {', '.join(f'{c:.2f}' for c in control)}; jobs running at"
        f" once on 2 workers (their time in the workers / the wall time):"
        f" {', '.join(f'{b:.2f}' for b in busy)}; cluster start-up {startup_1:.1f} s"
        f" (1 worker), {startup_2:.1f} s (2 workers)"
    )
    total, inside = campaign[best], in_worker[best]
    print(
        f"{len(long)} jobs of {alone:.2f} s alone: {total:.2f} s each on a 1-worker cluster"
        f" -> overhead {(total - alone) * 1e3:.0f} ms/job = {100 * (total - alone) / alone:.1f}"
        f" % (goal <= 5 %): the engine (submit, schedule, result, CSV row)"
        f" {(total - inside) * 1e3:.0f} ms, the job itself {(inside - alone) * 1e3:.0f} ms"
        " slower inside the worker"
    )
    cpu_alone, cpu_campaign = min(alone_cpu), min(campaign_cpu)
    print(
        f"CPU time per job: {cpu_alone:.2f} s alone, {cpu_campaign:.2f} s on the 1-worker"
        f" cluster (all its processes) -> {(cpu_campaign - cpu_alone) * 1e3:.0f} ms ="
        f" {100 * (cpu_campaign - cpu_alone) / cpu_alone:.1f} % (what the overhead is on idle"
        " cores, where a single-threaded job's wall time is its CPU time)"
    )
    print(f"load average after: {Load()}")


if __name__ == "__main__":
    main()
