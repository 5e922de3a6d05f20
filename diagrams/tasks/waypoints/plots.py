"""Figures of the waypoint planner (like Pająk's figures 2-14): TCP path, c(t)."""

from __future__ import annotations

import numpy as np

from guidedarm.diagrams.plots import plt


def PlotTcpPath(
    paths: dict[str, np.ndarray], waypoints: np.ndarray, radius: float, start: np.ndarray
) -> plt.Figure:
    """3D TCP paths (samples x 3, m, base frame) with the waypoints and, around every
    intermediate waypoint, the blending neighbourhood sphere of `radius` (m)."""
    figure = plt.figure(figsize=(7, 6))
    axis = figure.add_subplot(projection="3d")
    for label, path in paths.items():
        axis.plot(path[:, 0], path[:, 1], path[:, 2], label=label, linewidth=1.5)
    points = np.atleast_2d(waypoints)[:, :3]
    axis.scatter(*points.T, color="k", marker="x", label="waypoints")
    axis.scatter(*start[:3], color="g", marker="o", label="start")
    u, v = np.meshgrid(np.linspace(0, 2 * np.pi, 24), np.linspace(0, np.pi, 12))
    sphere = radius * np.array([np.cos(u) * np.sin(v), np.sin(u) * np.sin(v), np.cos(v)])
    for point in points[:-1]:
        axis.plot_wireframe(
            point[0] + sphere[0],
            point[1] + sphere[1],
            point[2] + sphere[2],
            color="tab:orange",
            linewidth=0.4,
            alpha=0.6,
        )
    axis.set_xlabel("x (m)")
    axis.set_ylabel("y (m)")
    axis.set_zlabel("z (m)")
    axis.set_box_aspect(np.ptp(np.vstack([points, start[None, :3]]), axis=0) + 2 * radius)
    axis.legend(loc="upper left", fontsize="small")
    axis.set_title("TCP path in the base frame")
    return figure


def PlotScaling(times: np.ndarray, c: np.ndarray) -> plt.Figure:
    """The acceleration scaling coefficient c(t)."""
    figure, axis = plt.subplots(figsize=(8, 2.8))
    axis.plot(times, c, linewidth=1.2)
    axis.set_xlabel("t (s)")
    axis.set_ylabel("c")
    axis.set_ylim(-0.05, max(1.05, float(np.max(c)) + 0.05))
    axis.grid(True, alpha=0.3)
    axis.set_title("trajectory scaling coefficient c(t)")
    return figure
