"""DIR/report.html: a campaign's success rate, its comparisons and its table, in one
offline page.

For every column that is one of the task's numeric metrics (TaskDefinition.metrics, the
names a campaign's `metrics` are checked against) and every axis with more than one
value: a box plot of the metric per value of that axis (inline SVG), the jobs drawn over
it as points coloured by the value of another axis (the next one with more than one
value), failed jobs as crosses; and a table of the metric's mean with its 95 % interval
(Student's t over the jobs of that value) per axis value. Success rate overall and per
value of each axis.
"""

from __future__ import annotations

import html
import io
import json
import math
from collections import defaultdict
from pathlib import Path
from typing import Any

from guidedarm.diagrams.campaigns.campaign import CampaignConfig
from guidedarm.diagrams.campaigns.results import FormatCell, ResultsTable
from guidedarm.diagrams.plots import plt
from guidedarm.diagrams.tasks.registry import TaskDefinition

REPORT_FILE = "report.html"
MAX_PLOTS = 60
# Student's t quantile 0.975 by degrees of freedom 1..30; beyond, 1.96 + 2.4 / df is
# within 0.002 of it.
T_975 = (
    12.706, 4.303, 3.182, 2.776, 2.571, 2.447, 2.365, 2.306, 2.262, 2.228,
    2.201, 2.179, 2.160, 2.145, 2.131, 2.120, 2.110, 2.101, 2.093, 2.086,
    2.080, 2.074, 2.069, 2.064, 2.060, 2.056, 2.052, 2.048, 2.045, 2.042,
)  # fmt: skip
PALETTE = ("tab:blue", "tab:orange", "tab:green", "tab:purple", "tab:brown", "tab:pink")


def MeanInterval(values: list[float]) -> tuple[float, float, int]:
    """(mean, half-width of its 95 % confidence interval, count) of `values`, the interval
    from Student's t with count - 1 degrees of freedom (nan for fewer than 2 values)."""
    n = len(values)
    if n == 0:
        return math.nan, math.nan, 0
    mean = math.fsum(values) / n
    if n < 2:
        return mean, math.nan, n
    std = math.sqrt(math.fsum((v - mean) ** 2 for v in values) / (n - 1))
    df = n - 1
    t = T_975[df - 1] if df <= len(T_975) else 1.96 + 2.4 / df
    return mean, t * std / math.sqrt(n), n


def WriteReport(
    out_dir: Path,
    campaign: CampaignConfig,
    table: ResultsTable,
    total_jobs: int,
    task: TaskDefinition,
) -> Path:
    """Writes DIR/report.html from the rows of `table` (jobs of `task`); returns its path."""
    rows = table.rows
    axes = [a for a in campaign.AxisNames() if len({_Key(r.get(a)) for r in rows}) > 1]
    metrics = [
        c
        for c in table.columns
        if c not in campaign.AxisNames()
        and task.HasMetric(c)
        and any(_Number(r.get(c)) is not None for r in rows)
    ]
    succeeded = sum(1 for r in rows if r.get("success") is True)
    parts = [
        f"<h1>Campaign {html.escape(campaign.name)}</h1>",
        f"<p>{html.escape(campaign.description)}</p>" if campaign.description else "",
        f"<p>scenario <code>{html.escape(campaign.scenario)}</code>; {len(rows)} of "
        f"{total_jobs} jobs done; success {succeeded} / {len(rows)}"
        f"{f' ({100 * succeeded / len(rows):.1f} %)' if rows else ''}.</p>",
        _SuccessByAxis(rows, axes),
    ]
    plots = [(m, a) for m in metrics for a in axes][:MAX_PLOTS]
    if plots:
        parts.append("<h2>Metrics by axis</h2><div>")
        parts += [_PlotSvg(rows, metric, axis, _ColourAxis(axes, axis)) for metric, axis in plots]
        parts.append("</div>")
        parts.append(_MeansTables(rows, metrics, axes))
    parts.append("<h2>Results</h2>" + _Table(table.columns, rows))
    page = (
        "<!DOCTYPE html><html><head><meta charset='utf-8'>"
        f"<title>{html.escape(campaign.name)}</title><style>{_STYLE}</style></head><body>"
        + "\n".join(p for p in parts if p)
        + "</body></html>\n"
    )
    path = out_dir / REPORT_FILE
    path.write_text(page)
    return path


_STYLE = (
    "body{font-family:sans-serif;margin:1.5em}table{border-collapse:collapse;font-size:12px}"
    "td,th{border:1px solid #ccc;padding:2px 6px}tr.failed{background:#fdd}"
    "div>svg{display:inline-block;margin:4px}"
)


def _SuccessByAxis(rows: list[dict[str, Any]], axes: list[str]) -> str:
    if not rows or not axes:
        return ""
    out = ["<h2>Success rate by axis value</h2>"]
    for axis in axes:
        counts: dict[str, list[int]] = defaultdict(lambda: [0, 0])
        for r in rows:
            count = counts[_Key(r.get(axis))]
            count[0] += r.get("success") is True
            count[1] += 1
        cells = "".join(
            f"<tr><td>{html.escape(value)}</td><td>{ok} / {n}</td></tr>"
            for value, (ok, n) in counts.items()
        )
        out.append(
            f"<table><tr><th>{html.escape(axis)}</th><th>success</th></tr>{cells}</table><br>"
        )
    return "".join(out)


