"""The `guidedarm` command line. Each `diagrams/cli/command_*.py` module adds one subcommand.

Exit codes: 0 done, 1 the run failed (summary.json says why), 2 bad input or configuration.
"""

from __future__ import annotations

import argparse
import importlib
import pkgutil
import sys

import guidedarm.diagrams.cli as cli_package
from guidedarm.systems.errors import GuidedArmError

EXIT_RUN_FAILED = 1
EXIT_BAD_INPUT = 2


def MakeArgumentParser() -> argparse.ArgumentParser:
    """The parser with every discovered subcommand."""
    parser = argparse.ArgumentParser(
        prog="guidedarm", description="Drake diagrams for sensor-guided industrial arms."
    )
    subparsers = parser.add_subparsers(dest="command", required=True)
    for module_info in sorted(pkgutil.iter_modules(cli_package.__path__), key=_name):
        if module_info.name.startswith("command_"):
            module = importlib.import_module(f"guidedarm.diagrams.cli.{module_info.name}")
            module.register(subparsers)
    return parser


def main(argv: list[str] | None = None) -> int:
    """Entry point of the `guidedarm` console script."""
    args = MakeArgumentParser().parse_args(argv)
    try:
        return int(args.func(args) or 0)
    except GuidedArmError as e:
        print(f"guidedarm: error: {e}", file=sys.stderr)
        return EXIT_BAD_INPUT
    except KeyboardInterrupt:
        print("guidedarm: interrupted", file=sys.stderr)
        return 130


def _name(module_info: pkgutil.ModuleInfo) -> str:
    return module_info.name


if __name__ == "__main__":
    sys.exit(main())
