"""Ground-truth metrics and figures of a path-following run (seed 000, figures 11-21).

Errors are distances to the true centerline (m in, mm in the summary). Steps whose tool
centre O lies beyond either end of the hose (the follower looking for more hose after the
end) are left out of the tracking and detection errors; coverage is the fraction of the
centerline that lies within TRACKING_BOUND of some sensing position O.
"""

from __future__ import annotations

import numpy as np

from guidedarm.diagrams import plots  # noqa: F401  (selects the Agg backend)
from guidedarm.systems.path_following.hose_geometry import DistanceToCenterline, Resample
from guidedarm.systems.path_following.path_follower_math import RECORD_FIELDS

TRACKING_BOUND = 0.025


def Column(records: np.ndarray, name: str) -> np.ndarray:
    """One RECORD_FIELDS column of the step records."""
    return records[:, RECORD_FIELDS.index(name)] if len(records) else np.zeros(0)


def Positions(records: np.ndarray, prefix: str) -> np.ndarray:
    """(steps, 3) of O or S."""
    return np.column_stack([Column(records, f"{prefix}_{a}") for a in "xyz"]).reshape(-1, 3)


def OnHose(points: np.ndarray, centerline: np.ndarray) -> np.ndarray:
    """Whether each point projects inside the centerline (not beyond an end)."""
    start_dir = centerline[1] - centerline[0]
    end_dir = centerline[-1] - centerline[-2]
    before = (points - centerline[0]) @ start_dir < 0
    after = (points - centerline[-1]) @ end_dir > 0
    return ~(before | after)


def Metrics(records: np.ndarray, centerline: np.ndarray) -> dict:
    """The summary's ground-truth metrics (mm) of one run."""
    p_WO = Positions(records, "O")
    S = Positions(records, "S")
    detected = Column(records, "detected") > 0.5
    inside = OnHose(p_WO, centerline) if len(p_WO) else np.zeros(0, bool)
    tracking = DistanceToCenterline(p_WO[inside], centerline) if inside.any() else np.zeros(1)
    use = detected & inside
    detection = DistanceToCenterline(S[use], centerline) if use.any() else np.zeros(1)
    fine = Resample(centerline, 0.002)
    if len(p_WO):
        nearest = np.min(np.linalg.norm(fine[:, None, :] - p_WO[None], axis=2), axis=1)
        coverage = float(np.mean(nearest <= TRACKING_BOUND))
    else:
        coverage = 0.0
    ik = Column(records, "ik_time")
    ik = ik[ik > 0] if (ik > 0).any() else np.zeros(1)
    return {
        "steps": len(records),
        "coverage": round(coverage, 4),
        "tracking_error_mean_mm": round(1000 * float(np.mean(tracking)), 2),
        "tracking_error_max_mm": round(1000 * float(np.max(tracking)), 2),
        "detected_path_error_mean_mm": round(1000 * float(np.mean(detection)), 2),
        "detected_path_error_max_mm": round(1000 * float(np.max(detection)), 2),
        "lost_steps": int(np.sum(~detected)),
        "recoveries": int(Column(records, "recoveries")[-1]) if len(records) else 0,
        "ik_time_median_ms": round(1000 * float(np.median(ik)), 2),
        "ik_time_p99_ms": round(1000 * float(np.percentile(ik, 99)), 2),
    }


def DetectedPath(records: np.ndarray) -> np.ndarray:
    """The detected hose points S, in step order (m)."""
    return Positions(records, "S")[Column(records, "detected") > 0.5]


def Repeatability(first: np.ndarray, second: np.ndarray) -> tuple[float, float]:
    """Mean and max distance (mm) of the second run's detected points to the first run's
    detected path (a polyline), as the seed compares its runs 1 and 2 of path 1."""
    if len(first) < 2 or len(second) == 0:
        return 0.0, 0.0
    d = DistanceToCenterline(second, first)
    return round(1000 * float(np.mean(d)), 2), round(1000 * float(np.max(d)), 2)


def PlotDetectedPath(centerline: np.ndarray, runs: dict[str, np.ndarray], title: str):
    """Four views like the seed's figures 11-21: isometric, front (YZ), side (XZ), top (YX);
    the true hose in grey, each run's detected path in green shades."""
    import matplotlib.pyplot as plt

    figure = plt.figure(figsize=(11, 9))
    colours = ["tab:green", "darkgreen", "limegreen"]
    iso = figure.add_subplot(2, 2, 1, projection="3d")
    views = [
        (figure.add_subplot(2, 2, k), axes) for k, axes in ((2, (1, 2)), (3, (0, 2)), (4, (1, 0)))
    ]
    names = "xyz"
    iso.plot(*centerline.T, color="0.6", linewidth=5, alpha=0.6, label="hose (true)")
    for (name, points), colour in zip(runs.items(), colours, strict=False):
        if len(points):
            iso.plot(*points.T, color=colour, linewidth=1.5, marker=".", label=name)
    iso.set_xlabel("x (m)")
    iso.set_ylabel("y (m)")
    iso.set_zlabel("z (m)")
    iso.set_title("(a) isometric")
    iso.legend(fontsize="small")
    for (axis, (i, j)), label in zip(
        views, ("(b) front YZ", "(c) side XZ", "(d) top YX"), strict=True
    ):
        axis.plot(centerline[:, i], centerline[:, j], color="0.6", linewidth=5, alpha=0.6)
        for (_, points), colour in zip(runs.items(), colours, strict=False):
            if len(points):
                axis.plot(
                    points[:, i],
                    points[:, j],
                    color=colour,
                    linewidth=1.2,
                    marker=".",
                    markersize=3,
                )
        axis.set_xlabel(f"{names[i]} (m)")
        axis.set_ylabel(f"{names[j]} (m)")
        axis.set_aspect("equal", adjustable="datalim")
        axis.grid(True, alpha=0.3)
        axis.set_title(label)
    figure.suptitle(title)
    return figure
