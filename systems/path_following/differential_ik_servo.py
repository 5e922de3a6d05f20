"""DifferentialIkServo: streams joint positions that bring a frame to a moving target pose,
within joint position, velocity and acceleration limits.

Every period it solves Drake's differential IK (DoDifferentialInverseKinematics: the
joint velocity v_next whose frame velocity J v_next points at the pose error / period,
scaled down as far as the limits require) at its own commanded state (q, v) and integrates
q += v_next period. Drake's DifferentialInverseKinematicsIntegrator keeps only q and
linearises at v = 0, so its acceleration limits bound the speed itself to
acceleration x period; here the state carries v, and the acceleration limits bound the
change of v. When the program has no solution (the limits cannot turn v toward the error
in one period), v decelerates toward 0 at the acceleration limit.
"""

from __future__ import annotations

import numpy as np
from pydrake.common.value import AbstractValue
from pydrake.math import RigidTransform
from pydrake.multibody.inverse_kinematics import (
    DifferentialInverseKinematicsParameters,
    DifferentialInverseKinematicsStatus,
    DoDifferentialInverseKinematics,
)
from pydrake.multibody.plant import MultibodyPlant
from pydrake.multibody.tree import Frame
from pydrake.systems.framework import BasicVector, Context, DiscreteValues, LeafSystem


class DifferentialIkServo(LeafSystem):
    """Input `X_WT_desired` (RigidTransform of `frame` in world W). Outputs
    `position_commanded` (n, rad) and `velocity_commanded` (n, rad/s), the state; `status`
    ([0 solved, 1 stuck, 2 no solution] of the latest period).

    plant: a controller plant whose positions are exactly the arm's n joints; frame: the
    controlled frame on it; q_initial: the start joints (rad); period (s); max_speed
    (rad/s) and max_acceleration (rad/s^2) per joint; the plant's position limits apply.
    """

    def __init__(
        self,
        plant: MultibodyPlant,
        frame: Frame,
        q_initial: np.ndarray,
        period: float,
        max_speed: float,
        max_acceleration: float,
    ) -> None:
        super().__init__()
        n = plant.num_positions()
        self._plant, self._frame, self._n = plant, frame, n
        self._plant_context = plant.CreateDefaultContext()
        self._period, self._max_acceleration = period, max_acceleration
        params = DifferentialInverseKinematicsParameters(n, plant.num_velocities())
        params.set_time_step(period)
        params.set_joint_position_limits(
            (plant.GetPositionLowerLimits(), plant.GetPositionUpperLimits())
        )
        params.set_joint_velocity_limits((-np.full(n, max_speed), np.full(n, max_speed)))
        params.set_joint_acceleration_limits(
            (-np.full(n, max_acceleration), np.full(n, max_acceleration))
        )
        self._params = params
        self._target = self.DeclareAbstractInputPort(
            "X_WT_desired", AbstractValue.Make(RigidTransform())
        )
        initial = np.concatenate([np.asarray(q_initial, float), np.zeros(n), [0.0]])
        self._state = self.DeclareDiscreteState(initial)
        self.DeclarePeriodicDiscreteUpdateEvent(period, 0.0, self._Update)
        self.DeclareVectorOutputPort("position_commanded", n, lambda c, o: self._Output(c, o, 0, n))
        self.DeclareVectorOutputPort(
            "velocity_commanded", n, lambda c, o: self._Output(c, o, n, 2 * n)
        )
        self.DeclareVectorOutputPort("status", 1, lambda c, o: self._Output(c, o, 2 * n, 2 * n + 1))

    def _Update(self, context: Context, discrete: DiscreteValues) -> None:
        n = self._n
        x = context.get_discrete_state(self._state).get_value()
        q, v = x[:n], x[n : 2 * n]
        self._plant.SetPositions(self._plant_context, q)
        self._plant.SetVelocities(self._plant_context, v)
        result = DoDifferentialInverseKinematics(
            self._plant,
            self._plant_context,
            self._target.Eval(context),
            self._frame,
            self._params,
        )
        status = result.status
        if status == DifferentialInverseKinematicsStatus.kNoSolutionFound:
            slow = self._max_acceleration * self._period
            v_next = v - np.clip(v, -slow, slow)
            code = 2.0
        else:
            v_next = np.asarray(result.joint_velocities, float)
            code = 0.0 if status == DifferentialInverseKinematicsStatus.kSolutionFound else 1.0
        q_next = q + v_next * self._period
        discrete.set_value(self._state, np.concatenate([q_next, v_next, [code]]))

    def _Output(self, context: Context, output: BasicVector, start: int, end: int) -> None:
        output.SetFromVector(context.get_discrete_state(self._state).get_value()[start:end])
