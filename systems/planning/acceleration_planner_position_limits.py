"""Joint position limits of the robust planner: the viability bound on the commanded qd.

A joint at distance d from a position limit can still stop there when braking at b
(rad/s^2) only if its speed towards the limit is at most sqrt(2 b d), the square-root law of
time-optimal braking. PositionStepBounds turns that speed into a bound on the next step's
q'' (rad/s^2) beside the acceleration and velocity limits of StepBounds
(systems/planning/acceleration_planner_robust_limits.py): qd tracks the viable speed at the rate
of the velocity bound, with the speed's own rate of change along the motion as a feed-
forward, so braking starts in time and the joint comes to rest at the limit, never past it.
A joint at rest at its limit gets a zero bound towards it (no push back, no chatter), and
away from the limit the bound is inactive.

Units: rad, rad/s, rad/s^2; sequences of six floats like the robust step's other limits.
"""

from __future__ import annotations

import math
from collections.abc import Sequence


def ViableSpeed(distance: float, braking: float, rate: float) -> tuple[float, float]:
    """(v, dv/d distance): the largest speed towards a limit `distance` (rad) away from
    which braking at `braking` (rad/s^2) stops at the limit, smoothed at the limit:
    v = sqrt(2 braking distance + c^2) - c with c = braking / rate (rad/s). Far from the
    limit it is the square-root law sqrt(2 braking distance) less c; at the limit its slope
    is `rate` (1/s) instead of the square root's infinite one, which would make the bound
    switch from step to step there, and its slope braking / (v + c) is continuous, so the
    bound is (a piecewise bound's kink made the commanded q'' jump by 0.7 rad/s^2 in one
    step on the UR10e). 0 at or past the limit."""
    c = braking / rate
    if distance <= 0.0:
        return 0.0, rate
    v = math.sqrt(2.0 * braking * distance + c * c) - c
    return v, braking / (v + c)


def PositionStepBounds(
    q: Sequence[float],
    qd: Sequence[float],
    lower: Sequence[float],
    upper: Sequence[float],
    q_lower: Sequence[float],
    q_upper: Sequence[float],
    braking: Sequence[float],
    rate: float,
) -> tuple[list[float], list[float]]:
    """The step bounds [lower, upper] on q'' tightened so that the commanded q stays within
    [q_lower, q_upper] (rad): towards the upper limit, with v = ViableSpeed(q_upper - q,
    braking, rate) the bound is rate (v - qd) + dv/dt, dv/dt = -(dv/d distance) qd while
    moving towards the limit (zero while moving away); the lower limit likewise. `braking` per joint
    (rad/s^2) must be below the acceleration limit, so that the law keeps room; `rate` (1/s)
    is the velocity bound's (StepBounds). A bound tighter than the other side is clipped to
    it: braking harder than the acceleration limit is never asked for."""
    new_lower, new_upper = [], []
    for q_i, qd_i, lo, hi, q_lo, q_hi, b in zip(q, qd, lower, upper, q_lower, q_upper, braking):
        v, slope = ViableSpeed(q_hi - q_i, b, rate)
        bound = rate * (v - qd_i)
        if qd_i > 0.0:
            bound -= slope * qd_i
        if bound < hi:
            hi = bound if bound > lo else lo
        v, slope = ViableSpeed(q_i - q_lo, b, rate)
        bound = rate * (-v - qd_i)
        if qd_i < 0.0:
            bound -= slope * qd_i
        if bound > lo:
            lo = bound if bound < hi else hi
        new_lower.append(lo)
        new_upper.append(hi)
    return new_lower, new_upper
