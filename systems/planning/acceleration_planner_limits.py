"""Joint velocity and acceleration limits of the acceleration-level planner.

The paper's (Pająk) two mechanisms: the interior velocity penalty (14)-(15) and the
acceleration scaling q'' = a + c b (17) with the cases (1)-(4), the rules (a)-(c) and the
exponential return (18). Beyond the paper, for the robust mode: the speed governor, which
keeps the velocity-driven term a = -J^-1 Jdot qd within a margin of the acceleration limits
(a grows with qd^2, so slowing early keeps case (c) away), the per-joint saturation that
replaces the scaling of the whole task (SaturatedLeastSquares), and the braking fallback
used should no admissible c exist all the same. Units: rad/s, rad/s^2, s.
"""

from __future__ import annotations

import math

import numpy as np

from guidedarm.systems.errors import ConfigurationError
from guidedarm.systems.planning.acceleration_planner_kinematics import PlanningError


def CheckLimits(name: str, lower: np.ndarray, upper: np.ndarray) -> None:
    """ConfigurationError unless lower < 0 < upper, finite and of the same length."""
    if lower.shape != upper.shape or lower.ndim != 1:
        raise ConfigurationError(f"{name}: lower and upper limits need the same length")
    if not np.all(np.isfinite(lower)) or not np.all(np.isfinite(upper)):
        raise ConfigurationError(f"{name}: limits must be finite")
    if np.any(upper <= 0) or np.any(lower >= 0):
        raise ConfigurationError(
            f"{name}: need lower < 0 < upper, got lower={lower.tolist()}, upper={upper.tolist()}"
        )


class VelocityPenalty:
    """Interior penalty (14) and its perturbation (15) keeping qd inside [lower, upper].

    kappa_i = rho (1/d_i - 1/theta) when the normalised distance d_i of qd_i from its
    nearer limit is below theta; dq''_i = -d kappa_i / d qd_i = rho / d_i^2 d d_i/d qd_i,
    which points away from the nearer limit and grows without bound at the limit.
    d is floored at `min_distance` so that a sampled step that lands on a limit keeps a
    finite (large) push back instead of a division by zero.
    """

    def __init__(
        self,
        lower: np.ndarray,
        upper: np.ndarray,
        theta: float,
        rho: float,
        min_distance: float = 1e-4,
    ) -> None:
        lower, upper = np.asarray(lower, float), np.asarray(upper, float)
        CheckLimits("velocity limits", lower, upper)
        if not 0 < theta < 0.5:
            raise ConfigurationError(f"velocity threshold theta must be in (0, 0.5), got {theta}")
        if not rho > 0:
            raise ConfigurationError(f"penalty strength rho must be positive, got {rho}")
        self.lower, self.upper = lower, upper
        self.range = upper - lower
        self.theta = theta
        self.rho = rho
        self.min_distance = min_distance
        self.zero = np.zeros(lower.shape)
        self.zero.flags.writeable = False
        # the velocities at which every d_i >= theta
        band = theta * self.range
        self._inside = ((lower + band).tolist(), (upper - band).tolist())

    def Perturbation(self, qd: np.ndarray) -> np.ndarray:
        """dq'' (rad/s^2) of eq. (15) for the penalty (14); `zero` (this object's read-only
        zeros) where every d_i >= theta, found in scalar arithmetic (the common case)."""
        for qd_i, lo, hi in zip(qd.tolist(), *self._inside):
            if not lo < qd_i < hi:
                break
        else:
            return self.zero
        to_lower = (qd - self.lower) / self.range
        to_upper = (self.upper - qd) / self.range
        d = np.maximum(np.minimum(to_lower, to_upper), self.min_distance)
        if d.min() >= self.theta:
            return self.zero
        direction = np.where(to_lower < to_upper, 1.0, -1.0) / self.range
        return np.where(d < self.theta, self.rho / d**2 * direction, 0.0)


