"""Ground-truth metrics and figures of a path-following run (Wawrzyniak et al., figures 11-21).

Errors are distances to the true centerline (m in, mm in the summary). Each step is compared
with the part of the centerline near its own arc length (CenterlineMatch), so that a closed or
self-crossing hose is judged where the tool is on its way, not against another branch
passing nearby. Steps whose tool centre O lies beyond either end of the hose (the follower
looking for more hose after the end) are left out of the tracking and detection errors;
coverage is the fraction of the centerline that lies within TRACKING_BOUND of a sensing
position O matched near it.
"""

from __future__ import annotations

import numpy as np

from guidedarm.diagrams.plots import PlotAlongPath  # (also selects the Agg backend)
from guidedarm.systems.path_following.path_follower_math import RECORD_FIELDS
from guidedarm.systems.scene.hose_geometry import ArcLength, DistanceToCenterline, Resample

TRACKING_BOUND = 0.025
# A step is matched within MATCH_SLACK + 2 x the tool's move since the previous step, at
# most MATCH_WINDOW, of arc length (m) from the previous step's match: the closest point of
# a tool within TRACKING_BOUND of a bend of radius 2 x TRACKING_BOUND or more moves at most
# twice as far as the tool. A fixed window let the match jump to a parallel branch of a
# folded hose within it (and the followed length with it).
MATCH_WINDOW = 0.1
MATCH_SLACK = 0.01
MATCH_SPACING = 0.002


def Column(records: np.ndarray, name: str) -> np.ndarray:
    """One RECORD_FIELDS column of the step records."""
    return records[:, RECORD_FIELDS.index(name)] if len(records) else np.zeros(0)


def Positions(records: np.ndarray, prefix: str) -> np.ndarray:
    """(steps, 3) of O or S."""
    return np.column_stack([Column(records, f"{prefix}_{a}") for a in "xyz"]).reshape(-1, 3)


class CenterlineMatch:
    """The tool centres O of a run (in step order, starting at the hose's first point)
    matched to the centerline: `s` (m), each step's arc length, the closest centerline
    point within reach of the previous step's (MATCH_SLACK); `beyond`, whether O lies beyond an
    end of the hose; `pieces`, each step's index range of the resampled centerline within
    2 x TRACKING_BOUND of arc length of its match (where the errors are measured and the
    hose counts as covered: another branch of a folded hose is not)."""

    def __init__(self, p_WO: np.ndarray, centerline: np.ndarray) -> None:
        self.fine = Resample(centerline, MATCH_SPACING)
        self.s_fine = ArcLength(self.fine)
        count = len(p_WO)
        self.s = np.zeros(count)
        self.beyond = np.zeros(count, bool)
        self.pieces = []
        s_previous, last = 0.0, len(self.fine) - 1
        moves = np.linalg.norm(np.diff(p_WO, axis=0, prepend=p_WO[:1]), axis=1)
        for i, p in enumerate(p_WO):
            lo, hi = self._Piece(s_previous, min(MATCH_SLACK + 2 * moves[i], MATCH_WINDOW))
            k = lo + int(np.argmin(np.linalg.norm(self.fine[lo : hi + 1] - p, axis=1)))
            self.s[i] = s_previous = self.s_fine[k]
            self.pieces.append(self._Piece(s_previous, 2 * TRACKING_BOUND))
            self.beyond[i] = (
                k == 0 and (p - self.fine[0]) @ (self.fine[1] - self.fine[0]) < 0
            ) or (k == last and (p - self.fine[-1]) @ (self.fine[-1] - self.fine[-2]) > 0)

    def _Piece(self, s: float, window: float) -> tuple[int, int]:
        """The index range of the resampled centerline within `window` (m) of arc length
        s."""
        lo = int(np.searchsorted(self.s_fine, s - window))
        hi = int(np.searchsorted(self.s_fine, s + window, side="right")) - 1
        return lo, max(hi, lo + 1)

    def Distances(self, points: np.ndarray, steps: np.ndarray) -> np.ndarray:
        """Distance (m) of points[i] to the centerline piece of step i, for the steps
        selected by the boolean mask `steps`."""
        return np.array(
            [
                DistanceToCenterline(points[i], self.fine[lo : hi + 1])[0]
                for i, (lo, hi) in enumerate(self.pieces)
                if steps[i]
            ]
        )

    def Coverage(self, p_WO: np.ndarray) -> float:
        """Fraction of the centerline within TRACKING_BOUND of a step matched near it."""
        covered = np.zeros(len(self.fine), bool)
        for p, (lo, hi) in zip(p_WO, self.pieces, strict=True):
            near = np.linalg.norm(self.fine[lo : hi + 1] - p, axis=1) <= TRACKING_BOUND
            covered[lo : hi + 1] |= near
        return float(np.mean(covered))


