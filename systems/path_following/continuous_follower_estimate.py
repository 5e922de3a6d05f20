"""The hose estimate of continuous path following: readings taken while moving, fitted.

Frames: world W; tool T with centre O and x_T along the path (the detection plane is T's
y-z plane). Units: m, s, rad.

Each reading is stamped with its measurement instant; the tool pose at that instant
(forward kinematics of the joints interpolated in JointHistory) turns the hose centre the
estimator found in T into a world point on the hose. HoseEstimate keeps those points with
their path coordinate s (the tool centre's travel, each step projected on the tool's own
x axis, so that it runs backwards when the tool backs up) and fits a
quadratic p(s) by least squares to the last fit_length of them (FitHose): the fit's end is
the estimated hose point at the latest reading, its derivative the tangent, its second
derivative the curvature, its residual the noise. Beyond the last reading the path is
extrapolated along the fit (at most look_ahead), behind it the trail of past fit ends
is the path. continuous_follower_math moves the target along it. A point beyond the gate
is an outlier; a run of them that moves along with the tool and that most of the window's
earlier points agree with is the hose the fit had left (_Recovered).
"""

import bisect
import functools
import math
from dataclasses import dataclass, field

import numpy as np
from pydrake.math import RigidTransform

from guidedarm.systems.path_following.continuous_follower_config import ContinuousConfig
from guidedarm.systems.small_vectors import Dot, Norm, Vector

# HoseEstimate's row flag for a hose point the gate rejected (1: the hose, 0: none seen).
OUTLIER = -1.0
# Consecutive outliers _Recovered tests as the hose the fit left (8 mm at the cruise).
RECOVERY_READINGS = 4


@dataclass(frozen=True)
class JointHistory:
    """Measured joint positions (rad) at their times (s, increasing), the last `span`
    seconds; immutable (With returns the history with one more measurement)."""

    span: float
    times: tuple[float, ...] = ()
    positions: tuple[np.ndarray, ...] = ()

    def With(self, t: float, q: np.ndarray) -> "JointHistory":
        """The history with q measured at t (replacing a measurement at or after t), less
        the measurements before t - span that interpolation no longer needs (two kept)."""
        times, positions = self.times, self.positions
        if times and t <= times[-1]:
            times, positions = times[:-1], positions[:-1]
        times, positions = times + (t,), positions + (np.array(q, float),)
        # The first measurement kept: the last one before t - span.
        first = min(max(bisect.bisect_left(times, t - self.span) - 1, 0), len(times) - 2)
        if first > 0:
            times, positions = times[first:], positions[first:]
        return JointHistory(self.span, times, positions)

    def At(self, t: float) -> np.ndarray:
        """q at time t, linearly interpolated (the nearest end outside the kept span)."""
        times = self.times
        if t <= times[0]:
            return self.positions[0]
        if t >= times[-1]:
            return self.positions[-1]
        k = bisect.bisect_left(times, t)  # np.searchsorted's index, without a list -> array
        w = (t - times[k - 1]) / (times[k] - times[k - 1])
        return (1 - w) * self.positions[k - 1] + w * self.positions[k]


