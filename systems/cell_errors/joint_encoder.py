"""JointEncoder: the joint state an arm's controller measures, from the true plant state."""

from __future__ import annotations

import numpy as np
from pydrake.multibody.plant import MultibodyPlant
from pydrake.systems.framework import BasicVector, Context, LeafSystem

from guidedarm.systems.cell_errors.joint_encoder_math import EncoderPositions
from guidedarm.systems.config_checks import CheckInstance


class JointEncoder(LeafSystem):
    """Input `true_state` [q; v] of an arm (n + n: rad, rad/s), output `measured_state`
    [q_measured; v] (EncoderPositions; velocities pass unchanged).

    With `stiffness` (N m/rad per joint) the transmission deflects under the static
    holding torque: the gravity torque of the arm's `controller_plant` (what it carries)
    at the true link angles, which the joint must hold, so the link sags while the motor
    side, which the encoder reads, is where the servo put it. Contact forces are not part
    of the holding torque.
    """

    def __init__(
        self,
        joint_offset: np.ndarray,
        resolution: float,
        stiffness: np.ndarray | None = None,
        controller_plant: MultibodyPlant | None = None,
    ) -> None:
        super().__init__()
        self._offset = np.asarray(joint_offset, float)
        n = self._offset.size
        self._resolution = float(resolution)
        self._stiffness = None if stiffness is None else np.asarray(stiffness, float)
        self._plant = controller_plant
        if self._stiffness is not None:
            CheckInstance("controller_plant", controller_plant, MultibodyPlant)
            self._plant_context = controller_plant.CreateDefaultContext()
        self.DeclareVectorInputPort("true_state", 2 * n)
        self.DeclareVectorOutputPort("measured_state", 2 * n, self._Calc)

    def _Calc(self, context: Context, output: BasicVector) -> None:
        x = self.get_input_port().Eval(context)
        n = self._offset.size
        q, v = x[:n], x[n:]
        holding = None
        if self._stiffness is not None:
            self._plant.SetPositions(self._plant_context, q)
            holding = -self._plant.CalcGravityGeneralizedForces(self._plant_context)
        measured = EncoderPositions(q, self._offset, self._resolution, holding, self._stiffness)
        output.SetFromVector(np.concatenate([measured, v]))