def ScalingBound(a: float, b: float, limit: float, above: bool) -> tuple[float, bool]:
    """Cases (1)-(4) of the paper for a joint whose q'' = a + c b violates `limit` (its
    maximum if `above`, else its minimum): c-hat_i = (limit - a) / b, an upper bound on c
    when b pushes past the violated limit (cases 1, 2), a lower bound otherwise (3, 4).
    Returns (bound, is_upper)."""
    return (limit - a) / b, (b > 0) == above


def ChooseScaling(
    uppers: list[float], lowers: list[float], c_previous: float
) -> tuple[float, bool]:
    """Rules (a)-(c) of the paper: (a) only upper bounds -> the smallest; (b) only lower
    bounds -> the largest; (c) both -> the value of [c_min, c_max] nearest the previous c.
    Returns (c, admissible); admissible is False when case (c) has c_min > c_max."""
    if not lowers:
        return min(uppers), True  # rule (a)
    if not uppers:
        return max(lowers), True  # rule (b)
    c_min, c_max = max(lowers), min(uppers)  # rule (c)
    if c_min > c_max:
        return c_min, False
    return float(np.clip(c_previous, c_min, c_max)), True


def ScalingReturn(c_hat0: float, t: float, t0: float, rate: float) -> float:
    """Eq. (18): c(t) = (c-hat_0 - 1) exp(-rate (t - t0)) + 1, the continuous return of c
    to 1 after the last scaling at t0 (the paper's rate is 1/s)."""
    return (c_hat0 - 1.0) * math.exp(-rate * (t - t0)) + 1.0


def SelectScaling(
    a: np.ndarray,
    b: np.ndarray,
    c_free: float,
    c_previous: float,
    lower: np.ndarray,
    upper: np.ndarray,
) -> tuple[float, bool]:
    """The scaling coefficient c of q'' = a + c b (17) under lower <= q'' <= upper.

    Returns (c, limited): c_free if it satisfies the limits, else the c-hat chosen by the
    rules (a)-(c) from the bounds of the cases (1)-(4) of every violating joint. Joints that
    a new c pushes past a limit join the violators and the choice is repeated, so the
    result satisfies every limit. Violators are found at trial values of c, where a
    case-(1)/(2) bound lies below and a case-(3)/(4) bound above the trial value, so rule (c)
    is admissible only in the degenerate case c_min = c_max; in practice (c) means the
    limits cannot be met: PlanningError naming the joints.
    """
    uppers: list[float] = []
    lowers: list[float] = []
    seen = np.zeros(a.shape, bool)
    c = c_free
    for _ in range(a.size + 1):
        qdd = a + c * b
        above = (qdd > upper + 1e-12 * np.abs(upper)) & ~seen
        below = (qdd < lower - 1e-12 * np.abs(lower)) & ~seen
        if not (above.any() or below.any()):
            return c, bool(seen.any())
        for i in np.flatnonzero(above | below):
            if abs(b[i]) < 1e-12:
                raise PlanningError(
                    f"acceleration limit of joint {i + 1} cannot be met by scaling: its "
                    f"unscaled part a = {a[i]:.3f} rad/s^2 alone exceeds the limit"
                )
            limit = upper[i] if above[i] else lower[i]
            bound, is_upper = ScalingBound(a[i], b[i], limit, bool(above[i]))
            (uppers if is_upper else lowers).append(bound)
        seen |= above | below
        c, admissible = ChooseScaling(uppers, lowers, c_previous)
        if not admissible:
            joints = ", ".join(str(i + 1) for i in np.flatnonzero(seen))
            raise PlanningError(
                f"acceleration scaling case (c) has no admissible c (joints {joints}: "
                f"c_min {max(lowers):.4f} > c_max {min(uppers):.4f})"
            )
    return c, True


class AccelerationScaling:
    """The acceleration limits lower <= q'' <= upper (rad/s^2) and SelectScaling under them."""

    def __init__(self, lower: np.ndarray, upper: np.ndarray) -> None:
        lower, upper = np.asarray(lower, float), np.asarray(upper, float)
        CheckLimits("acceleration limits", lower, upper)
        self.lower, self.upper = lower, upper

    def Select(
        self, a: np.ndarray, b: np.ndarray, c_free: float, c_previous: float
    ) -> tuple[float, bool]:
        """SelectScaling under these limits: (c, limited)."""
        return SelectScaling(a, b, c_free, c_previous, self.lower, self.upper)


