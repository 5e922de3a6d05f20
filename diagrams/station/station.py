"""MakeStation: the arms, tools, sensors and scene of a scenario, behind fixed port names.

The simulated branch builds a MultibodyPlant and SceneGraph from the scenario's model
directives, adds a position servo per arm and a camera per CameraConfig (rendered by a
headless VTK renderer, added only when there is a camera). The servo is the stiff
model-based loop of an industrial arm controller, computed-torque control on the arm's
velocities a:

    tau = M_aa(q) (kp (q_d - q) + kd (v_d - v)) + c_a(q, v) - tau_g,a(q)

Drake's InverseDynamics evaluates it (in C++, at every plant step) on the arm's
controller plant: MakeMultibodyPlant of the arm and what its joints carry (gripper,
tools), which has the arm's M_aa, c_a and tau_g,a of the station's plant as long as the
arm's base does not move; the other models of the scene keep their own dynamics.

The hardware branch (diagrams/station/hardware_station.py) exports the same ports
from drivers, the kinematic one (diagrams/station/kinematic_station.py) from the plant posed
at the command. Sim-only ground truth is exported under the `sim.` prefix and is not part of
the sim/hardware contract.
"""

from __future__ import annotations

import copy

import numpy as np
from pydrake.geometry import MakeRenderEngineVtk, Meshcat, RenderEngineVtkParams, SceneGraph
from pydrake.math import RigidTransform
from pydrake.multibody.plant import AddMultibodyPlant, MultibodyPlant
from pydrake.systems.controllers import InverseDynamics
from pydrake.systems.framework import Diagram, DiagramBuilder
from pydrake.systems.primitives import (
    Demultiplexer,
    MatrixGain,
    Multiplexer,
    SharedPointerSystem,
    StateInterpolatorWithDiscreteDerivative,
)
from pydrake.systems.sensors import CameraConfig, RgbdSensor

from guidedarm.diagrams.station.hardware_station import MakeHardwareStation
from guidedarm.diagrams.station.kinematic_station import MakeKinematicStation
from guidedarm.diagrams.station.scenario import (
    RENDERER_NAME,
    ArmConfig,
    StationKind,
    StationScenario,
)
from guidedarm.diagrams.station.station_errors import ArmErrors
from guidedarm.diagrams.station.station_plant import (
    AddStationModels,
    ArmAndAttachments,
    ArmCalibrationOffset,
    GetArmInstance,
    MakeMultibodyPlant,
    SetInitialPositions,
)
from guidedarm.diagrams.station.station_wiring import (
    AddMeshcatVisualization,
    AddOffset,
    AddToFTools,
)
from guidedarm.systems.cell_errors.camera_errors import CameraErrors, MakeTrueCamera
from guidedarm.systems.cell_errors.joint_encoder import JointEncoder
from guidedarm.systems.cell_errors.lens_distortion import LensDistortion
from guidedarm.systems.config_checks import (
    CheckConfig,
    CheckInstance,
    ChoiceViolation,
    FieldError,
)
from guidedarm.systems.errors import ConfigurationError
from guidedarm.systems.plant_frames import GetScopedFrame


def MakeStation(
    scenario: StationScenario,
    meshcat: Meshcat | None = None,
    kind: StationKind = "simulation",
) -> Diagram:
    """Builds the station Diagram of `scenario`, one of three kinds behind the same ports:
    `simulation` (the default), `hardware` (the real cell's drivers, MakeHardwareStation)
    or `kinematic` (the arm posed where it is commanded, without dynamics,
    MakeKinematicStation: one arm, no camera, no `sim.` ports but `sim.query_object`)."""
    CheckInstance("scenario", scenario, StationScenario)
    CheckConfig(scenario, "scenario")
    CheckInstance("meshcat", meshcat, (Meshcat, type(None)))
    why = ChoiceViolation(kind, StationKind)
    if why is not None:
        raise FieldError("kind", why)
    if kind == "hardware":
        return MakeHardwareStation(scenario, meshcat)
    if kind == "kinematic":
        return MakeKinematicStation(scenario, meshcat)
    scenario.CheckSimulated()
    errors = scenario.WithErrorsDrawn(None).errors
    builder = DiagramBuilder()
    plant, scene_graph = AddMultibodyPlant(scenario.plant_config, builder)
    AddStationModels(scenario, plant, model_errors=errors.models, arm_errors=errors.arms)
    if scenario.cameras:
        # Only cameras render; a renderer poses every perception geometry at every plant
        # step (SceneGraph's pose update), most of the step's cost without a camera.
        scene_graph.AddRenderer(RENDERER_NAME, MakeRenderEngineVtk(RenderEngineVtkParams()))
    plant.Finalize()
    SetInitialPositions(scenario, plant)
    for name, arm in scenario.arms.items():
        _AddArm(builder, plant, scenario, name, arm, errors.arms.get(name))
    for name, camera in scenario.cameras.items():
        _AddCamera(builder, plant, scene_graph, name, camera, errors.cameras.get(name))
    AddToFTools(builder, scenario, plant, scene_graph, errors.tof_tools)
    AddMeshcatVisualization(builder, scenario, meshcat, plant, scene_graph)
    builder.ExportOutput(scene_graph.get_query_output_port(), "sim.query_object")
    builder.ExportOutput(plant.get_body_poses_output_port(), "sim.body_poses")
    builder.ExportOutput(plant.get_state_output_port(), "sim.plant_state")
    builder.ExportOutput(plant.get_contact_results_output_port(), "sim.contact_results")
    diagram = builder.Build()
    diagram.set_name("station")
    return diagram


