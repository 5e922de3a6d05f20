"""The `panel_operation` task's scenario (PanelOperationScenario: the start, the planner of
operation.motion "planner") and the rules between its keys, checked at load."""

from dataclasses import dataclass, field

from pydrake.math import RigidTransform

from guidedarm.diagrams.panel.panel_files import (
    LoadCameraMount,
    LoadEstimatorIntrinsics,
    LoadPanelSpec,
    ResolvePanelFile,
)
from guidedarm.diagrams.station.scenario import StationScenario
from guidedarm.systems.config_checks import ChangedKey, CheckFields, InRange, NonNegative, Positive
from guidedarm.systems.errors import ConfigurationError
from guidedarm.systems.markers.image_degradation import (
    CheckRenderedSupersampling,
    DegradationConfig,
)
from guidedarm.systems.markers.marker_pose_estimator_math import CameraIntrinsics
from guidedarm.systems.panel.panel_operation_math import PanelOperationConfig
from guidedarm.systems.planning.acceleration_planner_config import CheckModeFields
from guidedarm.systems.planning.acceleration_planner_math import PlannerConfig


@dataclass
class StartConfig:
    """The start: explicit joints, or a random camera pose in front of the panel.

    position: explicit start joints (rad); empty draws a camera pose from the scenario's
        random_seed.
    distance_m: [min, max] camera distance to the aim point (m).
    max_tilt_deg: largest angle of the camera's axis from the panel normal (deg).
    aim_offset_m: the aim point lies within this of the markers' middle (m).
    """

    position: list[float] = field(default_factory=list)
    distance_m: list[float] = Positive(factory=lambda: [0.30, 0.40])
    max_tilt_deg: float = InRange(0.0, 90.0, 30.0, high_open=True)
    aim_offset_m: float = NonNegative(0.02)

    def Validate(self) -> None:
        """Raises ConfigurationError naming the first bad value."""
        CheckFields(self)
        if len(self.distance_m) != 2 or not self.distance_m[0] <= self.distance_m[1]:
            raise ConfigurationError(f"distance_m must be [min, max], got {self.distance_m}")


@dataclass
class PanelPlannerConfig:
    """The acceleration-level planner of operation.motion "planner" (MakeAccelerationPlanner
    on the station's own models of the arm and gripper; its TCP is the scenario's tip frame).

    base_frame: the planner's base B (scoped frame name; empty: `<arm>::base`).
    max_joint_velocity, max_joint_acceleration: symmetric limits, one value or one per
        joint (rad/s, rad/s^2): modest, for the rover arm's DC/harmonic-drive joints.
    parameters: the law's gains and settings (the robust mode by default: facing the panel
        the tip is at Z-Y-X pitch -90 deg, the Euler singularity of the paper's law). A
        move ends within 0.1 mm and 0.1 mrad of its target (PlannerConfig's own default is
        1 mm and 1 mrad): the sequencer measures and presses where the planner ends.
    """

    base_frame: str = ""
    max_joint_velocity: list[float] = Positive(factory=lambda: [0.5])
    max_joint_acceleration: list[float] = Positive(factory=lambda: [1.5])
    parameters: PlannerConfig = field(
        default_factory=lambda: PlannerConfig(position_tolerance=1e-4, orientation_tolerance=1e-4)
    )


