"""The registry of runnable tasks: every module of diagrams/tasks/ that defines `TASK`."""

from __future__ import annotations

import importlib
import pkgutil
from collections.abc import Callable, Collection
from dataclasses import dataclass
from typing import Any

import guidedarm.diagrams.tasks as tasks_package
from guidedarm.diagrams.run_context import RunContext
from guidedarm.systems.errors import ConfigurationError


@dataclass(frozen=True)
class TaskDefinition:
    """A task: its scenario schema (a dataclass with a `task: str` field) and its runner.

    run(scenario, context) simulates (or drives hardware) and returns the summary metrics;
    it raises GuidedArmError for bad input and reports run failures in the metrics.
    station(scenario), when given, is the station scenario a run builds, with the values
    the task derives filled in (e.g. the hose and start pose of path following); without
    it, scenario.station.
    check_overrides(scenario, keys), when given, refuses (ConfigurationError) a dotted key
    given on the command line (`--set`) that the scenario it made would not read, where the
    scenario file may hold the same key for another choice (e.g. `random_path` beside a
    named hose).
    simulates: False for a task that simulates no station (marker_view renders one image):
    `run` refuses --hardware, --realtime and --meshcat for it, which it would not read.
    """

    name: str
    scenario_type: type
    run: Callable[[Any, RunContext], dict[str, Any]]
    description: str
    station: Callable[[Any], Any] | None = None
    check_overrides: Callable[[Any, Collection[str]], None] | None = None
    simulates: bool = True

    def Station(self, scenario: Any) -> Any:
        """The station scenario a run of `scenario` builds (see the class docstring)."""
        return self.station(scenario) if self.station else scenario.station


def AvailableTasks() -> dict[str, TaskDefinition]:
    """All tasks, discovered from the modules of guidedarm.diagrams.tasks."""
    tasks = {}
    for module_info in pkgutil.iter_modules(tasks_package.__path__):
        module = importlib.import_module(f"guidedarm.diagrams.tasks.{module_info.name}")
        task = getattr(module, "TASK", None)
        if task is not None:
            tasks[task.name] = task
    return tasks


def GetTask(name: str) -> TaskDefinition:
    """The task called `name`, or a ConfigurationError listing the known ones."""
    tasks = AvailableTasks()
    if name not in tasks:
        raise ConfigurationError(f"unknown task '{name}' (known: {', '.join(sorted(tasks))})")
    return tasks[name]
