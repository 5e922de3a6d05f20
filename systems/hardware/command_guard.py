"""Joint limits of an arm (from its MultibodyPlant), the check every streamed command
passes before it reaches the robot, and the check every joint measurement passes before it
is acted on.

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

# A measurement beyond the model's limits by more than these is not the arm's: a real arm
# stops within its position limits (encoders may read slightly past a limit it rests on)
# and never moves faster than its velocity limit (a controller's or the link's velocity
# estimate may overshoot it a little).
MEASURED_POSITION_TOLERANCE = 0.02  # rad
MEASURED_VELOCITY_FACTOR = 1.5


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


def ImplausibleMeasurement(limits: JointLimits, q: np.ndarray, v: np.ndarray) -> str | None:
    """Why joint positions q (rad) and velocities v (rad/s) measured by an arm's controller
    cannot be the arm's (a corrupted or misrouted reply, a jump, a controller clock that
    does not advance with the arm), or None: not one finite value per joint, a position
    beyond the model's range by more than MEASURED_POSITION_TOLERANCE, or a speed beyond
    MEASURED_VELOCITY_FACTOR times the joint's velocity limit."""
    n = limits.lower.size
    if q.shape != (n,) or v.shape != (n,):
        return f"measurement has {q.size} joint positions and {v.size} velocities, the arm {n}"
    if not (np.all(np.isfinite(q)) and np.all(np.isfinite(v))):
        return "measurement not finite"
    tolerance = MEASURED_POSITION_TOLERANCE
    outside = (q < limits.lower - tolerance) | (q > limits.upper + tolerance)
    if np.any(outside):
        i = int(np.argmax(outside))
        return (
            f"measured joint {limits.names[i]} at {q[i]:.4g} rad, outside its range "
            f"[{limits.lower[i]:.4g}, {limits.upper[i]:.4g}] rad"
        )
    too_fast = np.abs(v) > MEASURED_VELOCITY_FACTOR * limits.velocity
    if np.any(too_fast):
        i = int(np.argmax(too_fast))
        return (
            f"measured joint {limits.names[i]} moving at {v[i]:.4g} rad/s, beyond "
            f"{MEASURED_VELOCITY_FACTOR:g} x its limit {limits.velocity[i]:.4g} rad/s"
        )
    return None
