"""What a task run writes: summary.json, plots (PNG and SVG), and a Meshcat replay page.

Every `guidedarm run` gets a RunContext. Tasks use it to record the Meshcat animation of
their simulation, to save figures, to pace the simulator and to report progress (on stderr
and, with Meshcat, on the page); the CLI writes the summary.

Meshcat: Drake's Meshcat always listens on a port, even when it only records. MakeMeshcat
serves a live page (on `localhost` unless another host is asked for) only when asked;
otherwise it listens on 127.0.0.1 at an ephemeral port, announced nowhere, and is used
only to write replay.html.
"""

from __future__ import annotations

import gc
import json
import logging
import math
import sys
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from pydrake.geometry import Meshcat, MeshcatParams
from pydrake.systems.analysis import Simulator

from guidedarm.diagrams.interrupts import DeferredInterrupts, RaiseIfInterrupted, TakeInterrupt
from guidedarm.diagrams.station.hardware_config import ListenHostProblem
from guidedarm.systems.errors import ConfigurationError, GuidedArmError
from guidedarm.systems.hardware.arm_link import ReportStopErrors, StopAllArms

REPLAY_FILE = "replay.html"
SUMMARY_FILE = "summary.json"
# The fully resolved scenario (overrides applied, defaults written out): running it again
# with `guidedarm run DIR/scenario.yaml` reproduces the run.
RESOLVED_SCENARIO_FILE = "scenario.yaml"
# The Meshcat control that shows a live run's simulated time.
PROGRESS_SLIDER = "sim time (s)"
# Wall-clock interval between Meshcat progress updates (s).
_PAGE_PROGRESS_PERIOD = 0.1


@dataclass
class RunContext:
    """Output directory, Meshcat and progress reporting of one task run.

    realtime_rate: the pace of a simulated run, in simulated seconds per wall-clock second
    (0 = as fast as possible); against hardware the pace is always 1.
    live: the Meshcat page is served live (--meshcat), so progress is shown on it; a
    Meshcat that only records the replay gets none (each update waits for its thread).
    title: the run's name on every figure (run_labels.RunTitle); headline: metrics a task
    has computed, printed under the figures they belong to (run_labels.HEADLINES).
    """

    out_dir: Path
    meshcat: Meshcat | None = None
    hardware: bool = False
    quiet: bool = False
    realtime_rate: float = 0.0
    live: bool = False
    title: str = ""
    headline: dict[str, Any] = field(default_factory=dict)
    written: list[Path] = field(default_factory=list)
    _last_progress: float = 0.0
    _last_page_progress: float = 0.0
    _simulator: Simulator | None = None

    def __post_init__(self) -> None:
        PrepareOutputDirectory(self.out_dir)

    @property
    def station_kind(self) -> str:
        """The kind of station the run builds (MakeStation's `kind`): `hardware` with
        --hardware, else `simulation`."""
        return "hardware" if self.hardware else "simulation"

    def pace(self, simulator: Simulator, t_final: float) -> None:
        """Sets the simulator's target realtime rate (1 against hardware, else
        realtime_rate) and shows its simulated time, up to t_final (s), on the Meshcat page
        whenever progress() is called."""
        simulator.set_target_realtime_rate(1.0 if self.hardware else self.realtime_rate)
        if self.hardware:
            # Against hardware the diagram must keep real time: a full garbage collection
            # walks every object built so far (Drake's among them) in one pause, holding
            # the GIL the link threads need (80-180 ms measured in a hardware run's
            # process while it was built and reported; several times that on a loaded
            # machine, against watchdogs of 0.5 s). Frozen objects are never walked again.
            gc.freeze()
        self._simulator = simulator
        if self.meshcat is not None and self.live:
            if PROGRESS_SLIDER in self.meshcat.GetSliderNames():
                self.meshcat.DeleteSlider(PROGRESS_SLIDER)
            self.meshcat.AddSlider(PROGRESS_SLIDER, 0.0, max(t_final, 1e-3), 0.01, 0.0)

    def progress(self, message: str | Callable[[], str], force: bool = False) -> None:
        """Prints a progress line to stderr, at most once a second unless forced; after
        pace(), also shows the simulated time and realtime rate on the Meshcat page.
        message: the line, or a function making it only when it is printed (for a caller
        at every simulator step)."""
        RaiseIfInterrupted()
        now = time.monotonic()
        self._ShowOnPage(now)
        if self.quiet or (not force and now - self._last_progress < 1.0):
            return
        self._last_progress = now
        line = message if isinstance(message, str) else message()
        print(f"  ... {line}", file=sys.stderr, flush=True)

    def _ShowOnPage(self, now: float) -> None:
        if self.meshcat is None or not self.live or self._simulator is None:
            return
        if now - self._last_page_progress < _PAGE_PROGRESS_PERIOD:
            return
        self._last_page_progress = now
        t = self._simulator.get_context().get_time()
        self.meshcat.SetSimulationTime(t)
        self.meshcat.SetSliderValue(PROGRESS_SLIDER, t)

    def save_figure(self, figure: Any, name: str) -> Path:
        """Finishes a matplotlib figure (plots.FinishFigure: title, headline figures),
        saves it as DIR/name.png and DIR/name.svg and closes it; returns the PNG's path."""
        import matplotlib.pyplot as plt

        from guidedarm.diagrams.plots import FinishFigure
        from guidedarm.diagrams.run_labels import HeadlineText

        FinishFigure(figure, self.title, HeadlineText(name, self.headline))
        path = self.out_dir / f"{name}.png"
        figure.savefig(path, dpi=110, bbox_inches="tight")
        vector = path.with_suffix(".svg")
        figure.savefig(vector, bbox_inches="tight")
        plt.close(figure)
        self.written += [path, vector]
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
        """Starts recording the Meshcat animation (StartReplay; call before simulating)."""
        if self.meshcat is not None:
            StartReplay(self.meshcat, live=self.live)

    def write_replay(self) -> Path | None:
        """Writes the recorded animation as DIR/replay.html (SaveReplay)."""
        if self.meshcat is None:
            return None
        path = SaveReplay(self.meshcat, self.out_dir / REPLAY_FILE)
        self.written.append(path)
        return path

    def write_summary(self, summary: dict[str, Any]) -> Path:
        """Writes DIR/summary.json; a NaN or infinity anywhere is an error, not a value."""
        bad = NonFiniteKeys(summary)
        if bad:
            raise GuidedArmError(f"summary has non-finite values for {', '.join(bad)}")
        path = self.out_dir / SUMMARY_FILE
        path.write_text(json.dumps(summary, indent=2, sort_keys=False) + "\n")
        self.written.append(path)
        return path


