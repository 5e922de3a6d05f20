"""Mathematics of 3D path following with a ToF tool (Wawrzyniak et al., equations (1)-(26), 3.2).

Frames: world W = robot base; tool T with origin O (position p_WO) at the centre of the
detection field and x_T the travel direction (the detection plane's normal n); gripper G.

One step, from the tool pose X_WT (O, R) and the detected hose point S (or none):
  m = S - O (9); t = O - O' (10), O' the last tool position with a detection;
  w = t + m (11); P_n = O + w_hat d (12)-(13), or P_n = O + R x_hat d when S = O (14);
  d = short_step when the hose is seen only at the centre or not at all, else long_step;
  w_a = n a + m b (15)-(17) with a = |t|, b in (0, 1);
  yaw = atan2(w_a,y, w_a,x) (20), pitch = atan(-w_a,z / |w_a,xy|) (21), roll = 0 (22)
  (beyond the paper: a fixed roll, the scenario's tool_roll_deg, for a hose on the table).
Tool pose from gripper pose: O = O_c + R_c z_hat l_e, R_e = R_c R_ec (23)-(26).

Beyond the paper (its discussion): after lost_limit steps without a detection the tool
returns to the last pose that saw the hose and retries in a direction turned by
recovery_angle_deg (yaw +, yaw -, pitch up; a downward retry near the end finds the
bracket post and follows it); when every retry is lost too, or the hose is lost again
within two long steps of where it was lost before, the hose has ended (or is lost for
good) and the follower stops there.
"""

import math
import typing
from dataclasses import dataclass, field, replace
from typing import Literal

import numpy as np
from pydrake.math import RigidTransform, RollPitchYaw, RotationMatrix

from guidedarm.systems.config_checks import (
    CheckFields,
    ChoiceViolation,
    FieldError,
    InRange,
    Positive,
    TextChoices,
)
from guidedarm.systems.errors import ConfigurationError

Estimator = Literal["grid", "ranging"]
Steering = Literal["paper", "centring"]
ESTIMATORS = typing.get_args(Estimator)
STEERINGS = typing.get_args(Steering)


@TextChoices
@dataclass
class FollowerConfig:
    """Parameters of the path follower (m, deg). Its automatic values depend on the
    hose estimator it runs with (Estimator: `grid`, the paper's presence-only 3 x 3 grid,
    or `ranging`, ranges localise the hose between the grid points), given to Resolved().

    steering: `paper` (w = t + m, w_a = n a + m b) or `centring` (w = n a + m: forward along
        the tool axis plus the full offset, and w_a = n a + (S - S') b: turn toward the
        hose's own direction, S' the previous detected point); empty picks `paper` for the
        grid estimator and `centring` for ranging, whose S is accurate enough to steer on.
    long_step, short_step: the paper's d for long and short steps.
    rotation_reduction: the paper's b in (0, 1); 0 picks 0.3 (paper) or 0.5 (centring).
    readings: sensor readings averaged per step; 0 picks 1 for the grid (the paper reads
        once) and 4 for ranging, whose accuracy is the ranges' noise (2 mm each, halved by
        four readings), where the grid's is its 22 mm spacing.
    reading_period: time between readings (s): the sensors' measurement period, so that
        each reading is a new measurement.
    lost_limit: steps without detection before a recovery (0 disables recoveries).
    recovery_angle_deg: turn of the retry direction.
    max_steps: the run stops with a failure after this many steps.
    """

    steering: Literal["", Steering] = ""
    long_step: float = Positive(0.015)
    short_step: float = Positive(0.010)
    rotation_reduction: float = InRange(0.0, 1.0, 0.0, high_open=True)
    readings: int = 0
    reading_period: float = Positive(0.02)
    lost_limit: int = 3
    recovery_angle_deg: float = InRange(0.0, 180.0, 20.0, low_open=True)
    max_steps: int = Positive(400)

    def Resolved(self, estimator: Estimator) -> "FollowerConfig":
        """A checked copy with the automatic steering, rotation_reduction and readings
        filled in for `estimator` (FieldError naming it if it is none of ESTIMATORS)."""
        why = ChoiceViolation(estimator, Estimator)
        if why is not None:
            raise FieldError("estimator", why)
        steering = self.steering or ("centring" if estimator == "ranging" else "paper")
        b = self.rotation_reduction or (0.5 if steering == "centring" else 0.3)
        readings = self.readings or (4 if estimator == "ranging" else 1)
        resolved = replace(self, steering=steering, rotation_reduction=b, readings=readings)
        resolved.Validate()
        return resolved

    def Validate(self) -> None:
        """Raises ConfigurationError naming the first bad parameter (the automatic values,
        an empty steering and zeros, are accepted)."""
        CheckFields(self)
        if not self.short_step <= self.long_step:
            raise ConfigurationError("need short_step <= long_step")