@dataclass
class PanelOperationScenario:
    """The panel task's scenario. The controller (IK, planner) knows the arm from the
    station's own models without the panel (MakeMultibodyPlant of the arm and the model
    instances of its camera and tip).

    arm: the key of station.arms that presses.
    switch: 1-based index into the panel file's switches.
    camera: the key of station.cameras on the arm (1920 x 1080 C920 by default).
    tip_frame: the scoped frame T that presses (gripper tip).
    panel_file: the PANEL.yaml (markers, switches): a path, absolute or relative to the
        working directory, or a name under models/. It drives both the estimator and the
        simulated scene: the model of `panel_model` is generated from it at load.
    estimator_camera_file: the estimator's camera model, a CAMERA.yaml (intrinsics and
        distortion, e.g. written by `guidedarm calibrate camera`): a path, absolute or
        relative to the working directory, or a name under models/, of the camera's
        width x height; empty: derived from the station's
        CameraConfig (no distortion).
    camera_mount_file: the controller's belief of where the camera sits on the arm, a
        hand_eye.yaml (`guidedarm calibrate hand-eye`: X_PC in the frame the camera's X_PB
        names), given as estimator_camera_file is; empty: the camera's X_PB X_BC. The
        simulated camera stays where X_PB (and station.errors) put it.
    panel_model: the panel's model instance in the directives (its model is replaced by
        the one generated from panel_file).
    supersampling: the camera renders this many times its resolution, and
        ImageDegradation averages it back (1..8; degradation.supersampling must stay 1;
        width x height x supersampling^2 <= MAX_RENDER_PIXELS).
    degradation: lighting, blur and noise of the camera image (its noise seed is the
        scenario's random_seed).
    random_seed: the scenario's random seed: the start pose and the image noise each draw
        their own stream from it.
    start: where the arm starts.
    cover_markers_after_base: slide a cover over the markers once the base measurement is
        taken (the paper's Table 6 case).
    operation: the sequence's parameters.
    planner: the planner of operation.motion "planner".
    time_limit_s: simulated time allowed (s).
    station: the station's models, arms and cameras.
    """

    task: str = "panel_operation"
    arm: str = "rover_arm"
    switch: int = Positive(2)
    camera: str = "camera"
    tip_frame: str = "rover_gripper::gripper_tip"
    panel_file: str = "panel/panel.yaml"
    estimator_camera_file: str = ""
    camera_mount_file: str = ""
    panel_model: str = "panel"
    supersampling: int = InRange(1, 8, 3)
    degradation: DegradationConfig = field(default_factory=DegradationConfig)
    random_seed: int = 0
    start: StartConfig = field(default_factory=StartConfig)
    cover_markers_after_base: bool = False
    operation: PanelOperationConfig = field(default_factory=PanelOperationConfig)
    planner: PanelPlannerConfig = field(default_factory=PanelPlannerConfig)
    time_limit_s: float = Positive(40.0)
    station: StationScenario = field(default_factory=StationScenario)

    def Validate(self) -> None:
        """Checked at load (CheckConfig): the fields' bounds, `arm` and `camera` in the
        station, and the camera's supersampling set by the top-level key only."""
        CheckFields(self)
        if self.arm not in self.station.arms:
            raise ConfigurationError(f"arm '{self.arm}' is not in station.arms")
        if self.camera not in self.station.cameras:
            raise ConfigurationError(f"camera '{self.camera}' is not in station.cameras")
        CheckRenderedSupersampling(
            self.degradation, self.station.cameras[self.camera], self.supersampling
        )
        self.EstimatorIntrinsics()
        self.CameraMount()
        panel = LoadPanelSpec(ResolvePanelFile(self.panel_file))
        if not self.switch <= len(panel.switches):
            raise ConfigurationError(
                f"switch must be 1 .. {len(panel.switches)}, got {self.switch} (the switches "
                f"of {self.panel_file})"
            )
        _CheckModeKeys(self)

    def CameraMount(self) -> RigidTransform | None:
        """X_PC of camera_mount_file (None when empty), refused when its base_frame is
        not the camera's X_PB.base_frame."""
        return LoadCameraMount(self.camera_mount_file, self.station.cameras[self.camera])

    def EstimatorIntrinsics(self) -> CameraIntrinsics | None:
        """The estimator's camera model (estimator_camera_file), None when derived."""
        return LoadEstimatorIntrinsics(
            self.estimator_camera_file, self.station.cameras[self.camera], self.camera
        )


def _CheckModeKeys(scenario: PanelOperationScenario) -> None:
    """Refuses a key set away from its default that the chosen mode does not read: the
    random start's keys beside an explicit start.position, operation.max_joint_speed
    with operation.motion=planner (the planner's own limits apply), `planner` with
    operation.motion=joint_trajectory, and station.hardware (the task refuses --hardware,
    CheckRun)."""
    changed = ChangedKey(scenario.station.hardware, StationScenario().hardware, "station.hardware")
    if changed:
        raise ConfigurationError(
            f"'{changed}' has no effect on panel_operation (it cannot run "
            "with --hardware): remove it"
        )
    if scenario.operation.motion == "planner":
        CheckModeFields(scenario.planner.parameters, "planner.parameters")
    else:
        changed = ChangedKey(scenario.planner, PanelPlannerConfig(), "planner")
        if changed:
            raise ConfigurationError(
                f"'{changed}' has no effect with operation.motion={scenario.operation.motion} "
                "(it is read only with operation.motion=planner): remove it or change motion"
            )
    start = scenario.start
    if start.position:
        changed = ChangedKey(start, StartConfig(position=start.position), "start")
        if changed:
            raise ConfigurationError(
                f"'{changed}' has no effect with start.position given (it shapes the random "
                "start only): remove it or start.position"
            )
    speed = scenario.operation.max_joint_speed
    if scenario.operation.motion == "planner" and speed != PanelOperationConfig().max_joint_speed:
        raise ConfigurationError(
            "'operation.max_joint_speed' has no effect with operation.motion=planner (the "
            "planner's planner.max_joint_velocity applies): remove it or change motion"
        )