def PrepareOutputDirectory(out_dir: Path, name: str = "--out") -> Path:
    """Creates an output directory, or refuses (ConfigurationError, naming the argument
    `name`) before the run when it names a file, lies under a file, or cannot be written."""
    for parent in [out_dir, *out_dir.parents]:
        if parent.exists() and not parent.is_dir():
            raise ConfigurationError(f"{name} {out_dir}: '{parent}' is a file, not a directory")
    try:
        out_dir.mkdir(parents=True, exist_ok=True)
        probe = out_dir / ".guidedarm_write_probe"
        probe.write_text("")
        probe.unlink()
    except OSError as e:
        raise ConfigurationError(f"{name} {out_dir}: cannot write there ({e.strerror})") from None
    return out_dir


def MakeMeshcat(serve: bool = False, host: str = "localhost") -> Meshcat:
    """A Meshcat that serves a live page on `host` (first free port from 7000) when `serve`,
    else a recorder on 127.0.0.1 at an ephemeral port (see the module docstring)."""
    # "*" is Meshcat's own word for every interface.
    problem = ListenHostProblem(host) if serve and host != "*" else None
    if problem is not None:
        raise ConfigurationError(f"Meshcat cannot listen on host '{host}': {problem}")
    params = MeshcatParams(host=host) if serve else MeshcatParams(host="127.0.0.1", port=0)
    drake_log = logging.getLogger("drake")
    level = drake_log.level
    drake_log.setLevel(logging.WARNING)  # the caller announces a live page itself
    try:
        return Meshcat(params)
    except RuntimeError as e:
        raise ConfigurationError(f"Meshcat cannot listen on host '{host}': {e}") from None
    finally:
        drake_log.setLevel(level)


