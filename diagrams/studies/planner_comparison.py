"""The acceleration-level planner against the paper's law, movej, Toppra and Ruckig
(`guidedarm compare-planners`): every planner's commanded trajectory for one task
(ComparePlanners), its figures (TableRow, Breaches), and the comparison on seeded random
reachable tasks (RandomComparison, PrintRandomTable). The command's docstring
(diagrams/cli/command_compare_planners.py) describes the planners and the figures."""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np

from guidedarm.diagrams.studies.random_task_cell import CellFigures, RandomTaskCell
from guidedarm.diagrams.tasks.common.cell_collisions import CellCollisions
from guidedarm.diagrams.tasks.common.planner_route import RouteClearOfCell
from guidedarm.diagrams.tasks.registry import LoadScenario
from guidedarm.diagrams.tasks.waypoints import MakePlannerSetup, PlannerSetup
from guidedarm.systems.errors import ConfigurationError, GuidedArmError
from guidedarm.systems.planning.acceleration_planner_math import (
    AccelerationPlanning,
    ClosestApproach,
    PlannerConfig,
    RunPlanning,
)
from guidedarm.systems.planning.acceleration_planner_state import PlannedTrajectory
from guidedarm.systems.planning.planner_baselines import (
    JointTrajectory,
    MoveJ,
    RuckigThroughWaypoints,
    ToppraThroughWaypoints,
)
from guidedarm.systems.planning.random_waypoint_tasks import EXTRA_KINDS, MakeRandomWaypointTasks
from guidedarm.systems.planning.waypoint_ik import SolveWaypointIk

BLEND_RADIUS_M = 0.05
ROBUST, PAPER = "acceleration planner", "paper's law"
MOVEJ = f"movej blend {BLEND_RADIUS_M} m"
ARM_SCENARIOS = {"mz04d": "mz04d_waypoints", "ur10e": "ur10e_waypoints"}
ARM_SCENARIOS["rover_arm"] = "rover_arm_waypoints"
LIMIT_TOLERANCE = 1e-6  # relative: a sample beyond limit * (1 + this) is a breach


def Jerk(trajectory: JointTrajectory) -> np.ndarray:
    """Finite differences of the sampled accelerations (rad/s^3)."""
    return np.diff(trajectory.qdd, axis=0) / np.diff(trajectory.times)[:, None]


def PlannerTrajectory(
    planning: AccelerationPlanning, q0: np.ndarray, max_time: float
) -> JointTrajectory | None:
    """The law's commanded trajectory from rest at q0 until the task ended; None if it did
    not end within max_time or stopped with a PlanningError (the paper's law)."""
    try:
        return FinishedTrajectory(RunPlanning(planning, q0, max_time))
    except GuidedArmError:
        return None


def FinishedTrajectory(planned: PlannedTrajectory) -> JointTrajectory | None:
    """A planned trajectory up to the end of its task; None if the task did not end."""
    if planned.done_time < 0:
        return None
    end = int(np.searchsorted(planned.times, planned.done_time - 1e-9)) + 1
    return JointTrajectory(
        planned.times[:end], planned.q[:end], planned.qd[:end], planned.qdd[:end]
    )


def ComparePlanners(
    setup: PlannerSetup,
    waypoints: np.ndarray,
    q0: np.ndarray,
    max_time: float,
    collisions: CellCollisions | None = None,
) -> dict[str, JointTrajectory | None]:
    """Every planner's commanded trajectory for one task (None where a planner failed);
    with the cell's `collisions`, the robust planner's route is chosen as a run chooses it
    (RouteClearOfCell; its ConfigurationError when the task is refused before motion)."""
    planning = setup.planning
    if planning.scaling is None or planning.penalty is None:
        raise ConfigurationError("compare-planners needs limits=velocity,acceleration")
    margin = planning.parameters.joint_limit_margin
    joints = SolveWaypointIk(planning.kinematics, waypoints, q0, margin=margin)
    robust = _Planning(planning, waypoints, joints, True)
    if collisions is None:
        robust_trajectory = PlannerTrajectory(robust, q0, max_time)
    else:
        robust_trajectory = FinishedTrajectory(
            RouteClearOfCell(robust, q0, max_time, collisions).planned
        )
    trajectories = {
        ROBUST: robust_trajectory,
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
    runs, route_refused = [], []
    for task, configuration_refused in zip(tasks, refused, strict=True):
        # a task whose start or waypoint configuration collides has no route to choose
        collisions = None if configuration_refused else cell.collisions
        try:
            run = ComparePlanners(setup, task.waypoints, task.q0, scenario.max_time, collisions)
            route_refused.append(False)
        except ConfigurationError:  # no route clear of the cell: refused before motion
            run = ComparePlanners(setup, task.waypoints, task.q0, scenario.max_time)
            run[ROBUST] = None
            route_refused.append(True)
        runs.append(run)
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
            **CellFigures(
                cell,
                tasks,
                [a or (b and name == ROBUST) for a, b in zip(refused, route_refused, strict=True)],
                [run[name] for run in runs],
            ),
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
