"""Mathematics of the six-sensor ToF detection tool (Wawrzyniak et al., sections 2.2 and 3.1).

Ray casting. Each VL6180X-like sensor S sees a cone (25 deg vertex angle) around its +z
axis. The cone is sampled by rays (a centre ray and rings of rays); the sensor reports the
nearest surface any ray meets within max_range. A ray is cast by sphere tracing against the
scene's proximity geometry with QueryObject.ComputeSignedDistanceToPoint: at a point p the
nearest surface is at least the minimum signed distance d away, so the ray advances by d
until d < hit_tolerance (a hit) or it leaves the range (no return). This senses whatever
geometry SceneGraph holds (hose, table, brackets, the robot), is exact for every shape that
query supports (all Drake primitives), and costs only a broadphase check for a sensor with
nothing within range. A depth camera per sensor would also work, but six VTK renders cost
more than the handful of distance queries a reading needs, and rendered depth is quantised
by the pixel grid.

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
            ranges. Nothing detected by the grid means nothing detected here too.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from pydrake.geometry import GeometryId, QueryObject
from pydrake.math import RigidTransform

# A range agrees with a grid point within this fraction of the grid spacing a. A hose
# centred anywhere in the point's cell (a / 2 either way) reads up to a / 2 nearer or
# a / 2 + 1.4 mm farther (seen off-axis by the cone's edge rays) than a hose on the point,
# plus the noise (2 sigma = 4 mm): 16.4 mm for a = 22 mm. A tolerance of only a / 2 made a
# hose midway between two points a coin toss between them (biasing S by up to half a
# diagonal, 15.6 mm, plus noise), while a hose at the next point of the line is a off and
# stays rejected.
CONSISTENCY_FRACTION = 0.75
# Rim rays over the half of a cone's rim that faces an oblique hose (_CylinderRange).
BOUNDARY_SAMPLES = 19
_RIM_PHI = np.linspace(-math.pi / 2, math.pi / 2, BOUNDARY_SAMPLES)
# A 3-vector as floats (x, y, z).
Vector = tuple[float, float, float]


def ConeRays(cone_angle: float, rings: int) -> np.ndarray:
    """Unit ray directions (K, 3) in the sensor frame: the +z axis and `rings` rings up to
    the cone's half angle, with 6 k rays on ring k."""
    half = cone_angle / 2
    rays = [np.array([0.0, 0.0, 1.0])]
    for k in range(1, rings + 1):
        theta = half * k / rings
        for j in range(6 * k):
            phi = 2 * math.pi * j / (6 * k)
            rays.append(
                np.array(
                    [
                        math.sin(theta) * math.cos(phi),
                        math.sin(theta) * math.sin(phi),
                        math.cos(theta),
                    ]
                )
            )
    return np.array(rays)


@dataclass(frozen=True)
class RayCaster:
    """Sphere tracing of cone rays against a QueryObject (ranges in m, poses in world W)."""

    rays_S: np.ndarray
    max_range: float
    ignored: frozenset[GeometryId] = frozenset()
    hit_tolerance: float = 2e-4
    max_iterations: int = 48

    def Range(self, query: QueryObject, X_WS: RigidTransform) -> float:
        """Nearest return within the cone (m), or math.inf when nothing is in range."""
        origin = X_WS.translation()
        d_origin = self._Distance(query, origin, self.max_range)
        if d_origin is None:
            return math.inf
        directions = X_WS.rotation().matrix() @ self.rays_S.T
        best = math.inf
        for k in range(directions.shape[1]):
            best = min(best, self._Trace(query, origin, directions[:, k], best, d_origin))
        return best

    def _Trace(self, query, origin: np.ndarray, u: np.ndarray, limit: float, d: float) -> float:
        """Distance along u to the first surface within limit (m), or math.inf; d is the
        distance from the origin to the nearest surface. The distance field is 1-Lipschitz,
        so after an advance by d the nearest surface is at most 2 d away: querying only
        that far skips the hose's other capsules and gives the same distances."""
        t = 0.0
        limit = min(limit, self.max_range)
        if d > limit:
            return math.inf
        for _ in range(self.max_iterations - 1):
            if d < self.hit_tolerance:
                return t
            t += d
            if t > limit:
                return math.inf
            d = self._Distance(query, origin + t * u, min(limit - t, 2 * d + 1e-6))
            if d is None:
                return math.inf
        return t if d < self.hit_tolerance else math.inf

    def _Distance(self, query: QueryObject, p_W: np.ndarray, threshold: float):
        """Smallest signed distance to a non-ignored geometry within threshold, or None."""
        if threshold <= 0:
            return None
        best = None
        for result in query.ComputeSignedDistanceToPoint(p_W, threshold):
            if result.id_G in self.ignored:
                continue
            if best is None or result.distance < best:
                best = result.distance
        return None if best is None else max(best, 0.0)


