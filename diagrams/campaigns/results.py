"""DIR/results.csv: one row per finished job, written as each job finishes.

Columns: the axes, the collected metrics, `success`, `failure`, `wall_time_s` (the job's
time in its worker, s), `job_id`, `worker`. Each row is appended and flushed to disk as
it arrives, so an interrupted campaign leaves a valid table; a row that brings a new metric
column rewrites the table (to a temporary file, then renamed over it). Cells: numbers as
Python writes them (exact round trip), true/false, lists and mappings as JSON, text as is.
"""

from __future__ import annotations

import csv
import io
import json
import os
from collections.abc import Iterable
from pathlib import Path
from typing import Any

import numpy as np

from guidedarm.diagrams.campaigns.campaign import CampaignError

RESULTS_FILE = "results.csv"
TRAILING_COLUMNS = ("success", "failure", "wall_time_s", "job_id", "worker")
# The failure of a job whose workers were lost more often than allowed: not a result of
# the job's scenario, so a rerun of the campaign runs that job again.
LOST_PREFIX = "engine: "


def CollectMetrics(metrics: dict[str, Any], wanted: list[str] | None) -> dict[str, Any]:
    """The columns of one job's summary: `wanted` dotted keys (a list index is a key too;
    a missing key gives an empty cell), or every scalar key of the summary."""
    if wanted is None:
        return {
            k: v
            for k, v in metrics.items()
            if k not in TRAILING_COLUMNS and (v is None or isinstance(v, bool | int | float | str))
        }
    return {key: _Lookup(metrics, key) for key in wanted}


def EmptyMetrics(rows: Iterable[dict[str, Any]], wanted: list[str] | None) -> list[str]:
    """The `wanted` metrics no successful row has a value for: metrics the task reports only
    in some configurations (the names were checked at load, jobs.CheckMetrics). Empty when
    no job succeeded."""
    done = [r for r in rows if r["success"] is True]
    if not wanted or not done:
        return []
    return [m for m in wanted if all(r.get(m) in (None, "") for r in done)]


def RowOf(axes: dict[str, Any], result: dict[str, Any], wanted: list[str] | None) -> dict[str, Any]:
    """The results row of a worker's result (see worker.RunJob)."""
    metrics = result["metrics"]
    failure = metrics.get("failure")
    return {
        **axes,
        **CollectMetrics(metrics, wanted),
        "success": bool(metrics.get("success", failure is None)) and not failure,
        "failure": failure or "",
        "wall_time_s": result["wall_time_s"],
        "job_id": result["job_id"],
        "worker": result.get("worker", ""),
    }


class ResultsTable:
    """The rows of DIR/results.csv, in memory and on disk."""

    def __init__(self, path: Path, axis_names: list[str]) -> None:
        self.path = path
        self.columns: list[str] = [*axis_names, *TRAILING_COLUMNS]
        self.rows: list[dict[str, Any]] = []
        if path.exists():
            self._Read()

    def _Read(self) -> None:
        text = self.path.read_text()
        complete = text if text.endswith("\n") or not text else text[: text.rfind("\n") + 1]
        reader = csv.DictReader(io.StringIO(complete))
        if reader.fieldnames is None:
            return
        missing = [c for c in ("job_id", "failure") if c not in reader.fieldnames]
        if missing:
            raise CampaignError(f"{self.path}: not a results table (no column '{missing[0]}')")
        self.columns = _Merge(self.columns, reader.fieldnames)
        self.rows = [{k: ParseCell(v) for k, v in row.items()} for row in reader]
        if complete != text:  # a line cut short by a crash: drop it
            self._Rewrite()

    def DoneIds(self) -> set[str]:
        """Jobs that have a result (their own failure counts; a lost worker's does not)."""
        return {r["job_id"] for r in self.rows if not str(r["failure"]).startswith(LOST_PREFIX)}

    def Keep(self, job_ids: Iterable[str]) -> None:
        """Drops every row whose job is not in `job_ids` (rows to be run again)."""
        keep = set(job_ids)
        if any(r["job_id"] not in keep for r in self.rows):
            self.rows = [r for r in self.rows if r["job_id"] in keep]
            self._Rewrite()

    def Order(self, job_ids: list[str]) -> None:
        """Rewrites the table with its rows in the order of `job_ids` (the campaign's)."""
        position = {job_id: i for i, job_id in enumerate(job_ids)}
        self.rows.sort(key=lambda r: position.get(r["job_id"], len(position)))
        self._Rewrite()

    def Add(self, row: dict[str, Any]) -> None:
        """Appends one row, flushed to disk before returning."""
        self.rows.append(row)
        columns = _Merge(self.columns, list(row))
        if columns != self.columns or not self.path.exists():
            self.columns = columns
            self._Rewrite()
            return
        with self.path.open("a", newline="") as f:
            f.write(self._Lines([row]))
            f.flush()
            os.fsync(f.fileno())

    def _Rewrite(self) -> None:
        temporary = self.path.with_suffix(".csv.tmp")
        with temporary.open("w", newline="") as f:
            f.write(self._Lines(self.rows, header=True))
            f.flush()
            os.fsync(f.fileno())
        temporary.replace(self.path)

    def _Lines(self, rows: list[dict[str, Any]], header: bool = False) -> str:
        buffer = io.StringIO()
        writer = csv.writer(buffer, lineterminator="\n")
        if header:
            writer.writerow(self.columns)
        for row in rows:
            writer.writerow([FormatCell(row.get(c)) for c in self.columns])
        return buffer.getvalue()


def FormatCell(value: Any) -> str:
    """A CSV cell (see the module docstring)."""
    if isinstance(value, np.generic):
        value = value.item()
    if value is None:
        return ""
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, float):
        return repr(float(value))
    if isinstance(value, int):
        return repr(int(value))
    if isinstance(value, str):
        return value
    return json.dumps(value, default=_Plain)


def ParseCell(text: str | None) -> Any:
    """The value of a CSV cell written by FormatCell."""
    if text is None or text == "":
        return None
    if text[0] in "-0123456789[{tfn" or text in ("inf", "-inf"):
        try:
            return json.loads(text)
        except ValueError:
            try:
                return float(text)
            except ValueError:
                return text
    return text


def _Plain(value: Any) -> Any:
    """json.dumps's fallback for numpy values in lists and mappings."""
    if isinstance(value, np.generic | np.ndarray):
        return value.tolist()
    raise TypeError(f"cannot write {type(value).__name__} to a results cell")


def _Lookup(metrics: Any, dotted: str) -> Any:
    node = metrics
    for part in dotted.split("."):
        if isinstance(node, dict) and part in node:
            node = node[part]
        elif isinstance(node, list) and part.isdigit() and int(part) < len(node):
            node = node[int(part)]
        else:
            return None
    return node


def _Merge(columns: list[str], new: Iterable[str]) -> list[str]:
    """`columns` with the names of `new` it lacks inserted before the trailing columns."""
    extra = [c for c in new if c not in columns]
    if not extra:
        return columns
    head = [c for c in columns if c not in TRAILING_COLUMNS]
    tail = [c for c in columns if c in TRAILING_COLUMNS]
    return [*head, *extra, *tail]
