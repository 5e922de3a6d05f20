"""The registry of runnable tasks, one package per task under diagrams/tasks/ (named after
the task, its __init__ exporting `TASK`), and LoadScenario: a scenario file to its task and
typed scenario."""

from __future__ import annotations

import importlib
import pkgutil
from collections.abc import Callable, Collection, Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import guidedarm.diagrams.tasks as tasks_package
from guidedarm.diagrams.run_context import RunContext
from guidedarm.diagrams.scenario_loading import (
    ScenarioError,
    apply_overrides,
    load_typed,
    parse_overrides,
    read_raw_scenario,
    resolve_scenario_path,
)
from guidedarm.diagrams.station.scenario import StationScenario
from guidedarm.systems.config_checks import CheckInstance, FieldError
from guidedarm.systems.errors import ConfigurationError

# The packages of diagrams/tasks/ that are not tasks: helpers several tasks share.
NOT_TASKS = ("common",)

# A list's elements in a metric's dotted name: `waypoint_distance_m.#`.
LIST_INDEX = "#"

# A metric's documentation: its unit and what it measures (`guidedarm describe --metrics`).
MetricDoc = tuple[str, str]

# What RunTask adds to every task's metrics.
RUN_METRICS: dict[str, MetricDoc] = {
    "wall_time_s": ("s", "wall-clock time of the whole run (setup, simulation, report)"),
}

# The keys of every summary.json beside the task's metrics (`guidedarm run` writes them).
SUMMARY_KEYS: dict[str, MetricDoc] = {
    "scenario": ("text", "the scenario's name or file"),
    "task": ("text", "the task it ran"),
    "success": ("bool", "the run did what the task asks; false when `failure` is set"),
    "failure": ("text", "null, or one line naming why the run failed and when"),
    "command": ("text", "the command line of the run"),
    "version": ("text", "guidedarm's version"),
}

# Where RunTask writes the run's drawn cell errors (station.errors) in the summary: the
# cell of the run, not a metric.
ERRORS_KEY = "errors"


@dataclass(frozen=True)
class RunFlags:
    """The command-line flags of a run that a task may refuse: hardware (--hardware),
    live (--meshcat: a page served during the run), realtime (--realtime given)."""

    hardware: bool = False
    live: bool = False
    realtime: bool = False


@dataclass(frozen=True)
class TaskDefinition:
    """A task: its scenario schema (a dataclass with a `task: str` field) and its runner.

    prepare(scenario), when given, runs every check that needs models (the plant from the
    directives, joint limits, the hose, the panel, reach, the start pose's IK) without
    writing anything, raising GuidedArmError (one line) on bad input, and returns what the
    run reuses (e.g. path following's Setup): `guidedarm run` calls it before it announces
    the run (task_run.PrepareRun).
    run(scenario, context) simulates (or drives hardware) and returns the summary metrics;
    with prepare, run(scenario, context, prepared) reuses what prepare returned (and makes
    it itself when given None). It raises GuidedArmError for bad input and reports run
    failures in the metrics.
    station(scenario), when given, is the station scenario a run builds, with the values
    the task derives filled in (e.g. the hose and start pose of path following); without
    it, scenario.station.
    check_overrides(scenario, keys), when given, refuses (ConfigurationError) a dotted key
    given on the command line (`--set`) that the scenario it made would not read, where the
    scenario file may hold the same key for another choice (e.g. `random_path` beside a
    named hose).
    simulates: False for a task that simulates no station (marker_view renders one image):
    CheckRun refuses --hardware, --realtime and --meshcat for it, which it would not read.
    check_run(scenario, flags), when given, refuses (ConfigurationError) a scenario the
    task cannot run with these RunFlags (e.g. path following's kinematic executor with
    --hardware); CheckRun calls it before anything of the run is written.
    resolve(scenario), when given, returns the scenario as it runs, with a key that another
    key replaces cleared (e.g. path following's `path` under `path_csv`), so that the run's
    scenario.yaml and figure titles show only what the run used.
    metrics: every number its summary.json can carry, by dotted name (a list's elements as
    `name.#`; RUN_METRICS are added to every task's), with its MetricDoc (unit, meaning):
    what a campaign may collect, its report plots and `guidedarm describe TASK --metrics`
    prints. tests/test_sweep.py compares the names with real runs.
    ground_truth_metrics: metrics measured against the simulation's truth that have no
    `true_` prefix (e.g. marker_view's errors against the rendered pose); `guidedarm
    describe --metrics` lists each metric's source (MetricSource).
    """

    name: str
    scenario_type: type
    run: Callable[[Any, RunContext], dict[str, Any]]
    description: str
    station: Callable[[Any], Any] | None = None
    check_overrides: Callable[[Any, Collection[str]], None] | None = None
    simulates: bool = True
    metrics: Mapping[str, MetricDoc] = field(default_factory=dict, hash=False)
    check_run: Callable[[Any, RunFlags], None] | None = None
    resolve: Callable[[Any], Any] | None = None
    ground_truth_metrics: tuple[str, ...] = ()
    prepare: Callable[[Any], Any] | None = None

    def MetricSource(self, name: str) -> str:
        """Where a metric comes from: the true cell (a `true_` metric, or one of
        ground_truth_metrics), what the controller commands or measures (one with a
        `true_` twin), or '' for the others (times, counts, settings)."""
        parts = name.split(".")
        if any(p.startswith("true_") for p in parts) or name in self.ground_truth_metrics:
            return "the true cell (simulation ground truth; none on hardware)"
        for i in range(len(parts)):
            twin = ".".join([*parts[:i], f"true_{parts[i]}", *parts[i + 1 :]])
            if twin in self.metrics:
                return f"what the controller commands or measures (on the true cell: {twin})"
        return ""

    def CheckRun(self, scenario: Any, flags: RunFlags) -> None:
        """Refuses (ConfigurationError, one line) running `scenario` with `flags`: a flag a
        task that simulates no station would not read, what only the hardware station
        reads in a simulated run (StationScenario.CheckSimulated), then the task's check_run. Called
        by `guidedarm run` before it announces the run, and by RunTask before it writes."""
        if not self.simulates:
            given = {"--hardware": flags.hardware, "--realtime": flags.realtime}
            given["--meshcat"] = flags.live
            for flag, value in given.items():
                if value:
                    raise ConfigurationError(
                        f"{flag} has no effect on task {self.name} (it simulates no station)"
                    )
        station = getattr(scenario, "station", None)
        if isinstance(station, StationScenario) and flags.hardware and station.HasErrors():
            raise ConfigurationError(
                "station.errors and station.errors_preset describe a simulated cell; a "
                "--hardware run drives the real one: remove them"
            )
        if isinstance(station, StationScenario) and not flags.hardware:
            try:
                station.CheckSimulated()
            except FieldError as e:
                raise FieldError(f"station.{e.key}", e.why) from None
        if self.check_run is not None:
            self.check_run(scenario, flags)

    def Station(self, scenario: Any) -> Any:
        """The station scenario a run of `scenario` builds (see the class docstring)."""
        return self.station(scenario) if self.station else scenario.station

    def MetricDocs(self) -> dict[str, MetricDoc]:
        """Every metric of its summary, RUN_METRICS included, with its unit and meaning,
        sorted by name."""
        return dict(sorted({**self.metrics, **RUN_METRICS}.items()))

    def KnownMetrics(self) -> list[str]:
        """The metric names of its summary, RUN_METRICS included, sorted."""
        return sorted({*self.metrics, *RUN_METRICS})

    def HasMetric(self, dotted: str) -> bool:
        """Whether `dotted` (a list index as digits, e.g. `press_tip_W_mm.0`) names one
        of its numeric metrics."""
        parts = dotted.split(".")

        def Matches(known: list[str]) -> bool:
            return len(known) == len(parts) and all(
                k == p or (k == LIST_INDEX and p.isdigit())
                for k, p in zip(known, parts, strict=True)
            )

        return any(Matches(name.split(".")) for name in self.KnownMetrics())


