"""`guidedarm demo-index RUNS_DIR`: one page with every run's metrics, plots and replay."""

from __future__ import annotations

import argparse
from pathlib import Path

from guidedarm.diagrams.demo_index import WriteDemoIndex


def register(subparsers: argparse._SubParsersAction) -> None:
    parser = subparsers.add_parser(
        "demo-index", help="write RUNS_DIR/index.html: every run's metrics, plots and replay"
    )
    parser.add_argument("runs_dir", type=Path, nargs="?", default=Path("runs"))
    parser.set_defaults(func=demo_index_command)


def demo_index_command(args: argparse.Namespace) -> int:
    print(f"wrote {WriteDemoIndex(args.runs_dir)}")
    return 0