def StepBounds(
    acceleration: tuple[list[float], list[float]] | None,
    velocity: tuple[list[float], list[float]] | None,
    qd: list[float],
    rate: float,
) -> tuple[list[float], list[float]]:
    """Bounds on q'' for the next step: the acceleration limits, tightened to
    rate (velocity limit - qd) near the velocity limits, so that qd approaches a limit at
    most exponentially (time constant 1 / rate, s) and never passes it for rate <= 1 / dt:
    the robust mode's hard guarantee behind the penalty (14)-(15), which only acts through
    the scaled part c b. The bounds move continuously with qd, so q'' does too.

    The robust step's functions below take and return sequences of six floats (lists):
    for six joints plain floats cost several times less than NumPy's small-array calls."""
    n = len(qd)
    lower = [-math.inf] * n if acceleration is None else acceleration[0]
    upper = [math.inf] * n if acceleration is None else acceleration[1]
    if velocity is None:
        return lower, upper
    tightened_lower, tightened_upper = [], []
    # conditional expressions: builtin min / max calls cost more than the comparison
    for qd_i, lo, hi, v_lo, v_hi in zip(qd, lower, upper, *velocity):
        bound = rate * (v_lo - qd_i)
        tightened_lower.append(bound if bound > lo else lo)
        bound = rate * (v_hi - qd_i)
        tightened_upper.append(bound if bound < hi else hi)
    return tightened_lower, tightened_upper


def AdmissibleScaling(
    a: list[float], b: list[float], lower: list[float], upper: list[float]
) -> tuple[float, float]:
    """The interval [c_lo, c_hi] of c >= 0 with lower <= a + c b <= upper for every joint
    (both limits of every joint, not only the violators' violated ones); c_lo > c_hi when
    it is empty. The robust mode's scaling: c = c_free clipped into it is the paper's rule
    (a) or (b) whenever those are admissible, and an empty interval is detected instead of
    leaving a joint unchecked."""
    c_lo, c_hi = 0.0, math.inf
    for a_i, b_i, lo, hi in zip(a, b, lower, upper):
        if abs(b_i) < 1e-12:
            if a_i > hi or a_i < lo:
                return 1.0, 0.0
            continue
        bound_hi, bound_lo = (hi - a_i) / b_i, (lo - a_i) / b_i
        if b_i < 0:
            bound_hi, bound_lo = bound_lo, bound_hi
        if bound_hi < c_hi:
            c_hi = bound_hi
        if bound_lo > c_lo:
            c_lo = bound_lo
    return c_lo, c_hi


def GovernorDamping(
    a: list[float],
    qd: list[float],
    lower: list[float],
    upper: list[float],
    margin: float,
    gain: float,
) -> float:
    """The speed governor's joint damping d (1/s): its braking -d qd (rad/s^2) keeps
    a = -J^-1 Jdot qd within `margin` of the acceleration limits ahead of time.

    a(q, s qd) = s^2 a(q, qd): at the load r = max_i |a_i| / limit_i the speed may grow by
    sqrt(margin / r) before a uses `margin` of the limits. Above that the governor adds
    the joint damping d = gain (r / margin - 1), continuous in the state and zero below
    the margin, i.e. it raises the damping Lambda_V of (9) along the motion; d is capped so
    that a - d qd stays within [lower, upper], which keeps c = 0 admissible.
    """
    load = 0.0
    for a_i, lo, hi in zip(a, lower, upper):
        share = a_i / hi if a_i >= 0 else a_i / lo
        if share > load:
            load = share
    if load <= margin:
        return 0.0
    d = gain * (load / margin - 1.0)
    for a_i, qd_i, lo, hi in zip(a, qd, lower, upper):
        # the room of the joint in the direction the braking pushes it
        if abs(qd_i) > 1e-12:
            room = hi - a_i if qd_i < 0 else a_i - lo
            d = min(d, max(room, 0.0) / abs(qd_i))
    return d


