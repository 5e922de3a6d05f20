"""Matplotlib figures shared by the tasks (Agg backend: no display needed).

Every figure a run saves goes through FinishFigure (RunContext.save_figure): the run's
title (arm, scenario, variant) on top, its headline figures below, plain tick labels (no
offset notation, so a 60 urad wiggle is not drawn as if it filled the panel), equal axes in
3D, and one scale across the equal-aspect views of a figure.
"""

from __future__ import annotations

import matplotlib

matplotlib.use("Agg")

import matplotlib.pyplot as plt
import matplotlib.ticker
import numpy as np

# Below this, tracking errors are drawn in milli-units (rad -> mrad).
_MILLI = 1e3


def PlotJointSeries(
    times: np.ndarray,
    series: dict[str, np.ndarray],
    ylabel: str,
    limits: tuple[np.ndarray, np.ndarray] | None = None,
    title: str = "",
) -> plt.Figure:
    """One subplot per joint; each series is (num_joints, num_samples); limits dashed (pass
    None when the limit is off). With both a "commanded" and a "measured" series a second
    column shows the tracking error, measured - commanded, in milli-units (e.g. mrad)."""
    first = next(iter(series.values()))
    n = first.shape[0]
    tracking = "commanded" in series and "measured" in series
    columns = 2 if tracking else 1
    figure, axes = plt.subplots(
        n, columns, sharex=True, figsize=(8 + 4 * (columns - 1), 1.6 * n + 0.6), squeeze=False
    )
    for j in range(n):
        axis = axes[j, 0]
        for label, values in series.items():
            # Dashed and wider where the measured line would hide it.
            on_top = tracking and label == "commanded"
            style = {"linestyle": "--", "linewidth": 1.6} if on_top else {}
            axis.plot(times, values[j], label=label, **{"linewidth": 1.2, **style})
        if limits is not None:
            for bound in limits:
                axis.axhline(bound[j], color="k", linestyle="--", linewidth=0.8)
        axis.set_ylabel(f"J{j + 1}")
        axis.grid(True, alpha=0.3)
        if tracking:
            error = _MILLI * (series["measured"][j] - series["commanded"][j])
            axes[j, 1].plot(times, error, color="tab:red", linewidth=1.0)
            axes[j, 1].axhline(0.0, color="k", linewidth=0.5)
            axes[j, 1].grid(True, alpha=0.3)
    axes[0, 0].legend(loc="upper right", fontsize="small")
    axes[0, 0].set_title(title or ylabel)
    if tracking:
        unit = ylabel[ylabel.find("(") + 1 : ylabel.rfind(")")] if "(" in ylabel else ""
        axes[0, 1].set_title(f"tracking error, measured - commanded (m{unit})")
        axes[-1, 1].set_xlabel("t (s)")
    axes[-1, 0].set_xlabel("t (s)")
    figure.supylabel(ylabel)
    return figure


def PlotAlongPath(
    s: np.ndarray, series: list[tuple[str, np.ndarray, float | None]], title: str = ""
) -> plt.Figure:
    """One panel per series over the arc length s (m, drawn in mm): (y label, values,
    a bound drawn dashed or None), e.g. speed and tracking error along a hose."""
    figure, axes = plt.subplots(len(series), 1, figsize=(9, 2.6 * len(series)), sharex=True)
    axes = np.atleast_1d(axes)
    for axis, (label, values, bound) in zip(axes, series, strict=True):
        axis.plot(1000 * s, values, linewidth=1.0)
        if bound is not None:
            axis.axhline(bound, color="tab:red", linestyle="--", linewidth=0.8)
        axis.set_ylabel(label)
        axis.grid(True, alpha=0.3)
    axes[-1].set_xlabel("arc length along the hose (mm)")
    if title:
        figure.suptitle(title)
    return figure


def FinishFigure(figure: plt.Figure, title: str = "", headline: str = "") -> None:
    """The finishing every saved figure gets (see the module docstring): `title` above
    everything (and above a title of its own), `headline` (e.g. "max error 1.2 mm") below
    everything, so neither covers a label."""
    for axis in figure.axes:
        for formatter_axis in _ValueAxes(axis):
            formatter = formatter_axis.get_major_formatter()
            if isinstance(formatter, matplotlib.ticker.ScalarFormatter):
                formatter.set_useOffset(False)
    _OneScale(figure)
    if not (title or headline):
        return
    # Placed from the axes' positions (no drawing needed), clear of the axes' titles above
    # and of their tick labels and x label below; the saved figure's tight box grows to them.
    inch = 1.0 / figure.get_figheight()
    top = max(a.get_position().y1 for a in figure.axes)
    bottom = min(a.get_position().y0 for a in figure.axes)
    own = figure.get_suptitle()
    if title:
        y = max(top + 0.45 * inch, 0.98 + (0.3 * inch if own else 0.0))
        figure.text(0.5, y, title, ha="center", va="bottom", fontsize="medium")
    if headline:
        figure.text(0.5, bottom - 0.6 * inch, headline, ha="center", va="top")


def _ValueAxes(axis) -> list:
    names = ["xaxis", "yaxis", "zaxis"]
    return [getattr(axis, n) for n in names if hasattr(axis, n)]


def _Is3d(axis) -> bool:
    return hasattr(axis, "get_zlim")


def _OneScale(figure: plt.Figure) -> None:
    """3D axes get equal x, y, z scales; when a figure holds 2D axes drawn with equal
    aspect, every such view and every 3D view spans the same length (one scale)."""
    flat = [a for a in figure.axes if not _Is3d(a) and a.get_aspect() == 1.0]
    spans = []
    for axis in flat:
        bounds = axis.dataLim
        spans.append(max(bounds.width, bounds.height))
    for axis in figure.axes:
        if _Is3d(axis):
            limits = np.array([axis.get_xlim3d(), axis.get_ylim3d(), axis.get_zlim3d()])
            spans.append(float(np.max(limits[:, 1] - limits[:, 0])))
    if not spans:
        return
    span = max(spans) * (1.08 if flat else 1.0)
    for axis in flat:
        centre = axis.dataLim.get_points().mean(axis=0)
        axis.set_adjustable("box")
        axis.set_xlim(centre[0] - span / 2, centre[0] + span / 2)
        axis.set_ylim(centre[1] - span / 2, centre[1] + span / 2)
    for axis in figure.axes:
        if _Is3d(axis):
            limits = np.array([axis.get_xlim3d(), axis.get_ylim3d(), axis.get_zlim3d()])
            own = float(np.max(limits[:, 1] - limits[:, 0])) if not flat else span
            centre = limits.mean(axis=1)
            axis.set_xlim3d(centre[0] - own / 2, centre[0] + own / 2)
            axis.set_ylim3d(centre[1] - own / 2, centre[1] + own / 2)
            axis.set_zlim3d(centre[2] - own / 2, centre[2] + own / 2)
            axis.set_box_aspect((1.0, 1.0, 1.0))