@dataclass(frozen=True)
class LocalFit:
    """The hose near the latest estimate: point p (m, W) at path coordinate s, unit
    tangent u, curvature vector c (1/m, normal to u), RMS residual (m), readings in the
    window and how many of them saw the hose, `heading` (below), `spread`, the standard
    error (m) of p (the readings' noise through the fit: it falls as more readings fill
    the window), and `curvature_error`, the standard error of |c| (1/m; a quadratic on
    30 mm of readings with 2 mm noise has a curvature of about 10 1/m from the noise
    alone).

    heading: the unit direction of a line fitted to the window, four times less noisy than
    u (the end slope of a quadratic) but the path's direction at the window's middle;
    advanced to its end by the curvature the readings support (significant_curvature).
    The tool's x axis follows it."""

    s: float
    p: np.ndarray
    u: np.ndarray
    c: np.ndarray
    residual: float
    readings: int
    detections: int
    heading: np.ndarray
    spread: float = 0.0
    curvature_error: float = 0.0
    span: float = 0.0
    # Derived once (Advance reads them every servo period): |c| (1/m); the curvature the
    # readings support, |c| less two standard errors, >= 0 (1/m); the curvature vector
    # of the extrapolation ahead of p (c scaled to the significant curvature).
    curvature: float = field(init=False, repr=False)
    significant_curvature: float = field(init=False, repr=False)
    c_ahead: np.ndarray = field(init=False, repr=False)

    def __post_init__(self) -> None:
        k = Norm(self.c)
        significant = max(k - 2 * self.curvature_error, 0.0)
        object.__setattr__(self, "curvature", k)
        object.__setattr__(self, "significant_curvature", significant)
        object.__setattr__(self, "c_ahead", self.c * (significant / k) if k > 0 else self.c)

    @functools.cached_property
    def _quadratics(self) -> tuple[tuple[Vector, Vector, Vector], tuple[Vector, Vector, Vector]]:
        """Point's (p, slope, half the curvature vector) as floats, behind and ahead of p;
        made on first use (an axis fit never needs them)."""
        p = tuple(self.p.tolist())
        behind = (p, tuple(self.u.tolist()), _Half(self.c))
        return behind, (p, tuple(self.heading.tolist()), _Half(self.c_ahead))

    def Point(self, s: float) -> Vector:
        """The hose at path coordinate s (m, W; floats): the quadratic within the window;
        ahead of p, along `heading` bending by the significant curvature (the quadratic's
        end slope and curvature, extrapolated, carry the noise of the readings ahead)."""
        d = s - self.s
        behind, ahead = self._quadratics
        p, u, h = behind if d <= 0 else ahead
        return (
            p[0] + u[0] * d + h[0] * d * d,
            p[1] + u[1] * d + h[1] * d * d,
            p[2] + u[2] * d + h[2] * d * d,
        )