def JerkLimited(
    qdd: list[float],
    qdd_previous: list[float],
    max_change: float,
    lower: list[float],
    upper: list[float],
) -> list[float]:
    """qdd reached from qdd_previous by a change of at most max_change per joint (rad/s^2
    in one step), then kept within [lower, upper]: the bounds move continuously with qd,
    so the result stays continuous, and no limit is exceeded."""
    limited = []
    for value, previous, lo, hi in zip(qdd, qdd_previous, lower, upper):
        change = value - previous
        if change > max_change:
            value = previous + max_change
        elif change < -max_change:
            value = previous - max_change
        if value < lo:
            value = lo
        limited.append(hi if value > hi else value)
    return limited


def BrakingAcceleration(
    qd: list[float],
    qdd_previous: list[float],
    lower: list[float],
    upper: list[float],
    dt: float,
    max_change: float,
) -> list[float]:
    """The fallback when no admissible c exists: towards q'' = -beta qd, every joint slowing
    in proportion (the joint-space direction of motion kept) as hard as [lower, upper] allow
    and at most to rest within the step (beta <= 1/dt), reached from the previous q'' by
    changes of at most max_change per step (rad/s^2) and kept within [lower, upper].
    Slowing shrinks a with qd^2 until the scaling is admissible again."""
    beta = 1.0 / dt
    for qd_i, lo, hi in zip(qd, lower, upper):
        if abs(qd_i) > 1e-12:
            room = -lo if qd_i > 0 else hi
            beta = min(beta, max(room, 0.0) / abs(qd_i))
    return JerkLimited([-beta * qd_i for qd_i in qd], qdd_previous, max_change, lower, upper)


def JerkWindow(
    desired: list[float],
    qdd_previous: list[float],
    max_change: float,
    lower: list[float],
    upper: list[float],
) -> tuple[list[float], list[float], bool]:
    """The bounds on the next q'' (rad/s^2): within max_change of the previous q'' and
    within [lower, upper]; where the two do not overlap (the step bounds moved past the
    previous q'') the nearer step bound, as JerkLimited does. Returns (lower, upper, whether
    `desired` lies within them)."""
    window_lower, window_upper = [], []
    inside = True
    for x, previous, lo, hi in zip(desired, qdd_previous, lower, upper):
        w_lo, w_hi = previous - max_change, previous + max_change
        w_lo = lo if w_lo < lo else (hi if w_lo > hi else w_lo)
        w_hi = hi if w_hi > hi else (lo if w_hi < lo else w_hi)
        window_lower.append(w_lo)
        window_upper.append(w_hi)
        if not w_lo <= x <= w_hi:
            inside = False
    return window_lower, window_upper, inside


def SaturationMetricFactor(J: np.ndarray, inverse: np.ndarray | None = None) -> np.ndarray:
    """F with F F^T = M^-1 for the metric M = J^T J of joint accelerations, in which
    |x - q''_d|_M = |J (x - q''_d)| is how far the TCP's acceleration J x strays from the one
    the law asks for: F = J^-1 (`inverse` if known). Only where J is well conditioned: near
    a singularity M's near-null directions cost nothing, and saturation in it would move
    the joints along them without bound (the planner takes M = I there)."""
    return inverse if inverse is not None else np.linalg.inv(J)


