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
from guidedarm.systems.tof.hose_range_model import _RIM_PHI, RADIUS_FIT_SENSORS, RADIUS_STARTS


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

    def PlaneRange(self, k: int, c: Vector, radius: float | None = None) -> float | None:
        """hose_range_model.HoseRangeModel.PlaneRange."""
        r = self.hose_radius if radius is None else radius
        (e0, e1, e2), (z0, z1, z2) = self.emitters[k], self.axes[k]
        d0, d1, d2 = c[0] - e0, c[1] - e1, c[2] - e2
        distance = math.sqrt(d0 * d0 + d1 * d1 + d2 * d2)
        along = d0 * z0 + d1 * z1 + d2 * z2
        if along <= 0:
            return None
        if along >= distance * self._cone_cos:
            return distance - r
        s0, s1, s2 = d0 - along * z0, d1 - along * z1, d2 - along * z2
        norm = math.sqrt(s0 * s0 + s1 * s1 + s2 * s2)
        cos_half, sin_half = self._cone_cos, self._cone_sin
        t = (
            d0 * (cos_half * z0 + sin_half * s0 / norm)
            + d1 * (cos_half * z1 + sin_half * s1 / norm)
            + d2 * (cos_half * z2 + sin_half * s2 / norm)
        )
        h2 = distance * distance - t * t
        r2 = r * r
        return None if h2 > r2 else t - math.sqrt(r2 - h2)

    def CylinderRange(
        self, k: int, c: Vector, axis: Vector, radius: float | None = None
    ) -> float | None:
        """hose_range_model.HoseRangeModel.CylinderRange."""
        (e0, e1, e2), (z0, z1, z2) = self.emitters[k], self.axes[k]
        a0, a1, a2 = axis
        f0, f1, f2 = e0 - c[0], e1 - c[1], e2 - c[2]
        along = f0 * a0 + f1 * a1 + f2 * a2
        # From the axis to the emitter, normal to the axis.
        d0, d1, d2 = f0 - a0 * along, f1 - a1 * along, f2 - a2 * along
        distance = math.sqrt(d0 * d0 + d1 * d1 + d2 * d2)
        r = self.hose_radius if radius is None else radius
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
    range_of = model.RangeFunction(axis)
    u, v = np.array(model.axes[0]), np.array(model.axes[3])
    x, h = np.array(c, float), 1e-5
    for _ in range(10):
        p, pu, pv = tuple(x.tolist()), tuple((x + h * u).tolist()), tuple((x + h * v).tolist())
        rows, residuals = [], []
        for k in sensors:
            values = (range_of(k, p, radius), range_of(k, pu, radius), range_of(k, pv, radius))
            grown = range_of(k, p, radius + h)
            if None in values or grown is None:
                continue
            at = values[0]
            rows.append([(values[1] - at) / h, (values[2] - at) / h, (grown - at) / h])
            residuals.append(ranges[k] - at)
        if len(rows) < RADIUS_FIT_SENSORS:
            return None
        step = np.linalg.lstsq(np.array(rows), np.array(residuals), rcond=None)[0]
        x = x + step[0] * u + step[1] * v
        radius += float(step[2])
        if not model.hose_radius / 2 <= radius <= 2 * model.hose_radius:
            return None
        if math.sqrt(float(step @ step)) < 1e-6:
            break
    misfit = math.sqrt(float(np.mean(np.square(residuals))))
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
