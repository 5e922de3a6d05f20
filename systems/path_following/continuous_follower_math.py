"""Mathematics of continuous path following: sense while moving, no stops (beyond the paper).

Frames: world W; tool T with centre O and x_T along the path (the detection plane is T's
y-z plane). Units: m, s, rad.

Each reading is stamped with its measurement instant; the tool pose at that instant
(forward kinematics of the joints interpolated in JointHistory) turns the hose centre the
estimator found in T into a world point on the hose. HoseEstimate keeps those points with
their path coordinate s (the tool centre's travel, each step projected on the tool's own
x axis, so that it runs backwards when the tool backs up) and fits a
quadratic p(s) by least squares to the last fit_length of them: the fit's end is the
estimated hose point at the latest reading, its derivative the tangent, its second
derivative the curvature, its residual the noise. Beyond the last reading the path is
extrapolated along the fit (at most look_ahead), behind it the trail of past fit ends
is the path.

Reference (Advance, every servo period): a target pose moves along the estimated path at
the commanded speed v, which ramps (acceleration) toward
    min(speed, sqrt(lateral_acceleration / curvature), confidence-scaled speed)
and brakes so as never to pass the estimate's end by more than look_ahead. The target
position and direction follow the estimated path through a first-order filter
(correction_gain) at bounded rates (max_correction_speed, max_turn_rate_deg), so the noise
of one reading never jerks the arm.
The detection plane stays perpendicular to the path: the target's x axis is the tangent.

Loss: a reading without the hose leaves the estimate where it was. Once the tool is
loss_distance past the last estimate, the follower SEARCHES at search_speed along the
extrapolation to search_distance past it; with no hose there it BACKS UP along its trail
to the last estimate and RETRIES in directions turned about the world z axis by each of
search_turns_deg; a reading that sees the hose again resumes FOLLOW (a recovery). When
every retry is lost too, the hose has ended: the follower backs up to the last estimate
and is DONE.
"""

import bisect
import functools
import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any, TypeVar

import numpy as np
from pydrake.math import RigidTransform, RotationMatrix

from guidedarm.systems.config_checks import CheckFields, InRange, Positive
from guidedarm.systems.errors import ConfigurationError
from guidedarm.systems.path_following.path_follower_math import OrientationFromVector

FOLLOW, SEARCH, BACK, RETRY, DONE = range(5)
# A search leg ends this close to its end (m); the braking target approaches it only
# asymptotically.
END_OF_LEG = 5e-4
MODE_NAMES = ("follow", "search", "back", "retry", "done")
# A 3-vector as floats (x, y, z).
Vector = Sequence[float]
Frozen = TypeVar("Frozen")


