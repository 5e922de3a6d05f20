"""The error budget of a scenario: its accuracy metrics over N draws of the cell's errors,
with every error source on, then with each source alone (`guidedarm errors-budget`).

A source is one field of the error model that a preset or the scenario sets (its dotted
name under station.errors, e.g. `arms.ur10e.joint_offset`, or `camera_errors.<field>` for
marker_view). Draw k of every configuration runs with random_seed = k, so a source
alone draws exactly the values it draws beside the others (one stream per source).
"""

from __future__ import annotations

import csv
import dataclasses
import tempfile
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from guidedarm.diagrams.run_context import RunContext
from guidedarm.diagrams.station.scenario import StationScenario
from guidedarm.diagrams.station.station_errors import (
    CombinedErrors,
    LoadPreset,
    PresetNames,
    StationErrors,
)
from guidedarm.diagrams.task_run import RunTask
from guidedarm.diagrams.tasks.registry import TaskDefinition
from guidedarm.systems.cell_errors.camera_errors import CameraErrors
from guidedarm.systems.cell_errors.distributions import ErrorsAsData
from guidedarm.systems.errors import ConfigurationError

# The configuration with every source on.
ALL_SOURCES = "all"
GROUPS = ("arms", "cameras", "tof_tools", "models")


@dataclass
class BudgetRow:
    """One metric's statistics over the draws of one configuration (`source`): mean, 95th
    percentile and maximum over the runs that reported it, and the success rate."""

    source: str
    metric: str
    mean: float
    p95: float
    max: float
    runs: int
    success_rate: float


def WithPreset(scenario: Any, preset: str) -> Any:
    """`scenario` with the presets of `preset` ("NAME[,NAME]") under its own errors: for a
    station, its errors_preset (after any it names); for marker_view, the presets' one
    camera entry as camera_errors (its own camera_errors override it field by field)."""
    station = getattr(scenario, "station", None)
    if isinstance(station, StationScenario):
        names = ",".join([*PresetNames(station.errors_preset), *PresetNames(preset)])
        station = dataclasses.replace(station, errors_preset=names)
        station.Validate()
        return dataclasses.replace(scenario, station=station)
    if isinstance(getattr(scenario, "camera_errors", None), CameraErrors):
        cameras = [e for n in PresetNames(preset) for e in LoadPreset(n).cameras.values()]
        if len(cameras) > 1:
            raise ConfigurationError(f"--preset {preset}: more than one camera for one view")
        base = cameras[0] if cameras else CameraErrors()
        merged = _Merged(base, scenario.camera_errors)
        return dataclasses.replace(scenario, camera_errors=merged)
    raise ConfigurationError("the scenario's task has no error model (station or camera)")


def ErrorSources(scenario: Any) -> list[str]:
    """The dotted names of the error fields the scenario sets (presets included)."""
    station = getattr(scenario, "station", None)
    if isinstance(station, StationScenario):
        errors = CombinedErrors(station.errors_preset, station.errors)
        return [
            f"{group}.{key}.{name}"
            for group in GROUPS
            for key, entry in getattr(errors, group).items()
            for name in ErrorsAsData(entry)
        ]
    return [f"camera_errors.{name}" for name in ErrorsAsData(scenario.camera_errors)]


def OnlySource(scenario: Any, source: str) -> Any:
    """`scenario` with only the error field `source` set (ALL_SOURCES: all of them)."""
    if source == ALL_SOURCES:
        return scenario
    station = getattr(scenario, "station", None)
    if isinstance(station, StationScenario):
        errors = CombinedErrors(station.errors_preset, station.errors)
        group, key, name = source.split(".")
        entry = getattr(errors, group)[key]
        only = dataclasses.replace(type(entry)(), **{name: getattr(entry, name)})
        station = dataclasses.replace(
            station, errors=StationErrors(**{group: {key: only}}), errors_preset=""
        )
        return dataclasses.replace(scenario, station=station)
    name = source.split(".", 1)[1]
    only = dataclasses.replace(CameraErrors(), **{name: getattr(scenario.camera_errors, name)})
    return dataclasses.replace(scenario, camera_errors=only)


def RunBudget(
    task: TaskDefinition,
    scenario: Any,
    runs: int,
    progress: Callable[[str], None] = lambda _: None,
    each_source: bool = True,
    done: Callable[[list[BudgetRow], list[tuple[str, int, str, float]]], None] | None = None,
) -> tuple[list[BudgetRow], list[tuple[str, int, str, float]]]:
    """Runs `scenario` `runs` times (random_seed 0..runs-1) with every source, then (with
    `each_source`) with each source alone, and returns the statistics of every accuracy
    metric (_AccuracyMetrics) per configuration, and every run's
    values as (source, random_seed, metric, value). `done`, when given, receives both after
    each configuration (so that a long budget's finished part is kept)."""
    if not hasattr(scenario, "random_seed"):
        raise ConfigurationError(f"task {task.name} has no random_seed to draw errors from")
    rows, values = [], []
    for source in [ALL_SOURCES, *(ErrorSources(scenario) if each_source else [])]:
        summaries = []
        for seed in range(runs):
            progress(f"{source}: draw {seed + 1} of {runs}")
            configured = dataclasses.replace(OnlySource(scenario, source), random_seed=seed)
            with tempfile.TemporaryDirectory(prefix="guidedarm-budget-") as out:
                summaries.append(RunTask(task, configured, RunContext(Path(out), quiet=True)))
            values += [(source, seed, *v) for v in _AccuracyMetrics(summaries[-1])]
        rows += _Statistics(source, summaries)
        if done is not None:
            done(rows, values)
    return rows, values


