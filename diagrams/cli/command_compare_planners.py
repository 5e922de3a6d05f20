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
(position, velocity or acceleration); then the arm's cell (diagrams/studies/random_task_cell.py:
near_limit and large tasks are drawn clear of it): tasks refused (a start or waypoint IK
solution colliding; for the robust planner also a task with no route clear of the cell, its
route chosen as a run chooses it, diagrams/tasks/common/planner_route.py), and over the
others the tasks ending within 1 mm, the tasks whose commanded motion touches the cell or
the arm (every 10 ms), and the largest oscillation rate (the planner watch's measure, 1/s).
"""

from __future__ import annotations

import argparse
from pathlib import Path

from guidedarm.diagrams.run_context import RunContext
from guidedarm.diagrams.scenario_loading import AddOverridesArgument
from guidedarm.diagrams.studies.planner_comparison import (
    ARM_SCENARIOS,
    ComparePlanners,
    LoadWaypointsScenario,
    PrintRandomTable,
    RandomComparison,
    TableRow,
)
from guidedarm.diagrams.tasks.waypoints import MakePlannerSetup
from guidedarm.diagrams.tasks.waypoints.report import PlotTcpPathsOfJoints
from guidedarm.systems.errors import ConfigurationError
from guidedarm.systems.planning.random_waypoint_tasks import EXTRA_KINDS, KINDS


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