@dataclass(frozen=True)
class HoseEstimate:
    """Readings along the path: rows (s, flag, p_x, p_y, p_z), flag 1 with p the hose
    point, OUTLIER with p a point the gate rejected, 0 with p the tool centre (no hose
    seen); the current fit, the trail of past fit ends (rows
    s, p, u), and the tool centre and its s at the latest reading; axis_fit and its rows:
    the same fit of the hose points estimated for a perpendicular hose (AxisInTool).
    Immutable: WithReading returns a new estimate."""

    fit: LocalFit
    rows: np.ndarray
    trail: np.ndarray
    p_WO: np.ndarray
    s_tool: float = 0.0
    axis_fit: LocalFit | None = None
    axis_rows: np.ndarray | None = None

    @staticmethod
    def Start(X_WT: RigidTransform) -> "HoseEstimate":
        """The hose assumed under O along x_T (the start pose), nothing read yet."""
        p = X_WT.translation()
        u = X_WT.rotation().matrix()[:, 0]
        fit = LocalFit(0.0, p, u, np.zeros(3), 0.0, 0, 0, u)
        return HoseEstimate(fit, np.zeros((0, 5)), np.concatenate([[0.0], p, u])[None], p)

    def ToolCoordinate(self, X_WT: RigidTransform) -> float:
        """Path coordinate (m) of the tool at X_WT: the latest reading's plus the travel
        since, along x_T."""
        x_T = X_WT.rotation().matrix()[:, 0]
        return self.s_tool + float((X_WT.translation() - self.p_WO) @ x_T)

    def AxisInTool(self, X_WT: RigidTransform, config: ContinuousConfig) -> np.ndarray | None:
        """The hose's direction in T at the tool X_WT (unit), for the ranging estimator to
        model a hose crossing the detection plane obliquely; None until the axis fit has
        min_fit_points detections over a third of fit_length.

        It is the heading of `axis_fit`, fitted to the hose points the estimator found
        assuming a perpendicular hose (WithReading's S_W_plain): those depend on the tool's
        pose alone. The heading of the fit of the corrected points would close a loop
        (heading -> correction -> points -> heading) whose gain nears 1 at a 17 deg tilt,
        and on random_3 it did run away (tracking max 13.8 mm against 11.4 uncorrected)."""
        fit = self.axis_fit
        if (
            fit is None
            or fit.detections < config.min_fit_points
            or fit.span < config.fit_length / 3
        ):
            return None
        return X_WT.rotation().inverse() @ fit.heading

    def IsDetected(self) -> bool:
        """Whether the latest reading saw the hose (and was no outlier)."""
        return bool(len(self.rows) and self.rows[-1, 1] > 0.5)

    def WithReading(
        self,
        X_WT: RigidTransform,
        S_W: np.ndarray | None,
        config: ContinuousConfig,
        S_W_plain: np.ndarray | None = None,
    ) -> "HoseEstimate":
        """The estimate after a reading with the tool at X_WT (the measurement instant's)
        that saw the hose centre at S_W (or nothing); an outlier (IsOutlier) counts as
        nothing unless it ends a run _Recovered takes as the hose. S_W_plain: the same
        reading's hose centre for a hose perpendicular to the detection plane, which feeds
        axis_fit (AxisInTool); None leaves axis_fit as it is."""
        s = self.ToolCoordinate(X_WT)
        p_WO = X_WT.translation().copy()
        seen = float(S_W is not None)
        if S_W is not None and self.IsOutlier(s, S_W, config):
            seen = OUTLIER
        point = S_W if S_W is not None else p_WO
        rows = np.concatenate((self.rows, [[s, seen, *point.tolist()]]))
        if seen == OUTLIER:
            rows = _Recovered(rows, s, self.fit, config)
        axis_fit, axis_rows = self.axis_fit, self.axis_rows
        if rows[-1, 1] > 0.5 and S_W_plain is not None:
            axis_fit, axis_rows = self._AxisFit(s, S_W_plain, config)
        if rows[-1, 1] <= 0.5:
            keep = rows[:, 0] >= self.fit.s - config.fit_length
            rows = rows[keep] if np.count_nonzero(keep) >= 2 else rows[-2:]
            return HoseEstimate(self.fit, rows, self.trail, p_WO, s, axis_fit, axis_rows)
        rows = rows[rows[:, 0] >= s - config.fit_length]
        fit = FitHose(rows, s, self.fit, config)
        trail = np.concatenate((self.trail, [[fit.s, *fit.p.tolist(), *fit.u.tolist()]]))
        return HoseEstimate(fit, rows, trail, p_WO, s, axis_fit, axis_rows)

    def _AxisFit(
        self, s: float, S_W: np.ndarray, config: ContinuousConfig
    ) -> tuple[LocalFit, np.ndarray]:
        """(axis_fit, axis_rows) refitted with the hose point S_W (perpendicular model) at s."""
        row = [[s, 1.0, *S_W.tolist()]]
        rows = np.array(row) if self.axis_rows is None else np.concatenate((self.axis_rows, row))
        rows = rows[rows[:, 0] >= s - config.fit_length]
        return FitHose(rows, s, self.axis_fit or self.fit, config), rows

    def IsOutlier(self, s: float, S_W: np.ndarray, config: ContinuousConfig) -> bool:
        """Whether S_W, read at path coordinate s, is off the established fit by > gate."""
        if self.fit.detections < config.min_fit_points:
            return False
        return Norm(S_W - self.fit.Point(s)) > config.gate

    def TrailPoint(self, s: float) -> tuple[np.ndarray, np.ndarray]:
        """(point, unit tangent) of the trail at path coordinate s (clamped to its ends)."""
        trail = self.trail
        order = np.argsort(trail[:, 0], kind="stable")
        ss, ps, us = trail[order, 0], trail[order, 1:4], trail[order, 4:7]
        p = np.array([np.interp(s, ss, ps[:, k]) for k in range(3)])
        u = np.array([np.interp(s, ss, us[:, k]) for k in range(3)])
        return p, u / np.linalg.norm(u)


