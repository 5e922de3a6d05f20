"""State of the acceleration-level planner between steps, and the trajectory it commands.

PlannerState is what the planner carries from one 2 ms step to the next (the LeafSystem's
discrete state); PlannedTrajectory is a run of them, sampled at the planner period.
Units: rad, rad/s, rad/s^2, s.
"""

from __future__ import annotations

from dataclasses import dataclass, field

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
    The robust mode's watch over the motion (systems/planning/acceleration_planner_watch.py):
    handover_time, when the law was handed over to joint space for the rest of the task
    (s, -1 if not); best_error, best_progress, best_time: the smallest error to the
    current target (m, rotations counted at 0.1 m/rad), the waypoint progress index + sigma
    and when either last improved (s); reversal_sign, reversal_rate: per joint, the sign
    of its last commanded acceleration beyond half its limit and the rate of its sign
    reversals (1/s, averaged over the last 2 s; acceleration_planner_watch).
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
    handover_time: float = -1.0
    best_error: float = 1e9
    best_progress: float = 0.0
    best_time: float = 0.0
    reversal_sign: np.ndarray = field(default_factory=lambda: np.zeros(6))
    reversal_rate: np.ndarray = field(default_factory=lambda: np.zeros(6))

    SIZE_EXTRA = 13 + 12  # the scalars, then reversal_sign and reversal_rate of 6 joints
    TIME_ROW = 18  # row of t in ToVector() of a 6-joint arm
    DONE_ROW = 26  # row of done_time

    def ToVector(self) -> np.ndarray:
        scalars = [self.t, self.c, self.c_hat0, self.t0, self.index, self.sigma]
        scalars += [float(self.inside), float(self.braking), self.done_time]
        scalars += [self.handover_time, self.best_error, self.best_progress, self.best_time]
        return np.concatenate(
            [self.q, self.qd, self.qdd, scalars, self.reversal_sign, self.reversal_rate]
        )

    @staticmethod
    def FromVector(x: np.ndarray) -> PlannerState:
        n = 6
        t, c, c_hat0, t0, index, sigma, inside, braking, done_time = x[3 * n : 3 * n + 9]
        handover_time, best_error, best_progress, best_time = x[3 * n + 9 : 3 * n + 13]
        return PlannerState(
            x[:n].copy(), x[n : 2 * n].copy(), x[2 * n : 3 * n].copy(), float(t), float(c),
            float(c_hat0), float(t0), round(index), float(sigma),
            bool(inside > 0.5), bool(braking > 0.5), float(done_time), float(handover_time),
            float(best_error), float(best_progress), float(best_time),
            x[3 * n + 13 : 4 * n + 13].copy(), x[4 * n + 13 : 5 * n + 13].copy(),
        )  # fmt: skip

    @property
    def done(self) -> bool:
        return self.done_time >= 0


@dataclass
class PlannedTrajectory:
    """A commanded trajectory sampled at the planner period: times (s), q, qd, qdd
    (samples x 6; rad, rad/s, rad/s^2), c, the waypoint index and whether the step was the
    robust mode's braking fallback, per sample, the time the task ended (s; -1 if it
    did not), the joints' acceleration reversal rates (samples x 6, 1/s; the robust mode's
    oscillation measure) and the time the law handed over to joint space (s, -1 if not)."""

    times: np.ndarray
    q: np.ndarray
    qd: np.ndarray
    qdd: np.ndarray
    c: np.ndarray
    index: np.ndarray
    braking: np.ndarray
    done_time: float
    reversal_rate: np.ndarray
    handover_time: float

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
            reversal_rate=columns[4 * n + 13 : 5 * n + 13].T.copy(),
            handover_time=float(extra[9].max(initial=-1.0)),
        )
