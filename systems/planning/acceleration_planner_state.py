"""State of the acceleration-level planner between steps, and the trajectory it commands.

PlannerState is what the planner carries from one 2 ms step to the next (the LeafSystem's
discrete state); PlannedTrajectory is a run of them, sampled at the planner period.
Units: rad, rad/s, rad/s^2, s.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass(slots=True)
class PlannerState:
    """Everything the planner carries from one step to the next.

    q, qd: commanded joint positions (rad) and velocities (rad/s) at time t (s); qdd: the
    acceleration applied over the step that ended at t (rad/s^2). c: scaling coefficient of
    that step; c_hat0, t0: start value and time of the exponential return (18). index: the
    waypoint the TCP moves towards; sigma: blending progress in its neighbourhood,
    inside = 1 while blending; braking = 1 if that step was the robust mode's braking
    fallback; done_time: first time the task ended (s), -1 before.
    """

    q: np.ndarray
    qd: np.ndarray
    qdd: np.ndarray
    t: float = 0.0
    c: float = 1.0
    c_hat0: float = 1.0
    t0: float = 0.0
    index: int = 0
    sigma: float = 0.0
    inside: bool = False
    braking: bool = False
    done_time: float = -1.0

    SIZE_EXTRA = 9
    TIME_ROW = 18  # row of t in ToVector() of a 6-joint arm

    def ToVector(self) -> np.ndarray:
        scalars = [self.t, self.c, self.c_hat0, self.t0, self.index, self.sigma]
        scalars += [float(self.inside), float(self.braking), self.done_time]
        return np.concatenate([self.q, self.qd, self.qdd, scalars])

    @staticmethod
    def FromVector(x: np.ndarray) -> PlannerState:
        n = (x.size - PlannerState.SIZE_EXTRA) // 3
        t, c, c_hat0, t0, index, sigma, inside, braking, done_time = x[3 * n :]
        return PlannerState(
            x[:n].copy(), x[n : 2 * n].copy(), x[2 * n : 3 * n].copy(), float(t), float(c),
            float(c_hat0), float(t0), round(index), float(sigma),
            bool(inside > 0.5), bool(braking > 0.5), float(done_time),
        )  # fmt: skip

    @property
    def done(self) -> bool:
        return self.done_time >= 0


@dataclass
class PlannedTrajectory:
    """A commanded trajectory sampled at the planner period: times (s), q, qd, qdd
    (samples x 6; rad, rad/s, rad/s^2), c, the waypoint index and whether the step was the
    robust mode's braking fallback, per sample, and the time the task ended (s; -1 if it
    did not)."""

    times: np.ndarray
    q: np.ndarray
    qd: np.ndarray
    qdd: np.ndarray
    c: np.ndarray
    index: np.ndarray
    braking: np.ndarray
    done_time: float

    @staticmethod
    def FromStateVectors(columns: np.ndarray) -> PlannedTrajectory:
        """From PlannerState vectors, one per column (e.g. a VectorLog of them)."""
        n = (columns.shape[0] - PlannerState.SIZE_EXTRA) // 3
        extra = columns[3 * n :]
        done = extra[8][extra[8] >= 0]
        return PlannedTrajectory(
            times=extra[0].copy(),
            q=columns[:n].T.copy(),
            qd=columns[n : 2 * n].T.copy(),
            qdd=columns[2 * n : 3 * n].T.copy(),
            c=extra[1].copy(),
            index=extra[4].round().astype(int),
            braking=extra[7] > 0.5,
            done_time=float(done[0]) if done.size else -1.0,
        )
