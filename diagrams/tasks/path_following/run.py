"""Task `path_following`: follow a hose with the six-sensor ToF tool of Wawrzyniak et al.
("Three-Dimensional Path-Following with Articulated 6DoF Robot and ToF Sensors", 2025).

The hose comes from a named path (`paper_path_1..4`, any models/hoses/NAME.csv), a CSV file
(`path_csv`, also the `--path-csv` flag) or a seeded random path (`random_<seed>`), in the
arm's base frame, inside the `workspace` walls. The tool starts at the hose's first point,
its x axis along the hose; the arm's start joints come from the IK. The run ends at the end
of the hose (the follower loses it and every retry fails) or at the first failure; the
summary compares what the follower saw and did with the true centerline.
"""

import dataclasses
from collections.abc import Collection
from typing import Any

import numpy as np

from guidedarm.diagrams.run_context import RunContext
from guidedarm.diagrams.tasks.path_following.execution import Execute, Execution
from guidedarm.diagrams.tasks.path_following.report import (
    FOLLOWING_METRICS,
    TRUE_METRICS,
    DetectedPath,
    Metrics,
    PlotDetectedPath,
    Repeatability,
    SpeedAndErrorAlongPath,
    TrueMetrics,
)
from guidedarm.diagrams.tasks.path_following.scenario import PathFollowingScenario
from guidedarm.diagrams.tasks.path_following.setup import IsRandomHose, MakeSetup, Setup
from guidedarm.diagrams.tasks.registry import RunFlags, TaskDefinition
from guidedarm.systems.errors import ConfigurationError
from guidedarm.systems.path_following.path_follower_math import RECORD_FIELDS
from guidedarm.systems.scene.hose_geometry import WriteCenterline


def RunPathFollowing(
    scenario: PathFollowingScenario, context: RunContext, prepared: Setup | None = None
) -> dict[str, Any]:
    """Runs the follower on `prepared` (the task's prepare: MakeSetup(scenario), which
    writes nothing into the run's folder; made here when None), a second time with
    repeat_random_seed on a setup of its own, and returns the summary metrics; a random
    hose is written to DIR/hose.csv."""
    repeat_seed = scenario.repeat_random_seed
    setup = prepared or MakeSetup(scenario)
    if IsRandomHose(scenario):
        WriteCenterline(setup.centerline_B, context.out_dir / "hose.csv")
    execution = Execute(setup, scenario.executor, context)
    centerline = setup.centerline
    metrics = Metrics(execution.records, centerline, scenario.motion == "continuous")
    truth = execution.truth
    true_metrics = {} if truth is None else TrueMetrics(truth.p_WO, centerline)
    if truth is not None:
        true_metrics["true_collisions"] = truth.collisions
    # A touch of the true robot fails the run; without truth (hardware), one of the believed.
    touches = execution.collisions if truth is None else truth.collisions
    failure = execution.failure
    if failure is None and touches:
        failure = f"the robot touched the hose during {touches} step(s)"
    if failure is None and metrics["coverage"] < scenario.min_coverage:
        failure = (
            f"hose lost after step {metrics['steps'] - 1}: coverage "
            f"{metrics['coverage']:.2f} < {scenario.min_coverage}"
        )
    runs = {f"detected (random_seed {scenario.random_seed})": DetectedPath(execution.records)}
    summary = {
        "success": failure is None,
        **metrics,
        "collisions": execution.collisions,
        **true_metrics,
        "estimator": scenario.estimator,
        "executor": scenario.executor,
        "motion": scenario.motion,
        "failure": failure,
        "sim_time_s": round(execution.sim_time, 3),
        # simulated over wall-clock time of the follower's loop (setup and report excluded)
        "realtime_factor": round(execution.sim_time / max(execution.wall_time, 1e-9), 2),
    }
    context.headline = summary  # the figures below print its headline figures
    if repeat_seed is not None and not execution.aborted:
        second_setup = MakeSetup(dataclasses.replace(scenario, random_seed=repeat_seed))
        second = Execute(second_setup, scenario.executor, context)
        runs[f"detected (random_seed {repeat_seed})"] = DetectedPath(second.records)
        first_path, second_path = runs.values()
        mean, worst = Repeatability(first_path, second_path)
        summary["repeatability_mean_mm"], summary["repeatability_max_mm"] = mean, worst
        context.save_figure(
            PlotDetectedPath(centerline, runs, "two runs overlaid"), "repeatability"
        )
    first = dict(list(runs.items())[:1])
    context.save_figure(
        PlotDetectedPath(
            centerline,
            first,
            f"{scenario.path_csv or scenario.path}: {scenario.estimator} estimator",
        ),
        "detected_path",
    )
    context.save_figure(
        SpeedAndErrorAlongPath(
            execution.records, centerline, f"{scenario.motion}: speed and tracking error"
        ),
        "speed_along_path",
    )
    WriteSteps(context, execution)
    return summary


