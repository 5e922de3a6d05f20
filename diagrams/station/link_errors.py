"""An arm's link geometry errors and a compliant base in an unfinalized plant: each
revolute joint re-attached to its parent link at its true pose, the base's weld replaced
by a sprung tilt (the simulated station's plant only)."""

from __future__ import annotations

import numpy as np
from pydrake.math import RigidTransform
from pydrake.multibody.plant import MultibodyPlant
from pydrake.multibody.tree import (
    FixedOffsetFrame,
    Frame,
    JointActuatorIndex,
    RevoluteJoint,
    RevoluteSpring,
    SpatialInertia,
)

from guidedarm.systems.errors import ConfigurationError


def MoveJointFrames(plant: MultibodyPlant, arm: str, X_errors: list[RigidTransform]) -> None:
    """Re-creates the revolute joints of model instance `arm` of the unfinalized `plant`
    (in their order, with their limits, damping, default angle and actuator), each on a
    frame at X_PF @ X_errors[i] on its parent link instead of X_PF (the true lengths and
    twists of the links). The joints keep their names and order, so the arm's positions
    and actuators keep theirs."""
    instance = plant.GetModelInstanceByName(arm)
    joints = [
        plant.get_joint(j)
        for j in plant.GetJointIndices(instance)
        if isinstance(plant.get_joint(j), RevoluteJoint)
    ]
    if len(X_errors) != len(joints):
        raise ConfigurationError(
            f"errors.arms.{arm}.link_errors has {len(X_errors)} poses, the arm has "
            f"{len(joints)} revolute joints"
        )
    actuators = {}
    for i in range(plant.num_actuators()):
        actuator = plant.get_joint_actuator(JointActuatorIndex(i))
        if actuator.model_instance() == instance:
            actuators[actuator.joint().name()] = actuator
    specs = [_JointSpec(j, actuators.get(j.name())) for j in joints]
    for joint in joints:
        if joint.name() in actuators:
            plant.RemoveJointActuator(actuators[joint.name()])
        plant.RemoveJoint(joint)
    for spec, X_error in zip(specs, X_errors, strict=True):
        _AddJoint(plant, spec, X_error)


def _JointSpec(joint: RevoluteJoint, actuator) -> dict:
    spec = {
        "name": joint.name(),
        "parent": joint.frame_on_parent(),
        "child": joint.frame_on_child(),
        "axis": joint.revolute_axis(),
        "limits": (joint.position_lower_limits()[0], joint.position_upper_limits()[0]),
        "velocity": (joint.velocity_lower_limits(), joint.velocity_upper_limits()),
        "acceleration": (joint.acceleration_lower_limits(), joint.acceleration_upper_limits()),
        "damping": float(np.ravel(joint.default_damping())[0]),
        "angle": joint.get_default_angle(),
        "actuator": None,
    }
    if actuator is not None:
        spec["actuator"] = (
            actuator.name(),
            actuator.effort_limit(),
            actuator.default_gear_ratio(),
            actuator.default_rotor_inertia(),
        )
    return spec


def _AddJoint(plant: MultibodyPlant, spec: dict, X_error: RigidTransform) -> None:
    parent = spec["parent"]
    X_BF = parent.GetFixedPoseInBodyFrame() @ X_error
    frame = plant.AddFrame(
        FixedOffsetFrame(f"{parent.name()}_true", parent.body().body_frame(), X_BF)
    )
    lower, upper = spec["limits"]
    joint = plant.AddJoint(
        RevoluteJoint(
            spec["name"], frame, spec["child"], spec["axis"], lower, upper, spec["damping"]
        )
    )
    joint.set_velocity_limits(*spec["velocity"])
    joint.set_acceleration_limits(*spec["acceleration"])
    joint.set_default_angle(spec["angle"])
    if spec["actuator"] is not None:
        name, effort, gear, rotor = spec["actuator"]
        actuator = plant.AddJointActuator(name, joint, effort)
        actuator.set_default_gear_ratio(gear)
        actuator.set_default_rotor_inertia(rotor)


# The small body between the two tilt joints of a compliant base (kg, m): it carries no
# load of its own, only enough inertia for the plant's mass matrix.
_TILT_BODY_MASS = 0.01
_TILT_BODY_RADIUS = 0.01


def AddCompliantBase(
    plant: MultibodyPlant,
    arm: str,
    parent: Frame,
    X_PC: RigidTransform,
    child: Frame,
    stiffness: list[float],
    damping: list[float],
) -> None:
    """Joins `child` (the arm's base frame) to `parent` at X_PC through a tilt about the
    weld frame's x axis and then its y axis, each a revolute joint with Drake's
    RevoluteSpring (`stiffness`, N m/rad) and joint damping (N m s/rad), in their own
    model instance `<arm>_base_compliance` (the arm keeps its joints): the base tilts as
    the arm's weight moves over it. Unfinalized `plant`."""
    instance = plant.AddModelInstance(f"{arm}_base_compliance")
    inertia = SpatialInertia.SolidSphereWithMass(_TILT_BODY_MASS, _TILT_BODY_RADIUS)
    # Each joint belongs to its child body's model instance: both tilts end on bodies of
    # the compliance instance, and a weld (no position) joins the arm's base to the last.
    bodies = [plant.AddRigidBody(f"{arm}_base_tilt_{axis}", instance, inertia) for axis in "xy"]
    weld = plant.AddFrame(FixedOffsetFrame(f"{arm}_base_weld", parent, X_PC, instance))
    frame_P = weld
    for axis, body, k, c in zip("xy", bodies, stiffness, damping, strict=True):
        joint = plant.AddJoint(
            RevoluteJoint(f"{arm}_base_tilt_{axis}", frame_P, body.body_frame(), _Axis(axis), c)
        )
        plant.AddForceElement(RevoluteSpring(joint, 0.0, k))
        frame_P = body.body_frame()
    plant.WeldFrames(frame_P, child)


def _Axis(name: str) -> np.ndarray:
    return np.eye(3)["xyz".index(name)]