def WriteBudget(
    rows: list[BudgetRow], values: list[tuple[str, int, str, float]], out_dir: Path
) -> list[Path]:
    """errors_budget.csv, errors_budget_runs.csv (every run's values) and
    errors_budget.png (mean and p95 per metric, a bar per source)."""
    import matplotlib.pyplot as plt  # after guidedarm.diagrams.plots chose Agg

    import guidedarm.diagrams.plots  # noqa: F401  (selects the Agg backend)

    out_dir.mkdir(parents=True, exist_ok=True)
    table = out_dir / "errors_budget.csv"
    with table.open("w", newline="") as f:
        writer = csv.writer(f)
        writer.writerow([field.name for field in dataclasses.fields(BudgetRow)])
        for row in rows:
            writer.writerow([getattr(row, field.name) for field in dataclasses.fields(row)])
    runs_table = out_dir / "errors_budget_runs.csv"
    with runs_table.open("w", newline="") as f:
        writer = csv.writer(f)
        writer.writerow(["source", "random_seed", "metric", "value"])
        writer.writerows(values)
    metrics = sorted({r.metric for r in rows})
    sources = list(dict.fromkeys(r.source for r in rows))
    figure, axes = plt.subplots(len(metrics), 1, figsize=(8, 1.2 + 1.6 * len(metrics)))
    for ax, metric in zip(np.atleast_1d(axes), metrics, strict=True):
        values = {r.source: r for r in rows if r.metric == metric}
        means = [values[s].mean if s in values else np.nan for s in sources]
        p95 = [values[s].p95 if s in values else np.nan for s in sources]
        y = np.arange(len(sources))
        ax.barh(y, p95, color="0.75", label="p95")
        ax.barh(y, means, height=0.4, color="C0", label="mean")
        ax.set_yticks(y, sources, fontsize=7)
        ax.invert_yaxis()
        ax.set_title(metric, fontsize=9)
        ax.grid(True, axis="x", alpha=0.3)
    np.atleast_1d(axes)[0].legend(fontsize=7)
    figure.suptitle("error budget: each source alone and all together")
    figure.tight_layout()
    picture = out_dir / "errors_budget.png"
    figure.savefig(picture, dpi=110)
    plt.close(figure)
    return [table, runs_table, picture]


def FormatBudget(rows: list[BudgetRow]) -> str:
    """The budget as a text table."""
    lines = [f"{'source':40} {'metric':36} {'mean':>10} {'p95':>10} {'max':>10} {'runs':>5}"]
    for r in rows:
        lines.append(
            f"{r.source:40} {r.metric:36} {r.mean:10.4g} {r.p95:10.4g} {r.max:10.4g} {r.runs:5d}"
        )
    return "\n".join(lines)


def _AccuracyMetrics(summary: dict[str, Any]) -> list[tuple[str, float]]:
    """(name, value) of a summary's accuracy metrics: its numbers whose name says `error`
    or `repeatability`."""
    return [
        (name, value)
        for name, value in _Scalars(summary)
        if "error" in name or "repeatability" in name
    ]


def _Statistics(source: str, summaries: list[dict[str, Any]]) -> list[BudgetRow]:
    values: dict[str, list[float]] = {}
    for summary in summaries:
        for name, value in _AccuracyMetrics(summary):
            values.setdefault(name, []).append(value)
    success = float(np.mean([s.get("success") is True for s in summaries]))
    return [
        BudgetRow(
            source,
            name,
            float(np.mean(v)),
            float(np.percentile(v, 95)),
            float(np.max(v)),
            len(v),
            success,
        )
        for name, v in sorted(values.items())
    ]


def _Scalars(summary: dict[str, Any], prefix: str = ""):
    """(dotted name, number) of the summary's numbers outside lists and the drawn errors."""
    for key, value in summary.items():
        name = f"{prefix}{key}"
        if key == "errors" and not prefix:
            continue
        if isinstance(value, dict):
            yield from _Scalars(value, f"{name}.")
        elif isinstance(value, int | float) and not isinstance(value, bool):
            yield name, float(value)


def _Merged(base: CameraErrors, override: CameraErrors) -> CameraErrors:
    set_fields = ErrorsAsData(override)
    return dataclasses.replace(base, **{n: getattr(override, n) for n in set_fields})
