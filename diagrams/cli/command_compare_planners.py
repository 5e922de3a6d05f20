"""`guidedarm compare-planners`: the acceleration-level planner against movej, Toppra and Ruckig.

Without --random: one table for a waypoints scenario (default `ur10e_waypoints`, the paper's
task). Every planner moves the arm from the same start through the same waypoints under the
same joint limits: the acceleration-level planner (robust mode, both limits on), the paper's
law (planner.robust false), a UR-controller-like movej with a 0.05 m blend radius, Drake's
Toppra through the planner's IK joint waypoints, and Ruckig (jerk-limited, offline
state-to-state segments with Toppra's via velocities, or at rest at the waypoints where Toppra
found no parameterisation) at the robust planner's own max jerk.
Figures are computed on the commanded trajectories sampled at the planner period: T (s),
max |qd| (rad/s), max |qdd| (rad/s^2), max |jerk| (rad/s^3, finite differences of qdd), and
the closest TCP approach to each waypoint (mm).

With --random N --arm ARM [--seed S] [--kind KIND] [--set KEY=VALUE]: N seeded random
reachable tasks (systems/planning/random_waypoint_tasks.py; the kinds regular,
near_singular, steep in turn, or all of one --kind, including near_limit and large) on the
arm's waypoints scenario (with the overrides), every planner on each, one table:
success rate (the planner ended within 1 mm and 1 mrad and kept every limit; a baseline
found a trajectory), T median, median ratios of T to Ruckig's and Toppra's on the same task,
max |qd|, |qdd|, |jerk| over all tasks, and the number of tasks with a limit breach
(position, velocity or acceleration); then the arm's cell (diagrams/tasks/random_task_cell.py:
near_limit and large tasks are drawn clear of it): tasks refused (a start or waypoint IK
solution colliding), and over the others the tasks ending within 1 mm, the tasks whose
commanded motion touches the cell or the arm (every 10 ms), and the largest oscillation
rate (the planner watch's measure, 1/s).
"""

from __future__ import annotations

import argparse
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

from guidedarm.diagrams.cli.command_run import LoadScenario
from guidedarm.diagrams.run_context import RunContext
from guidedarm.diagrams.scenario_loading import AddOverridesArgument
from guidedarm.diagrams.tasks.random_task_cell import CellFigures, RandomTaskCell
from guidedarm.diagrams.tasks.waypoints import MakePlannerSetup, PlannerSetup, PlotTcpPathsOfJoints
from guidedarm.systems.errors import ConfigurationError, GuidedArmError
from guidedarm.systems.planning.acceleration_planner_math import (
    AccelerationPlanning,
    ClosestApproach,
    PlannerConfig,
    RunPlanning,
)
from guidedarm.systems.planning.planner_baselines import (
    JointTrajectory,
    MoveJ,
    RuckigThroughWaypoints,
    ToppraThroughWaypoints,
)
from guidedarm.systems.planning.random_waypoint_tasks import (
    EXTRA_KINDS,
    KINDS,
    MakeRandomWaypointTasks,
)
from guidedarm.systems.planning.waypoint_ik import SolveWaypointIk

BLEND_RADIUS_M = 0.05
ROBUST, PAPER = "acceleration planner", "paper's law"
MOVEJ = f"movej blend {BLEND_RADIUS_M} m"
ARM_SCENARIOS = {"mz04d": "mz04d_waypoints", "ur10e": "ur10e_waypoints"}
ARM_SCENARIOS["rover_arm"] = "rover_arm_waypoints"
LIMIT_TOLERANCE = 1e-6  # relative: a sample beyond limit * (1 + this) is a breach


def register(subparsers: argparse._SubParsersAction) -> None:
    parser = subparsers.add_parser(
        "compare-planners",
        help="the acceleration-level planner vs the paper's law, movej, Toppra and Ruckig",
    )
    parser.add_argument(
        "--scenario", help="a waypoints scenario (default ur10e_waypoints; not with --random)"
    )
    parser.add_argument("--out", type=Path, help="also write compare_planners.csv and a plot")
    AddOverridesArgument(
        parser, "override a key of the scenario (with --random: of the arm's scenario)"
    )
    parser.add_argument("--random", type=int, metavar="N", help="N seeded random reachable tasks")
    parser.add_argument("--arm", choices=sorted(ARM_SCENARIOS), help="the arm of --random")
    parser.add_argument("--seed", type=int, help="random seed of --random (>= 0, default 0)")
    parser.add_argument(
        "--kind",
        choices=[*KINDS, *EXTRA_KINDS],
        help="all --random tasks of one kind (default: regular, near_singular, steep in turn)",
    )
    parser.set_defaults(func=compare_command)


