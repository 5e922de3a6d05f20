"""The command-line reference page of the documentation site, made from the parsers
themselves (MakeArgumentParser), so that it lists every subcommand and option as
`guidedarm ... --help` prints them."""

from __future__ import annotations

import argparse
import os

from guidedarm.diagrams.cli.main import MakeArgumentParser

# argparse wraps its help to the terminal's width; the page uses a fixed one.
HELP_WIDTH = 100


def CommandLineReference() -> str:
    """The Markdown of the reference: the program's help, then each subcommand's."""
    previous = os.environ.get("COLUMNS")
    os.environ["COLUMNS"] = str(HELP_WIDTH)
    try:
        parser = MakeArgumentParser()
        sections = [
            "# Command-line reference\n",
            "Made from the `guidedarm` parsers: each section is what `guidedarm COMMAND "
            "--help` prints. How the commands fit together, the scenario files and the "
            "exit codes: [Running scenarios](usage.md).\n",
            _Block(parser.format_help()),
        ]
        for name, subparser in _Subcommands(parser).items():
            sections += [f"## guidedarm {name}\n", _Block(subparser.format_help())]
    finally:
        if previous is None:
            os.environ.pop("COLUMNS", None)
        else:
            os.environ["COLUMNS"] = previous
    return "\n".join(sections)


def _Subcommands(parser: argparse.ArgumentParser) -> dict[str, argparse.ArgumentParser]:
    """The subcommand parsers of `parser`, by name, in the order of its help."""
    for action in parser._actions:  # argparse keeps its subparsers only here
        if isinstance(action, argparse._SubParsersAction):
            return dict(action.choices)
    return {}


def _Block(text: str) -> str:
    return f"```text\n{text.rstrip()}\n```\n"