# The numbers of Metrics (the last three not with continuous motion). The tool centre O of
# the records is where the follower believes the tool is (its measured joints through the
# nominal kinematics); TRUE_METRICS are its twins on the true cell.
FOLLOWING_METRICS = {
    "steps": (
        "count",
        "the follower's steps (one ToF reading and move each); with motion continuous its "
        "ToF readings",
    ),
    "coverage": (
        "fraction",
        f"share of the hose's centerline within {1000 * TRACKING_BOUND:.0f} mm of a tool "
        "centre O (believed) matched near it",
    ),
    "tracking_error_mean_mm": (
        "mm",
        "mean distance of the tool centre O (believed) from the true centerline over the "
        "steps (steps beyond either end of the hose left out)",
    ),
    "tracking_error_max_mm": ("mm", "largest distance of O (believed) from the true centerline"),
    "detected_path_error_mean_mm": (
        "mm",
        "mean distance of the detected hose point S (placed from the tool pose the follower "
        "believes: the path a user gets) from the hose's centerline, over the steps that "
        "detected the hose",
    ),
    "detected_path_error_max_mm": ("mm", "largest distance of S from the true centerline"),
    "average_speed_mm_s": (
        "mm/s",
        "hose length followed (the farthest arc length reached within "
        f"{1000 * TRACKING_BOUND:.0f} mm of the hose) over the time it took",
    ),
    "lost_steps": (
        "count",
        "steps (continuous: readings) in which the tool did not detect the hose: no "
        "error-free grid point or no estimate; the search past the hose's end and a "
        "recovery's retries count, so a successful run has some",
    ),
    "recoveries": ("count", "retries after losing the hose that found it again (stop-and-go)"),
    "ik_time_median_ms": ("ms", "median wall-clock time of one IK solve per step (stop-and-go)"),
    "ik_time_p99_ms": ("ms", "99th percentile of that time (stop-and-go)"),
}


TRUE_METRICS = {
    "true_coverage": ("fraction", "coverage of the true tool centre (the true arm's)"),
    "true_tracking_error_mean_mm": (
        "mm",
        "tracking_error_mean_mm of the true tool centre: the true arm's tool frame origin "
        "at each step's reading",
    ),
    "true_tracking_error_max_mm": ("mm", "tracking_error_max_mm of the true tool centre"),
}


def Metrics(records: np.ndarray, centerline: np.ndarray, continuous: bool = False) -> dict:
    """The summary's ground-truth metrics (mm) of one run. `steps` counts the follower's
    steps (continuous: its readings); an error without a point to measure is None.
    Continuous following has no IK steps and no recoveries, so it reports neither."""
    p_WO = Positions(records, "O")
    S = Positions(records, "S")
    detected = Column(records, "detected") > 0.5
    match = CenterlineMatch(p_WO, centerline)
    use = detected & ~match.beyond
    detection = match.Distances(S, use) if use.any() else None
    metrics = {
        "steps": len(records),
        **_ToolMetrics(p_WO, match),
        **_MeanAndMax("detected_path_error", detection),
        "average_speed_mm_s": round(1000 * AverageSpeed(records, match), 1) if len(p_WO) else 0.0,
        "lost_steps": int(np.sum(~detected)),
    }
    if continuous:
        return metrics
    ik = Column(records, "ik_time")
    ik = ik[ik > 0] if (ik > 0).any() else np.zeros(1)
    return {
        **metrics,
        "recoveries": int(Column(records, "recoveries")[-1]) if len(records) else 0,
        "ik_time_median_ms": round(1000 * float(np.median(ik)), 2),
        "ik_time_p99_ms": round(1000 * float(np.percentile(ik, 99)), 2),
    }


