"""runs/index.html: one page with every run's headline metrics, plots and replay link.

`guidedarm demo-index runs/` (called by `make demo`) reads each `runs/<scenario>/` that
holds a summary.json and writes a self-contained page that links to the run's files with
relative paths, so the folder can be opened, copied or served as it is.
"""

from __future__ import annotations

import html
import json
from pathlib import Path
from typing import Any

from guidedarm.diagrams.run_context import REPLAY_FILE, RESOLVED_SCENARIO_FILE, SUMMARY_FILE
from guidedarm.systems.errors import ConfigurationError

INDEX_FILE = "index.html"
# Summary keys that describe the run rather than measure it.
_NOT_METRICS = {"scenario", "task", "command", "version", "failure", "success"}
# The longest list of numbers shown in full in the metrics table.
_LIST_SHOWN = 8

_STYLE = """
body { font-family: sans-serif; margin: 1.5em auto; max-width: 1200px; color: #222; }
h1 { font-size: 1.5em; } h2 { font-size: 1.2em; margin-top: 2em; border-top: 1px solid #ccc;
  padding-top: 1em; }
.ok { color: #1a7f37; } .failed { color: #c62828; }
table.metrics { border-collapse: collapse; font-size: 0.9em; margin: 0.5em 0; }
table.metrics td { border: 1px solid #ddd; padding: 2px 8px; }
table.metrics td:first-child { color: #555; }
.plots { display: flex; flex-wrap: wrap; gap: 8px; }
.plots figure { margin: 0; width: 380px; } .plots img { width: 100%; border: 1px solid #ddd; }
.plots figcaption { font-size: 0.8em; color: #555; }
code { background: #f4f4f4; padding: 1px 4px; }
"""


def WriteDemoIndex(runs_dir: Path) -> Path:
    """Writes runs_dir/index.html for the runs in runs_dir; returns its path."""
    runs_dir = Path(runs_dir)
    if not runs_dir.is_dir():
        raise ConfigurationError(f"{runs_dir}: not a directory of runs")
    runs = [d for d in sorted(runs_dir.iterdir()) if (d / SUMMARY_FILE).is_file()]
    if not runs:
        raise ConfigurationError(f"{runs_dir}: no run (no */{SUMMARY_FILE}); run `make demo`")
    sections = [_RunSection(d) for d in runs]
    overview = "".join(_OverviewRow(d) for d in runs)
    page = f"""<!DOCTYPE html>
<html><head><meta charset="utf-8"><title>guidedarm demo runs</title>
<style>{_STYLE}</style></head><body>
<h1>guidedarm demo runs</h1>
<p>Each scenario's headline metrics, its plots (click for the full PNG; SVG beside it) and
its Meshcat replay, which opens offline: overlays under <code>/overlays</code> show what the
systems sensed, estimated and planned.</p>
<table class="metrics"><tr><td>scenario</td><td>result</td><td>replay</td></tr>{overview}
</table>
{"".join(sections)}
</body></html>
"""
    path = runs_dir / INDEX_FILE
    path.write_text(page)
    return path


def _Summary(run: Path) -> dict[str, Any]:
    """The run's summary.json; ConfigurationError naming the file when it cannot be read,
    is not UTF-8 JSON, or is not a JSON object."""
    path = run / SUMMARY_FILE
    try:
        summary = json.loads(path.read_text(encoding="utf-8"))
    except json.JSONDecodeError as e:
        raise ConfigurationError(f"{path}: not JSON ({e.msg})") from None
    except UnicodeDecodeError as e:
        raise ConfigurationError(f"{path}: not UTF-8 text (byte {e.start})") from None
    except OSError as e:
        raise ConfigurationError(f"{path}: cannot read it ({e.strerror})") from None
    if not isinstance(summary, dict):
        raise ConfigurationError(f"{path}: not a JSON object of metrics")
    return summary


def _Result(summary: dict[str, Any]) -> str:
    failure = summary.get("failure")
    if failure:
        return f'<span class="failed">failed: {html.escape(str(failure))}</span>'
    return '<span class="ok">success</span>'


def _OverviewRow(run: Path) -> str:
    name = html.escape(run.name)
    replay = f'<a href="{name}/{REPLAY_FILE}">replay</a>' if (run / REPLAY_FILE).is_file() else ""
    cells = (f'<a href="#{name}">{name}</a>', _Result(_Summary(run)), replay)
    return "<tr>" + "".join(f"<td>{c}</td>" for c in cells) + "</tr>"


def _RunSection(run: Path) -> str:
    summary = _Summary(run)
    name = html.escape(run.name)
    links = [
        f'<a href="{name}/{f}">{f}</a>'
        for f in (REPLAY_FILE, SUMMARY_FILE, RESOLVED_SCENARIO_FILE)
        if (run / f).is_file()
    ]
    rows = "".join(
        f"<tr><td>{html.escape(k)}</td><td>{html.escape(_Value(v))}</td></tr>"
        for k, v in summary.items()
        if k not in _NOT_METRICS and _Shown(v)
    )
    plots = "".join(_Plot(run, png) for png in sorted(run.glob("*.png")))
    command = html.escape(str(summary.get("command", "")))
    return f"""<h2 id="{name}">{name} <small>(task {html.escape(str(summary.get("task", "?")))})
: {_Result(summary)}</small></h2>
<p>{" · ".join(links)}<br><code>{command}</code></p>
<table class="metrics">{rows}</table>
<div class="plots">{plots}</div>
"""


def _Plot(run: Path, png: Path) -> str:
    name, file = html.escape(run.name), html.escape(png.name)
    svg = png.with_suffix(".svg")
    vector = f' · <a href="{name}/{html.escape(svg.name)}">SVG</a>' if svg.is_file() else ""
    return (
        f'<figure><a href="{name}/{file}"><img src="{name}/{file}" alt="{file}"></a>'
        f"<figcaption>{html.escape(png.stem)}{vector}</figcaption></figure>"
    )


def _Shown(value: Any) -> bool:
    if isinstance(value, list):
        return len(value) <= _LIST_SHOWN and all(isinstance(v, int | float) for v in value)
    return not isinstance(value, dict) or all(isinstance(v, int | float) for v in value.values())


def _Value(value: Any) -> str:
    if isinstance(value, float):
        return f"{value:.6g}"
    if isinstance(value, dict):
        return ", ".join(f"{k} {_Value(v)}" for k, v in value.items())
    if isinstance(value, list):
        return "[" + ", ".join(_Value(v) for v in value) + "]"
    return str(value)