def _AddArm(
    builder: DiagramBuilder,
    plant: MultibodyPlant,
    scenario: StationScenario,
    name: str,
    arm: ArmConfig,
    errors: ArmErrors | None,
) -> None:
    instance = GetArmInstance(plant, name)
    n = plant.num_actuated_dofs(instance)
    if n == 0 or n != plant.num_velocities(instance):
        raise ConfigurationError(
            f"arms.{name}: every joint must have an actuator ({n} actuators, "
            f"{plant.num_velocities(instance)} joints)"
        )
    kd = arm.kd if arm.kd > 0 else 2.0 * np.sqrt(arm.kp)
    controller_plant = MakeMultibodyPlant(scenario, ArmAndAttachments(plant, name))
    if controller_plant.num_velocities() != n:
        raise ConfigurationError(
            f"arms.{name}: the models the arm carries must be welded to it (its controller "
            f"plant has {controller_plant.num_velocities()} joints, the arm {n})"
        )
    # The law's acceleration a_d = kp (q_d - q) + kd (v_d - v) from [x_d; x], then Drake's
    # InverseDynamics tau = M a_d + c - tau_g. (InverseDynamicsController is the same law,
    # but its PidController's integral state, even at ki = 0, makes the simulator
    # integrate it between every two events.)
    # What the controller measures: the true state, or what the encoders make of it.
    measured_state = plant.get_state_output_port(instance)
    if errors is not None and (
        errors.joint_offset or errors.encoder_resolution or errors.joint_stiffness
    ):
        encoder = builder.AddNamedSystem(
            f"{name}.encoder", _MakeEncoder(errors, n, controller_plant, f"errors.arms.{name}")
        )
        builder.Connect(measured_state, encoder.get_input_port())
        measured_state = encoder.get_output_port()
    # The controllers work in calibrated joint angles: the reading plus the identified
    # offsets (the servo below too, so its commands are in the same angles).
    calibration = ArmCalibrationOffset(scenario, name, n)
    if calibration is not None:
        calibrated = AddOffset(
            builder, f"{name}.joint_calibration", np.concatenate([calibration, np.zeros(n)])
        )
        builder.Connect(measured_state, calibrated.get_input_port())
        measured_state = calibrated.get_output_port()
    eye = np.eye(n)
    states = builder.AddNamedSystem(f"{name}.servo_states", Multiplexer([2 * n, 2 * n]))
    gains = np.hstack([arm.kp * eye, kd * eye, -arm.kp * eye, -kd * eye])
    pd = builder.AddNamedSystem(f"{name}.servo_pd", MatrixGain(gains))
    servo = builder.AddNamedSystem(f"{name}.servo", InverseDynamics(controller_plant))
    # InverseDynamics refers to the controller plant, which the diagram must keep alive.
    builder.AddNamedSystem(f"{name}.controller_plant", SharedPointerSystem(controller_plant))
    interpolator = builder.AddNamedSystem(
        f"{name}.command_interpolator",
        StateInterpolatorWithDiscreteDerivative(
            n, arm.control_period, suppress_initial_transient=True
        ),
    )
    builder.Connect(interpolator.get_output_port(), states.get_input_port(0))
    builder.Connect(measured_state, states.get_input_port(1))
    builder.Connect(states.get_output_port(), pd.get_input_port())
    builder.Connect(pd.get_output_port(), servo.get_input_port_desired_acceleration())
    builder.Connect(measured_state, servo.get_input_port_estimated_state())
    # Generalized forces of the controller plant's joints in the arm's actuator order.
    B = controller_plant.MakeActuationMatrix()
    actuation = servo.get_output_port_generalized_force()
    if not np.array_equal(B, np.eye(n)):
        to_actuators = builder.AddNamedSystem(f"{name}.servo_to_actuators", MatrixGain(B.T))
        builder.Connect(actuation, to_actuators.get_input_port())
        actuation = to_actuators.get_output_port()
    builder.Connect(actuation, plant.get_actuation_input_port(instance))
    builder.ExportInput(interpolator.get_input_port(), f"{name}.position_commanded")
    demux = builder.AddNamedSystem(f"{name}.state_demux", Demultiplexer([n, n]))
    builder.Connect(measured_state, demux.get_input_port())
    builder.ExportOutput(demux.get_output_port(0), f"{name}.position_measured")
    builder.ExportOutput(demux.get_output_port(1), f"{name}.velocity_estimated")
    builder.ExportOutput(measured_state, f"{name}.state_estimated")


