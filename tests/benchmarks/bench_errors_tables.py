"""The imperfect cell against the papers: reads the results of the errors_* campaigns
(`guidedarm sweep errors_panel`, errors_markers, errors_moves, errors_repeatability; each
job one cell drawn from the sourced presets) and prints, per paper figure, the paper's
real-robot mean and max beside the prediction's mean, p95 and max over the cells, and the
ratio of each (prediction over paper).

    .venv/bin/python tests/benchmarks/bench_errors_tables.py [--runs DIR] [--markdown]

DIR holds one folder per campaign (DIR/errors_panel/results.csv, ...; `guidedarm sweep`'s
default DIR is runs/). A campaign not run yet is skipped.
"""

import argparse
from pathlib import Path

import numpy as np

from guidedarm.diagrams.campaigns.results import ResultsTable

# (campaign, label, metric column, scale to the paper's unit, the rows it covers (column:
# values), paper mean, paper max). Seed 003 (Annusewicz-Mistal et al.) Tables 1-5; seed
# 000 (Wawrzyniak et al.) the repeatability of path 1's two runs.
FIGURES = [
    ("errors_moves", "T1: 50 mm move error (mm)", "true_move_error_m", 1e3, {}, 0.71, 3.0),
    # Table 2's straight series (13 views, 200-430 mm) and the far end of its angled one
    # (341-424 mm at 16-24 deg: 2.6, 2.6, 3.2, 5.9, 3.1 mm).
    ("errors_markers", "T2: distance error, straight (mm)", "abs_error_mm", 1,
     {"distance_m": [0.2, 0.43], "angle_deg": [0.0]}, 0.58, 1.0),
    ("errors_markers", "T2: distance error, 430 mm 24 deg (mm)", "abs_error_mm", 1,
     {"distance_m": [0.43], "angle_deg": [24.0]}, 3.5, 5.9),
    # Table 3: 13 views turned 0 deg, 12 turned 4-26 deg (their distance is not given).
    ("errors_markers", "T3: rotation error, 0 deg (deg)", "rotation_error_deg", 1,
     {"distance_m": [0.3], "angle_deg": [0.0]}, 2.78, 3.71),
    ("errors_markers", "T3: rotation error, 24 deg (deg)", "rotation_error_deg", 1,
     {"distance_m": [0.3], "angle_deg": [24.0]}, 1.38, 2.83),
    ("errors_panel", "T4: base point error (mm, true)", "true_base_position_error_mm", 1, {},
     4.54, 16.4),
    ("errors_panel", "T5: press error x (mm)", "press_error_mm.x", 1, {}, 8.91, 12.1),
    ("errors_panel", "T5: press error y (mm)", "press_error_mm.y", 1, {}, 4.99, 8.0),
    ("errors_panel", "T5: press error z (mm)", "press_error_mm.z", 1, {}, 3.28, 5.1),
    ("errors_panel", "true press error x (mm)", "true_press_error_mm.x", 1, {}, None, None),
    ("errors_panel", "true press error y (mm)", "true_press_error_mm.y", 1, {}, None, None),
    ("errors_panel", "true press error z (mm)", "true_press_error_mm.z", 1, {}, None, None),
    ("errors_repeatability", "000: repeatability mean (mm)", "repeatability_mean_mm", 1, {},
     5.2, 5.2),
    ("errors_repeatability", "000: repeatability max (mm)", "repeatability_max_mm", 1, {},
     15.2, 15.2),
]  # fmt: skip


def _Ratio(predicted: float, paper: float | None) -> str:
    return f"{predicted / paper:.2f}" if paper else ""


def Figures(runs: Path):
    """(label, paper mean / max text, mean, p95, max, ratio of the means, ratio of the
    maxima, values, failed jobs) of every figure whose campaign has results in `runs`."""
    for campaign, label, column, scale, where, paper_mean, paper_max in FIGURES:
        path = runs / campaign / "results.csv"
        if not path.is_file():
            continue
        rows = ResultsTable(path, []).rows
        rows = [r for r in rows if all(r.get(k) in v for k, v in where.items())]
        values = np.array([r[column] * scale for r in rows if r.get(column) is not None])
        failed = sum(1 for r in rows if not r["success"])
        paper = "" if paper_mean is None else f"{paper_mean} / {paper_max}"
        if paper_mean is not None and paper_mean == paper_max:
            paper = f"{paper_mean}"  # one figure (the paper's one pair of runs)
        if len(values) == 0:
            yield label, paper, np.nan, np.nan, np.nan, "", "", 0, failed
            continue
        mean, p95, worst = np.mean(values), np.percentile(values, 95), np.max(values)
        ratios = _Ratio(mean, paper_mean), _Ratio(worst, paper_max)
        yield label, paper, mean, p95, worst, *ratios, len(values), failed


def main() -> None:
    parser = argparse.ArgumentParser()
    parser.add_argument("--runs", type=Path, default=Path("runs"))
    parser.add_argument("--markdown", action="store_true", help="print a Markdown table")
    args = parser.parse_args()
    columns = ("figure", "paper mean / max", "mean", "p95", "max", "ratio mean", "ratio max")
    if args.markdown:
        print("| " + " | ".join((*columns, "values (failed jobs)")) + " |")
        print("|---" * (len(columns) + 1) + "|")
    else:
        print(f"{'figure':42} {'paper':>11} {'mean':>7} {'p95':>7} {'max':>7} {'ratios':>11} n")
    for label, paper, mean, p95, worst, r_mean, r_max, count, failed in Figures(args.runs):
        stats = f"{mean:.3g}", f"{p95:.3g}", f"{worst:.3g}"
        if args.markdown:
            cells = (label, paper, *stats, r_mean, r_max, f"{count} ({failed})")
            print("| " + " | ".join(c.strip() for c in cells) + " |")
        else:
            print(
                f"{label:42} {paper:>11} {stats[0]:>7} {stats[1]:>7} {stats[2]:>7} "
                f"{r_mean:>5} {r_max:>5} {count} ({failed} failed)"
            )


if __name__ == "__main__":
    main()
