"""Joint limits of an arm (from its MultibodyPlant) and the check every streamed command
passes before it reaches the robot.

A command q_k sent dt_k seconds after q_{k-1} implies the velocity v_k = (q_k - q_{k-1}) / dt_k
(at the middle of that interval) and the acceleration a_k = (v_k - v_{k-1}) / ((dt_k +
dt_{k-1}) / 2); a command outside the position range or implying a velocity or acceleration
beyond the limits is refused, never clipped.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from pydrake.multibody.plant import MultibodyPlant
from pydrake.multibody.tree import ModelInstanceIndex

from guidedarm.systems.errors import ConfigurationError, GuidedArmError


class CommandRefusedError(GuidedArmError):
    """A joint command would leave the arm's position, velocity or acceleration limits."""


@dataclass(frozen=True)
class JointLimits:
    """Per-joint limits: positions (rad), |velocity| (rad/s), |acceleration| (rad/s^2)."""

    names: list[str]
    lower: np.ndarray
    upper: np.ndarray
    velocity: np.ndarray
    acceleration: np.ndarray

    @staticmethod
    def FromPlant(
        plant: MultibodyPlant,
        instance: ModelInstanceIndex,
        acceleration_fallback: list[float] | None = None,
    ) -> JointLimits:
        """The limits of the instance's joints in state order. URDF cannot carry
        acceleration limits unless `drake:acceleration` is given; where the model has none,
        `acceleration_fallback` (from the scenario) supplies them."""
        joints = [plant.get_joint(i) for i in plant.GetJointIndices(instance)]
        joints = sorted((j for j in joints if j.num_velocities() == 1), key=_start)
        limits = JointLimits(
            names=[j.name() for j in joints],
            lower=np.array([j.position_lower_limits()[0] for j in joints]),
            upper=np.array([j.position_upper_limits()[0] for j in joints]),
            velocity=np.array([j.velocity_upper_limits()[0] for j in joints]),
            acceleration=np.array([j.acceleration_upper_limits()[0] for j in joints]),
        )
        if acceleration_fallback:
            if len(acceleration_fallback) != len(joints):
                raise ConfigurationError(
                    f"acceleration_limits has {len(acceleration_fallback)} values, "
                    f"the model has {len(joints)} joints"
                )
            missing = ~np.isfinite(limits.acceleration)
            limits.acceleration[missing] = np.asarray(acceleration_fallback, float)[missing]
        for kind in ("velocity", "acceleration"):
            values = getattr(limits, kind)
            if not np.all(np.isfinite(values) & (values > 0)):
                raise ConfigurationError(
                    f"model instance {plant.GetModelInstanceName(instance)} has no finite "
                    f"{kind} limit for some joints; give them in the model or the scenario"
                )
        return limits


def _start(joint) -> int:
    return joint.velocity_start()


def CheckCommand(
    limits: JointLimits,
    q_command: np.ndarray,
    q_previous: np.ndarray,
    v_previous: np.ndarray,
    dt: float,
    dt_previous: float | None = None,
) -> np.ndarray:
    """Returns the implied velocity (rad/s) of `q_command` sent `dt` s after `q_previous`
    (itself sent `dt_previous` s after its predecessor; default dt), or raises
    CommandRefusedError naming the first joint and limit it would violate."""
    if q_command.shape != limits.lower.shape or not np.all(np.isfinite(q_command)):
        raise CommandRefusedError(f"command refused: not {limits.lower.size} finite joints")
    v = (q_command - q_previous) / dt
    a = (v - v_previous) / (0.5 * (dt + (dt if dt_previous is None else dt_previous)))
    checks = (
        ("position", q_command < limits.lower, "below", limits.lower, q_command),
        ("position", q_command > limits.upper, "above", limits.upper, q_command),
        ("velocity", np.abs(v) > limits.velocity, "|v| >", limits.velocity, v),
        ("acceleration", np.abs(a) > limits.acceleration, "|a| >", limits.acceleration, a),
    )
    for kind, violated, relation, limit, value in checks:
        if np.any(violated):
            i = int(np.argmax(violated))
            raise CommandRefusedError(
                f"command refused before sending: joint {limits.names[i]} {kind} "
                f"{value[i]:.4g} {relation} limit {limit[i]:.4g}"
            )
    return v
