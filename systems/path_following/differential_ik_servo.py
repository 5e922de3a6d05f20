"""DifferentialIkServo: streams joint positions that bring a frame to a moving target pose,
within joint position, velocity and acceleration limits (differential_ik_servo_math: damped
least-squares resolved-rate control, each period, at the servo's own commanded q and v),
and inside the cell's workspace walls: when the arm, braking from the next period's
velocity at the acceleration limits, would carry the origin of one of the bodies the arm
moves past a wall (WorkspaceConfig, the constraint ToolPoseIk gives the IK of stop-and-go),
the servo brakes to a stop there and reports why on `failure`.
"""

from __future__ import annotations

import numpy as np
from pydrake.common.value import AbstractValue
from pydrake.math import RigidTransform
from pydrake.multibody.plant import MultibodyPlant
from pydrake.multibody.tree import Frame, JacobianWrtVariable
from pydrake.systems.framework import Context, DiscreteValues, LeafSystem

from guidedarm.systems.config_checks import (
    NON_NEGATIVE,
    POSITIVE,
    Bound,
    CheckArgument,
    CheckInstance,
    CheckVector,
    FieldError,
)
from guidedarm.systems.path_following.differential_ik_servo_math import (
    MIN_DAMPING,
    BrakeStep,
    JointLimits,
    ReachBound,
    Rows,
    ServoPeriod,
)
from guidedarm.systems.path_following.workspace import WorkspaceConfig
from guidedarm.systems.plant_frames import CheckFrame, CheckPlant

_ORIGIN = np.zeros(3)  # the controlled frame's origin, in that frame