@dataclass
class ContinuousConfig:
    """Continuous following (motion `continuous`; m, s, deg).

    speed: cruise speed of the tool along the hose (m/s); min_speed: the floor of the
        adapted speed (m/s); acceleration: the tool's speed change (m/s^2).
    lateral_acceleration: in a bend of curvature k (the fit's, less two standard
        errors) the speed is at most sqrt(lateral_acceleration / k) and
        max_turn_rate_deg / k (m/s^2).
    look_ahead: how far the target may run past the latest hose estimate (m).
    fit_length: length of hose behind the latest estimate fitted by the quadratic (m);
        min_fit_points: readings needed before the fit's tangent and curvature are used.
    spread_limit: the standard error of the estimated hose point at the tool (m) at which
        the confidence reaches 0; the speed falls from `speed` toward min_speed with the
        confidence (the fraction of readings in the fit window that saw the hose, times
        1 - (spread / spread_limit)^2); 0.1 mm to 50 mm (a hose's width).
    gate: a hose point farther than this from the fit's extrapolation (once the fit has
        min_fit_points) is an outlier, counted as a reading without the hose (m): past the
        hose's end the cones still see its end cap behind the detection plane, each
        reading a little farther off. 0.5 mm (below the estimates' own scatter, every
        reading would be an outlier) to 0.1 m.
    correction_gain: the target moves toward the estimated path at this rate times the
        distance, and its x axis turns toward the path's heading at this rate times the
        angle (1/s; a first-order filter of the fit's noise).
    max_correction_speed: the fastest correction of the target's position (m/s).
    max_turn_rate_deg: the fastest turn of the target's x axis (deg/s).
    heading_tolerance_deg: the target's x axis lagging the estimated heading by more than
        this slows the target in proportion (deg).
    lag_tolerance: the tool farther than this from the target at a reading (the arm cannot
        keep up, e.g. its wrist turning at its joint limits) slows the target in proportion
        (m); 0 (the default): off.
    servo_period: the target and the differential IK's tick (s); servo_gain: the
        differential IK's gain on the tool's pose error (1/s); servo_feedforward: the share
        of the target's own velocity the differential IK adds to that feedback (0 to 1;
        without it the arm lags the target by the feedback's braking curve, v^2 / 2 a, 15
        mm at 0.1 m/s); rotation_weight: the length (m) a rotation of 1 rad of the tool
        counts as against its position (the position, which the tracking needs, comes first;
        1 mm to 1 m, the arm's reach);
        roll_weight: the share of that weight of the roll about x_T (the hose's axis, which
        the detection does not need); servo_damping: the largest damping of the least
        squares, reached at a singularity (differential_ik_servo_math; a singular value
        of the weighted Jacobian, m/rad, from its floor MIN_DAMPING 1e-3 to 1).
    history: the measured joints kept for motion compensation (s).
    loss_distance: travel past the latest estimate without the hose before a search (m).
    search_distance: how far past the latest estimate a search goes (m).
    search_speed: the tool's speed while it searches and backs up (m/s).
    search_turns_deg: after the straight search, retries from the latest estimate in these
        directions, turned about the world z axis (deg); every one lost = the hose's end.
        Empty (the default): the straight search alone; a retry turns the tool about its
        centre, which swings the wrist fast (20 deg: 55 mm) and the arm fell behind.
    min_range: a valid range below this (m) means the tool is at the hose (a bend tighter
        than the tool can turn through, e.g. a kink): the run fails at that reading, in any
        mode, and the arm stops instead of pressing on (a 90 degree kink of zero radius:
        0.36 s of contact instead of 6.4 s). Following keeps the hose 28-50 mm from every
        sensor (4 mm noise included); 0 turns the check off.
    """

    speed: float = Positive(0.05)
    min_speed: float = Positive(0.02)
    acceleration: float = Positive(0.4)
    lateral_acceleration: float = Positive(0.1)
    look_ahead: float = Positive(0.015)
    fit_length: float = Positive(0.03)
    min_fit_points: int = InRange(3, 10000, 8)
    spread_limit: float = InRange(1e-4, 0.05, 0.006)
    gate: float = InRange(5e-4, 0.1, 0.008)
    correction_gain: float = Positive(8.0)
    max_correction_speed: float = Positive(0.03)
    max_turn_rate_deg: float = Positive(30.0)
    heading_tolerance_deg: float = InRange(0.5, 90.0, 10.0)
    lag_tolerance: float = InRange(0.0, 0.05, 0.0)
    servo_period: float = Positive(0.008)
    servo_gain: float = Positive(20.0)
    servo_feedforward: float = InRange(0.0, 1.0, 0.0)
    rotation_weight: float = InRange(1e-3, 1.0, 0.05)
    roll_weight: float = InRange(0.0, 1.0, 0.1)
    servo_damping: float = InRange(1e-3, 1.0, 0.01)
    history: float = Positive(0.3)
    loss_distance: float = Positive(0.008)
    search_distance: float = Positive(0.025)
    search_speed: float = Positive(0.02)
    search_turns_deg: list[float] = InRange(-90.0, 90.0, factory=list)
    min_range: float = InRange(0.0, 0.05, 0.015)

    def ServoWeights(self) -> list[float]:
        """The DifferentialIkServo's six weights (roll, pitch, yaw about T; x, y, z)."""
        w = self.rotation_weight
        return [self.roll_weight * w, w, w, 1.0, 1.0, 1.0]

    def Validate(self) -> None:
        """Raises ConfigurationError naming the first bad field or rule."""
        CheckFields(self)
        if not self.min_speed <= self.speed:
            raise ConfigurationError("continuous: need min_speed <= speed")
        if not self.search_speed <= self.speed:
            raise ConfigurationError("continuous: need search_speed <= speed")
        if not self.loss_distance < self.search_distance:
            raise ConfigurationError("continuous: need loss_distance < search_distance")
        if not self.loss_distance < self.look_ahead:
            raise ConfigurationError("continuous: need loss_distance < look_ahead")
        if not self.history >= 10 * self.servo_period:
            raise ConfigurationError("continuous: need history >= 10 servo_period")


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
        k = _Norm(self.c)
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
    """Readings along the path: rows (s, detected, p_x, p_y, p_z) with p the hose point (or
    the tool centre when undetected), the current fit, the trail of past fit ends (rows
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
        nothing. S_W_plain: the same reading's hose centre estimated for a hose
        perpendicular to the detection plane, which feeds axis_fit (AxisInTool); None
        leaves axis_fit as it is."""
        s = self.ToolCoordinate(X_WT)
        p_WO = X_WT.translation().copy()
        if S_W is not None and self.IsOutlier(s, S_W, config):
            S_W = None
        axis_fit, axis_rows = self.axis_fit, self.axis_rows
        if S_W is not None and S_W_plain is not None:
            axis_fit, axis_rows = self._AxisFit(s, S_W_plain, config)
        point = S_W if S_W is not None else p_WO
        rows = np.concatenate((self.rows, [[s, float(S_W is not None), *point.tolist()]]))
        if S_W is None:
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
        return _Norm(S_W - self.fit.Point(s)) > config.gate

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
        scale = 2 / max(math.sqrt(_Dot(derivative, derivative)), 1e-6) ** 2 / (length * length)
        a = [scale * v for v in coef[2]]
        along = _Dot(a, u_list)
        c = [v - along * w for v, w in zip(a, u_list, strict=True)]
        curvature_error = scale * math.sqrt(sigma2 * inverse[2][2])
        k = math.sqrt(_Dot(c, c))
        if k > 0:  # the line's direction is the path's at the window's centroid
            shrink = max(k - 2 * curvature_error, 0.0) / k * mean_tau * length
            norm = max(math.sqrt(_Dot(slope, slope)), 1e-9)
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
    norm = math.sqrt(_Dot(derivative, derivative))
    if norm < 1e-6 or _Dot(derivative, previous.tolist()) < 0:
        return previous
    return np.array([v / norm for v in derivative])