def TrueMetrics(p_WO: np.ndarray, centerline: np.ndarray) -> dict:
    """TRUE_METRICS of the true tool centres p_WO (steps x 3, m; truth.TrueCell), the
    believed ones' twins, matched to the centerline as Metrics matches the records."""
    metrics = _ToolMetrics(p_WO, CenterlineMatch(p_WO, centerline))
    return {f"true_{name}": value for name, value in metrics.items()}


def _ToolMetrics(p_WO: np.ndarray, match: CenterlineMatch) -> dict:
    """`coverage` and `tracking_error_mean_mm` / `_max_mm` of tool centres p_WO (m) and
    their match."""
    inside = ~match.beyond
    tracking = match.Distances(p_WO, inside) if inside.any() else None
    return {
        "coverage": round(match.Coverage(p_WO), 4) if len(p_WO) else 0.0,
        **_MeanAndMax("tracking_error", tracking),
    }


def _MeanAndMax(name: str, distances: np.ndarray | None) -> dict:
    """`<name>_mean_mm` and `<name>_max_mm` of distances (m), None without any."""
    if distances is None:
        return {f"{name}_mean_mm": None, f"{name}_max_mm": None}
    return {
        f"{name}_mean_mm": round(1000 * float(np.mean(distances)), 2),
        f"{name}_max_mm": round(1000 * float(np.max(distances)), 2),
    }


def AverageSpeed(records: np.ndarray, match: CenterlineMatch) -> float:
    """Followed hose length over the time it took (m/s): the farthest arc length a step
    reached within TRACKING_BOUND of the hose, over the time from the first record to the
    first step that reached it (the search past the hose's end is not following)."""
    t = Column(records, "t")
    on_hose = np.array(
        [
            np.min(np.linalg.norm(match.fine[lo : hi + 1] - p, axis=1)) <= TRACKING_BOUND
            for p, (lo, hi) in zip(Positions(records, "O"), match.pieces, strict=True)
        ]
    )
    if not on_hose.any():
        return 0.0
    reached = np.where(on_hose, match.s, 0.0)
    k = int(np.argmax(reached))
    return float(reached[k] / (t[k] - t[0])) if t[k] > t[0] else 0.0


def SpeedAndErrorAlongPath(records: np.ndarray, centerline: np.ndarray, title: str):
    """Figure: the tool's speed along the hose (mm/s; arc length gained per second, over
    0.2 s windows, or per step when steps are longer) and its tracking error (mm) over the
    arc length, up to the farthest point reached (plots.PlotAlongPath)."""
    match = CenterlineMatch(Positions(records, "O"), centerline)
    t = Column(records, "t")
    inside = ~match.beyond
    s, t = match.s[inside], t[inside]
    error = 1000 * match.Distances(Positions(records, "O"), inside)
    k = np.searchsorted(t, t - 0.2)
    speed = 1000 * (s - s[k]) / np.maximum(t - t[k], 1e-9)
    speed[t - t[k] <= 0] = 0.0
    return PlotAlongPath(
        s,
        [("speed along the hose (mm/s)", speed, None), ("tracking error (mm)", error, None)],
        title,
    )


def DetectedPath(records: np.ndarray) -> np.ndarray:
    """The detected hose points S, in step order (m)."""
    return Positions(records, "S")[Column(records, "detected") > 0.5]


def Repeatability(first: np.ndarray, second: np.ndarray) -> tuple[float, float]:
    """Mean and max distance (mm) of the second run's detected points to the first run's
    detected path (a polyline), as the paper compares its runs 1 and 2 of path 1."""
    if len(first) < 2 or len(second) == 0:
        return 0.0, 0.0
    d = DistanceToCenterline(second, first)
    return round(1000 * float(np.mean(d)), 2), round(1000 * float(np.max(d)), 2)


def PlotDetectedPath(centerline: np.ndarray, runs: dict[str, np.ndarray], title: str):
    """Four views like the paper's figures 11-21: isometric, front (YZ), side (XZ), top (YX);
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
