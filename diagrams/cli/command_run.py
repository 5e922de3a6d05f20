"""`guidedarm run SCENARIO`: load a scenario, run its task, write summary, plots, replay.

The run contract, all of it here:
  - refused before the run (bad scenario, bad flags, a setting the task cannot honour,
    what its models refuse: the task's prepare, PrepareRun; then an output directory that
    cannot be written): one line on stderr, exit 2, no summary, nothing written;
  - a run that started ends with DIR/summary.json: exit 0, or exit 1 with `failure` set
    (a failed task, a RunFailedError such as a hardware fault, Ctrl-C as
    `failure: interrupted`, non-finite metrics, or an internal error whose traceback goes
    to DIR/traceback.txt).
"""

from __future__ import annotations

import argparse
import importlib.metadata
import json
import math
import shlex
import sys
from pathlib import Path
from typing import Any

from guidedarm.diagrams.interrupts import DeferredInterrupts, RaiseIfInterrupted, TakeInterrupt
from guidedarm.diagrams.run_context import (
    MakeMeshcat,
    PrepareOutputDirectory,
    RealtimeRate,
    RunContext,
    ServeMeshcat,
)
from guidedarm.diagrams.run_labels import RunTitle
from guidedarm.diagrams.run_preparation import PrepareRun
from guidedarm.diagrams.scenario_loading import (
    AddOverridesArgument,
    parse_overrides,
)
from guidedarm.diagrams.task_run import InterruptedFailure, RunPrepared
from guidedarm.diagrams.tasks.registry import LoadScenario, RunFlags
from guidedarm.systems.errors import ConfigurationError

FAILED = 1


def register(subparsers: argparse._SubParsersAction) -> None:
    parser = subparsers.add_parser("run", help="run a named scenario or a scenario YAML file")
    parser.add_argument("scenario", help="scenario name (see `guidedarm list`) or YAML file")
    parser.add_argument("--out", type=Path, help="output directory (default runs/SCENARIO)")
    AddMeshcatArguments(parser)
    parser.add_argument("--hardware", action="store_true", help="drive the real hardware")
    parser.add_argument(
        "--realtime",
        type=float,
        metavar="RATE",
        help="pace the simulation at RATE x real time (0: as fast as possible; "
        "default 1 with --meshcat, else 0)",
    )
    AddOverridesArgument(parser, "override a scenario key (dotted keys reach nested fields)")
    parser.add_argument(
        "--path-csv",
        type=Path,
        metavar="FILE",
        help="hose centerline CSV for path following (same as --set path_csv=FILE)",
    )
    parser.set_defaults(func=run_command)


def AddMeshcatArguments(parser: argparse.ArgumentParser) -> None:
    """--meshcat, --meshcat-host and --meshcat-wait (see CheckMeshcatArguments)."""
    parser.add_argument(
        "--meshcat",
        action="store_true",
        help="serve Meshcat live during the run and keep serving after it",
    )
    parser.add_argument(
        "--meshcat-host",
        metavar="HOST",
        help="with --meshcat: the address Meshcat listens on (default localhost)",
    )
    parser.add_argument(
        "--meshcat-wait",
        type=float,
        metavar="SECONDS",
        help="with --meshcat: stop serving this long after the run (default: at Ctrl-C)",
    )


def CheckMeshcatArguments(args: argparse.Namespace) -> None:
    """Refuses --meshcat-host or --meshcat-wait without --meshcat, and a bad wait."""
    given = {"--meshcat-host": args.meshcat_host, "--meshcat-wait": args.meshcat_wait}
    for flag, value in given.items():
        if value is not None and not args.meshcat:
            raise ConfigurationError(f"{flag} needs --meshcat")
    if args.meshcat_wait is not None and not 0 <= args.meshcat_wait < math.inf:
        raise ConfigurationError(f"--meshcat-wait must be >= 0 s, got {args.meshcat_wait}")
    if args.meshcat_host is not None and not args.meshcat_host.strip():
        raise ConfigurationError("--meshcat-host must not be empty")


def run_command(args: argparse.Namespace) -> int:
    CheckMeshcatArguments(args)
    keys = parse_overrides(args.overrides).keys()
    if getattr(args, "path_csv", None) is not None:
        if "path_csv" in keys:
            raise ConfigurationError("--path-csv and --set path_csv both given: give one")
        args.overrides.append(f"path_csv={json.dumps(str(args.path_csv.resolve()))}")
    task, scenario, name = LoadScenario(args.scenario, args.overrides)
    hardware_keys = sorted(k for k in keys if k.split(".")[:2] == ["station", "hardware"])
    if hardware_keys and not args.hardware:
        raise ConfigurationError(
            f"--set {hardware_keys[0]} has no effect without --hardware (a simulated run "
            "reads no driver setting): remove it or add --hardware"
        )
    flags = RunFlags(args.hardware, live=args.meshcat, realtime=args.realtime is not None)
    prepared = PrepareRun(task, scenario, flags)
    meshcat = MakeMeshcat(args.meshcat, args.meshcat_host or "localhost")
    context = RunContext(
        out_dir=PrepareOutputDirectory(args.out or Path("runs") / name), hardware=args.hardware
    )
    context.meshcat = meshcat
    context.live = args.meshcat
    if args.meshcat:
        print(f"Meshcat: {context.meshcat.web_url()}", flush=True)
    context.realtime_rate = RealtimeRate(args.realtime, args.meshcat)
    context.title = RunTitle(name, scenario, args.overrides)
    print(f"guidedarm: running '{name}' (task {task.name}) -> {context.out_dir}", flush=True)
    try:
        metrics = RunPrepared(prepared, context)
    except KeyboardInterrupt as e:  # arrived as RunPrepared returned: the run still gets a summary
        metrics = {"success": False, "failure": InterruptedFailure(e)}
    with DeferredInterrupts():  # the run is over; what it did is written whole
        metrics = {"scenario": name, "task": task.name, **metrics, **RunProvenance(args.argv)}
        context.write_summary(metrics)
        _print_summary(metrics, context)
    if args.meshcat:
        RaiseIfInterrupted()  # one that came as the run ended ends the command, not a page
        ServeMeshcat(context.meshcat, args.meshcat_wait)
    TakeInterrupt()  # one that came after the run: its summary stands
    failure = metrics.get("failure")
    if failure:
        print(f"guidedarm: run failed: {failure}", file=sys.stderr)
        return FAILED
    return 0


def RunProvenance(argv: list[str] | None = None) -> dict[str, Any]:
    """What summary.json records of how the run was made: the command line (`argv`, the
    arguments given to main; default the process's) and the version."""
    argv = sys.argv[1:] if argv is None else argv
    return {
        "command": " ".join(shlex.quote(a) for a in ["guidedarm", *argv]),
        "version": importlib.metadata.version("guidedarm"),
    }


def _print_summary(metrics: dict[str, Any], context: RunContext) -> None:
    for key, value in metrics.items():
        if not isinstance(value, list | dict):
            print(f"  {key}: {json.dumps(value)}")
    print("wrote:")
    for path in context.written:
        print(f"  {path}")