def _Dot(a: Vector, b: Vector) -> float:
    return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]


def Confidence(fit: LocalFit, config: ContinuousConfig) -> float:
    """In [0, 1]: the fraction of readings in the fit window that saw the hose, times the
    fraction of fit_length their detections span (a window still filling knows the path
    ahead only roughly), times 1 - (spread / spread_limit)^2 (flat while the hose is known
    to a fraction of the limit, falling to 0 as its uncertainty reaches it)."""
    if fit.readings == 0:
        return 0.0
    seen = fit.detections / fit.readings
    filled = min(fit.span / config.fit_length, 1.0)
    known = 1 - (fit.spread / config.spread_limit) ** 2
    return min(max(float(seen * filled * known), 0.0), 1.0)


def TargetSpeed(fit: LocalFit, config: ContinuousConfig) -> float:
    """The speed the follower aims for on this fit (m/s): the limits of the bend (its
    significant curvature) and of the confidence, at least min_speed."""
    k = fit.significant_curvature
    turn = math.radians(config.max_turn_rate_deg)
    bend = min(math.sqrt(config.lateral_acceleration / k), turn / k) if k > 0 else np.inf
    confident = config.min_speed + (config.speed - config.min_speed) * Confidence(fit, config)
    return float(max(config.min_speed, min(config.speed, bend, confident)))


@dataclass(frozen=True)
class Reference:
    """The moving target: mode, position r (m, W), direction x (unit), path coordinate s,
    speed v (m/s), and the search's bookkeeping: the retries used since the last loss (0
    none) and the current one's direction, the recoveries so far, and the estimate's path
    coordinate at the last loss (None once the hose has been followed search_distance
    past it: a recovery)."""

    mode: int
    r: np.ndarray
    x: np.ndarray
    s: float
    v: float
    retry: int = 0
    retry_direction: np.ndarray | None = None
    recoveries: int = 0
    lost_s: float | None = None

    @staticmethod
    def Start(X_WT: RigidTransform) -> "Reference":
        return Reference(
            FOLLOW, X_WT.translation().copy(), X_WT.rotation().matrix()[:, 0].copy(), 0.0, 0.0
        )

    def Pose(self) -> RigidTransform:
        """X_WT of the target: O at r, x_T along x, roll 0 (OrientationFromVector)."""
        return RigidTransform(OrientationFromVector(self.x), self.r)


def Replaced(value: Frozen, **changes: Any) -> Frozen:
    """dataclasses.replace(value, **changes) for a frozen dataclass that derives nothing
    (no __post_init__, no init=False field: Reference, the follower's state): a copy of
    its fields with `changes`. replace walks the fields and runs __init__, a few us that
    the follower would pay several times per servo period."""
    if not changes.keys() <= value.__dataclass_fields__.keys():
        raise TypeError(f"{type(value).__name__} has no field among {sorted(changes)}")
    copy = object.__new__(type(value))
    copy.__dict__.update(value.__dict__, **changes)
    return copy


