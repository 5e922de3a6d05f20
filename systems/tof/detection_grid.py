"""The ToF tool's 3 x 3 detection grid and its estimators of the hose centre (Wawrzyniak
et al., sections 2.2 and 3.1).

Detection grid. Rows are sensors 1-3, columns sensors 4-6; point (i, j) is where the lines
of sight of row sensor i and column sensor j cross. It is detected when both sensors have a
return; it is a detection error when either range disagrees with a hose of radius r centred
on the point (|range - (distance to the point - r)| > 3/4 of the grid spacing), e.g. the table
seen far beyond the field, or the hose seen at another point of the same line, or when it
lies off the 4-connected patch of consistent points around the best-fitting one (the
flanks of a centred hose seen by the outer cones; see _PatchOfBestFit).

Estimators of the hose centre S in the tool frame T (the paper's S, eq. (8)):
  grid      the mean of the detected, error-free grid points (presence only, the paper).
  ranging   refines the grid: among the sensors of the error-free detected points, the
            nearest row sensor and the nearest column sensor trilaterate the hose centre
            (it lies at range + r from each emitter, in the detection plane, T's y-z
            plane). With the cone angle known, that point then starts a least-squares fit
            to every one of those sensors' ranges: a sensor whose cone holds the centre
            sees the surface at distance - r, one that sees only the hose's flank sees it
            along the cone's edge ray. Given the hose's direction in T, the fit models a
            cylinder of that axis (a hose crossing the plane obliquely) and needs only two
            ranges (the model and the fit: hose_range_model). Nothing detected by the
            grid means nothing detected here too.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from pydrake.math import RigidTransform

from guidedarm.systems.small_vectors import Cross, Distance, Dot, Vector
from guidedarm.systems.tof.hose_range_model import HoseRangeModel, RadiusFit

# A range agrees with a grid point within this fraction of the grid spacing a. A hose
# centred anywhere in the point's cell (a / 2 either way) reads up to a / 2 nearer or
# a / 2 + 1.4 mm farther (seen off-axis by the cone's edge rays) than a hose on the point,
# plus the noise (2 sigma = 4 mm): 16.4 mm for a = 22 mm. A tolerance of only a / 2 made a
# hose midway between two points a coin toss between them (biasing S by up to half a
# diagonal, 15.6 mm, plus noise), while a hose at the next point of the line is a off and
# stays rejected.
CONSISTENCY_FRACTION = 0.75


@dataclass(frozen=True)
class DetectionGrid:
    """The 3 x 3 grid of a tool with row sensors 0-2 and column sensors 3-5.

    X_TS: poses of the six sensor frames in the tool frame T (+z = line of sight).
    hose_radius: radius assumed by the consistency check and the ranging estimator (m).
    cone_angle: the sensors' full cone angle (rad); None keeps ranging to trilateration.
    """

    X_TS: tuple[RigidTransform, ...]
    hose_radius: float
    cone_angle: float | None = None

    def __post_init__(self) -> None:
        emitters = np.array([X.translation() for X in self.X_TS])
        axes = np.array([X.rotation().matrix()[:, 2] for X in self.X_TS])
        points = np.zeros((3, 3, 3))
        for i in range(3):
            for j in range(3):
                points[i, j] = _ClosestPointOfLines(
                    emitters[i], axes[i], emitters[3 + j], axes[3 + j]
                )
        object.__setattr__(self, "emitters", emitters)
        object.__setattr__(self, "axes", axes)
        object.__setattr__(self, "points", points)
        spacing = min(
            np.linalg.norm(points[1, 1] - points[0, 1]), np.linalg.norm(points[1, 1] - points[1, 0])
        )
        object.__setattr__(self, "spacing", float(spacing))
        extent = np.max(np.linalg.norm(points - points[1, 1], axis=2))
        object.__setattr__(self, "field_radius", float(extent + spacing / 2))
        # Detect compares every reading with these (fixed by the geometry).
        row = np.linalg.norm(points - emitters[:3, None, :], axis=2)
        col = np.linalg.norm(points - emitters[None, 3:, :], axis=2)
        object.__setattr__(self, "_expected", (row - self.hose_radius, col - self.hose_radius))
        object.__setattr__(self, "_detect_memo", [None])
        object.__setattr__(self, "_start_memo", [None])
        object.__setattr__(self, "_expected_lists", tuple(e.tolist() for e in self._expected))
        # Floats for the ranging estimator (_Start) and its model (HoseRangeModel).
        object.__setattr__(self, "_emitter_list", [tuple(e) for e in emitters.tolist()])
        object.__setattr__(self, "_axis_list", [tuple(a) for a in axes.tolist()])
        object.__setattr__(self, "_centre", tuple(points[1, 1].tolist()))
        if self.cone_angle is not None:
            model = HoseRangeModel(
                self._emitter_list, self._axis_list, self.hose_radius, self.cone_angle
            )
            object.__setattr__(self, "_ranging", model)

    def ExpectedRanges(self) -> tuple[np.ndarray, np.ndarray]:
        """Ranges (3, 3) of the row and the column sensor for a hose centred at each point."""
        return self._expected

    def Detect(self, ranges: np.ndarray, valid: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(detected, errors), each a (3, 3) bool array (row sensor i, column sensor j),
        read-only: the latest reading's are kept, since a follower, its estimator and the
        sensor's outputs each ask for the same reading's."""
        return self._Detection(ranges, valid)[:2]

    def _Detection(
        self, ranges: np.ndarray, valid: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray, list[list[bool]]]:
        """Detect's (detected, errors) and the error-free detections as lists (RangingEstimate's),
        of the latest reading (kept). In floats: nine points cost numpy more in per-call
        overhead than in arithmetic."""
        ranges, valid = np.asarray(ranges, float), np.asarray(valid, bool)
        key = (ranges.tobytes(), valid.tobytes())
        latest = self._detect_memo[0]  # one read and one write: safe across threads
        if latest is not None and latest[0] == key:
            return latest[1]
        r, v = ranges.tolist(), valid.tolist()
        expected_row, expected_col = self._expected_lists
        tolerance = self.spacing * CONSISTENCY_FRACTION
        detected = [[v[i] and v[3 + j] for j in range(3)] for i in range(3)]
        misfit = [
            [
                max(abs(r[i] - expected_row[i][j]), abs(r[3 + j] - expected_col[i][j]))
                for j in range(3)
            ]
            for i in range(3)
        ]
        consistent = [
            [detected[i][j] and misfit[i][j] <= tolerance for j in range(3)] for i in range(3)
        ]
        patch = _PatchOfBestFit(consistent, misfit)
        good = [[detected[i][j] and patch[i][j] for j in range(3)] for i in range(3)]
        errors = [[detected[i][j] and not patch[i][j] for j in range(3)] for i in range(3)]
        result = (np.array(detected), np.array(errors), good)
        for array in result[:2]:
            array.flags.writeable = False
        self._detect_memo[0] = (key, result)
        return result

    def GridEstimate(self, ranges: np.ndarray, valid: np.ndarray) -> tuple[np.ndarray | None, bool]:
        """The paper's S in T (mean of the error-free detected points) or None; and whether
        the centre point is the only one (the paper's short-step condition)."""
        detected, errors = self.Detect(ranges, valid)
        good = detected & ~errors
        if not good.any():
            return None, False
        centre_only = bool(good[1, 1]) and int(good.sum()) == 1
        return self.points[good].mean(axis=0), centre_only

    def RangingEstimate(
        self, ranges: np.ndarray, valid: np.ndarray, axis: np.ndarray | None = None
    ) -> tuple[np.ndarray | None, bool]:
        """The hose centre in T from the ranges (see the module docstring) or None; and
        whether it lies within half a grid spacing of the centre point. `axis`: the hose's
        unit direction in T when known (the fit then models a cylinder of that axis through
        the centre, see PredictedRange); None: the hose crosses the detection plane
        perpendicularly (along x_T)."""
        start = self._Start(ranges, valid)
        if start is None:
            return None, False
        c, ranges, sensors = start
        if self.cone_angle is not None:
            c = self._ranging.Refine(c, ranges, sensors, axis, self.spacing / 2)
        return np.array(c), Distance(c, self._centre) < self.spacing / 2

    def RadiusEstimate(
        self, ranges: np.ndarray, valid: np.ndarray, axis: np.ndarray | None = None
    ) -> float | None:
        """The hose's radius (m) fitted with its centre to every valid range
        (hose_range_model.RadiusFit, from the ranging estimator's start), or None when the
        grid detects nothing or fewer than five sensors see the hose."""
        start = self._Start(ranges, valid) if self.cone_angle is not None else None
        if start is None:
            return None
        c, range_list, _ = start
        sensors = [k for k in range(6) if valid[k]]
        fit = RadiusFit(self._ranging, c, range_list, sensors, axis, self.spacing / 2)
        return None if fit is None else fit[1]

    def _Start(
        self, ranges: np.ndarray, valid: np.ndarray
    ) -> tuple[Vector, list[float], list[int]] | None:
        """The ranging estimator's start (module docstring): the trilaterated centre (T),
        the ranges and the trusted sensors with a return; None when the grid detects
        nothing or the start lies off the field. The latest reading's is kept: a follower
        estimates each reading twice (without and with the hose's axis)."""
        ranges, valid = np.asarray(ranges, float), np.asarray(valid, bool)
        key = (ranges.tobytes(), valid.tobytes())
        latest = self._start_memo[0]  # one read and one write: safe across threads
        if latest is not None and latest[0] == key:
            return latest[1]
        good = self._Detection(ranges, valid)[2]
        # Only sensors that take part in an error-free grid detection are trusted.
        trusted = [any(line) for line in good] + [any(column) for column in zip(*good, strict=True)]
        # Floats from here on (numpy's per-call overhead on 3-vectors outweighs the work).
        ranges, valid = ranges.tolist(), valid.tolist()
        centre = self._centre
        row = _Nearest(ranges, trusted, range(3))
        col = _Nearest(ranges, trusted, range(3, 6))
        r = self.hose_radius
        emitters, axes = self._emitter_list, self._axis_list
        candidates = []
        if row is not None and col is not None:
            candidates.append(
                _CircleIntersection(
                    emitters[row],
                    ranges[row] + r,
                    emitters[col],
                    ranges[col] + r,
                    axes[row],
                    centre,
                )
            )
        for k in (row, col):
            if k is not None:
                e, z, t = emitters[k], axes[k], ranges[k] + r
                candidates.append((e[0] + z[0] * t, e[1] + z[1] * t, e[2] + z[2] * t))
        start = next(
            (c for c in candidates if c is not None and Distance(c, centre) <= self.field_radius),
            None,
        )
        if start is not None:
            start = (start, ranges, [k for k in range(6) if trusted[k] and valid[k]])
        self._start_memo[0] = (key, start)
        return start

    def PredictedRange(self, k: int, c: np.ndarray, axis: np.ndarray | None = None) -> float | None:
        """Range (m) sensor k reads for a hose centred at c (the detection plane, T), or None
        when its cone misses the hose: the nearest in-plane ray of the cone. With `axis`
        (unit, T) the hose is the cylinder of that axis through c (HoseRangeModel's
        CylinderRange). Needs cone_angle."""
        c = tuple(np.asarray(c, float).tolist())
        if axis is not None:
            return self._ranging.CylinderRange(k, c, tuple(np.asarray(axis, float).tolist()))
        return self._ranging.PlaneRange(k, c)


