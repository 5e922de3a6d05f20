"""The Python reference of hose_range_model's compiled kernel (csrc/hose_range.c): the
range model and the Gauss-Newton fits of systems/tof/hose_range_model.py's docstrings,
in floats, which tests/test_hose_range_kernel.py holds the kernel to.

A sensor's cone sees a hose centred at c in the detection plane (the tool frame T) at the
nearest in-plane ray of the cone; a hose crossing the plane obliquely is a cylinder of
that axis through c. The Gauss-Newton fit moves c to match the ranges of the trusted
sensors.
"""

from __future__ import annotations

import math

import numpy as np

from guidedarm.systems.small_vectors import Distance, Vector
from guidedarm.systems.tof import hose_range_model
from guidedarm.systems.tof.hose_range_model import (
    _RIM_PHI,
    MAX_MISS,
    MISS_SLOPE,
    RADIUS_FIT_SENSORS,
    RADIUS_STARTS,
)


class HoseRangeModel(hose_range_model.HoseRangeModel):
    """hose_range_model.HoseRangeModel with its range model and centre fit in Python (its
    RangeFunction, inherited, picks these)."""

    def __post_init__(self) -> None:
        super().__post_init__()
        half = self.cone_angle / 2
        object.__setattr__(self, "_cone_cos", math.cos(half))
        object.__setattr__(self, "_cone_sin", math.sin(half))
        rim = [
            (math.sin(half) * math.cos(phi), math.sin(half) * math.sin(phi))
            for phi in _RIM_PHI.tolist()
        ]
        object.__setattr__(self, "_rim", rim)

    def _PlaneView(self, k: int, c: Vector) -> tuple[int, float, float, float]:
        """Sensor k's view of a hose perpendicular to the detection plane centred at c:
        (0, ...) when c is behind the emitter; (1, distance, ...) when c is inside the cone;
        (2, distance, t, h2): t along the rim ray nearest c to c's foot on it, h2 c's squared
        distance from that ray."""
        (e0, e1, e2), (z0, z1, z2) = self.emitters[k], self.axes[k]
        d0, d1, d2 = c[0] - e0, c[1] - e1, c[2] - e2
        distance = math.sqrt(d0 * d0 + d1 * d1 + d2 * d2)
        along = d0 * z0 + d1 * z1 + d2 * z2
        if along <= 0:
            return 0, distance, 0.0, 0.0
        if along >= distance * self._cone_cos:
            return 1, distance, 0.0, 0.0
        s0, s1, s2 = d0 - along * z0, d1 - along * z1, d2 - along * z2
        norm = math.sqrt(s0 * s0 + s1 * s1 + s2 * s2)
        cos_half, sin_half = self._cone_cos, self._cone_sin
        t = (
            d0 * (cos_half * z0 + sin_half * s0 / norm)
            + d1 * (cos_half * z1 + sin_half * s1 / norm)
            + d2 * (cos_half * z2 + sin_half * s2 / norm)
        )
        return 2, distance, t, distance * distance - t * t

    def PlaneRange(self, k: int, c: Vector, radius: float | None = None) -> float | None:
        """hose_range_model.HoseRangeModel.PlaneRange."""
        r = self.hose_radius if radius is None else radius
        view, distance, t, h2 = self._PlaneView(k, c)
        if view == 0:
            return None
        if view == 1:
            return distance - r
        r2 = r * r
        return None if h2 > r2 else t - math.sqrt(r2 - h2)

    def _CylinderView(self, k: int, c: Vector, axis: Vector, r: float) -> tuple[int, tuple]:
        """Sensor k's view of the cylinder of radius r, unit axis `axis` through c:
        (0, ...) when the emitter is inside it or the axis lies behind; (1, (distance,))
        when the axis's nearest point is inside the cone; (2, (distance, za, xa, ya, zd, xd,
        yd, ad)): the axis and the emitter's offset d from it projected on the rim frame (z
        the line of sight, x toward the axis, y = z x x) and d on the axis."""
        (e0, e1, e2), (z0, z1, z2) = self.emitters[k], self.axes[k]
        a0, a1, a2 = axis
        f0, f1, f2 = e0 - c[0], e1 - c[1], e2 - c[2]
        along = f0 * a0 + f1 * a1 + f2 * a2
        # From the axis to the emitter, normal to the axis.
        d0, d1, d2 = f0 - a0 * along, f1 - a1 * along, f2 - a2 * along
        distance = math.sqrt(d0 * d0 + d1 * d1 + d2 * d2)
        if distance <= r:
            return 0, ()
        n0, n1, n2 = -d0 / distance, -d1 / distance, -d2 / distance
        nz = n0 * z0 + n1 * z1 + n2 * z2
        if nz >= self._cone_cos:
            return 1, (distance,)
        s0, s1, s2 = n0 - nz * z0, n1 - nz * z1, n2 - nz * z2
        norm = math.sqrt(s0 * s0 + s1 * s1 + s2 * s2)
        if norm < 1e-12 or nz <= 0:
            return 0, ()
        x0, x1, x2 = s0 / norm, s1 / norm, s2 / norm
        y0, y1, y2 = z1 * x2 - z2 * x1, z2 * x0 - z0 * x2, z0 * x1 - z1 * x0
        return 2, (
            distance,
            z0 * a0 + z1 * a1 + z2 * a2,
            x0 * a0 + x1 * a1 + x2 * a2,
            y0 * a0 + y1 * a1 + y2 * a2,
            z0 * d0 + z1 * d1 + z2 * d2,
            x0 * d0 + x1 * d1 + x2 * d2,
            y0 * d0 + y1 * d1 + y2 * d2,
            a0 * d0 + a1 * d1 + a2 * d2,
        )

    def CylinderRange(
        self, k: int, c: Vector, axis: Vector, radius: float | None = None
    ) -> float | None:
        """hose_range_model.HoseRangeModel.CylinderRange."""
        r = self.hose_radius if radius is None else radius
        view, geometry = self._CylinderView(k, c, axis, r)
        if view < 2:
            return geometry[0] - r if view == 1 else None
        distance, za, xa, ya, zd, xd, yd, ad = geometry
        cos_half = self._cone_cos
        # A rim ray w = cos_half z + sin_half (cos(phi) x + sin(phi) y) (unit) meets the
        # cylinder where |d + t w_perp| = r, w_perp its part normal to the axis:
        # a t^2 + 2 b t + distance^2 - r^2 = 0 with a = |w_perp|^2 = 1 - (w . axis)^2 and
        # b = w_perp . d = w . d - (w . axis)(axis . d); the nearer root when b < 0.
        wa0, wd0 = cos_half * za, cos_half * zd
        gap = distance * distance - r * r
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

    def MissRange(
        self, k: int, c: Vector, axis: Vector | None, radius: float
    ) -> tuple[float, float] | None:
        """(range, gap) the radius fit models for sensor k where its cone misses the hose
        by a gap of at most MAX_MISS (hose_range_model.RadiusFit): the range along the rim
        ray of the hose's closest approach plus MISS_SLOPE times the gap; None otherwise."""
        if axis is None:
            view, _, t, h2 = self._PlaneView(k, c)
            gap = math.sqrt(max(h2, 0.0)) - radius
            return None if view != 2 or gap > MAX_MISS else (t + MISS_SLOPE * gap, gap)
        view, geometry = self._CylinderView(k, c, axis, radius)
        if view != 2:
            return None
        distance, za, xa, ya, zd, xd, yd, ad = geometry
        cos_half = self._cone_cos
        best, best_gap = math.inf, 0.0
        for cos_phi, sin_phi in self._rim:
            wa = cos_half * za + cos_phi * xa + sin_phi * ya
            b = cos_half * zd + cos_phi * xd + sin_phi * yd - wa * ad
            aa = 1.0 - wa * wa
            # The rim ray's closest approach to the axis, not behind the emitter.
            t = -b / aa if b < 0 and aa > 1e-12 else 0.0
            gap = math.sqrt(max(distance * distance + 2 * b * t + aa * t * t, 0.0)) - radius
            value = t + MISS_SLOPE * gap
            if gap <= MAX_MISS and value < best:
                best, best_gap = value, gap
        return None if best == math.inf else (best, best_gap)

    def Refine(
        self,
        c: Vector,
        ranges: list[float],
        sensors: list[int],
        axis: np.ndarray | None,
        max_shift: float,
    ) -> Vector:
        """hose_range_model.HoseRangeModel.Refine."""
        # Two ranges determine the centre exactly; the perpendicular model asks for a third
        # to average, while an oblique hose moves even the two sensors trilateration uses.
        needed = 3 if axis is None else 2
        if len(sensors) < needed:
            return c
        model = self.RangeFunction(axis)
        (u0, u1, u2), (v0, v1, v2) = self.axes[0], self.axes[3]
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
        return x if Distance(x, c) <= max_shift else c


