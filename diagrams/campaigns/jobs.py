"""A campaign's jobs: each is one fully resolved scenario, checked in the client.

A job carries its resolved scenario as YAML text (`yaml_dump_typed`), never a Drake object:
the worker that runs it loads the text and builds its own diagram, so a job's result
depends only on that text, and the job id is a hash of it.
"""

from __future__ import annotations

import hashlib
import json
from dataclasses import dataclass
from typing import Any

from pydrake.common.yaml import yaml_dump_typed

from guidedarm.diagrams.campaigns.campaign import DRAW_AXIS, CampaignConfig, CampaignError
from guidedarm.diagrams.tasks.registry import LoadScenario, TaskDefinition
from guidedarm.systems.errors import ConfigurationError

ID_LENGTH = 16


@dataclass(frozen=True)
class Job:
    """One run of a campaign: id (hash of the resolved scenario), index in the campaign,
    axis values, and the resolved scenario as YAML text."""

    id: str
    index: int
    axes: dict[str, Any]
    scenario_yaml: str
    task: str


def JobId(scenario_yaml: str) -> str:
    """The job id: the first hex digits of the SHA-256 of the resolved scenario text."""
    return hashlib.sha256(scenario_yaml.encode()).hexdigest()[:ID_LENGTH]


def ExpandJobs(campaign: CampaignConfig) -> list[Job]:
    """Every job of the campaign, each scenario loaded and checked against its task's
    schema; refuses (CampaignError, one line) an unknown scenario, a key the scenario
    lacks, a value of the wrong type, a metric its task does not declare (CheckMetrics), or
    two jobs that resolve to one scenario."""
    jobs: list[Job] = []
    by_id: dict[str, Job] = {}
    for index, axes in enumerate(campaign.AxisPoints()):
        overrides = [_Override(k, v) for k, v in {**campaign.set, **axes}.items() if k != DRAW_AXIS]
        try:
            task, scenario, _ = LoadScenario(campaign.scenario, overrides)
        except ConfigurationError as e:
            where = f" (job {DescribeAxes(axes)})" if axes else ""
            raise CampaignError(f"{campaign.source}{where}: {e}") from None
        if index == 0:
            CheckMetrics(campaign, task)
        elif task.name != jobs[0].task:
            raise CampaignError(
                f"{campaign.source}: job {DescribeAxes(axes)} runs task '{task.name}', the "
                f"others '{jobs[0].task}': a campaign runs one task"
            )
        text = yaml_dump_typed(scenario)
        job = Job(JobId(text), index, axes, text, task.name)
        if job.id in by_id:
            raise CampaignError(
                f"{campaign.source}: jobs {DescribeAxes(by_id[job.id].axes)} and "
                f"{DescribeAxes(axes)} resolve to the same scenario"
            )
        by_id[job.id] = job
        jobs.append(job)
    return jobs


def CheckMetrics(campaign: CampaignConfig, task: TaskDefinition) -> None:
    """Refuses (CampaignError) a metric of the campaign that is not one of the numbers its
    task's summary carries (TaskDefinition.metrics): a misspelt name or a text field."""
    for metric in campaign.metrics or []:
        if not task.HasMetric(metric):
            raise CampaignError(
                f"{campaign.source}: metric '{metric}' is not a numeric metric of task "
                f"'{task.name}' (known: {', '.join(task.KnownMetrics())})"
            )


def DescribeAxes(axes: dict[str, Any]) -> str:
    """`key=value, ...` of a job's axes (long values shortened)."""
    parts = []
    for key, value in axes.items():
        text = json.dumps(value)
        parts.append(f"{key}={text if len(text) <= 40 else text[:37] + '...'}")
    return ", ".join(parts) or "the only job"


def _Override(key: str, value: Any) -> str:
    """A `--set` item; JSON is YAML's flow syntax, so lists and mappings pass unchanged."""
    return f"{key}={json.dumps(value)}"