def Measure(
    true_ranges: np.ndarray,
    rng: np.random.Generator,
    noise_std: float,
    quantization: float,
    max_range: float,
) -> tuple[np.ndarray, np.ndarray]:
    """Noisy, quantised readings (m) and validity flags. An invalid reading (no return, or
    noise pushing it past max_range) reports max_range, as the device reports its limit."""
    noise = rng.normal(0.0, noise_std, size=true_ranges.shape)
    finite = np.isfinite(true_ranges)
    noisy = np.where(finite, true_ranges, max_range) + noise
    if quantization > 0:
        noisy = np.round(noisy / quantization) * quantization
    noisy = np.clip(noisy, 0.0, None)
    valid = finite & (noisy <= max_range)
    return np.where(valid, noisy, max_range), valid


def CalibratedRanges(ranges: np.ndarray, valid: np.ndarray, offset: np.ndarray) -> np.ndarray:
    """Readings (m) with each sensor's calibrated offset (m, how much it reads too long;
    `guidedarm calibrate tof`) subtracted where valid; an invalid reading keeps the device's
    report (its limit)."""
    return np.where(valid, ranges - offset, ranges)


def DriftStep(
    drift: np.ndarray, rng: np.random.Generator, rate: float, dt: float, bound: float
) -> np.ndarray:
    """The range drift (m) of each sensor dt seconds later: a random walk whose change over
    one second has standard deviation `rate` (m), reflected at +-bound (the datasheet's
    temperature drift reaches 9 mm)."""
    drift = drift + rng.normal(0.0, rate * math.sqrt(dt), size=drift.shape)
    drift = np.where(drift > bound, 2 * bound - drift, drift)
    drift = np.where(drift < -bound, -2 * bound - drift, drift)
    return np.clip(drift, -bound, bound)