def RadiusFit(
    model: HoseRangeModel,
    c: Vector,
    ranges: list[float],
    sensors: list[int],
    axis: np.ndarray | None,
    max_shift: float,
) -> tuple[Vector, float] | None:
    """hose_range_model.RadiusFit."""
    if len(sensors) < RADIUS_FIT_SENSORS:
        return None
    fits = [_RadiusFitFrom(model, c, factor * model.hose_radius, ranges, sensors, axis)
            for factor in RADIUS_STARTS]  # fmt: skip
    fits = [f for f in fits if f is not None and Distance(f[0], c) <= max_shift]
    if not fits:
        return None
    centre, radius, _ = min(fits, key=lambda f: f[2])
    return centre, radius


def _RadiusFitFrom(
    model: HoseRangeModel,
    c: Vector,
    radius: float,
    ranges: list[float],
    sensors: list[int],
    axis: np.ndarray | None,
) -> tuple[Vector, float, float] | None:
    """RadiusFit from one start radius: (centre, radius, RMS misfit) or None."""
    modelled = model.RangeFunction(axis)
    axis_floats = None if axis is None else tuple(axis.tolist())

    def range_of(k: int, c: Vector, r: float) -> tuple[float, float] | None:
        """(range, gap): the cone's range, 0; or past its rim (MissRange)."""
        value = modelled(k, c, r)
        return model.MissRange(k, c, axis_floats, r) if value is None else (value, 0.0)

    u, v = np.array(model.axes[0]), np.array(model.axes[3])
    # A hose thicker by e reads as one e nearer along both facing sensors' lines of sight.
    e = radius - model.hose_radius
    x, h = np.array([c[i] + e * u[i] + e * v[i] for i in range(3)]), 1e-5
    for _ in range(10):
        p, pu, pv = tuple(x.tolist()), tuple((x + h * u).tolist()), tuple((x + h * v).tolist())
        rows, residuals, gaps = [], [], []
        for k in sensors:
            values = (range_of(k, p, radius), range_of(k, pu, radius), range_of(k, pv, radius))
            grown = range_of(k, p, radius + h)
            if None in values or grown is None:
                continue
            (at, gap), at_u, at_v = values[0], values[1][0], values[2][0]
            rows.append([(at_u - at) / h, (at_v - at) / h, (grown[0] - at) / h])
            residuals.append(ranges[k] - at)
            gaps.append(gap)
        if len(rows) < RADIUS_FIT_SENSORS:
            return None
        step = np.linalg.lstsq(np.array(rows), np.array(residuals), rcond=None)[0]
        x = x + step[0] * u + step[1] * v
        radius += float(step[2])
        if not model.hose_radius / 2 <= radius <= 2 * model.hose_radius:
            return None
        if math.sqrt(float(step @ step)) < 1e-6:
            break
    # A row its cone still misses counts its gap too (the sensor saw the hose there).
    misfit = math.sqrt(float(np.mean(np.square(residuals) + np.square(gaps))))
    return tuple(x.tolist()), radius, misfit


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