# The powers of the fit's polynomial (np.vander's columns, without its overhead).
_POWERS = np.arange(3)


def _Recovered(
    rows: np.ndarray, s_end: float, previous: LocalFit, config: ContinuousConfig
) -> np.ndarray:
    """rows (the window, its last a rejected point) with its trailing run of outliers taken
    as the hose, when the run holds RECOVERY_READINGS or more, its points move along with
    the tool (a fixed object's do not), and a fit of it with the window's earlier points,
    the farthest dropped one by one, holds every point within the gate having dropped at
    most a third of them: those that bent the fit (the facing cones' first view of a collar)
    become the outliers. Otherwise rows unchanged: something off the hose's course (a
    post, a crossing hose) agrees with few of the points behind."""
    window = rows[:, 0] >= s_end - config.fit_length
    trial = rows[window].copy()
    hose = np.flatnonzero(trial[:, 1] != OUTLIER)
    run = len(trial) - 1 - (int(hose[-1]) if len(hose) else -1)
    if run < RECOVERY_READINGS or not _MovesAlong(trial[-run:], previous.heading):
        return rows
    trial[-run:, 1] = 1.0
    most, dropped = np.count_nonzero(trial[:-run, 1] > 0.5) // 3, 0
    while True:
        fit = FitHose(trial, s_end, previous, config)
        on_fit = np.array([fit.Point(s) for s in trial[:, 0].tolist()])
        misfit = np.linalg.norm(trial[:, 2:5] - on_fit, axis=1)
        misfit[trial[:, 1] <= 0.5] = 0.0
        worst = int(np.argmax(misfit))
        if misfit[worst] <= config.gate:
            return trial
        if worst >= len(trial) - run or dropped == most:
            return rows
        trial[worst, 1] = OUTLIER
        dropped += 1


def _MovesAlong(run: np.ndarray, heading: np.ndarray) -> bool:
    """Whether the points of a run of readings (rows) advanced along `heading` at least half
    as far as the tool did, between the means of its first and last halves."""
    half = len(run) // 2
    first, last = run[:half], run[-half:]
    travel = float(last[:, 0].mean() - first[:, 0].mean())
    advance = float((last[:, 2:5].mean(axis=0) - first[:, 2:5].mean(axis=0)) @ heading)
    return advance >= 0.5 * travel