def StartReplay(meshcat: Meshcat, live: bool = False) -> None:
    """Starts recording everything drawn in `meshcat` (a MeshcatVisualizer, the station's
    visualization, overlays) into an animation, at 30 frames/s of simulated time: call it
    before simulating, then SaveReplay. With live=False poses and properties go into the
    recording only, which saves the simulation the cost of sending each to a page nobody
    watches; live=True also shows them on the served page."""
    meshcat.StartRecording(frames_per_second=30.0, set_visualizations_while_recording=live)


def SaveReplay(meshcat: Meshcat, path: str | Path) -> Path:
    """Stops the recording StartReplay began and writes it, with the scene, to `path` as a
    self-contained HTML page a browser opens offline (its three.js scripts are inlined);
    returns the path."""
    meshcat.StopRecording()
    meshcat.PublishRecording()
    path = Path(path)
    path.write_text(meshcat.StaticHtml())
    return path


def ServeMeshcat(meshcat: Meshcat, wait_s: float | None = None) -> None:
    """Keeps serving `meshcat` until Ctrl-C, or for wait_s seconds; never reads stdin."""
    until = f"for {wait_s:g} s or until Ctrl-C" if wait_s is not None else "until Ctrl-C"
    deadline = math.inf if wait_s is None else time.monotonic() + wait_s
    try:  # a Ctrl-C right after the announcement ends the serving too, not the command
        print(f"Meshcat keeps serving at {meshcat.web_url()} {until}.", flush=True)
        while (left := deadline - time.monotonic()) > 0:
            time.sleep(min(left, 0.5))
    except KeyboardInterrupt:
        TakeInterrupt()


def AdvanceWithProgress(
    simulator: Simulator,
    t_final: float,
    context: RunContext,
    chunk_s: float = 0.25,
    describe: Callable[[], str] | None = None,
) -> float:
    """Advances `simulator` to `t_final` in chunks, printing progress (describe(), or
    the simulated time) after each; returns the sim time.

    An event or a monitor returning EventStatus.ReachedTermination stops it early; the
    returned time is where it stopped. The pace is the context's (RunContext.pace): against
    hardware wall-clock pace, since the drivers' clocks are real.
    """
    context.pace(simulator, t_final)
    t = simulator.get_context().get_time()
    try:
        while t < t_final:
            status = simulator.AdvanceTo(min(t + chunk_s, t_final))
            t = simulator.get_context().get_time()
            context.progress(describe or (lambda t=t: f"simulated {t:.2f} / {t_final:.2f} s"))
            if status.reason() != status.ReturnReason.kReachedBoundaryTime:
                break
    except KeyboardInterrupt:
        # Ctrl-C or SIGTERM: hardware arms are told to stop now, not after the report of
        # the interrupted run (seconds of figures and replay) at the end of the command.
        with DeferredInterrupts():
            ReportStopErrors(StopAllArms(), "after the interrupt")
        raise
    return t


def RealtimeRate(realtime: float | None, meshcat: bool) -> float:
    """The pace of a run from `--realtime RATE` and `--meshcat`: RATE if given (0 = as fast
    as possible), else real time with a live Meshcat page and as fast as possible without."""
    if realtime is None:
        return 1.0 if meshcat else 0.0
    if not (realtime >= 0 and math.isfinite(realtime)):
        raise ConfigurationError(f"--realtime must be a rate >= 0, got {realtime}")
    return realtime


def _csv_cell(value: Any) -> str:
    """A CSV cell; empty for a value a run did not produce (None, NaN, infinity)."""
    if value is None or (isinstance(value, float) and not math.isfinite(value)):
        return ""
    if isinstance(value, float):
        return f"{value:.9g}"
    return str(value)


def NonFiniteKeys(value: Any, prefix: str = "") -> list[str]:
    """Dotted keys of the NaN and infinite floats in a nested summary."""
    if isinstance(value, float):
        return [] if math.isfinite(value) else [prefix.rstrip(".") or "<value>"]
    if isinstance(value, dict):
        return [k for key, v in value.items() for k in NonFiniteKeys(v, f"{prefix}{key}.")]
    if isinstance(value, list | tuple):
        return [k for i, v in enumerate(value) for k in NonFiniteKeys(v, f"{prefix}[{i}].")]
    return []