def SaturatedLeastSquares(
    desired: list[float],
    lower: list[float],
    upper: list[float],
    metric_factor: np.ndarray | None,
) -> tuple[list[float], list[int]]:
    """Joint accelerations x within [lower, upper] closest to the law's q''_d = `desired` in
    the metric M (rad/s^2; `metric_factor` F with F F^T = M^-1, None for M = I): saturation
    in the manner of SNS (Flacco, De Luca, Khatib), one joint at a time, without scaling
    the task.

    The joint that exceeds its bound most is held at that bound, and the other joints
    minimise |x - q''_d|_M given the held ones, x = q''_d + P_:S P_SS^-1 (x_S - q''_d,S)
    with P = M^-1 and S the held joints; repeated until every joint is within its bounds
    (at most once per joint: each pass holds one more). Joints that never reach a bound get
    their full share of the law and, for the metric of SaturationMetricFactor, also make
    up as much of the held joints' part of the TCP's acceleration as they can; with M = I
    the compensation is zero and x is q''_d clipped joint by joint. A 6-DoF arm with a 6-D
    task has no redundancy, so SNS proper (which scales the task once the remaining joints
    lose rank) would scale the whole task; here the task is met in least squares instead.
    Returns (x, the held joints in the order held)."""
    x = list(desired)
    held: list[int] = []
    values: list[float] = []
    P: list[list[float]] = []  # M^-1 = F F^T as floats, once a joint is held
    for _ in range(len(x)):
        joint = MostViolated(x, lower, upper)
        if joint < 0:
            return x, held
        value = upper[joint] if x[joint] > upper[joint] else lower[joint]
        held.append(joint)
        values.append(value)
        if metric_factor is None:
            x[joint] = value
            continue
        if not P:  # one product for all rows: cheaper than one per held joint
            P = metric_factor.dot(metric_factor.T).tolist()
        # the common cases in closed form; the held joints set exactly on their bounds
        if len(held) == 1:
            w = (value - desired[joint]) / P[joint][joint]
            x = [d_i + w * p_i for d_i, p_i in zip(desired, P[joint])]
            x[joint] = value
            continue
        if len(held) == 2:
            j, k = held
            shift_j, shift_k = values[0] - desired[j], value - desired[k]
            p_jj, p_jk, p_kk = P[j][j], P[j][k], P[k][k]
            det = p_jj * p_kk - p_jk * p_jk
            w_j = (p_kk * shift_j - p_jk * shift_k) / det
            w_k = (p_jj * shift_k - p_jk * shift_j) / det
            x = [d_i + w_j * a_i + w_k * b_i for d_i, a_i, b_i in zip(desired, P[j], P[k])]
            x[j], x[k] = values
            continue
        shift = [v - desired[j] for j, v in zip(held, values)]
        weights = CholeskySolve([[P[j][k] for k in held] for j in held], shift)
        x = list(desired)
        for k, w in zip(held, weights):
            x = [x_i + w * p_i for x_i, p_i in zip(x, P[k])]
        for j, v in zip(held, values):
            x[j] = v
    return x, held


def MostViolated(x: list[float], lower: list[float], upper: list[float]) -> int:
    """The joint whose x lies furthest outside [lower, upper] (the first of equals), -1
    if none is outside."""
    worst, joint = 0.0, -1
    for i, x_i in enumerate(x):
        excess = x_i - upper[i]
        if excess > worst:
            worst, joint = excess, i
            continue
        excess = lower[i] - x_i
        if excess > worst:
            worst, joint = excess, i
    return joint


def CholeskySolve(A: list[list[float]], y: list[float]) -> list[float]:
    """A^-1 y for a small symmetric positive definite A (nested lists): Cholesky
    factorisation and two triangular solves in scalar arithmetic, several times cheaper
    than np.linalg.solve's call for the 1-6 unknowns of SaturatedLeastSquares."""
    n = len(y)
    L = [[0.0] * n for _ in range(n)]
    for i in range(n):
        for j in range(i + 1):
            s = A[i][j] - sum(L[i][k] * L[j][k] for k in range(j))
            L[i][j] = math.sqrt(s) if i == j else s / L[j][j]
    z = [0.0] * n
    for i in range(n):
        z[i] = (y[i] - sum(L[i][k] * z[k] for k in range(i))) / L[i][i]
    for i in reversed(range(n)):
        z[i] = (z[i] - sum(L[k][i] * z[k] for k in range(i + 1, n))) / L[i][i]
    return z