def _PatchOfBestFit(consistent: list[list[bool]], misfit: list[list[float]]) -> list[list[bool]]:
    """The 4-connected patch of consistent points (3 x 3) that holds the best-fitting one.

    The hose crosses the detection plane once, and a hose between two points is consistent
    with both, so the points that see it are edge neighbours. A consistent point off that
    patch is a flank seen by a cone's edge rays or another object: with the hose at the
    centre the two outer sensors facing a far corner read the hose's flanks at ranges that
    fit the corner too, and the mean of centre and corner put S half a grid diagonal
    (15.6 mm) off the hose."""
    patch = [[False] * 3 for _ in range(3)]
    start = None
    for i in range(3):
        for j in range(3):
            if consistent[i][j] and (start is None or misfit[i][j] < misfit[start[0]][start[1]]):
                start = (i, j)
    frontier = [start] if start is not None else []
    while frontier:
        i, j = frontier.pop()
        if not (0 <= i < 3 and 0 <= j < 3) or patch[i][j] or not consistent[i][j]:
            continue
        patch[i][j] = True
        frontier += [(i + 1, j), (i - 1, j), (i, j + 1), (i, j - 1)]
    return patch


def _Nearest(ranges: list[float], valid: list[bool], indices: range) -> int | None:
    best = None
    for k in indices:
        if valid[k] and (best is None or ranges[k] < ranges[best]):
            best = k
    return best


