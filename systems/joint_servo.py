"""JointServo: the position servo of a simulated industrial arm controller.

Real arm controllers (UR servoJ, Nachi CFD) track joint position commands with stiff,
model-based servo loops. The simulated station reproduces that with computed-torque control:

    tau = M_aa(q) (kp (q_d - q) + kd (v_d - v)) + c_a(q, v) - tau_g,a(q)

where the subscript a selects the arm's velocities in the full plant, so the other models
of the scene (other arms, switches, free bodies) keep their own dynamics.
"""

from __future__ import annotations

import numpy as np
from pydrake.multibody.plant import MultibodyPlant
from pydrake.multibody.tree import ModelInstanceIndex
from pydrake.systems.framework import BasicVector, Context, LeafSystem

from guidedarm.systems.errors import ConfigurationError


class ComputedTorqueLaw:
    """The servo law above for one model instance of `plant` (units: rad, rad/s, N m)."""

    def __init__(
        self, plant: MultibodyPlant, instance: ModelInstanceIndex, kp: float, kd: float
    ) -> None:
        if not (0 < kp < np.inf and 0 < kd < np.inf):
            raise ConfigurationError(f"servo gains must be positive, got kp={kp}, kd={kd}")
        self.plant = plant
        self.kp = kp
        self.kd = kd
        actuators = [plant.get_joint_actuator(i) for i in plant.GetJointActuatorIndices(instance)]
        self.velocity_indices = np.array([a.joint().velocity_start() for a in actuators])
        self.position_indices = np.array([a.joint().position_start() for a in actuators])
        self._context = plant.CreateDefaultContext()
        self._nq = plant.num_positions()
        self._arm_block = np.ix_(self.velocity_indices, self.velocity_indices)

    @property
    def num_joints(self) -> int:
        return len(self.velocity_indices)

    def torque(
        self, plant_state: np.ndarray, q_desired: np.ndarray, v_desired: np.ndarray
    ) -> np.ndarray:
        """Actuation of the arm's joints, in the instance's actuator order (N m)."""
        plant = self.plant
        plant.SetPositionsAndVelocities(self._context, plant_state)
        nq = self._nq
        q = plant_state[:nq][self.position_indices]
        v = plant_state[nq:][self.velocity_indices]
        a = self.velocity_indices
        M = plant.CalcMassMatrix(self._context)[self._arm_block]
        bias = plant.CalcBiasTerm(self._context)[a]
        gravity = plant.CalcGravityGeneralizedForces(self._context)[a]
        acceleration = self.kp * (q_desired - q) + self.kd * (v_desired - v)
        return M @ acceleration + bias - gravity


class JointServo(LeafSystem):
    """Computed-torque position servo for one arm of a MultibodyPlant.

    Input ports: `plant_state` (full plant [q; v]), `desired_state` ([q_d; v_d] of the arm,
    rad and rad/s). Output port: `actuation` (N m, the arm's actuator order).
    """

    def __init__(self, law: ComputedTorqueLaw) -> None:
        super().__init__()
        self._law = law
        n = law.num_joints
        plant = law.plant
        self.DeclareVectorInputPort("plant_state", plant.num_multibody_states())
        self.DeclareVectorInputPort("desired_state", 2 * n)
        self.DeclareVectorOutputPort("actuation", n, self.CalcActuation)

    def CalcActuation(self, context: Context, output: BasicVector) -> None:
        n = self._law.num_joints
        desired = self.get_input_port(1).Eval(context)
        state = self.get_input_port(0).Eval(context)
        output.SetFromVector(self._law.torque(state, desired[:n], desired[n:]))
