"""The robust planner's joint velocity and acceleration limits (beyond the paper).

The speed governor, which keeps the velocity-driven term a = -J^-1 Jdot qd within a margin
of the acceleration limits (a grows with qd^2, so slowing early keeps case (c) of the
paper's scaling, acceleration_planner_limits, away), the step bounds that keep qd within
its limits, the per-joint saturation that replaces the scaling of the whole task
(SaturatedLeastSquares), and the braking fallback used should no admissible c exist all
the same. Units: rad/s, rad/s^2, s.
"""

from __future__ import annotations

import math

import numpy as np


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