def AverageReadings(
    readings: Sequence[tuple[np.ndarray, np.ndarray]],
) -> tuple[np.ndarray, np.ndarray]:
    """One reading (ranges, valid) from N readings (ranges, valid) of the same sensors at
    rest: a sensor is valid when more than half of its readings are, with the mean of those
    as its range; an invalid one keeps the device's report (its limit)."""
    ranges = np.array([r for r, _ in readings])
    valid = np.array([v for _, v in readings], bool)
    count = valid.sum(axis=0)
    mean = np.where(valid, ranges, 0.0).sum(axis=0) / np.maximum(count, 1)
    averaged_valid = 2 * count > len(ranges)
    return np.where(averaged_valid, mean, ranges.max(axis=0)), averaged_valid


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
        # Floats for the ranging model (_CylinderRange, _Refine).
        object.__setattr__(self, "_emitter_list", [tuple(e) for e in emitters.tolist()])
        object.__setattr__(self, "_axis_list", [tuple(a) for a in axes.tolist()])
        object.__setattr__(self, "_centre", tuple(points[1, 1].tolist()))
        if self.cone_angle is not None:
            half = self.cone_angle / 2
            object.__setattr__(self, "_cone_cos", math.cos(half))
            object.__setattr__(self, "_cone_sin", math.sin(half))
            rim = [
                (math.sin(half) * math.cos(phi), math.sin(half) * math.sin(phi))
                for phi in _RIM_PHI.tolist()
            ]
            object.__setattr__(self, "_rim", rim)

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
        c = self._Refine(c, ranges, sensors, axis)
        return np.array(c), _Distance(c, self._centre) < self.spacing / 2

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
            (c for c in candidates if c is not None and _Distance(c, centre) <= self.field_radius),
            None,
        )
        if start is not None:
            start = (start, ranges, [k for k in range(6) if trusted[k] and valid[k]])
        self._start_memo[0] = (key, start)
        return start

    def PredictedRange(self, k: int, c: np.ndarray, axis: np.ndarray | None = None) -> float | None:
        """Range (m) sensor k reads for a hose centred at c (the detection plane, T), or None
        when its cone misses the hose: the nearest in-plane ray of the cone. With `axis`
        (unit, T) the hose is the cylinder of that axis through c (_CylinderRange)."""
        c = tuple(np.asarray(c, float).tolist())
        if axis is not None:
            return self._CylinderRange(k, c, tuple(np.asarray(axis, float).tolist()))
        return self._PlaneRange(k, c)

    def _PlaneRange(self, k: int, c: Vector) -> float | None:
        """PredictedRange of a hose perpendicular to the detection plane, in floats (the
        Gauss-Newton of _Refine calls it a dozen times a reading)."""
        (e0, e1, e2), (z0, z1, z2) = self._emitter_list[k], self._axis_list[k]
        d0, d1, d2 = c[0] - e0, c[1] - e1, c[2] - e2
        distance = math.sqrt(d0 * d0 + d1 * d1 + d2 * d2)
        along = d0 * z0 + d1 * z1 + d2 * z2
        if along <= 0:
            return None
        if along >= distance * self._cone_cos:
            return distance - self.hose_radius
        s0, s1, s2 = d0 - along * z0, d1 - along * z1, d2 - along * z2
        norm = math.sqrt(s0 * s0 + s1 * s1 + s2 * s2)
        cos_half, sin_half = self._cone_cos, self._cone_sin
        t = (
            d0 * (cos_half * z0 + sin_half * s0 / norm)
            + d1 * (cos_half * z1 + sin_half * s1 / norm)
            + d2 * (cos_half * z2 + sin_half * s2 / norm)
        )
        h2 = distance * distance - t * t
        r2 = self.hose_radius**2
        return None if h2 > r2 else t - math.sqrt(r2 - h2)

    def _CylinderRange(self, k: int, c: Vector, axis: Vector) -> float | None:
        """Range (m) sensor k reads for the cylinder of radius hose_radius, unit axis `axis`
        through c (T), or None when its cone misses it.

        A hose crossing the detection plane obliquely is nearer to some cones and farther
        from others than the perpendicular one PredictedRange assumes (its section in the
        plane is an ellipse of semi-axis r / cos(tilt)): 3 mm of estimate at 20 deg. The
        nearest point of the cylinder is at distance - r toward the foot of the emitter's
        perpendicular on the axis; when that direction leaves the cone the nearest return
        is on the cone's rim, minimised over BOUNDARY_SAMPLES rim rays on the side facing
        the axis and a parabola through the least three (smooth in c, which the
        Gauss-Newton's finite differences need).

        In floats, not arrays: _Refine calls it a dozen times a reading, and numpy's
        per-call overhead on 3-vectors costs more than the arithmetic."""
        (e0, e1, e2), (z0, z1, z2) = self._emitter_list[k], self._axis_list[k]
        a0, a1, a2 = axis
        f0, f1, f2 = e0 - c[0], e1 - c[1], e2 - c[2]
        along = f0 * a0 + f1 * a1 + f2 * a2
        # From the axis to the emitter, normal to the axis.
        d0, d1, d2 = f0 - a0 * along, f1 - a1 * along, f2 - a2 * along
        distance = math.sqrt(d0 * d0 + d1 * d1 + d2 * d2)
        r = self.hose_radius
        if distance <= r:
            return None
        n0, n1, n2 = -d0 / distance, -d1 / distance, -d2 / distance
        nz = n0 * z0 + n1 * z1 + n2 * z2
        cos_half = self._cone_cos
        if nz >= cos_half:
            return distance - r
        s0, s1, s2 = n0 - nz * z0, n1 - nz * z1, n2 - nz * z2
        norm = math.sqrt(s0 * s0 + s1 * s1 + s2 * s2)
        if norm < 1e-12 or nz <= 0:
            return None
        x0, x1, x2 = s0 / norm, s1 / norm, s2 / norm
        y0, y1, y2 = z1 * x2 - z2 * x1, z2 * x0 - z0 * x2, z0 * x1 - z1 * x0
        # A rim ray w = cos_half z + sin_half (cos(phi) x + sin(phi) y) (unit) meets the
        # cylinder where |d + t w_perp| = r, w_perp its part normal to the axis:
        # a t^2 + 2 b t + distance^2 - r^2 = 0 with a = |w_perp|^2 = 1 - (w . axis)^2 and
        # b = w_perp . d = w . d - (w . axis)(axis . d); the nearer root when b < 0.
        za, xa, ya = (
            z0 * a0 + z1 * a1 + z2 * a2,
            x0 * a0 + x1 * a1 + x2 * a2,
            y0 * a0 + y1 * a1 + y2 * a2,
        )
        zd, xd, yd = (
            z0 * d0 + z1 * d1 + z2 * d2,
            x0 * d0 + x1 * d1 + x2 * d2,
            y0 * d0 + y1 * d1 + y2 * d2,
        )
        ad = a0 * d0 + a1 * d1 + a2 * d2
        wa0, wd0 = cos_half * za, cos_half * zd
        gap = distance * distance - r * r
        # The loop runs some 250 times a reading: names bound locally, and a < 1e-12 tested
        # inline for max(a, 1e-12) (the same value, NaN included).
        t = []
        append, sqrt, inf = t.append, math.sqrt, math.inf
        for cos_phi, sin_phi in self._rim:
            wa = wa0 + cos_phi * xa + sin_phi * ya
            b = wd0 + cos_phi * xd + sin_phi * yd - wa * ad
            a = 1.0 - wa * wa
            disc = b * b - a * gap
            append((-b - sqrt(disc)) / (1e-12 if a < 1e-12 else a) if disc >= 0 and b < 0 else inf)
        best = min(t)
        if best == math.inf:
            return None
        i = t.index(best)
        if 0 < i < len(t) - 1 and t[i - 1] < math.inf and t[i + 1] < math.inf:
            curvature = t[i - 1] - 2 * best + t[i + 1]
            if curvature > 0:
                slope = (t[i + 1] - t[i - 1]) / 2
                return best - slope * slope / (2 * curvature)
        return best

    def _Refine(
        self, c: Vector, ranges: list[float], sensors: list[int], axis: np.ndarray | None
    ) -> Vector:
        """Gauss-Newton fit of the hose centre to the sensors' ranges, from c (a hose along
        `axis` when given); c itself when the fit has fewer than three ranges (two with
        `axis`) to use or leaves the grid cell it started in. The Jacobian is by finite
        differences, the 2 x 2 normal equations solved directly (lstsq when they are
        ill-conditioned), all in floats (a reading's dozen model evaluations cost more in
        numpy's per-call overhead than in arithmetic)."""
        # Two ranges determine the centre exactly; the perpendicular model asks for a third
        # to average, while an oblique hose moves even the two sensors trilateration uses.
        needed = 3 if axis is None else 2
        if self.cone_angle is None or len(sensors) < needed:
            return c
        if axis is None:
            model = self._PlaneRange
        else:
            axis_floats = tuple(axis.tolist())
            model = lambda k, p: self._CylinderRange(k, p, axis_floats)  # noqa: E731
        (u0, u1, u2), (v0, v1, v2) = self._axis_list[0], self._axis_list[3]
        measured = [ranges[k] for k in sensors]
        x0, x1, x2 = c
        h = 1e-5
        for _ in range(8):
            moved_u = (x0 + h * u0, x1 + h * u1, x2 + h * u2)
            moved_v = (x0 + h * v0, x1 + h * v1, x2 + h * v2)
            rows, residuals = [], []
            for k, measured_k in zip(sensors, measured, strict=True):
                p = model(k, (x0, x1, x2))
                q_u = model(k, moved_u)
                q_v = model(k, moved_v)
                if p is None or q_u is None or q_v is None:
                    continue
                rows.append(((q_u - p) / h, (q_v - p) / h))
                residuals.append(measured_k - p)
            if len(rows) < needed:
                return c
            step_u, step_v = _LeastSquares2(rows, residuals)
            x0 += step_u * u0 + step_v * v0
            x1 += step_u * u1 + step_v * v1
            x2 += step_u * u2 + step_v * v2
            if math.sqrt(step_u * step_u + step_v * step_v) < 1e-6:
                break
        x = (x0, x1, x2)
        return x if _Distance(x, c) <= self.spacing / 2 else c