def _ClosestPointOfLines(p1, u1, p2, u2) -> np.ndarray:
    """Midpoint of the shortest segment between lines p1 + s u1 and p2 + t u2."""
    w = p1 - p2
    a, b, c = u1 @ u1, u1 @ u2, u2 @ u2
    d, e = u1 @ w, u2 @ w
    den = a * c - b * b
    s = (b * e - c * d) / den
    t = (a * e - b * d) / den
    return (p1 + s * u1 + p2 + t * u2) / 2


def _CircleIntersection(
    c1: Vector, r1: float, c2: Vector, r2: float, u1: Vector, centre: Vector
) -> Vector | None:
    """The intersection of spheres (c1, r1), (c2, r2) in the plane of c1, c2 and u1 that is
    nearest to `centre` (closest point when they do not meet)."""
    d = Distance(c2, c1)
    if d < 1e-9:
        return None
    ex = tuple((b - a) / d for a, b in zip(c1, c2, strict=True))
    normal = Cross(ex, u1)
    length = math.sqrt(Dot(normal, normal))
    if length < 1e-9:
        return None
    ey = Cross(tuple(v / length for v in normal), ex)
    x = (r1 * r1 - r2 * r2 + d * d) / (2 * d)
    h2 = r1 * r1 - x * x
    h = math.sqrt(h2) if h2 > 0 else 0.0
    options = [
        tuple(c + x * a + sign * h * b for c, a, b in zip(c1, ex, ey, strict=True))
        for sign in (1.0, -1.0)
    ]
    return min(options, key=lambda p: Distance(p, centre))
