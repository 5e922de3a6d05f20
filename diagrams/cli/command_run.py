"""`guidedarm run SCENARIO`: load a scenario, run its task, write summary, plots, replay."""

from __future__ import annotations

import argparse
import importlib.metadata
import json
import shlex
import sys
import time
from pathlib import Path
from typing import Any

from pydrake.common.yaml import yaml_dump_typed
from pydrake.geometry import Meshcat

from guidedarm.diagrams.run_context import RESOLVED_SCENARIO_FILE, RealtimeRate, RunContext
from guidedarm.diagrams.run_labels import RunTitle
from guidedarm.diagrams.scenario_loading import (
    ScenarioError,
    apply_overrides,
    load_typed,
    parse_overrides,
    read_raw_scenario,
    resolve_scenario_path,
)
from guidedarm.diagrams.tasks.registry import GetTask
from guidedarm.systems.errors import ConfigurationError, RunFailedError

FAILED = 1


def register(subparsers: argparse._SubParsersAction) -> None:
    parser = subparsers.add_parser("run", help="run a named scenario or a scenario YAML file")
    parser.add_argument("scenario", help="scenario name (see `guidedarm list`) or YAML file")
    parser.add_argument("--out", type=Path, help="output directory (default runs/SCENARIO)")
    parser.add_argument("--meshcat", action="store_true", help="serve Meshcat live and wait")
    parser.add_argument("--hardware", action="store_true", help="drive the real hardware")
    parser.add_argument(
        "--realtime",
        type=float,
        metavar="RATE",
        help="pace the simulation at RATE x real time (0: as fast as possible; "
        "default 1 with --meshcat, else 0)",
    )
    parser.add_argument(
        "--set",
        dest="overrides",
        action="append",
        default=[],
        metavar="KEY=VALUE",
        help="override a scenario key (dotted keys reach nested fields)",
    )
    parser.add_argument(
        "--path-csv",
        type=Path,
        metavar="FILE",
        help="hose centerline CSV for path following (same as --set path_csv=FILE)",
    )
    parser.set_defaults(func=run_command)


def LoadScenario(name_or_path: str, overrides: list[str]) -> tuple[Any, Any, str]:
    """Returns (task, typed scenario, scenario name) for a scenario and `--set` overrides."""
    path = resolve_scenario_path(name_or_path)
    raw = apply_overrides(read_raw_scenario(path), parse_overrides(overrides))
    task_name = raw.get("task")
    if not isinstance(task_name, str):
        raise ScenarioError(f"{path}: missing key 'task' (the task this scenario runs)")
    task = GetTask(task_name)
    return task, load_typed(task.scenario_type, raw, str(path)), path.stem


def run_command(args: argparse.Namespace) -> int:
    if getattr(args, "path_csv", None) is not None:
        args.overrides.append(f"path_csv={json.dumps(str(args.path_csv.resolve()))}")
    task, scenario, name = LoadScenario(args.scenario, args.overrides)
    out_dir = PrepareOutputDirectory(args.out or Path("runs") / name)
    meshcat = Meshcat()
    if args.meshcat:
        print(f"Meshcat: {meshcat.web_url()}", flush=True)
    context = RunContext(out_dir=out_dir, meshcat=meshcat, hardware=args.hardware)
    context.realtime_rate = RealtimeRate(args.realtime, args.meshcat)
    context.title = RunTitle(name, scenario, args.overrides)
    context.write_text(RESOLVED_SCENARIO_FILE, yaml_dump_typed(scenario))
    print(f"guidedarm: running '{name}' (task {task.name}) -> {out_dir}", flush=True)
    wall_start = time.perf_counter()
    try:
        metrics = task.run(scenario, context)
    except RunFailedError as e:
        metrics = {"success": False, "failure": str(e)}
    except KeyboardInterrupt:
        metrics = {"success": False, "failure": "interrupted"}
    metrics["wall_time_s"] = round(time.perf_counter() - wall_start, 3)
    metrics = {"scenario": name, "task": task.name, **metrics, **RunProvenance()}
    context.write_summary(metrics)
    _print_summary(metrics, context)
    if args.meshcat and sys.stdin.isatty():
        input("Meshcat is serving the replay; press Enter to exit.\n")
    failure = metrics.get("failure")
    if failure:
        print(f"guidedarm: run failed: {failure}", file=sys.stderr)
        return FAILED
    return 0


def PrepareOutputDirectory(out_dir: Path) -> Path:
    """Creates the run's output directory, or refuses (ConfigurationError) before the run
    when it names a file, lies under a file, or cannot be written."""
    for parent in [out_dir, *out_dir.parents]:
        if parent.exists() and not parent.is_dir():
            raise ConfigurationError(f"--out {out_dir}: '{parent}' is a file, not a directory")
    try:
        out_dir.mkdir(parents=True, exist_ok=True)
        probe = out_dir / ".guidedarm_write_probe"
        probe.write_text("")
        probe.unlink()
    except OSError as e:
        raise ConfigurationError(f"--out {out_dir}: cannot write there ({e.strerror})") from None
    return out_dir


def RunProvenance() -> dict[str, Any]:
    """What summary.json records of how the run was made: the command line and version."""
    return {
        "command": " ".join(shlex.quote(a) for a in ["guidedarm", *sys.argv[1:]]),
        "version": importlib.metadata.version("guidedarm"),
    }


def _print_summary(metrics: dict[str, Any], context: RunContext) -> None:
    for key, value in metrics.items():
        if not isinstance(value, list | dict):
            print(f"  {key}: {json.dumps(value)}")
    print("wrote:")
    for path in context.written:
        print(f"  {path}")