def OnReading(
    ref: Reference, estimate: HoseEstimate, X_WT: RigidTransform, config: ContinuousConfig
) -> Reference:
    """The reference after a reading (the tool at X_WT then): its path coordinate
    re-anchored to the tool's (the tool's plus the target's lead along the tangent, so
    the two never drift apart), and the mode changes. The hose seen while searching
    resumes FOLLOW; it is a recovery once followed search_distance past the loss (a
    glimpse of the hose's end from a retry is not, and the next loss goes on with the
    next retry instead of starting the search over). In FOLLOW, the tool loss_distance
    past the estimate starts a search."""
    fit = estimate.fit
    s_tool = estimate.s_tool
    if ref.mode == FOLLOW:
        ref = Replaced(ref, s=s_tool + float((ref.r - X_WT.translation()) @ fit.u))
    detected = estimate.IsDetected()
    if detected and ref.mode in (SEARCH, RETRY):
        return Replaced(ref, mode=FOLLOW, retry_direction=None)
    if (
        ref.mode == FOLLOW
        and ref.lost_s is not None
        and fit.s > ref.lost_s + config.search_distance
    ):
        return Replaced(ref, retry=0, lost_s=None, recoveries=ref.recoveries + 1)
    if not detected and ref.mode == FOLLOW and s_tool > fit.s + config.loss_distance:
        return Replaced(ref, mode=SEARCH, lost_s=fit.s if ref.lost_s is None else ref.lost_s)
    return ref


def Advance(
    ref: Reference,
    estimate: HoseEstimate,
    dt: float,
    config: ContinuousConfig,
    lag: float = 0.0,
) -> Reference:
    """The target one servo period later (module docstring); lag: how far (m) the arm's
    tool was from the target at the latest reading. Its 3-vectors in floats: numpy's
    per-call overhead on them costs more than the arithmetic, every servo period."""
    if ref.mode == DONE:
        return Replaced(ref, v=0.0)
    fit = estimate.fit
    if ref.mode == FOLLOW:
        v_goal, s_stop = TargetSpeed(fit, config), fit.s + config.look_ahead
    elif ref.mode in (SEARCH, RETRY):
        v_goal, s_stop = config.search_speed, fit.s + config.search_distance
    else:  # BACK: to the latest estimate, backwards
        v_goal, s_stop = config.search_speed, fit.s
    if ref.mode == BACK:
        remaining = ref.s - s_stop
    elif ref.mode == RETRY:
        remaining = config.search_distance - float((ref.r - fit.p) @ ref.retry_direction)
    else:
        remaining = s_stop - ref.s
    v_goal = min(v_goal, math.sqrt(2 * config.acceleration * max(remaining, 0.0)))
    # A target whose heading lags the path by more than heading_tolerance_deg slows down in
    # proportion: it waits for the tool to turn instead of dragging it off the hose
    # sideways. (The heading of 30 mm of noisy readings wobbles by a few degrees, which
    # tilts the detection plane harmlessly.)
    arm_lag = lag
    x_ref, heading = ref.x.tolist(), fit.heading.tolist()
    lag = math.acos(max(-1.0, min(1.0, _Dot(x_ref, heading)))) if ref.mode == FOLLOW else 0.0
    tolerance = math.radians(config.heading_tolerance_deg)
    if lag > tolerance:
        v_goal *= tolerance / lag
    # An arm that cannot keep up (a fast turn of the wrist at its joint limits) slows the
    # target the same way: the speed is what the arm can follow, not what the fit allows.
    if ref.mode == FOLLOW and 0 < config.lag_tolerance < arm_lag:
        v_goal *= config.lag_tolerance / arm_lag
    dv_max = config.acceleration * dt
    v = ref.v + max(-dv_max, min(dv_max, v_goal - ref.v))
    # The target moves with the path it is on (the estimate's curve in FOLLOW, the search's
    # line, the trail backwards), then is corrected toward the path's point at a bounded
    # speed: a new fit moves that point, and the correction filters the jump.
    r_ref = ref.r.tolist()
    if ref.mode == RETRY:
        s = ref.s + v * dt
        x_goal = ref.retry_direction.tolist()
        moved = goal = [a + b * v * dt for a, b in zip(r_ref, x_goal, strict=True)]
    elif ref.mode == BACK:
        s = ref.s - v * dt
        goal, x_goal = (w.tolist() for w in _BackPoint(estimate, ref, s))
        back = _BackPoint(estimate, ref, ref.s)[0].tolist()
        moved = [a + b - c for a, b, c in zip(r_ref, goal, back, strict=True)]
    elif ref.mode == SEARCH:  # straight on: the fit's curvature is not extrapolated so far
        s = ref.s + v * dt
        p, x_goal = fit.p.tolist(), fit.u.tolist()
        goal = [a + b * (s - fit.s) for a, b in zip(p, x_goal, strict=True)]
        moved = [a + b * v * dt for a, b in zip(r_ref, x_goal, strict=True)]
    else:
        s = ref.s + v * dt
        goal, x_goal = fit.Point(s), heading
        back = fit.Point(ref.s)
        moved = [a + b - c for a, b, c in zip(r_ref, goal, back, strict=True)]
    d = [a - b for a, b in zip(goal, moved, strict=True)]
    gap = math.sqrt(_Dot(d, d))
    budget = min(config.correction_gain * gap, config.max_correction_speed) * dt
    # Toward the goal by at most the budget.
    r = goal if gap <= budget else [a + b * (budget / gap) for a, b in zip(moved, d, strict=True)]
    angle = math.acos(max(-1.0, min(1.0, _Dot(x_ref, x_goal))))
    turn = min(config.correction_gain * angle, math.radians(config.max_turn_rate_deg)) * dt
    x = _Turn(x_ref, x_goal, turn)
    ref = Replaced(ref, r=np.array(r), x=np.array(x), s=s, v=v)
    if remaining <= END_OF_LEG:
        ref = _NextSearchStage(ref, estimate, config)
    return ref


