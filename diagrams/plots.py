"""Matplotlib figures shared by the tasks (Agg backend: no display needed)."""

from __future__ import annotations

import matplotlib

matplotlib.use("Agg")

import matplotlib.pyplot as plt
import numpy as np


def PlotJointSeries(
    times: np.ndarray,
    series: dict[str, np.ndarray],
    ylabel: str,
    limits: tuple[np.ndarray, np.ndarray] | None = None,
    title: str = "",
) -> plt.Figure:
    """One subplot per joint; each series is (num_joints, num_samples); limits dashed."""
    first = next(iter(series.values()))
    n = first.shape[0]
    figure, axes = plt.subplots(n, 1, sharex=True, figsize=(8, 1.6 * n + 0.6))
    axes = np.atleast_1d(axes)
    for j, axis in enumerate(axes):
        for label, values in series.items():
            axis.plot(times, values[j], label=label, linewidth=1.2)
        if limits is not None:
            for bound in limits:
                axis.axhline(bound[j], color="k", linestyle="--", linewidth=0.8)
        axis.set_ylabel(f"J{j + 1}")
        axis.grid(True, alpha=0.3)
    axes[0].legend(loc="upper right", fontsize="small")
    axes[0].set_title(title or ylabel)
    axes[-1].set_xlabel("t (s)")
    figure.supylabel(ylabel)
    return figure