class DifferentialIkServo(LeafSystem):
    """Input `X_WT_desired` (RigidTransform of `frame` in world W). Outputs
    `position_commanded` (n, rad) and `velocity_commanded` (n, rad/s), the state; `status`
    ([1 when a limit bound the latest period's velocity, else 0]); `failure` (str: which
    body reached which wall, '' while none has).

    plant: a controller plant whose positions are exactly the arm's n joints; frame: the
    controlled frame on it; q_initial: the start joints (rad); period (s); max_speed
    (rad/s) and max_acceleration (rad/s^2) per joint; the plant's position limits apply;
    gain: of the pose error (1/s); weights (6 >= 0, not all 0: roll about x_T, pitch, yaw,
    x, y, z) and damping (in [MIN_DAMPING, 1]): of the least squares
    (differential_ik_servo_math.ServoStep); workspace and X_WB: the walls (m, the arm's base
    frame B) and B's pose in W, None: no walls; feedforward: the share (0 to 1) of the
    target's velocity (its change over the last period) fed forward beside the feedback, 0:
    none. Bad arguments raise ConfigurationError naming them.
    """

    def __init__(
        self,
        plant: MultibodyPlant,
        frame: Frame,
        q_initial: np.ndarray,
        period: float,
        max_speed: float,
        max_acceleration: float,
        gain: float,
        weights: np.ndarray,
        damping: float,
        workspace: WorkspaceConfig | None = None,
        X_WB: RigidTransform | None = None,
        feedforward: float = 0.0,
    ) -> None:
        super().__init__()
        CheckPlant("plant", plant)
        CheckFrame("frame", frame, plant)
        n = plant.num_positions()
        q_initial = CheckVector("q_initial", q_initial, n)
        for name, value in (
            ("period", period),
            ("max_speed", max_speed),
            ("max_acceleration", max_acceleration),
            ("gain", gain),
        ):
            CheckArgument(name, value, POSITIVE)
        weights = CheckVector("weights", weights, 6, NON_NEGATIVE)
        if not weights.any():
            raise FieldError("weights", f"at least one must be > 0, got {weights}")
        CheckArgument("damping", damping, Bound(MIN_DAMPING, 1.0))
        CheckArgument("feedforward", feedforward, Bound(0.0, 1.0))
        CheckInstance("workspace", workspace, (WorkspaceConfig, type(None)))
        if workspace is not None:
            workspace.Validate()
        CheckInstance("X_WB", X_WB, (RigidTransform, type(None)))
        self._plant, self._frame, self._n = plant, frame, n
        self._plant_context = plant.CreateDefaultContext()
        self._period, self._gain = period, gain
        self._weights, self._damping = np.ascontiguousarray(weights, float), damping
        self._feedforward = feedforward / period
        self._limits = JointLimits(
            plant.GetPositionLowerLimits(),
            plant.GetPositionUpperLimits(),
            np.full(n, max_speed),
            np.full(n, max_acceleration),
        )
        self._workspace, self._X_BW = workspace, (X_WB or RigidTransform()).inverse()
        moved = plant.GetBodiesKinematicallyAffectedBy(
            [plant.get_joint(j).index() for j in plant.GetJointIndices()]
        )
        self._bodies = [plant.get_body(b) for b in moved]
        self._body_indices = [int(b) for b in moved]
        # A memo of the wall check, a pure function of q: (q_checked, margin) where every
        # origin was at least `margin` (m) inside the walls, so no q with
        # reach * sum |q - q_checked| < margin needs the kinematics.
        self._reach = ReachBound(plant, self._bodies)
        self._clear = ([0.0] * n, 0.0)
        self._R_BW = self._X_BW.rotation().matrix()
        self._p_BW = self._X_BW.translation()
        self._world = plant.world_frame()
        self._target = self.DeclareAbstractInputPort(
            "X_WT_desired", AbstractValue.Make(RigidTransform())
        )
        # q, v, [status], and the memory: [1 + the index in _bodies of the body at a wall
        # (0: none); the previous period's target for the feedforward (X_WD as a 3 x 4
        # matrix, row-major; all NaN before the first)], one group: one read and one
        # write a period.
        self._q = self.DeclareDiscreteState(q_initial)
        self._v = self.DeclareDiscreteState(n)
        self._status = self.DeclareDiscreteState(1)
        self._memory = self.DeclareDiscreteState(np.r_[0.0, np.full(12, np.nan)])
        self.DeclarePeriodicDiscreteUpdateEvent(period, 0.0, self._Update)
        # Outputs copied from the state by Drake, without a Python call.
        self.DeclareStateOutputPort("position_commanded", self._q)
        self.DeclareStateOutputPort("velocity_commanded", self._v)
        self.DeclareStateOutputPort("status", self._status)
        self.DeclareAbstractOutputPort(
            "failure",
            lambda: AbstractValue.Make(""),
            self._CalcFailure,
            prerequisites_of_calc={self.xd_ticket()},
        )

    def _Update(self, context: Context, discrete: DiscreteValues) -> None:
        q = context.get_discrete_state(self._q).get_value()
        v = context.get_discrete_state(self._v).get_value()
        memory = context.get_discrete_state(self._memory).get_value()
        if memory[0] > 0:  # at a wall: brake to a stop, stay
            q_next, v_next = BrakeStep(q, v, self._period, self._limits)
            discrete.set_value(self._q, q_next)
            discrete.set_value(self._v, v_next)
            return
        plant, plant_context = self._plant, self._plant_context
        plant.SetPositions(plant_context, q)
        X_WT = self._frame.CalcPoseInWorld(plant_context)
        J = plant.CalcJacobianSpatialVelocity(
            plant_context, JacobianWrtVariable.kV, self._frame, _ORIGIN, self._world, self._world
        )
        M_WD = Rows(self._target.Eval(context))
        # The kernel writes the next q and v into the update's state.
        q_next = discrete.get_mutable_vector(self._q).get_mutable_value()
        v_next = discrete.get_mutable_vector(self._v).get_mutable_value()
        limited, stop = ServoPeriod(
            J,
            Rows(X_WT),
            M_WD,
            memory[1:],
            self._feedforward,
            q,
            v,
            self._period,
            self._limits,
            self._weights,
            self._damping,
            self._gain,
            q_next,
            v_next,
        )
        wall = self._BodyAtWall(stop)
        if wall:
            q_next[:], v_next[:] = BrakeStep(q, v, self._period, self._limits)
        discrete.set_value(self._status, [float(limited)])
        memory_next = discrete.get_mutable_vector(self._memory).get_mutable_value()
        memory_next[0] = wall
        if self._feedforward:
            memory_next[1:] = M_WD.ravel()

    def _BodyAtWall(self, q: list[float]) -> int:
        """1 + the index of the first body whose origin at q (rad) lies outside the walls,
        or 0."""
        if self._workspace is None:
            return 0
        q_checked, margin = self._clear
        if self._reach * sum([abs(a - b) for a, b in zip(q, q_checked, strict=True)]) < margin:
            return 0
        self._plant.SetPositions(self._plant_context, q)
        # All body poses in one evaluation of the plant's port, then the origins in B.
        poses = self._plant.get_body_poses_output_port().Eval(self._plant_context)
        p_WBo = np.array([poses[i].translation() for i in self._body_indices])
        p_BBo = p_WBo @ self._R_BW.T + self._p_BW
        k = self._workspace.FirstOutside(p_BBo)
        if k is not None:
            return k + 1
        self._clear = (q, self._workspace.Margin(p_BBo))
        return 0

    def _CalcFailure(self, context: Context, output: AbstractValue) -> None:
        k = int(context.get_discrete_state(self._memory)[0])
        output.set_value(
            ""
            if k == 0
            else f"{self._bodies[k - 1].name()} would leave the workspace "
            f"({self._workspace.Describe()}; m, base frame)"
        )