def _ColourAxis(axes: list[str], axis: str) -> str | None:
    """The axis that colours the points of a plot grouped by `axis`: the next one."""
    others = axes[axes.index(axis) + 1 :] + axes[: axes.index(axis)]
    return others[0] if others else None


def _AxisValues(rows: list[dict[str, Any]], axis: str) -> list[str]:
    """Every value of `axis` (as keys), numbers in numeric order, others sorted."""
    keys = {_Key(r.get(axis)): r.get(axis) for r in rows}
    if all(_Number(v) is not None for v in keys.values()):
        return sorted(keys, key=lambda k: _Number(keys[k]))
    return sorted(keys)


def _PlotSvg(rows: list[dict[str, Any]], metric: str, axis: str, colour_axis: str | None) -> str:
    """A box per value of `axis` (successful jobs), every job's point over it, coloured by
    its value of `colour_axis`; failed jobs as red crosses."""
    values = _AxisValues(rows, axis)
    colours = _AxisValues(rows, colour_axis) if colour_axis else []
    figure, ax = plt.subplots(figsize=(4.6, 3.2))
    boxes = [
        [_Number(r.get(metric)) for r in rows if _Key(r.get(axis)) == v and r.get("success")]
        for v in values
    ]
    boxes = [[y for y in box if y is not None] for box in boxes]
    ax.boxplot(boxes, positions=range(len(values)), widths=0.5, showfliers=False)
    seen = defaultdict(int)  # points per box so far: they spread across its width
    labels: set[str] = set()  # each legend entry once
    for r in rows:
        y = _Number(r.get(metric))
        if y is None:
            continue
        i = values.index(_Key(r.get(axis)))
        x = i + 0.3 * ((seen[i] * 0.618) % 1.0 - 0.5)
        seen[i] += 1
        if r.get("success") is not True:
            ax.plot(x, y, "x", color="tab:red", label=_Once("failed", labels))
            continue
        key = _Key(r.get(colour_axis)) if colour_axis else ""
        colour = PALETTE[colours.index(key) % len(PALETTE)] if colour_axis else PALETTE[0]
        label = _Once(f"{colour_axis} = {key[:10]}", labels) if colour_axis else None
        ax.plot(x, y, "o", color=colour, alpha=0.75, markersize=4, label=label)
    ax.set_xticks(range(len(values)))
    ax.set_xticklabels([v[:12] for v in values], rotation=45, ha="right", fontsize=7)
    ax.set_xlabel(axis)
    ax.set_ylabel(metric)
    ax.grid(True, alpha=0.3)
    if labels:
        ax.legend(fontsize=6)
    buffer = io.StringIO()
    # The saved box grows to hold every tick label (tight_layout cannot when an axis has
    # many values, and warns).
    figure.savefig(buffer, format="svg", bbox_inches="tight")
    plt.close(figure)
    svg = buffer.getvalue()
    return svg[svg.index("<svg") :]


def _Once(label: str, labels: set[str]) -> str | None:
    """`label` the first time it is asked for (then kept in `labels`), else None."""
    if label in labels:
        return None
    labels.add(label)
    return label


def _MeansTables(rows: list[dict[str, Any]], metrics: list[str], axes: list[str]) -> str:
    """Per axis, a table: each value's mean of each metric +- its 95 % interval (n), over
    the successful jobs."""
    out = ["<h2>Means and 95 % intervals by axis value (successful jobs)</h2>"]
    for axis in axes:
        head = "".join(f"<th>{html.escape(m)}</th>" for m in metrics)
        body = []
        for value in _AxisValues(rows, axis):
            cells = []
            for metric in metrics:
                numbers = [
                    _Number(r.get(metric))
                    for r in rows
                    if _Key(r.get(axis)) == value and r.get("success") is True
                ]
                mean, half, n = MeanInterval([y for y in numbers if y is not None])
                text = (
                    ""
                    if n == 0
                    else f"{mean:.4g}" + (f" ± {half:.2g}" if not math.isnan(half) else "")
                )
                cells.append(f"<td>{html.escape(text)} ({n})</td>")
            body.append(f"<tr><td>{html.escape(value)}</td>{''.join(cells)}</tr>")
        out.append(f"<table><tr><th>{html.escape(axis)}</th>{head}</tr>{''.join(body)}</table><br>")
    return "".join(out)


def _Table(columns: list[str], rows: list[dict[str, Any]]) -> str:
    head = "".join(f"<th>{html.escape(c)}</th>" for c in columns)
    body = []
    for r in rows:
        cells = "".join(f"<td>{html.escape(FormatCell(r.get(c)))}</td>" for c in columns)
        failed = " class='failed'" if r.get("success") is not True else ""
        body.append(f"<tr{failed}>{cells}</tr>")
    return f"<table><tr>{head}</tr>{''.join(body)}</table>"


def _Number(value: Any) -> float | None:
    if isinstance(value, bool) or not isinstance(value, int | float):
        return None
    return float(value)


def _Key(value: Any) -> str:
    return value if isinstance(value, str) else json.dumps(value)
