"""DIR/report.html: a campaign's success rate, its plots and its table, in one offline page.

Plots (inline SVG): every column that is one of the task's numeric metrics
(TaskDefinition.metrics, the names a campaign's `metrics` are checked against) against
every axis with more than one value;
numeric axes on a linear scale, other axes (text, lists) as categories. Success rate
overall and per value of each axis.
"""

from __future__ import annotations

import html
import io
import json
from collections import defaultdict
from pathlib import Path
from typing import Any

from guidedarm.diagrams.campaigns.campaign import CampaignConfig
from guidedarm.diagrams.campaigns.results import FormatCell, ResultsTable
from guidedarm.diagrams.plots import plt
from guidedarm.diagrams.tasks.registry import TaskDefinition

REPORT_FILE = "report.html"
MAX_PLOTS = 60


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
        parts.append("<h2>Metrics against the axes</h2><div>")
        parts += [_PlotSvg(rows, metric, axis) for metric, axis in plots]
        parts.append("</div>")
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


def _PlotSvg(rows: list[dict[str, Any]], metric: str, axis: str) -> str:
    numeric = all(_Number(r.get(axis)) is not None for r in rows)
    categories = sorted({_Key(r.get(axis)) for r in rows})  # every value, with a point or not
    points = [(r.get(axis), _Number(r.get(metric)), r.get("success") is True) for r in rows]
    points = [p for p in points if p[1] is not None]
    figure, ax = plt.subplots(figsize=(4.2, 3.0))
    for ok, colour, label in ((True, "tab:blue", "success"), (False, "tab:red", "failed")):
        chosen = [p for p in points if p[2] == ok]
        if not chosen:
            continue
        xs = [_Number(x) if numeric else categories.index(_Key(x)) for x, _, _ in chosen]
        ax.plot(xs, [y for _, y, _ in chosen], "o", color=colour, label=label, alpha=0.7)
    if not numeric:
        ax.set_xticks(range(len(categories)))
        ax.set_xticklabels([c[:12] for c in categories], rotation=45, ha="right", fontsize=7)
    ax.set_xlabel(axis)
    ax.set_ylabel(metric)
    ax.grid(True, alpha=0.3)
    ax.legend(fontsize=7)
    figure.tight_layout()
    buffer = io.StringIO()
    figure.savefig(buffer, format="svg")
    plt.close(figure)
    svg = buffer.getvalue()
    return svg[svg.index("<svg") :]


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