def WriteSteps(context: RunContext, execution: Execution) -> None:
    """steps.csv: the step records (RECORD_FIELDS), with the true tool centre
    (`true_O_x`, `_y`, `_z`, m) beside them when the run has truth."""
    if execution.truth is None:
        context.write_csv("steps", RECORD_FIELDS, execution.records.tolist())
        return
    rows = np.column_stack([execution.records, execution.truth.p_WO])
    context.write_csv("steps", [*RECORD_FIELDS, "true_O_x", "true_O_y", "true_O_z"], rows.tolist())


def CheckRun(scenario: PathFollowingScenario, flags: RunFlags) -> None:
    """Refuses (before the run) what the scenario cannot do with the run's flags: the
    kinematic executor with --hardware (it drives no arm) or a live --meshcat page (it draws
    nothing during the run), and against hardware the continuous motion with a `move`
    driver or a servo period other than the arm's control period."""
    if scenario.executor == "kinematic" and flags.hardware:
        raise ConfigurationError(
            "executor=kinematic cannot run with --hardware: it poses a model and drives no "
            "arm (use executor=station)"
        )
    if scenario.executor == "kinematic" and flags.live:
        raise ConfigurationError(
            "executor=kinematic cannot be watched with --meshcat: it draws nothing in Meshcat "
            "(use executor=station)"
        )
    link = scenario.station.hardware.arms.get(scenario.arm)
    if scenario.motion == "continuous" and flags.hardware and link and link.command_mode == "move":
        raise ConfigurationError(
            f"motion=continuous streams a target every servo period: station.hardware.arms."
            f"{scenario.arm}.command_mode must be 'stream', not 'move'"
        )
    control_period = scenario.station.arms[scenario.arm].control_period
    if (
        scenario.motion == "continuous"
        and flags.hardware
        and scenario.continuous.servo_period != control_period
    ):
        raise ConfigurationError(
            f"with --hardware, continuous.servo_period ({scenario.continuous.servo_period} s) "
            f"must equal station.arms.{scenario.arm}.control_period ({control_period} s): the "
            "driver streams each command it samples, and a command held over two samples "
            "reads as a velocity step"
        )


def CheckOverrides(scenario: PathFollowingScenario, keys: Collection[str]) -> None:
    """Refuses `--set path` beside a path_csv (which overrides it), and `--set random_path.*`
    when the hose is not random_<seed> (a scenario file may keep its arm's random_path
    region beside a named hose)."""
    if scenario.path_csv and "path" in keys:
        raise ConfigurationError(
            f"'path' has no effect with path_csv (--path-csv) set ('{scenario.path_csv}', "
            "which overrides it): give one of them"
        )
    if not IsRandomHose(scenario):
        for key in keys:
            if key.split(".")[0] == "random_path":
                raise ConfigurationError(
                    f"'{key}' has no effect with the hose "
                    f"'{scenario.path_csv or scenario.path}' (it shapes path=random_<seed> "
                    "only): remove it or set a random path"
                )


def WithoutReplacedPath(scenario: PathFollowingScenario) -> PathFollowingScenario:
    """The scenario with `path` cleared when `path_csv` (which replaces it) is set."""
    return dataclasses.replace(scenario, path="") if scenario.path_csv else scenario


# The numbers of RunPathFollowing's summary (TaskDefinition.metrics); the repeatability
# figures only with repeat_random_seed.
PATH_FOLLOWING_METRICS = {
    **FOLLOWING_METRICS,
    "collisions": (
        "count",
        "steps during which the robot penetrated the hose, the nominal arm posed at its "
        "measured joints (samples every 20 ms); any fails a run without truth (hardware)",
    ),
    **TRUE_METRICS,
    "true_collisions": (
        "count",
        "collisions of the true arm (the simulated plant's state, samples every 20 ms) with "
        "the hose; any fails the run",
    ),
    "sim_time_s": ("s", "simulated time of the run"),
    "realtime_factor": ("ratio", "simulated over wall-clock time of the follower's loop"),
    "repeatability_mean_mm": (
        "mm",
        "with repeat_random_seed: mean distance between the detected paths of the two runs",
    ),
    "repeatability_max_mm": (
        "mm",
        "with repeat_random_seed: largest distance between the two detected paths",
    ),
}

TASK = TaskDefinition(
    name="path_following",
    scenario_type=PathFollowingScenario,
    run=RunPathFollowing,
    description="follow a hose with the six-sensor ToF tool (Wawrzyniak et al.) on any arm",
    station=lambda scenario: MakeSetup(scenario).station,
    prepare=MakeSetup,
    check_overrides=CheckOverrides,
    metrics=PATH_FOLLOWING_METRICS,
    check_run=CheckRun,
    resolve=WithoutReplacedPath,
)