def Rotation(roll: float, pitch: float, yaw: float) -> np.ndarray:
    """R = Rz(yaw) Ry(pitch) Rx(roll), equations (1)-(4)."""
    cr, sr, cp, sp, cy, sy = (
        math.cos(roll),
        math.sin(roll),
        math.cos(pitch),
        math.sin(pitch),
        math.cos(yaw),
        math.sin(yaw),
    )
    Rx = np.array([[1, 0, 0], [0, cr, -sr], [0, sr, cr]])
    Ry = np.array([[cp, 0, sp], [0, 1, 0], [-sp, 0, cp]])
    Rz = np.array([[cy, -sy, 0], [sy, cy, 0], [0, 0, 1]])
    return Rz @ Ry @ Rx


@dataclass(frozen=True)
class ToolMount:
    """The tool frame relative to the gripper: l_e along gripper z, then roll, pitch, yaw
    (m, rad); the paper's tool: 0.1597 m, (pi, 0, -pi/4)."""

    l_e: float
    roll: float
    pitch: float
    yaw: float

    def ToolPose(self, X_WG: RigidTransform) -> RigidTransform:
        """X_WT from the gripper pose, equations (23)-(26)."""
        R_c = X_WG.rotation().matrix()
        p_WO = X_WG.translation() + R_c @ np.array([0.0, 0.0, 1.0]) * self.l_e
        R_e = R_c @ Rotation(self.roll, self.pitch, self.yaw)
        return RigidTransform(RotationMatrix(R_e), p_WO)

    def GripperPose(self, X_WT: RigidTransform) -> RigidTransform:
        """X_WG for a tool pose: the inverse of ToolPose."""
        R_c = X_WT.rotation().matrix() @ Rotation(self.roll, self.pitch, self.yaw).T
        O_c = X_WT.translation() - R_c @ np.array([0.0, 0.0, 1.0]) * self.l_e
        return RigidTransform(RotationMatrix(R_c), O_c)

    @staticmethod
    def FromTransform(X_GT: RigidTransform) -> "ToolMount":
        """The mount of a weld X_GT; ConfigurationError unless it is an offset along z."""
        p = X_GT.translation()
        if np.linalg.norm(p[:2]) > 1e-9:
            raise ConfigurationError(f"tool frame is not on the gripper z axis (offset {p})")
        rpy = RollPitchYaw(X_GT.rotation())
        return ToolMount(float(p[2]), rpy.roll_angle(), rpy.pitch_angle(), rpy.yaw_angle())


def OrientationFromVector(w_a: np.ndarray, roll: float = 0.0) -> RotationMatrix:
    """Tool orientation with x along w_a, equations (20)-(22): Rotation(roll, pitch, yaw)
    written out (the continuous follower needs it every servo period). roll (rad) about
    x_T: the paper's 0 keeps z_T in the vertical plane through x_T; the scenario's
    tool_roll_deg turns the tool about the hose (a hose on the table)."""
    x, y, z = float(w_a[0]), float(w_a[1]), float(w_a[2])
    yaw = math.atan2(y, x)
    pitch = math.atan2(-z, math.hypot(x, y))
    cp, sp, cy, sy = math.cos(pitch), math.sin(pitch), math.cos(yaw), math.sin(yaw)
    R = np.array([[cy * cp, -sy, cy * sp], [sy * cp, cy, sy * sp], [-sp, 0.0, cp]])
    if roll:
        cr, sr = math.cos(roll), math.sin(roll)
        R = R @ np.array([[1.0, 0.0, 0.0], [0.0, cr, -sr], [0.0, sr, cr]])
    return RotationMatrix(R)


