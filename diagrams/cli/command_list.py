"""`guidedarm list`: the named scenarios and the tasks they run."""

from __future__ import annotations

import argparse

from guidedarm.diagrams.scenario_loading import (
    SCENARIO_DIR,
    list_named_scenarios,
    read_raw_scenario,
)
from guidedarm.diagrams.tasks.registry import AvailableTasks


def register(subparsers: argparse._SubParsersAction) -> None:
    parser = subparsers.add_parser("list", help="list the named scenarios and tasks")
    parser.set_defaults(func=list_command)


def list_command(args: argparse.Namespace) -> int:
    tasks = AvailableTasks()
    print("scenarios:")
    for name in list_named_scenarios():
        task = read_raw_scenario(SCENARIO_DIR / f"{name}.yaml").get("task", "?")
        print(f"  {name:28s} task {task}")
    print("tasks:")
    for task in tasks.values():
        print(f"  {task.name:28s} {task.description}")
    return 0
