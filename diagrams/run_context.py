"""What a task run writes: summary.json, PNG plots, and a Meshcat replay page.

Every `guidedarm run` gets a RunContext. Tasks use it to record the Meshcat animation of
their simulation, to save figures, and to report progress; the CLI writes the summary.
"""

from __future__ import annotations

import json
import math
import sys
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from pydrake.geometry import Meshcat
from pydrake.systems.analysis import Simulator

from guidedarm.systems.errors import GuidedArmError

REPLAY_FILE = "replay.html"
SUMMARY_FILE = "summary.json"
# The fully resolved scenario (overrides applied, defaults written out): running it again
# with `guidedarm run DIR/scenario.yaml` reproduces the run.
RESOLVED_SCENARIO_FILE = "scenario.yaml"


@dataclass
class RunContext:
    """Output directory, Meshcat and progress reporting of one task run."""

    out_dir: Path
    meshcat: Meshcat | None = None
    hardware: bool = False
    quiet: bool = False
    written: list[Path] = field(default_factory=list)
    _last_progress: float = 0.0

    def __post_init__(self) -> None:
        self.out_dir.mkdir(parents=True, exist_ok=True)

    def progress(self, message: str, force: bool = False) -> None:
        """Prints a progress line to stderr, at most once a second unless forced."""
        now = time.monotonic()
        if self.quiet or (not force and now - self._last_progress < 1.0):
            return
        self._last_progress = now
        print(f"  ... {message}", file=sys.stderr, flush=True)

    def save_figure(self, figure: Any, name: str) -> Path:
        """Saves a matplotlib figure as DIR/name.png and closes it."""
        import matplotlib.pyplot as plt

        path = self.out_dir / f"{name}.png"
        figure.savefig(path, dpi=110, bbox_inches="tight")
        plt.close(figure)
        self.written.append(path)
        return path

    def write_text(self, name: str, text: str) -> Path:
        """Writes DIR/name."""
        path = self.out_dir / name
        path.write_text(text)
        self.written.append(path)
        return path

    def write_csv(self, name: str, header: list[str], rows: list[list[Any]]) -> Path:
        """Writes DIR/name.csv."""
        path = self.out_dir / f"{name}.csv"
        lines = [",".join(header)] + [",".join(_csv_cell(v) for v in row) for row in rows]
        path.write_text("\n".join(lines) + "\n")
        self.written.append(path)
        return path

    def start_recording(self) -> None:
        """Starts recording the Meshcat animation (call before simulating)."""
        if self.meshcat is not None:
            self.meshcat.StartRecording(frames_per_second=30.0)

    def write_replay(self) -> Path | None:
        """Publishes the recorded animation and writes it as a self-contained HTML page."""
        if self.meshcat is None:
            return None
        self.meshcat.StopRecording()
        self.meshcat.PublishRecording()
        path = self.out_dir / REPLAY_FILE
        path.write_text(self.meshcat.StaticHtml())
        self.written.append(path)
        return path

    def write_summary(self, summary: dict[str, Any]) -> Path:
        """Writes DIR/summary.json; a NaN or infinity anywhere is an error, not a value."""
        bad = _non_finite_keys(summary)
        if bad:
            raise GuidedArmError(f"summary has non-finite values for {', '.join(bad)}")
        path = self.out_dir / SUMMARY_FILE
        path.write_text(json.dumps(summary, indent=2, sort_keys=False) + "\n")
        self.written.append(path)
        return path


def AdvanceWithProgress(
    simulator: Simulator, t_final: float, context: RunContext, chunk_s: float = 0.25
) -> float:
    """Advances `simulator` to `t_final` in chunks, printing progress; returns the sim time.

    A monitor set on the simulator may stop it early (EventStatus.ReachedTermination); the
    returned time is where it stopped. Against hardware the simulator keeps wall-clock pace,
    since the drivers' clocks are real.
    """
    if context.hardware:
        simulator.set_target_realtime_rate(1.0)
    t = simulator.get_context().get_time()
    while t < t_final:
        status = simulator.AdvanceTo(min(t + chunk_s, t_final))
        t = simulator.get_context().get_time()
        context.progress(f"simulated {t:.2f} / {t_final:.2f} s")
        if status.reason() != status.ReturnReason.kReachedBoundaryTime:
            break
    return t


def _csv_cell(value: Any) -> str:
    if isinstance(value, float):
        return f"{value:.9g}"
    return str(value)


def _non_finite_keys(value: Any, prefix: str = "") -> list[str]:
    if isinstance(value, float):
        return [] if math.isfinite(value) else [prefix or "<value>"]
    if isinstance(value, dict):
        return [k for key, v in value.items() for k in _non_finite_keys(v, f"{prefix}{key}.")]
    if isinstance(value, list | tuple):
        return [k for i, v in enumerate(value) for k in _non_finite_keys(v, f"{prefix}[{i}].")]
    return []
