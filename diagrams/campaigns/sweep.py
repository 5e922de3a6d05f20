"""One campaign from file to report: expand and check the jobs, skip those already done in
DIR, run the rest on Dask, write DIR/results.csv, DIR/campaign.yaml and DIR/report.html."""

from __future__ import annotations

import os
import sys
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

from pydrake.common.yaml import yaml_dump

from guidedarm.diagrams.campaigns.campaign import CampaignConfig, CampaignError
from guidedarm.diagrams.campaigns.engine import OpenClient, Outcome, RunJobs
from guidedarm.diagrams.campaigns.jobs import ExpandJobs, Job
from guidedarm.diagrams.campaigns.report import WriteReport
from guidedarm.diagrams.campaigns.results import RESULTS_FILE, ResultsTable
from guidedarm.diagrams.interrupts import DeferredInterrupts
from guidedarm.diagrams.run_context import PrepareOutputDirectory
from guidedarm.diagrams.tasks.registry import GetTask
from guidedarm.systems.errors import ConfigurationError

CAMPAIGN_FILE = "campaign.yaml"
RUNS_DIR = "runs"


@dataclass
class SweepOptions:
    """workers: processes of the embedded cluster (None: one per core); scheduler: the
    address of an existing Dask scheduler instead; keep_runs: keep DIR/runs/<job id>/."""

    workers: int | None = None
    scheduler: str | None = None
    keep_runs: bool = False
    progress: Callable[[str], None] | None = None


def MakeSweepOptions(
    workers: int | None, scheduler: str | None, keep_runs: bool = False
) -> SweepOptions:
    """The options of `--workers N` and `--scheduler ADDRESS` (either, not both; N >= 1;
    neither: one worker per core). Bad values raise ConfigurationError naming the flag."""
    if scheduler is not None and workers is not None:
        raise ConfigurationError("--workers applies to the embedded cluster, not --scheduler")
    if workers is not None and workers < 1:
        raise ConfigurationError(f"--workers must be at least 1, got {workers}")
    return SweepOptions(
        workers=workers or (None if scheduler else os.cpu_count()),
        scheduler=scheduler,
        keep_runs=keep_runs,
    )


@dataclass
class SweepResult:
    """The campaign's jobs, its results table, and what this call ran."""

    jobs: list[Job]
    table: ResultsTable
    outcome: Outcome = field(default_factory=Outcome)
    written: list[Path] = field(default_factory=list)


def Sweep(
    campaign: CampaignConfig,
    out_dir: Path,
    options: SweepOptions,
    jobs: list[Job] | None = None,
) -> SweepResult:
    """Runs the jobs of `campaign` (`jobs`: ExpandJobs(campaign) done already) not yet done
    in `out_dir`. Bad input (the campaign, a job's scenario, DIR, an unreachable scheduler)
    is refused before any job starts."""
    jobs = ExpandJobs(campaign) if jobs is None else jobs
    out_dir = PrepareOutputDirectory(out_dir)
    table = ResultsTable(out_dir / RESULTS_FILE, campaign.AxisNames())
    ids = {job.id for job in jobs}
    foreign = {r["job_id"] for r in table.rows} - ids
    if foreign:
        raise CampaignError(
            f"{out_dir / RESULTS_FILE} holds {len(foreign)} job(s) that are not in this "
            "campaign: choose another --out"
        )
    table.Keep(table.DoneIds())
    done = table.DoneIds()
    pending = [job for job in jobs if job.id not in done]
    (out_dir / CAMPAIGN_FILE).write_text(
        f"# {campaign.source}, resolved: {len(jobs)} jobs\n{yaml_dump(campaign.Resolved())}\n"
    )
    result = SweepResult(jobs, table, written=[out_dir / CAMPAIGN_FILE, table.path])
    where = options.scheduler or f"{options.workers or 'one per core'} local worker(s)"
    print(
        f"guidedarm: campaign '{campaign.name}': {len(jobs)} jobs, {len(jobs) - len(pending)} "
        f"done already, {len(pending)} to run on {where}",
        file=sys.stderr,
        flush=True,
    )
    # Ctrl-C or SIGTERM stops the jobs only (RunJobs); the cluster's start and shutdown
    # and the report are not cut, so no worker process outlives the command.
    with DeferredInterrupts():
        if pending:
            runs_dir = out_dir / RUNS_DIR if options.keep_runs else None
            with OpenClient(options.workers, options.scheduler) as client:
                result.outcome = RunJobs(
                    client, pending, table, campaign.metrics, runs_dir, options.progress
                )
            if not result.outcome.interrupted:
                table.Order([job.id for job in jobs])
        task = GetTask(jobs[0].task)
        result.written.append(WriteReport(out_dir, campaign, table, len(jobs), task))
    return result
