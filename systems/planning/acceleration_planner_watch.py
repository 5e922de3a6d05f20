"""The robust planner's watch over its own motion: oscillation and progress.

A saturated joint held at a bound, or a bound switching on and off, can make a law of this
kind chatter: the commanded acceleration of a joint swings between its limits at a few hertz
while the TCP makes no headway. On a real arm that is a violent fault, so the planner
measures it and stops instead of running into a time limit.

- Oscillation measure: per joint, the sign reversals of the commanded q'' between
  excursions beyond REVERSAL_FRACTION (50 %) of its acceleration limit (a hysteresis, so
  small swings about zero do not count), as a rate (1/s) averaged exponentially over
  REVERSAL_WINDOW_S (2 s). A limit cycle swings a joint between its acceleration limits:
  at 3 Hz, 6 reversals a second. At 10 % of the limit and over 1 s, ordinary moves of the
  random set (45 tasks, 15 per arm) already reached 5.5 (UR10e) to 59 (rover arm: brief
  step-to-step switching of a saturated joint within the jerk limit, harmless); at 50 %
  and 2 s their largest rate was 2.9, and 3.7 on a near-singular rover arm task of the
  property test that still ends within 1 mm; the planner's default bound is 5 /s, which
  a 3 Hz full swing exceeds within 3.6 s.
- Progress: the error to the current target (position in m, rotation in rad counted at
  ROTATION_LENGTH_M per rad), or, once handed over to joint space, the joints' distance to
  their target (rad), and the waypoint progress index + sigma; progress is a 1 % smaller
  error or a larger index + sigma.

Units: s, rad/s^2; per-joint sequences of floats.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np

REVERSAL_FRACTION = 0.5
REVERSAL_WINDOW_S = 2.0
ROTATION_LENGTH_M = 0.1


def UpdateReversals(
    qdd: Sequence[float],
    limits: Sequence[float],
    signs: Sequence[float],
    rates: Sequence[float],
    dt: float,
) -> tuple[list[float], list[float]]:
    """One step (dt, s) of the oscillation measure: the new signs (+1, -1, 0 before the
    first excursion) and reversal rates (1/s) of the joints given their commanded q''
    (rad/s^2) and acceleration limits (rad/s^2, positive)."""
    decay = math.exp(-dt / REVERSAL_WINDOW_S)
    new_signs, new_rates = [], []
    for x, limit, sign, rate in zip(qdd, limits, signs, rates):
        rate *= decay
        threshold = REVERSAL_FRACTION * limit
        now = 1.0 if x > threshold else (-1.0 if x < -threshold else sign)
        if now * sign < 0:
            rate += 1.0 / REVERSAL_WINDOW_S
        new_signs.append(now)
        new_rates.append(rate)
    return new_signs, new_rates


def ReversalRates(qdd: np.ndarray, limits: np.ndarray, dt: float) -> np.ndarray:
    """The oscillation measure along a sampled acceleration series (samples x joints,
    rad/s^2; limits per joint): the reversal rate of each joint at each sample (1/s)."""
    signs, rates = [0.0] * qdd.shape[1], [0.0] * qdd.shape[1]
    out = np.zeros_like(qdd)
    for k, row in enumerate(qdd.tolist()):
        signs, rates = UpdateReversals(row, limits.tolist(), signs, rates, dt)
        out[k] = rates
    return out


def TargetError(e: Sequence[float]) -> float:
    """The size of a pose error [x; rotation vector] (m): |x| + ROTATION_LENGTH_M |rot|."""
    x, y, z, a, b, c = e
    return math.sqrt(x * x + y * y + z * z) + ROTATION_LENGTH_M * math.sqrt(a * a + b * b + c * c)


def Progressed(
    error: float, progress: float, best_error: float, best_progress: float
) -> tuple[bool, float, float]:
    """Whether (error, progress) improves on the best so far (a 1 % smaller error, or more
    waypoint progress), and the new best (error, progress): a larger progress restarts the
    best error from the current one."""
    if progress > best_progress + 1e-6:
        return True, error, progress
    if error < 0.99 * best_error - 1e-7:
        return True, error, best_progress
    return False, best_error, best_progress