def _NextSearchStage(ref: Reference, estimate: HoseEstimate, config: ContinuousConfig) -> Reference:
    """At the end of a search leg: forward legs turn back, a finished back-up starts the
    next retry, or (none left) the hose has ended."""
    if ref.mode in (SEARCH, RETRY):
        return Replaced(ref, mode=BACK, v=0.0)
    if ref.mode != BACK:
        return ref
    if ref.retry >= len(config.search_turns_deg):
        return Replaced(ref, mode=DONE, v=0.0)
    fit = estimate.fit
    turn = math.radians(config.search_turns_deg[ref.retry])
    direction = RotationMatrix.MakeZRotation(turn) @ fit.u
    return Replaced(ref, mode=RETRY, retry=ref.retry + 1, retry_direction=direction, s=fit.s, v=0.0)


def _BackPoint(estimate: HoseEstimate, ref: Reference, s: float) -> tuple[np.ndarray, np.ndarray]:
    """(point, direction) of the way back at path coordinate s: the trail behind the
    latest estimate, the straight search's or the retry's line beyond it."""
    fit = estimate.fit
    if s <= fit.s:
        return estimate.TrailPoint(s)
    direction = fit.u if ref.retry_direction is None else ref.retry_direction
    return fit.p + direction * (s - fit.s), direction


def _Norm(v: np.ndarray) -> float:
    """|v| of a small vector: np.linalg.norm's value (sqrt of the dot product) without its
    per-call overhead, which the servo-rate functions here would pay several times."""
    return math.sqrt(float(v.dot(v)))


def _Half(v: np.ndarray) -> Vector:
    return tuple((0.5 * v).tolist())


def _Turn(x: Vector, goal: Vector, angle: float) -> Vector:
    """x (unit) turned toward goal by at most `angle` (rad), unit length: within the plane
    of the two, toward goal's part perpendicular to x (floats)."""
    c = max(-1.0, min(1.0, _Dot(x, goal)))
    between = math.acos(c)
    if between <= angle:
        norm = math.sqrt(_Dot(goal, goal))
        return [v / norm for v in goal]
    perpendicular = [a - c * b for a, b in zip(goal, x, strict=True)]
    length = math.sqrt(_Dot(perpendicular, perpendicular))
    if length < 1e-12:  # goal opposite x: turn toward the world z axis (x if x is z)
        toward = [0.0, 0.0, 1.0] if abs(x[2]) < 1 - 1e-9 else [1.0, 0.0, 0.0]
        along = _Dot(x, toward)
        perpendicular = [a - along * b for a, b in zip(toward, x, strict=True)]
        length = math.sqrt(_Dot(perpendicular, perpendicular))
    cos, scale = math.cos(angle), math.sin(angle) / length
    turned = [a * cos + b * scale for a, b in zip(x, perpendicular, strict=True)]
    norm = math.sqrt(_Dot(turned, turned))
    return [v / norm for v in turned]