def Jerk(trajectory: JointTrajectory) -> np.ndarray:
    """Finite differences of the sampled accelerations (rad/s^3)."""
    return np.diff(trajectory.qdd, axis=0) / np.diff(trajectory.times)[:, None]


def PlannerTrajectory(
    planning: AccelerationPlanning, q0: np.ndarray, max_time: float
) -> JointTrajectory | None:
    """The law's commanded trajectory from rest at q0 until the task ended; None if it did
    not end within max_time or stopped with a PlanningError (the paper's law)."""
    try:
        planned = RunPlanning(planning, q0, max_time)
    except GuidedArmError:
        return None
    if planned.done_time < 0:
        return None
    end = int(np.searchsorted(planned.times, planned.done_time - 1e-9)) + 1
    return JointTrajectory(
        planned.times[:end], planned.q[:end], planned.qd[:end], planned.qdd[:end]
    )


def ComparePlanners(
    setup: PlannerSetup, waypoints: np.ndarray, q0: np.ndarray, max_time: float
) -> dict[str, JointTrajectory | None]:
    """Every planner's commanded trajectory for one task (None where a planner failed)."""
    planning = setup.planning
    if planning.scaling is None or planning.penalty is None:
        raise ConfigurationError("compare-planners needs limits=velocity,acceleration")
    margin = planning.parameters.joint_limit_margin
    joints = SolveWaypointIk(planning.kinematics, waypoints, q0, margin=margin)
    trajectories = {
        ROBUST: PlannerTrajectory(_Planning(planning, waypoints, joints, True), q0, max_time),
        PAPER: PlannerTrajectory(_Planning(planning, waypoints, None, False), q0, max_time),
    }
    path = np.vstack([q0, joints])
    v, a = setup.velocity_limit, setup.acceleration_limit
    period = planning.parameters.time_step
    kinematics = planning.kinematics
    trajectories[MOVEJ] = MoveJ(
        path, lambda q: kinematics.Position(q)[:3], v, a, BLEND_RADIUS_M, period
    )
    try:
        trajectories["toppra"], via = ToppraThroughWaypoints(setup.plant, path, v, a, period)
    except GuidedArmError:  # Toppra's grid occasionally finds no parameterisation
        trajectories["toppra"], via = None, np.zeros_like(path)
    reference = trajectories[ROBUST] or trajectories[PAPER]
    trajectories["ruckig"] = None
    if reference is not None:
        jerk = np.full(6, np.abs(Jerk(reference)).max())
        trajectories["ruckig"] = RuckigThroughWaypoints(path, via, v, a, jerk, period)
    return trajectories


def _Planning(
    planning: AccelerationPlanning, waypoints: np.ndarray, joints: np.ndarray | None, robust: bool
) -> AccelerationPlanning:
    """The law of `planning` (kinematics, limits, settings) in the given mode for a task."""
    return AccelerationPlanning(
        planning.kinematics,
        waypoints,
        PlannerConfig(**{**planning.parameters.__dict__, "robust": robust}),
        (planning.penalty.lower, planning.penalty.upper),
        (planning.scaling.lower, planning.scaling.upper),
        joints,
    )


def TableRow(setup: PlannerSetup, trajectory: JointTrajectory) -> dict[str, Any]:
    """T, max |qd|, max |qdd|, max |jerk| and the closest approach to each waypoint."""
    kinematics = setup.planning.kinematics
    tcp = np.array([kinematics.Position(q)[:3] for q in trajectory.q])
    return {
        "T_s": float(trajectory.times[-1]),
        "qd_abs_max": float(np.abs(trajectory.qd).max()),
        "qdd_abs_max": float(np.abs(trajectory.qdd).max()),
        "jerk_abs_max": float(np.abs(Jerk(trajectory)).max()),
        "waypoint_deviation_mm": (1e3 * ClosestApproach(tcp, setup.planning.waypoints)).tolist(),
    }