def NumericMetricNames(summary: Any, prefix: str = "") -> set[str]:
    """The dotted names of the numbers in a summary (booleans are not numbers), list
    indices written LIST_INDEX: what TaskDefinition.metrics declares. The drawn errors
    (ERRORS_KEY at the top) are not metrics."""
    if isinstance(summary, dict):
        items = [(str(k), v) for k, v in summary.items() if prefix or k != ERRORS_KEY]
    elif isinstance(summary, list):
        items = [(LIST_INDEX, v) for v in summary]
    elif isinstance(summary, int | float) and not isinstance(summary, bool):
        return {prefix}
    else:
        return set()
    names: set[str] = set()
    for key, value in items:
        names |= NumericMetricNames(value, f"{prefix}.{key}" if prefix else key)
    return names


def TaskNames() -> list[str]:
    """The names of every task: the task packages of guidedarm.diagrams.tasks (a package
    named after its task, defining TASK), found on disk without importing any, sorted."""
    return sorted(
        info.name
        for info in pkgutil.iter_modules(tasks_package.__path__)
        if info.ispkg and info.name not in NOT_TASKS
    )


def AvailableTasks() -> dict[str, TaskDefinition]:
    """All tasks by name; imports every task package (`guidedarm list` shows them all)."""
    return {name: _ImportTask(name) for name in TaskNames()}


def GetTask(name: str) -> TaskDefinition:
    """The task called `name`, importing its package only, or a ConfigurationError
    listing the known ones."""
    names = TaskNames()
    if name not in names:
        raise ConfigurationError(f"unknown task '{name}' (known: {', '.join(names)})")
    return _ImportTask(name)


def _ImportTask(name: str) -> TaskDefinition:
    task = importlib.import_module(f"{tasks_package.__name__}.{name}").TASK
    if task.name != name:
        raise ValueError(f"task package '{name}' defines TASK '{task.name}'")
    return task


def LoadScenario(name_or_path: str | Path, overrides: list[str]) -> tuple[Any, Any, str]:
    """Returns (task, typed scenario, scenario name) for a scenario and `--set` overrides
    (a list of `key=value` strings), after the task's checks of the scenario: its types and
    bounds, its Validate() (the rules between its keys) and the task's check_overrides;
    the scenario is the task's resolved one (TaskDefinition.resolve)."""
    CheckInstance("name_or_path", name_or_path, (str, Path))
    path = resolve_scenario_path(name_or_path)
    parsed = parse_overrides(overrides)
    raw = apply_overrides(read_raw_scenario(path), parsed)
    task_name = raw.get("task")
    if not isinstance(task_name, str):
        raise ScenarioError(f"{path}: missing key 'task' (the task this scenario runs)")
    task = GetTask(task_name)
    scenario = load_typed(task.scenario_type, raw, str(path), parsed.keys())
    if task.check_overrides is not None:
        task.check_overrides(scenario, parsed.keys())
    if task.resolve is not None:
        scenario = task.resolve(scenario)
    return task, scenario, path.stem