@dataclass(frozen=True)
class FollowerMemory:
    """What the follower remembers between steps (world frame, m)."""

    O_prime: np.ndarray
    last_detection: RigidTransform
    S_prime: np.ndarray | None = None
    lost: int = 0
    recovery: int = 0
    recoveries: int = 0
    retry_origin: np.ndarray | None = None
    last_loss: np.ndarray | None = None
    roll: float = 0.0

    @staticmethod
    def Start(X_WT: RigidTransform, params: FollowerConfig, roll: float = 0.0) -> "FollowerMemory":
        """Memory at the start pose: O' one short step behind O, as if arriving along x_T;
        roll: the tool's roll about x_T (rad) that every step keeps."""
        n = X_WT.rotation().matrix()[:, 0]
        return FollowerMemory(X_WT.translation() - n * params.short_step, X_WT, roll=roll)


@dataclass(frozen=True)
class StepResult:
    """Next tool pose, new memory, and what this step saw (S_W None: no detection)."""

    X_WT_next: RigidTransform
    memory: FollowerMemory
    S_W: np.ndarray | None
    long_step: bool
    ended: bool = False
    info: dict = field(default_factory=dict)


_RECOVERY_TURNS = ((1, 0), (-1, 0), (0, -1))


def FollowStep(
    X_WT: RigidTransform,
    S_T: np.ndarray | None,
    centre_only: bool,
    memory: FollowerMemory,
    params: FollowerConfig,
) -> StepResult:
    """One step of the paper's algorithm (module docstring); S_T is the detected hose point in
    the tool frame, centre_only whether it is the centre point alone."""
    p_WO = X_WT.translation()
    R = X_WT.rotation().matrix()
    n = R[:, 0]
    if S_T is None:
        return _StepWithoutDetection(X_WT, memory, params)
    S_W = X_WT @ np.asarray(S_T, float)
    m = S_W - p_WO
    t = p_WO - memory.O_prime
    d = params.short_step if centre_only else params.long_step
    a = np.linalg.norm(t)
    if np.linalg.norm(m) < 1e-9:
        P_n = p_WO + n * d
    else:
        # Centring trusts m as the hose's true offset: the forward part is the tool axis,
        # not the last displacement, whose sideways part made the paper's tool wave.
        w = (n * a if params.steering == "centring" else t) + m
        P_n = p_WO + w / np.linalg.norm(w) * d
    if params.steering == "centring" and memory.S_prime is not None:
        w_a = n * a + (S_W - memory.S_prime) * params.rotation_reduction
    else:
        w_a = n * a + m * params.rotation_reduction
    # A retry counts as a recovery once the tool sees the hose more than a long step from
    # where it restarted. One short step is not enough: past the end a retry that glimpses
    # the hose's end then counted as recovered, and the tool cycled lost-retry-recovered
    # around the end instead of stopping there.
    retrying = memory.recovery > 0
    recovered = retrying and np.linalg.norm(p_WO - memory.retry_origin) > params.long_step
    still_retrying = retrying and not recovered
    new_memory = FollowerMemory(
        O_prime=p_WO,
        S_prime=S_W,
        last_detection=memory.last_detection if still_retrying else X_WT,
        recovery=memory.recovery if still_retrying else 0,
        recoveries=memory.recoveries + int(recovered),
        retry_origin=memory.retry_origin if still_retrying else None,
        last_loss=memory.last_loss,
        roll=memory.roll,
    )
    return StepResult(
        RigidTransform(OrientationFromVector(w_a, memory.roll), P_n),
        new_memory,
        S_W,
        not centre_only,
    )


def GiveUpDirection(
    X_WT: RigidTransform, memory: FollowerMemory, params: FollowerConfig
) -> StepResult:
    """The step after the arm cannot reach the next pose of a lost or retrying tool: the
    next retry direction (or the end of the path)."""
    return _StepWithoutDetection(X_WT, replace(memory, lost=params.lost_limit), params)


