"""`guidedarm errors-budget SCENARIO --preset P [--runs N] [--all-only] [--out DIR] [--set K=V]`.

Runs the scenario over N draws of its cell's errors (the presets P and the scenario's own
station.errors), with every source on and then with each source alone, and prints and
writes the error budget: mean, p95 and max of every accuracy metric per source
(DIR/errors_budget.csv, every run's values in DIR/errors_budget_runs.csv,
DIR/errors_budget.png; diagrams/errors_budget.py). Runs are
sequential, in this process.
"""

from __future__ import annotations

import argparse
from pathlib import Path

from guidedarm.diagrams.errors_budget import FormatBudget, RunBudget, WithPreset, WriteBudget
from guidedarm.diagrams.run_context import PrepareOutputDirectory
from guidedarm.diagrams.scenario_loading import AddOverridesArgument
from guidedarm.diagrams.tasks.registry import LoadScenario
from guidedarm.systems.errors import ConfigurationError


def register(subparsers: argparse._SubParsersAction) -> None:
    parser = subparsers.add_parser(
        "errors-budget",
        help="a scenario's accuracy over draws of its cell's errors, per error source",
    )
    parser.add_argument("scenario", help="scenario name (see `guidedarm list`) or YAML file")
    parser.add_argument(
        "--preset", required=True, help="error presets NAME[,NAME] (models/errors/NAME.yaml)"
    )
    parser.add_argument("--runs", type=int, default=10, help="draws per configuration (10)")
    parser.add_argument(
        "--all-only", action="store_true", help="only every source together (no budget)"
    )
    parser.add_argument("--out", type=Path, help="output directory (default runs/budget-NAME)")
    AddOverridesArgument(parser, "override a scenario key (dotted keys reach nested fields)")
    parser.set_defaults(func=errors_budget_command)


def errors_budget_command(args: argparse.Namespace) -> int:
    if args.runs < 1:
        raise ConfigurationError(f"--runs must be >= 1, got {args.runs}")
    task, scenario, name = LoadScenario(args.scenario, args.overrides)
    scenario = WithPreset(scenario, args.preset)
    out_dir = PrepareOutputDirectory(args.out or Path("runs") / f"budget-{name}")
    rows, values = RunBudget(
        task,
        scenario,
        args.runs,
        lambda text: print(f"  {text}", flush=True),
        each_source=not args.all_only,
        done=lambda rows, values: WriteBudget(rows, values, out_dir),
    )
    print(FormatBudget(rows))
    print("wrote:")
    for path in WriteBudget(rows, values, out_dir):
        print(f"  {path}")
    return 0
