"""The `guidedarm` command line. Each `diagrams/cli/command_*.py` module adds one subcommand.

Exit codes, for every subcommand: 0 done; 1 a run that started failed (its summary.json
says why); 2 bad input or configuration, refused with one line on stderr (argument errors
included); 1 also for an internal error outside a run (a failed Drake check, one
line); 130 interrupted (Ctrl-C or SIGTERM) outside a run; 141 stdout closed early
(e.g. `| head -1`).
"""

from __future__ import annotations

import argparse
import gc
import importlib
import os
import pkgutil
import sys
import threading

import guidedarm.diagrams.cli as cli_package
from guidedarm.diagrams.interrupts import DeferredInterrupts, InstallInterruptHandlers
from guidedarm.systems.errors import ConfigurationError, DrakeCheckFailure, GuidedArmError
from guidedarm.systems.hardware.arm_link import (
    CloseAllArmLinks,
    ReportStopErrors,
    VendorThreadsAlive,
)

EXIT_RUN_FAILED = 1
EXIT_BAD_INPUT = 2
EXIT_INTERRUPTED = 130
EXIT_BROKEN_PIPE = 141


class OneLineArgumentParser(argparse.ArgumentParser):
    """An ArgumentParser whose errors are one line (a ConfigurationError), not usage text
    and SystemExit; its subcommand parsers are of the same class."""

    def error(self, message: str):
        command = self.prog.removeprefix("guidedarm").strip()
        where = f"{command}: " if command else ""
        raise ConfigurationError(f"{where}{message} (see {self.prog} --help)")


def MakeArgumentParser() -> argparse.ArgumentParser:
    """The parser with every discovered subcommand."""
    parser = OneLineArgumentParser(
        prog="guidedarm", description="Drake diagrams for sensor-guided industrial arms."
    )
    subparsers = parser.add_subparsers(dest="command", required=True)
    for module_info in sorted(pkgutil.iter_modules(cli_package.__path__), key=_name):
        if module_info.name.startswith("command_"):
            module = importlib.import_module(f"guidedarm.diagrams.cli.{module_info.name}")
            module.register(subparsers)
    return parser


def main(argv: list[str] | None = None) -> int:
    """Entry point of the `guidedarm` console script (argv None: the process is the
    command's) and of in-process calls (argv given)."""
    code = _Command(argv)
    if argv is None and VendorThreadsAlive():
        # A thread is still inside a vendor library (a controller that stopped answering
        # its disconnect): the interpreter's teardown could destroy what that thread uses
        # and crash the process after its summary was written. End it without teardown.
        sys.stdout.flush()
        sys.stderr.flush()
        os._exit(code)
    return code


def _Command(argv: list[str] | None) -> int:
    """Parses argv (None: sys.argv) and runs the subcommand; returns the exit code."""
    if threading.current_thread() is threading.main_thread():
        InstallInterruptHandlers()
    try:
        args = MakeArgumentParser().parse_args(argv)
        args.argv = list(sys.argv[1:] if argv is None else argv)  # for the run's summary
        code = int(args.func(args) or 0)
        sys.stdout.flush()  # a closed pipe shows here, not at interpreter exit
        return code
    except GuidedArmError as e:
        print(f"guidedarm: error: {e}", file=sys.stderr)
        return EXIT_BAD_INPUT
    except KeyboardInterrupt:
        print("guidedarm: interrupted", file=sys.stderr)
        return EXIT_INTERRUPTED
    except SystemExit as e:  # a failed Drake check outside a run (a run reports its own)
        failure = DrakeCheckFailure(e)
        if failure is None:
            raise
        print(f"guidedarm: internal error: {failure}", file=sys.stderr)
        return EXIT_RUN_FAILED
    except BrokenPipeError:
        # The reader left; send what Python still has to flush into the void, silently.
        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
        return EXIT_BROKEN_PIPE
    finally:
        with DeferredInterrupts():  # a signal now would cut the cleanup with a traceback
            ReportStopErrors(CloseAllArmLinks(), "at the end of the command")
            # Drake objects such as Meshcat must be destroyed on the thread that made them;
            # a reference cycle left to the collector could be freed on any thread.
            gc.collect()


def _name(module_info: pkgutil.ModuleInfo) -> str:
    return module_info.name


if __name__ == "__main__":
    sys.exit(main())