def IsExploring(memory: FollowerMemory) -> bool:
    """Whether the tool is moving without the hose in sight (lost or retrying)."""
    return memory.lost > 0 or memory.recovery > 0


def _StepWithoutDetection(
    X_WT: RigidTransform, memory: FollowerMemory, params: FollowerConfig
) -> StepResult:
    p_WO = X_WT.translation()
    n = X_WT.rotation().matrix()[:, 0]
    lost = memory.lost + 1
    if params.lost_limit == 0 or lost <= params.lost_limit:
        X_next = RigidTransform(OrientationFromVector(n, memory.roll), p_WO + n * params.short_step)
        return StepResult(X_next, replace(memory, lost=lost), None, False)
    attempt = memory.recovery + 1
    O_last = memory.last_detection.translation()
    if attempt > len(_RECOVERY_TURNS) or (attempt == 1 and _LostHereBefore(O_last, memory, params)):
        return StepResult(X_WT, memory, None, False, ended=True)
    turn_yaw, turn_pitch = _RECOVERY_TURNS[attempt - 1]
    delta = math.radians(params.recovery_angle_deg)
    last = memory.last_detection
    rpy = RollPitchYaw(last.rotation())
    R_retry = RotationMatrix(
        Rotation(
            memory.roll, rpy.pitch_angle() + turn_pitch * delta, rpy.yaw_angle() + turn_yaw * delta
        )
    )
    n_retry = R_retry.matrix()[:, 0]
    retry_memory = replace(
        memory,
        O_prime=O_last - n_retry * params.short_step,
        lost=0,
        recovery=attempt,
        retry_origin=O_last,
        last_loss=O_last if attempt == 1 else memory.last_loss,
    )
    return StepResult(
        RigidTransform(R_retry, O_last), retry_memory, None, False, info={"recovery": attempt}
    )


def _LostHereBefore(O_last: np.ndarray, memory: FollowerMemory, params: FollowerConfig) -> bool:
    """Whether the hose is lost again within two long steps of where it was lost last time:
    a retry there only glimpses the hose's end, and cycling around the end (each cycle
    sweeping the tool past it) is how the first version ended its runs."""
    if memory.last_loss is None:
        return False
    return bool(np.linalg.norm(O_last - memory.last_loss) <= 2 * params.long_step)


def EstimateHose(
    grid, estimator: str, ranges: np.ndarray, valid: np.ndarray, axis_T: np.ndarray | None = None
):
    """(S_T or None, centre_only) from a reading, by the selected estimator; axis_T: the
    hose's direction in T when known (the ranging estimator models it; the grid ignores it)."""
    if estimator == "ranging":
        return grid.RangingEstimate(ranges, valid, axis_T)
    return grid.GridEstimate(ranges, valid)


# Layout of one step's record (a vector, so that Drake loggers can keep it).
RECORD_FIELDS = (
    [
        "step",
        "t",
        "O_x",
        "O_y",
        "O_z",
        "S_x",
        "S_y",
        "S_z",
        "detected",
        "long_step",
        "lost",
        "recovery",
        "recoveries",
        "ended",
        "ik_time",
    ]
    + [f"range_{i}" for i in range(1, 7)]
    + [f"valid_{i}" for i in range(1, 7)]
)


def MakeRecord(
    step: int,
    t: float,
    X_WT: RigidTransform,
    result: StepResult,
    ranges: np.ndarray,
    valid: np.ndarray,
    ik_time: float = 0.0,
) -> np.ndarray:
    """One step as a vector in RECORD_FIELDS order (S is NaN-free: O when undetected)."""
    detected = result.S_W is not None
    S = result.S_W if detected else X_WT.translation()
    memory = result.memory
    return np.concatenate(
        [
            [step, t],
            X_WT.translation(),
            S,
            [
                float(detected),
                float(result.long_step),
                memory.lost,
                memory.recovery,
                memory.recoveries,
                float(result.ended),
                ik_time,
            ],
            ranges,
            np.asarray(valid, float),
        ]
    )
