"""`guidedarm sweep CAMPAIGN [--out DIR] [--workers N] [--scheduler ADDRESS] [--keep-runs]`.

Runs every job of a campaign (diagrams/campaigns/NAME.yaml or a campaign file) on Dask and
writes DIR/results.csv, DIR/campaign.yaml and DIR/report.html (docs/campaigns.md). Exit 0
when every job has its row (failed jobs included) and some job succeeded, 1 when some
job's workers were lost or every job failed, 2 for bad input (before any job starts),
130 when interrupted (rerun to finish).
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from guidedarm.diagrams.campaigns.campaign_file import LoadCampaign
from guidedarm.diagrams.campaigns.results import EmptyMetrics
from guidedarm.diagrams.campaigns.sweep import MakeSweepOptions, Sweep

EXIT_LOST = 1
EXIT_ALL_FAILED = 1
EXIT_INTERRUPTED = 130


def register(subparsers: argparse._SubParsersAction) -> None:
    parser = subparsers.add_parser(
        "sweep", help="run a campaign of scenarios on Dask into one results table"
    )
    parser.add_argument("campaign", help="campaign name (diagrams/campaigns/) or YAML file")
    parser.add_argument("--out", type=Path, help="output directory (default runs/CAMPAIGN)")
    parser.add_argument(
        "--workers", type=int, help="worker processes of the embedded cluster (default: cores)"
    )
    parser.add_argument(
        "--scheduler", metavar="ADDRESS", help="an existing Dask scheduler, tcp://host:port"
    )
    parser.add_argument(
        "--keep-runs", action="store_true", help="keep each job's run folder in DIR/runs/"
    )
    parser.set_defaults(func=sweep_command)


def sweep_command(args: argparse.Namespace) -> int:
    options = MakeSweepOptions(args.workers, args.scheduler, args.keep_runs)
    campaign = LoadCampaign(args.campaign)
    out_dir = args.out or Path("runs") / campaign.name
    result = Sweep(campaign, out_dir, options)
    rows = result.table.rows
    failed = sum(1 for r in rows if r["success"] is not True)
    print(f"  jobs: {len(result.jobs)}, results: {len(rows)}, failed: {failed}")
    empty = EmptyMetrics(rows, campaign.metrics)
    if empty:
        print(
            f"guidedarm: metric(s) {', '.join(empty)} in no successful job's summary "
            "(empty column): the task reports them only in some configurations",
            file=sys.stderr,
        )
    print("wrote:")
    for path in result.written:
        print(f"  {path}")
    if result.outcome.interrupted:
        print("guidedarm: interrupted; run the same command again to finish", file=sys.stderr)
        return EXIT_INTERRUPTED
    if result.outcome.lost:
        print(f"guidedarm: {result.outcome.lost} job(s) lost their workers", file=sys.stderr)
        return EXIT_LOST
    if rows and failed == len(rows):
        print(
            f"guidedarm: all {failed} job(s) failed, the first: {rows[0]['failure'][:200]}",
            file=sys.stderr,
        )
        return EXIT_ALL_FAILED
    return 0