def Breaches(setup: PlannerSetup, trajectory: JointTrajectory) -> bool:
    """Whether any sample exceeds a position, velocity or acceleration limit."""
    tolerance = 1 + LIMIT_TOLERANCE
    lower, upper = setup.planning.kinematics.PositionLimits()
    return bool(
        np.any(np.abs(trajectory.qd) > setup.velocity_limit * tolerance)
        or np.any(np.abs(trajectory.qdd) > setup.acceleration_limit * tolerance)
        or np.any(trajectory.q < lower - LIMIT_TOLERANCE)
        or np.any(trajectory.q > upper + LIMIT_TOLERANCE)
    )


def RandomComparison(
    arm: str,
    count: int,
    seed: int = 0,
    overrides: Sequence[str] = (),
    kind: str | None = None,
) -> dict[str, dict[str, Any]]:
    """Every planner on `count` random reachable tasks of `arm` (all of `kind` if given):
    one summary per planner; `overrides` (`key=value`) change the arm's waypoints scenario
    (its planner, limits)."""
    scenario = LoadWaypointsScenario(ARM_SCENARIOS[arm], list(overrides))
    setup = MakePlannerSetup(scenario)
    cell = RandomTaskCell(scenario, setup)
    clear = cell.Clear if kind in EXTRA_KINDS else None  # the mixed set stays as it was
    tasks = MakeRandomWaypointTasks(setup.planning.kinematics, count, seed, kind, clear)
    refused = [cell.Refused(task) for task in tasks]
    runs = [ComparePlanners(setup, task.waypoints, task.q0, scenario.max_time) for task in tasks]
    summaries = {}
    for name in runs[0]:
        found = [run[name] for run in runs if run.get(name) is not None]
        times = [run[name].times[-1] for run in runs if run.get(name) is not None]
        breaches = sum(Breaches(setup, t) for t in found)
        ok = len(found) - (breaches if name in (ROBUST, PAPER) else 0)
        summaries[name] = {
            "tasks": count,
            "success_rate": ok / count,
            "T_median_s": float(np.median(times)) if times else None,
            "T_ratio_ruckig": _MedianRatio(runs, name, "ruckig"),
            "T_ratio_toppra": _MedianRatio(runs, name, "toppra"),
            "qd_abs_max": max((float(np.abs(t.qd).max()) for t in found), default=None),
            "qdd_abs_max": max((float(np.abs(t.qdd).max()) for t in found), default=None),
            "jerk_abs_max": max((float(np.abs(Jerk(t)).max()) for t in found), default=None),
            "limit_breaches": breaches,
            **CellFigures(cell, tasks, refused, [run[name] for run in runs]),
        }
    return summaries


def _MedianRatio(runs: list[dict], name: str, reference: str) -> float | None:
    ratios = [
        run[name].times[-1] / run[reference].times[-1]
        for run in runs
        if run.get(name) is not None and run.get(reference) is not None
    ]
    return float(np.median(ratios)) if ratios else None


def PrintRandomTable(arm: str, count: int, summaries: dict[str, dict[str, Any]]) -> None:
    print(f"{count} random reachable tasks on {arm}")
    header = f"{'planner':<22}{'success':>8}{'T med s':>9}{'T/ruckig':>10}{'T/toppra':>10}"
    header += f"{'|qd| max':>10}{'|qdd| max':>11}{'|jerk| max':>12}{'breaches':>10}"
    print(header + f"{'refused':>9}{'in 1 mm':>9}{'contacts':>10}{'osc max':>9}")
    for name, row in summaries.items():
        cells = [f"{name:<22}", f"{100 * row['success_rate']:>7.0f}%"]
        for key, width, digits in (
            ("T_median_s", 9, 2),
            ("T_ratio_ruckig", 10, 3),
            ("T_ratio_toppra", 10, 3),
            ("qd_abs_max", 10, 3),
            ("qdd_abs_max", 11, 3),
            ("jerk_abs_max", 12, 1),
        ):
            value = row[key]
            cells.append(f"{value:>{width}.{digits}f}" if value is not None else f"{'-':>{width}}")
        cells.append(f"{row['limit_breaches']:>10d}{row['refused']:>9d}{row['within_1mm']:>9d}")
        cells.append(f"{row['contacts']:>10d}{row['oscillation_rate_max']:>9.2f}")
        print("".join(cells))


