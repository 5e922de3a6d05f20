"""`guidedarm compare-planners`: the seed-001 planner against movej and Toppra, one table.

All three move the UR10e of `ur10e_waypoints` (or another waypoints scenario) from the
same start through the same waypoints under the same joint limits: the acceleration-level
planner (both limits on), a UR-controller-like movej with a 0.05 m blend radius, and
Drake's Toppra through the planner's IK joint waypoints. Figures are computed on the
commanded trajectories sampled at the planner period: T (s), max |qd| (rad/s), max |qdd|
(rad/s^2), max |jerk| (rad/s^3, finite differences of qdd), and the closest TCP approach
to each waypoint (mm).
"""

from __future__ import annotations

import argparse
from pathlib import Path
from typing import Any

import numpy as np

from guidedarm.diagrams.cli.command_run import LoadScenario
from guidedarm.diagrams.run_context import RunContext
from guidedarm.diagrams.tasks.waypoints import MakePlannerSetup, PlannerSetup, PlotTcpPathsOfJoints
from guidedarm.systems.errors import ConfigurationError
from guidedarm.systems.planning.acceleration_planner_math import ClosestApproach, RunPlanning
from guidedarm.systems.planning.planner_baselines import (
    JointTrajectory,
    MoveJ,
    ToppraThroughWaypoints,
)

BLEND_RADIUS_M = 0.05


def register(subparsers: argparse._SubParsersAction) -> None:
    parser = subparsers.add_parser(
        "compare-planners", help="the seed-001 planner vs movej (blend 0.05 m) and Toppra"
    )
    parser.add_argument("--scenario", default="ur10e_waypoints", help="a waypoints scenario")
    parser.add_argument("--out", type=Path, help="also write compare_planners.csv and a plot")
    parser.add_argument("--set", dest="overrides", action="append", default=[], metavar="KEY=VALUE")
    parser.set_defaults(func=compare_command)


def ComparePlanners(setup: PlannerSetup, max_time: float) -> dict[str, JointTrajectory]:
    """The three commanded trajectories, each ending when its task ends."""
    planning = setup.planning
    period = planning.parameters.time_step
    if planning.scaling is None or planning.penalty is None:
        raise ConfigurationError("compare-planners needs limits=velocity,acceleration")
    planned = RunPlanning(planning, setup.q0, max_time)
    if planned.done_time < 0:
        raise ConfigurationError(f"the planner did not finish within {max_time} s")
    end = int(np.searchsorted(planned.times, planned.done_time - 1e-9)) + 1
    joint_waypoints = np.vstack([setup.q0, setup.joint_waypoints])
    kinematics = planning.kinematics
    return {
        "acceleration planner": JointTrajectory(
            planned.times[:end], planned.q[:end], planned.qd[:end], planned.qdd[:end]
        ),
        f"movej blend {BLEND_RADIUS_M} m": MoveJ(
            joint_waypoints,
            lambda q: kinematics.Position(q)[:3],
            setup.velocity_limit,
            setup.acceleration_limit,
            BLEND_RADIUS_M,
            period,
        ),
        "toppra": ToppraThroughWaypoints(
            setup.plant, joint_waypoints, setup.velocity_limit, setup.acceleration_limit, period
        ),
    }


def TableRow(setup: PlannerSetup, trajectory: JointTrajectory) -> dict[str, Any]:
    """T, max |qd|, max |qdd|, max |jerk| and the closest approach to each waypoint."""
    kinematics = setup.planning.kinematics
    period = setup.planning.parameters.time_step
    tcp = np.array([kinematics.Position(q)[:3] for q in trajectory.q])
    jerk = np.diff(trajectory.qdd, axis=0) / period
    return {
        "T_s": float(trajectory.times[-1]),
        "qd_abs_max": float(np.abs(trajectory.qd).max()),
        "qdd_abs_max": float(np.abs(trajectory.qdd).max()),
        "jerk_abs_max": float(np.abs(jerk).max()),
        "waypoint_deviation_mm": (1e3 * ClosestApproach(tcp, setup.planning.waypoints)).tolist(),
    }


def compare_command(args: argparse.Namespace) -> int:
    task, scenario, _ = LoadScenario(args.scenario, args.overrides)
    if task.name != "waypoints":
        raise ConfigurationError(
            f"--scenario {args.scenario}: compare-planners needs a waypoints scenario, "
            f"this one runs task {task.name}"
        )
    context = RunContext(out_dir=args.out) if args.out else None
    setup = MakePlannerSetup(scenario)
    trajectories = ComparePlanners(setup, scenario.max_time)
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
