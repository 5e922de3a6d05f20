"""Mathematics of continuous path following: sense while moving, no stops (beyond the paper).

Frames: world W; tool T with centre O and x_T along the path (the detection plane is T's
y-z plane). Units: m, s, rad.

The readings make the hose estimate (continuous_follower_estimate: HoseEstimate, a
quadratic fitted to the last fit_length of hose points, extrapolated ahead, the trail of
past fits behind); this module moves the target along it.

Reference (Advance, every servo period): a target pose moves along the estimated path at
the commanded speed v, which ramps (acceleration) toward
    min(speed, sqrt(lateral_acceleration / curvature), confidence-scaled speed)
and brakes so as never to pass the estimate's end by more than look_ahead. The target
position and direction follow the estimated path through a first-order filter
(correction_gain) at bounded rates (max_correction_speed, max_turn_rate_deg), so the noise
of one reading never jerks the arm.
The detection plane stays perpendicular to the path: the target's x axis is the tangent,
its roll about it the start's (the scenario's tool_roll_deg; 0: z_T in the vertical plane).

Loss: a reading without the hose leaves the estimate where it was. Once the tool is
loss_distance past the last estimate, the follower SEARCHES at search_speed along the
extrapolation to search_distance past it; with no hose there it BACKS UP along its trail
to the last estimate and RETRIES in directions turned about the world z axis by each of
search_turns_deg; a reading that sees the hose again resumes FOLLOW (a recovery). When
every retry is lost too, the hose has ended: the follower backs up to the last estimate
and is DONE.
"""

import math
from dataclasses import dataclass
from typing import Any, TypeVar

import numpy as np
from pydrake.math import RigidTransform, RotationMatrix

from guidedarm.systems.path_following.continuous_follower_config import ContinuousConfig
from guidedarm.systems.path_following.continuous_follower_estimate import HoseEstimate, LocalFit
from guidedarm.systems.path_following.path_follower_math import OrientationFromVector
from guidedarm.systems.small_vectors import Dot, Vector

FOLLOW, SEARCH, BACK, RETRY, DONE = range(5)
# A search leg ends this close to its end (m); the braking target approaches it only
# asymptotically.
END_OF_LEG = 5e-4
MODE_NAMES = ("follow", "search", "back", "retry", "done")
Frozen = TypeVar("Frozen")


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
    past it: a recovery); roll: the tool's fixed roll about x (rad)."""

    mode: int
    r: np.ndarray
    x: np.ndarray
    s: float
    v: float
    retry: int = 0
    retry_direction: np.ndarray | None = None
    recoveries: int = 0
    lost_s: float | None = None
    roll: float = 0.0

    @staticmethod
    def Start(X_WT: RigidTransform, roll: float = 0.0) -> "Reference":
        """At rest at the tool's start pose X_WT, keeping `roll` (rad) about x_T."""
        return Reference(
            FOLLOW,
            X_WT.translation().copy(),
            X_WT.rotation().matrix()[:, 0].copy(),
            0.0,
            0.0,
            roll=roll,
        )

    def Pose(self) -> RigidTransform:
        """X_WT of the target: O at r, x_T along x, the roll (OrientationFromVector)."""
        return RigidTransform(OrientationFromVector(self.x, self.roll), self.r)


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
    speed_cap: float = math.inf,
) -> Reference:
    """The target one servo period later (module docstring); lag: how far (m) the arm's
    tool was from the target at the latest reading; speed_cap: the fastest it may follow
    the hose (m/s; hose_thickness.Thickness.SpeedCap). Its 3-vectors in floats: numpy's
    per-call overhead on them costs more than the arithmetic, every servo period."""
    if ref.mode == DONE:
        return Replaced(ref, v=0.0)
    fit = estimate.fit
    if ref.mode == FOLLOW:
        v_goal, s_stop = min(TargetSpeed(fit, config), speed_cap), fit.s + config.look_ahead
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
    lag = math.acos(max(-1.0, min(1.0, Dot(x_ref, heading)))) if ref.mode == FOLLOW else 0.0
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
    gap = math.sqrt(Dot(d, d))
    budget = min(config.correction_gain * gap, config.max_correction_speed) * dt
    # Toward the goal by at most the budget.
    r = goal if gap <= budget else [a + b * (budget / gap) for a, b in zip(moved, d, strict=True)]
    angle = math.acos(max(-1.0, min(1.0, Dot(x_ref, x_goal))))
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


def _Turn(x: Vector, goal: Vector, angle: float) -> Vector:
    """x (unit) turned toward goal by at most `angle` (rad), unit length: within the plane
    of the two, toward goal's part perpendicular to x (floats)."""
    c = max(-1.0, min(1.0, Dot(x, goal)))
    between = math.acos(c)
    if between <= angle:
        norm = math.sqrt(Dot(goal, goal))
        return [v / norm for v in goal]
    perpendicular = [a - c * b for a, b in zip(goal, x, strict=True)]
    length = math.sqrt(Dot(perpendicular, perpendicular))
    if length < 1e-12:  # goal opposite x: turn toward the world z axis (x if x is z)
        toward = [0.0, 0.0, 1.0] if abs(x[2]) < 1 - 1e-9 else [1.0, 0.0, 0.0]
        along = Dot(x, toward)
        perpendicular = [a - along * b for a, b in zip(toward, x, strict=True)]
        length = math.sqrt(Dot(perpendicular, perpendicular))
    cos, scale = math.cos(angle), math.sin(angle) / length
    turned = [a * cos + b * scale for a, b in zip(x, perpendicular, strict=True)]
    norm = math.sqrt(Dot(turned, turned))
    return [v / norm for v in turned]
