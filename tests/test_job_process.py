"""A worker's job process (campaigns/job_process.py): jobs share a child until it holds too
much memory, and a child that ends is its job's failure, not the worker's."""

from __future__ import annotations

import os
import signal

import pytest
from test_sweep import TOUR, _Write

from guidedarm.diagrams.campaigns import job_process
from guidedarm.diagrams.campaigns.campaign_file import LoadCampaign
from guidedarm.diagrams.campaigns.jobs import ExpandJobs
from guidedarm.diagrams.campaigns.worker import RunJob


@pytest.fixture
def jobs(tmp_path):
    """Three 1 s tours; the worker's idle children ended after the test."""
    campaign = _Write(tmp_path, TOUR + "grid: {max_speed: [2.6, 2.8, 3.0]}\n")
    yield ExpandJobs(LoadCampaign(str(campaign)))
    while job_process._idle:
        job_process._idle.pop().End()


def _IdleChild() -> int:
    (child,) = job_process._idle
    return child.process.pid


def test_jobs_share_a_child_until_it_holds_too_much_memory(jobs, monkeypatch):
    first = RunJob(jobs[0])
    child = _IdleChild()
    assert first["metrics"]["success"] is True
    assert first["worker"].endswith(f":{os.getpid()}")  # the worker, not its child
    assert RunJob(jobs[1])["metrics"]["success"] is True
    assert _IdleChild() == child
    # Past the limit the child is ended after its job, and the next job gets a new one.
    monkeypatch.setattr(job_process, "RECYCLE_RSS_BYTES", 1)
    assert RunJob(jobs[2])["metrics"]["success"] is True
    assert job_process._idle == []
    with pytest.raises(ProcessLookupError):
        os.kill(child, 0)


def test_a_child_that_ends_is_its_jobs_failure_and_the_next_job_runs(jobs):
    RunJob(jobs[0])
    os.kill(_IdleChild(), signal.SIGSEGV)  # as a native crash inside a run would
    lost = RunJob(jobs[1])["metrics"]
    assert lost == {"success": False, "failure": "the job's process ended by SIGSEGV"}
    assert job_process._idle == []
    assert RunJob(jobs[1])["metrics"]["success"] is True