def _MakeEncoder(
    errors: ArmErrors, n: int, controller_plant: MultibodyPlant, key: str
) -> JointEncoder:
    """The arm's JointEncoder from its drawn errors (lengths checked against n joints)."""
    for field_name in ("joint_offset", "joint_stiffness"):
        values = getattr(errors, field_name)
        if len(values) not in (0, n):
            raise ConfigurationError(
                f"{key}.{field_name} has {len(values)} values, the arm has {n} joints"
            )
    offset = np.asarray(errors.joint_offset or np.zeros(n), float)
    stiffness = np.asarray(errors.joint_stiffness, float) if errors.joint_stiffness else None
    return JointEncoder(offset, errors.encoder_resolution, stiffness, controller_plant)


def _AddCamera(
    builder: DiagramBuilder,
    plant: MultibodyPlant,
    scene_graph: SceneGraph,
    name: str,
    config: CameraConfig,
    errors: CameraErrors | None,
) -> None:
    true = MakeTrueCamera(config, errors or CameraErrors())
    config = copy.deepcopy(true.config)  # the scenario's own is left as given
    config.renderer_name = RENDERER_NAME
    color, depth = config.MakeCameras()
    base = config.X_PB.base_frame or "world"
    try:
        frame = plant.GetFrameByName(base.split("::")[-1], _InstanceOf(plant, base))
    except Exception:
        raise ConfigurationError(f"cameras.{name}.X_PB.base_frame: no frame '{base}'") from None
    # The sensor body S is placed relative to frame F; RgbdSensor wants it relative to the
    # body that carries F. The camera's own offset X_BC is already inside `color`.
    X_BodyS = frame.GetFixedPoseInBodyFrame() @ config.X_PB.GetDeterministicValue()
    if errors is not None:
        # The error is the camera frame C's true pose in its nominal one: S moves with it.
        X_SC = color.core().sensor_pose_in_camera_body()
        X_BodyS = X_BodyS @ X_SC @ true.X_mount_error @ X_SC.inverse()
    body_frame_id = plant.GetBodyFrameIdOrThrow(frame.body().index())
    sensor = builder.AddNamedSystem(
        f"{name}.rgbd_sensor", RgbdSensor(body_frame_id, X_BodyS, color, depth)
    )
    builder.Connect(scene_graph.get_query_output_port(), sensor.query_object_input_port())
    image = sensor.color_image_output_port()
    if true.remap is not None:
        lens = builder.AddNamedSystem(f"{name}.lens", LensDistortion(true.remap))
        builder.Connect(image, lens.get_input_port())
        image = lens.get_output_port()
    builder.ExportOutput(image, f"{name}.rgb_image")
    builder.ExportOutput(sensor.body_pose_in_world_output_port(), f"sim.{name}.X_WS")


def _InstanceOf(plant: MultibodyPlant, scoped_name: str):
    if "::" not in scoped_name:
        return plant.world_body().model_instance()
    return plant.GetModelInstanceByName(scoped_name.rsplit("::", 1)[0])


def TrueArmPositions(station: Diagram, root_context, arm: str) -> np.ndarray | None:
    """The true joint positions (rad) of `arm` in the simulated station's plant in its
    context within `root_context`; None for a hardware station, which has no truth."""
    if not station.HasOutputPort("sim.plant_state"):
        return None
    plant = station.GetSubsystemByName("plant")
    context = plant.GetMyContextFromRoot(root_context)
    return plant.GetPositions(context, plant.GetModelInstanceByName(arm))


def TruePose(station: Diagram, root_context, frame_A: str, frame_B: str) -> RigidTransform | None:
    """X_AB between two scoped frames of the simulated station's (true) plant in its
    context within `root_context` (the ground truth of the `sim.` ports); None for a
    hardware station, which has no truth."""
    if not station.HasOutputPort("sim.plant_state"):
        return None
    plant = station.GetSubsystemByName("plant")
    context = plant.GetMyContextFromRoot(root_context)
    A = GetScopedFrame(plant, frame_A, "frame")
    B = GetScopedFrame(plant, frame_B, "frame")
    return B.CalcPose(context, A)