def FitHose(
    rows: np.ndarray, s_end: float, previous: LocalFit, config: ContinuousConfig
) -> LocalFit:
    """The fit (module docstring) of the detected rows, evaluated at s_end: the previous
    tangent with the mean of the last few points while the detections span less than a
    third of fit_length or number under min_fit_points (a line through a few noisy
    points points anywhere), a line up to two thirds, a quadratic beyond."""
    detected = rows[rows[:, 1] > 0.5]
    d = detected[:, 0] - s_end
    points = detected[:, 2:5]
    d_list = d.tolist()
    span = max(d_list) - min(d_list) if d_list else 0.0
    if len(d) < config.min_fit_points or span < config.fit_length / 3:
        p = points[-min(len(d), 4) :].mean(axis=0) if len(d) else previous.p
        # A handful of points says nothing about the noise: residual 0.
        return LocalFit(
            s_end,
            p,
            previous.u,
            np.zeros(3),
            0.0,
            len(rows),
            len(detected),
            previous.heading,
            span=span,
        )
    degree = 2 if span >= 2 * config.fit_length / 3 else 1
    # The normal equations in tau = d / fit_length (in [-1, 0]: well conditioned, unlike
    # those in d, whose powers span four orders of magnitude), solved by the inverse the
    # covariance needs anyway; the sums over the readings in numpy, the 3 x 3 algebra in
    # floats (lstsq, inv and numpy's calls on 3-vectors cost more in overhead than work).
    length = config.fit_length
    count = len(d)
    A = (d / length)[:, None] ** _POWERS[: degree + 1]
    gram = (A.T @ A).tolist()
    inverse = _InverseOfSymmetric(gram)
    moments = A.T @ points
    coef = np.array(inverse) @ moments
    misfit = points - A @ coef
    squares = float(np.vdot(misfit, misfit))
    residual = math.sqrt(squares / count)
    # The noise lies across the hose (the detection plane holds S): two axes of variance
    # sigma^2 each; the fit's covariance is sigma^2 (A^T A)^-1 per axis (in d: tau's
    # scaled by fit_length^-(i + j)).
    sigma2 = squares / (2 * max(count - degree - 1, 1))
    spread = math.sqrt(2 * sigma2 * inverse[0][0])
    coef, moments = coef.tolist(), moments.tolist()
    # The least-squares line's slope (per m of d), from the centred sums.
    mean_tau = gram[0][1] / count
    slope = [
        (m1 - mean_tau * m0) / ((gram[1][1] - mean_tau * gram[0][1]) * length)
        for m0, m1 in zip(moments[0], moments[1], strict=True)
    ]
    derivative = [v / length for v in coef[1]]
    u = _Direction(derivative, previous.u)
    u_list = u.tolist()
    c = [0.0, 0.0, 0.0]
    curvature_error = 0.0
    if degree == 2:
        scale = 2 / max(math.sqrt(Dot(derivative, derivative)), 1e-6) ** 2 / (length * length)
        a = [scale * v for v in coef[2]]
        along = Dot(a, u_list)
        c = [v - along * w for v, w in zip(a, u_list, strict=True)]
        curvature_error = scale * math.sqrt(sigma2 * inverse[2][2])
        k = math.sqrt(Dot(c, c))
        if k > 0:  # the line's direction is the path's at the window's centroid
            shrink = max(k - 2 * curvature_error, 0.0) / k * mean_tau * length
            norm = max(math.sqrt(Dot(slope, slope)), 1e-9)
            slope = [v / norm - shrink * w for v, w in zip(slope, c, strict=True)]
    heading = _Direction(slope, previous.heading)
    return LocalFit(
        s_end,
        np.array(coef[0]),
        u,
        np.array(c),
        residual,
        len(rows),
        count,
        heading,
        spread,
        curvature_error,
        span,
    )


def _InverseOfSymmetric(m: list[list[float]]) -> list[list[float]]:
    """The inverse of a symmetric positive definite 2 x 2 or 3 x 3 matrix (its adjugate
    over its determinant)."""
    if len(m) == 2:
        (a, b), (_, d) = m
        det = a * d - b * b
        return [[d / det, -b / det], [-b / det, a / det]]
    (a, b, c), (_, d, e), (_, _, f) = m
    A, B, C = d * f - e * e, c * e - b * f, b * e - c * d
    det = a * A + b * B + c * C
    D, E, F = a * f - c * c, b * c - a * e, a * d - b * b
    return [[A / det, B / det, C / det], [B / det, D / det, E / det], [C / det, E / det, F / det]]


def _Direction(derivative: list[float], previous: np.ndarray) -> np.ndarray:
    """The unit direction of a fitted derivative (floats); `previous` when it is ~0 or
    reverses the path (a fit cannot turn the direction of travel around)."""
    norm = math.sqrt(Dot(derivative, derivative))
    if norm < 1e-6 or Dot(derivative, previous.tolist()) < 0:
        return previous
    return np.array([v / norm for v in derivative])


def _Half(v: np.ndarray) -> Vector:
    return tuple((0.5 * v).tolist())