def LoadWaypointsScenario(name: str, overrides: list[str]) -> Any:
    """The typed waypoints scenario `name` with `overrides`; refuses another task."""
    task, scenario, _ = LoadScenario(name, overrides)
    if task.name != "waypoints":
        raise ConfigurationError(
            f"--scenario {name}: compare-planners needs a waypoints scenario, "
            f"this one runs task {task.name}"
        )
    if not scenario.planner.robust:
        raise ConfigurationError(
            "'planner.robust' is not read by compare-planners (it runs both modes): remove it"
        )
    return scenario


def _CheckModeOptions(args: argparse.Namespace) -> None:
    """Refuses an option the chosen mode (--random or one scenario) does not read."""
    if args.random is not None:
        problems = []
        if args.random < 1:
            problems.append(f"--random N needs N >= 1, got {args.random}")
        if args.arm is None:
            problems.append("--random needs --arm ARM")
        if args.scenario is not None:
            problems.append(
                "--scenario is not read with --random (the tasks run on the scenario of --arm)"
            )
        if args.seed is not None and args.seed < 0:
            problems.append(f"--seed must be >= 0, got {args.seed}")
        if problems:
            raise ConfigurationError("; ".join(problems))
        return
    for option in ("arm", "seed", "kind"):
        if getattr(args, option) is not None:
            raise ConfigurationError(f"--{option} is read only with --random N")


def compare_command(args: argparse.Namespace) -> int:
    _CheckModeOptions(args)
    if args.random is not None:
        summaries = RandomComparison(
            args.arm, args.random, args.seed or 0, args.overrides, args.kind
        )
        PrintRandomTable(args.arm, args.random, summaries)
        if args.out:
            context = RunContext(out_dir=args.out)
            keys = list(next(iter(summaries.values())))
            context.write_csv(
                "compare_planners_random",
                ["planner", *keys],
                [[name, *row.values()] for name, row in summaries.items()],
            )
            for path in context.written:
                print(f"wrote {path}")
        return 0
    scenario = LoadWaypointsScenario(args.scenario or "ur10e_waypoints", args.overrides)
    context = RunContext(out_dir=args.out) if args.out else None
    setup = MakePlannerSetup(scenario)
    found = ComparePlanners(setup, setup.planning.waypoints, setup.q0, scenario.max_time)
    trajectories = {name: t for name, t in found.items() if t is not None}
    rows = {name: TableRow(setup, t) for name, t in trajectories.items()}
    count = len(setup.planning.waypoints)
    header = f"{'planner':<22}{'T s':>7}{'|qd| max':>10}{'|qdd| max':>11}{'|jerk| max':>12}"
    header += "".join(f"{f'dev p{i + 1} mm':>12}" for i in range(count))
    print(header)
    for name, row in rows.items():
        line = f"{name:<22}{row['T_s']:>7.2f}{row['qd_abs_max']:>10.3f}"
        line += f"{row['qdd_abs_max']:>11.3f}{row['jerk_abs_max']:>12.1f}"
        line += "".join(f"{d:>12.2f}" for d in row["waypoint_deviation_mm"])
        print(line)
    for name in found:
        if found[name] is None:
            print(f"{name:<22} did not finish the task")
    if context is not None:
        context.write_csv(
            "compare_planners",
            ["planner", "T_s", "qd_abs_max", "qdd_abs_max", "jerk_abs_max"]
            + [f"deviation_p{i + 1}_mm" for i in range(count)],
            [
                [name, row["T_s"], row["qd_abs_max"], row["qdd_abs_max"], row["jerk_abs_max"]]
                + row["waypoint_deviation_mm"]
                for name, row in rows.items()
            ],
        )
        joint_paths = {name: t.q for name, t in trajectories.items()}
        context.save_figure(
            PlotTcpPathsOfJoints(setup, joint_paths, scenario.planner.neighbourhood_radius),
            "compare_tcp_paths",
        )
        for path in context.written:
            print(f"wrote {path}")
    return 0
