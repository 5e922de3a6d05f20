"""The step before a run: every refusal that needs the task's models, and the cell's errors
drawn, before `guidedarm run` announces the run or writes into --out."""

from __future__ import annotations

import dataclasses
from typing import Any

from guidedarm.diagrams.station.scenario import StationScenario
from guidedarm.diagrams.tasks.registry import RunFlags, TaskDefinition
from guidedarm.systems.cell_errors.camera_errors import CameraErrors
from guidedarm.systems.cell_errors.distributions import DrawErrors


@dataclasses.dataclass(frozen=True)
class PreparedRun:
    """A run checked and ready to start: its task, its scenario with the errors drawn
    (WithErrorsDrawn) and what the task's prepare made of it (None for a task without
    prepare), which the run reuses."""

    task: TaskDefinition
    scenario: Any
    prepared: Any


def PrepareRun(task: TaskDefinition, scenario: Any, flags: RunFlags) -> PreparedRun:
    """Every refusal of a run before it starts, writing nothing: the task's CheckRun for
    the run's flags, then its prepare (TaskDefinition.prepare: the checks that need
    models, e.g. the hose, the panel, the directives, joint limits and reach) on the
    scenario with its errors drawn. Raises GuidedArmError (one line) on bad input."""
    task.CheckRun(scenario, flags)
    scenario = WithErrorsDrawn(scenario)
    prepared = task.prepare(scenario) if task.prepare is not None else None
    return PreparedRun(task, scenario, prepared)


def WithErrorsDrawn(scenario: Any) -> Any:
    """`scenario` with its error models (station.errors and its presets, marker_view's
    camera_errors) drawn once from its random_seed, one stream per source: the cell of
    this run, which the resolved scenario.yaml repeats."""
    seed = getattr(scenario, "random_seed", None)
    station = getattr(scenario, "station", None)
    if isinstance(station, StationScenario):
        scenario = dataclasses.replace(scenario, station=station.WithErrorsDrawn(seed))
    camera_errors = getattr(scenario, "camera_errors", None)
    if isinstance(camera_errors, CameraErrors):
        drawn = DrawErrors(camera_errors, seed, "camera_errors")
        scenario = dataclasses.replace(scenario, camera_errors=drawn)
    return scenario
