"""`guidedarm sweep --scheduler`: a real Dask scheduler and worker processes on 127.0.0.1."""

from __future__ import annotations

import json
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest
from distributed import Client
from test_sweep import TOUR, ReadRows

BIN = Path(sys.executable).parent
SPEEDS = [2.0, 2.2, 2.4, 2.6, 2.8, 3.0]
# Columns that depend on where and when a job ran, not on its scenario.
PLACE_AND_TIME = ("wall_time_s", "worker")


def _Worker(scheduler_file: Path, name: str) -> subprocess.Popen:
    """A worker process without a nanny: killing it loses the worker for good."""
    command = [str(BIN / "dask"), "worker", "--scheduler-file", str(scheduler_file)]
    command += ["--nthreads", "1", "--no-nanny", "--host", "127.0.0.1", "--no-dashboard"]
    return subprocess.Popen([*command, "--name", name], stderr=subprocess.DEVNULL)


@pytest.fixture(scope="module")
def cluster(tmp_path_factory):
    """(scheduler address, scheduler file) of a scheduler with two worker processes."""
    folder = tmp_path_factory.mktemp("dask")
    scheduler_file = folder / "scheduler.json"
    scheduler = subprocess.Popen(
        [str(BIN / "dask"), "scheduler", "--host", "127.0.0.1", "--port", "0"]
        + ["--no-dashboard", "--scheduler-file", str(scheduler_file)],
        stderr=subprocess.DEVNULL,
    )
    processes = [scheduler]
    try:
        deadline = time.monotonic() + 30
        while not scheduler_file.exists() and time.monotonic() < deadline:
            time.sleep(0.1)
        address = json.loads(scheduler_file.read_text())["address"]
        assert address.startswith("tcp://127.0.0.1:")
        processes += [_Worker(scheduler_file, f"w{i}") for i in range(2)]
        yield address, scheduler_file
    finally:
        for process in processes:
            process.kill()
            process.wait(timeout=30)


def _Busy(client: Client, name: str) -> bool:
    """Whether the worker called `name` is running a job."""
    workers = client.scheduler_info(n_workers=-1)["workers"]
    address = next((a for a, w in workers.items() if w.get("name") == name), None)
    return address is not None and bool(client.processing([address]).get(address))


def _Sweep(tmp_path: Path, *args: str) -> subprocess.CompletedProcess:
    command = [sys.executable, "-m", "guidedarm.diagrams.cli.main", "sweep", *args]
    return subprocess.run(command, capture_output=True, text=True, timeout=180, cwd=tmp_path)


def _Comparable(rows: list[dict]) -> list[dict]:
    return [{k: v for k, v in r.items() if k not in PLACE_AND_TIME} for r in rows]


@pytest.mark.slow
def test_an_existing_cluster_gives_the_results_of_the_local_run(tmp_path, cluster, run_cli):
    address, _ = cluster
    campaign = tmp_path / "campaign.yaml"
    campaign.write_text(TOUR + f"grid: {{max_speed: {SPEEDS[:3]}}}\n")
    remote = _Sweep(tmp_path, str(campaign), "--out", "remote", "--scheduler", address)
    assert remote.returncode == 0, remote.stderr
    code, _, err = run_cli("sweep", campaign, "--out", tmp_path / "local", "--workers", "1")
    assert code == 0, err
    remote_rows = ReadRows(tmp_path / "remote" / "results.csv")
    local_rows = ReadRows(tmp_path / "local" / "results.csv")
    assert len(remote_rows) == 3 and all(r["success"] is True for r in remote_rows)
    assert _Comparable(remote_rows) == _Comparable(local_rows)  # every metric, bit for bit
    # Both of the cluster's workers took jobs.
    assert len({r["worker"] for r in remote_rows}) == 2


def test_a_killed_worker_loses_no_job(tmp_path, cluster):
    address, scheduler_file = cluster
    victim = _Worker(scheduler_file, "victim")
    campaign = tmp_path / "campaign.yaml"
    campaign.write_text(TOUR + f"grid: {{max_speed: {SPEEDS}}}\n")
    command = [sys.executable, "-m", "guidedarm.diagrams.cli.main", "sweep", str(campaign)]
    sweep = subprocess.Popen(
        [*command, "--out", str(tmp_path / "out"), "--scheduler", address],
        stderr=subprocess.PIPE,
        text=True,
    )
    table = tmp_path / "out" / "results.csv"
    with Client(address) as client:
        deadline = time.monotonic() + 60
        while not _Busy(client, "victim") and time.monotonic() < deadline:
            time.sleep(0.02)
        assert _Busy(client, "victim")
        victim.send_signal(signal.SIGKILL)  # while it runs a job of the campaign
    victim.wait(timeout=10)
    _, err = sweep.communicate(timeout=120)
    assert sweep.returncode == 0, err
    rows = ReadRows(table)
    assert sorted(r["max_speed"] for r in rows) == SPEEDS
    assert len({r["job_id"] for r in rows}) == len(SPEEDS)  # none twice
    assert all(r["success"] is True for r in rows)
