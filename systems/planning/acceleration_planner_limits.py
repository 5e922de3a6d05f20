"""Joint velocity and acceleration limits of the acceleration-level planner: the paper's.

The paper's (Pająk) two mechanisms: the interior velocity penalty (14)-(15) and the
acceleration scaling q'' = a + c b (17) with the cases (1)-(4), the rules (a)-(c) and the
exponential return (18). The robust mode's limits (beyond the paper):
acceleration_planner_robust_limits. Units: rad/s, rad/s^2, s.
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