def _LeastSquares2(rows: list[tuple[float, float]], residuals: list[float]) -> tuple[float, float]:
    """The least-squares solution of J s = r for J with two columns (rows), by the normal
    equations; np.linalg.lstsq's (the minimum-norm one) when J is nearly rank-deficient."""
    s00 = s01 = s11 = g0 = g1 = 0.0
    for (j0, j1), r in zip(rows, residuals, strict=True):
        s00 += j0 * j0
        s01 += j0 * j1
        s11 += j1 * j1
        g0 += j0 * r
        g1 += j1 * r
    det = s00 * s11 - s01 * s01
    if det <= 1e-10 * s00 * s11:
        step = np.linalg.lstsq(np.array(rows), np.array(residuals), rcond=None)[0]
        return float(step[0]), float(step[1])
    return (s11 * g0 - s01 * g1) / det, (s00 * g1 - s01 * g0) / det


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
    d = _Distance(c2, c1)
    if d < 1e-9:
        return None
    ex = tuple((b - a) / d for a, b in zip(c1, c2, strict=True))
    normal = _Cross(ex, u1)
    length = math.sqrt(_Dot(normal, normal))
    if length < 1e-9:
        return None
    ey = _Cross(tuple(v / length for v in normal), ex)
    x = (r1 * r1 - r2 * r2 + d * d) / (2 * d)
    h2 = r1 * r1 - x * x
    h = math.sqrt(h2) if h2 > 0 else 0.0
    options = [
        tuple(c + x * a + sign * h * b for c, a, b in zip(c1, ex, ey, strict=True))
        for sign in (1.0, -1.0)
    ]
    return min(options, key=lambda p: _Distance(p, centre))


def _Norm(v: np.ndarray) -> float:
    """|v| (np.linalg.norm's value, the square root of the dot product) without its
    per-call overhead."""
    return math.sqrt(float(v.dot(v)))


def _Dot(a: Vector, b: Vector) -> float:
    return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]


def _Distance(a: Vector, b: Vector) -> float:
    d0, d1, d2 = a[0] - b[0], a[1] - b[1], a[2] - b[2]
    return math.sqrt(d0 * d0 + d1 * d1 + d2 * d2)


def _Cross(a: Vector, b: Vector) -> Vector:
    return (a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0])
