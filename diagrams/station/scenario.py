"""Scenario schemas of the station, loaded with `yaml_load_typed` (see scenario_loading)."""

import dataclasses
import math
from dataclasses import dataclass, field
from typing import Literal

import numpy as np
from pydrake.multibody.parsing import ModelDirective
from pydrake.multibody.plant import MultibodyPlantConfig
from pydrake.systems.analysis import SimulatorConfig
from pydrake.systems.sensors import CameraConfig
from pydrake.visualization import VisualizationConfig

from guidedarm.diagrams.calibration.calibration_files import LoadJointOffsets, LoadToFOffsets
from guidedarm.diagrams.station.hardware_config import HardwareConfig
from guidedarm.diagrams.station.station_errors import (
    CheckErrorKeys,
    DrawStationErrors,
    LoadPreset,
    PresetNames,
    StationErrors,
)
from guidedarm.systems.config_checks import (
    MAX_JOINT_POSITION,
    ChangedKey,
    CheckFields,
    FieldError,
    InRange,
)
from guidedarm.systems.errors import ConfigurationError
from guidedarm.systems.scene.hose_geometry import HoseConfig
from guidedarm.systems.tof.tof_tool_sensor import ToFToolConfig
from guidedarm.systems.visualization.overlay_geometry import VISUALIZATION_PERIOD

# The station MakeStation builds from a scenario, behind the same ports: `simulation`
# (the MultibodyPlant's dynamics, rendered cameras), `kinematic` (the arm posed where it
# is commanded) or `hardware` (the real cell's drivers).
StationKind = Literal["simulation", "kinematic", "hardware"]


@dataclass
class ArmConfig:
    """One position-controlled arm: the model instance of the same name in `directives`.

    initial_position: joint positions at t = 0 (rad, each within +-MAX_JOINT_POSITION = 4 pi);
        empty keeps the model's defaults.
    kp, kd: servo gains of the simulated controller (1/s^2 in [1, 1e6], 1/s <= 2000); kd <= 0
        means critically damped, 2 sqrt(kp). Beyond these the 2 ms plant step goes unstable.
    control_period: period at which position commands are sampled and differentiated (s, in
        [1e-4, 1]); 0.002 s matches UR servoJ at 500 Hz.
    calibration_file: the arm's identified joint offsets, a joint_offsets.yaml written by
        `guidedarm calibrate hand-eye` (relative to models/ or absolute; '': none): the
        simulated encoders' and the hardware driver's measured positions gain them, and the
        driver's commands lose them, so the controllers work in calibrated joint angles
        while station.errors stays the truth.
    """

    initial_position: list[float] = InRange(-MAX_JOINT_POSITION, MAX_JOINT_POSITION, factory=list)
    kp: float = InRange(1.0, 1e6, 1600.0)
    kd: float = InRange(-math.inf, 2000.0, 0.0)
    control_period: float = InRange(1e-4, 1.0, 0.002)
    calibration_file: str = ""


def _default_plant_config() -> MultibodyPlantConfig:
    # Unsampled output ports: the plant steps by a discrete update (the same states), not
    # an unrestricted one, after which the simulator re-asks every system for witness
    # functions; contact results are computed when asked (nothing asks in a run).
    return MultibodyPlantConfig(
        time_step=0.002, discrete_contact_approximation="sap", use_sampled_output_ports=False
    )


def _default_visualization() -> VisualizationConfig:
    return VisualizationConfig(
        publish_period=VISUALIZATION_PERIOD, publish_contacts=False, publish_inertia=False
    )


# The name of the renderer that every camera of guidedarm renders with (VTK, its default
# parameters).
RENDERER_NAME = "vtk"
# CameraConfig fields no camera of the station reads: the simulated station renders colour
# images on demand with RENDERER_NAME's engine (its own background) and publishes nothing;
# the hardware station grabs width x height colour frames at `fps`.
UNSUPPORTED_CAMERA_FIELDS = (
    "capture_offset",
    "output_delay",
    "rgb",
    "depth",
    "label",
    "show_rgb",
    "do_compress",
    "lcm_bus",
    "z_near",
    "z_far",
    "X_BD",
    "background",
    "renderer_class",
)


def UnreadCameraKey(config: CameraConfig, fields: tuple[str, ...]) -> str:
    """The dotted name of the first of `fields` whose value differs from CameraConfig's
    default, or renderer_name when it names another renderer than RENDERER_NAME; ''
    when none does."""
    default = CameraConfig()
    for name in fields:
        changed = ChangedKey(getattr(config, name), getattr(default, name), name)
        if changed:
            return changed
    if config.renderer_name not in (default.renderer_name, RENDERER_NAME):
        return "renderer_name"
    return ""


@dataclass
class StationScenario:
    """Everything the station needs: models, arms, cameras, plant and visualisation.

    directives: Drake model directives placing every model (arms, tools, scene).
    arms: position-controlled arms, keyed by model instance name; each exports the ports
        `<name>.position_commanded`, `<name>.position_measured`, `<name>.velocity_estimated`
        and `<name>.state_estimated`.
    cameras: Drake CameraConfig per camera; each exports `<name>.rgb_image`.
    visualization: what the simulated station shows in Meshcat (Drake's
        VisualizationConfig; Meshcat only, lcm_bus stays "default").
    hardware: drivers used by `MakeStation(..., kind="hardware")` (diagrams/hardware_config).
    hose: a hose (centerline, brackets) registered on the world body, or None.
    tof_tools: six-sensor ToF tools; each exports `<name>.ranges`, `.valid`, `.measured_at`
        and the detection grid's `.detections`, `.detection_errors` (TOF_PORTS).
    errors: what the simulated (true) cell has and the nominal models do not
        (station_errors.StationErrors; empty: the exact cell); errors_preset: presets
        under it, "NAME[,NAME...]" of models/errors/NAME.yaml ('' none).
    """

    directives: list[ModelDirective] = field(default_factory=list)
    arms: dict[str, ArmConfig] = field(default_factory=dict)
    cameras: dict[str, CameraConfig] = field(default_factory=dict)
    plant_config: MultibodyPlantConfig = field(default_factory=_default_plant_config)
    simulator_config: SimulatorConfig = field(default_factory=SimulatorConfig)
    visualization: VisualizationConfig = field(default_factory=_default_visualization)
    hardware: HardwareConfig = field(default_factory=HardwareConfig)
    hose: HoseConfig | None = None
    tof_tools: dict[str, ToFToolConfig] = field(default_factory=dict)
    errors: StationErrors = field(default_factory=StationErrors)
    errors_preset: str = ""

    def Validate(self) -> None:
        """Checked at load (CheckConfig): the fields, then no camera field the station does
        not read (UNSUPPORTED_CAMERA_FIELDS, a `name` other than the camera's key) and no
        LCM bus for the visualization (Meshcat only)."""
        CheckFields(self)
        for key, camera in self.cameras.items():
            unread = UnreadCameraKey(camera, UNSUPPORTED_CAMERA_FIELDS)
            if not unread and camera.name not in (CameraConfig().name, key):
                unread = "name"
            if unread:
                raise FieldError(
                    f"cameras.{key}.{unread}",
                    "the station renders colour images on demand with its own VTK renderer "
                    f"and names each camera by its key; {unread} cannot be set",
                )
        if self.visualization.lcm_bus != VisualizationConfig().lcm_bus:
            raise FieldError(
                "visualization.lcm_bus", "the station visualizes in Meshcat only; it cannot be set"
            )
        for name in PresetNames(self.errors_preset):
            LoadPreset(name)
        known = {"arms": set(self.arms), "cameras": set(self.cameras)}
        known["tof_tools"] = set(self.tof_tools)
        CheckErrorKeys(self.errors, known)
        for name in PresetNames(self.errors_preset):
            CheckErrorKeys(LoadPreset(name), known)
        for name in self.tof_tools:
            try:
                self.ToFCalibration(name)
            except ConfigurationError as e:
                raise FieldError(f"tof_tools.{name}.calibration_file", str(e)) from None
        for name in self.arms:
            try:
                self.ArmCalibration(name)
            except ConfigurationError as e:
                raise FieldError(f"arms.{name}.calibration_file", str(e)) from None

    def ArmCalibration(self, name: str) -> np.ndarray | None:
        """The identified joint offsets (rad) of arms[name].calibration_file, None without."""
        calibration_file = self.arms[name].calibration_file
        return LoadJointOffsets(calibration_file) if calibration_file else None

    def ToFCalibration(self, name: str) -> np.ndarray | None:
        """The six calibrated offsets (m) of tof_tools[name].calibration_file, None without."""
        calibration_file = self.tof_tools[name].calibration_file
        return LoadToFOffsets(calibration_file) if calibration_file else None

    def WithErrorsDrawn(self, random_seed: int | None) -> "StationScenario":
        """A copy whose `errors` are the presets and errors combined and drawn from
        `random_seed` (station_errors.DrawStationErrors; None refuses distributions),
        `errors_preset` empty: the cell of one run, which repeats it when loaded."""
        drawn = DrawStationErrors(self.errors_preset, self.errors, random_seed)
        return dataclasses.replace(self, errors=drawn, errors_preset="")

    def HasErrors(self) -> bool:
        """Whether errors or a preset are set (the cell is not the exact one)."""
        return bool(PresetNames(self.errors_preset)) or self.errors != StationErrors()

    def CheckSimulated(self) -> None:
        """Refuses what only the hardware station reads, for a simulated run: a camera's
        `fps` (the simulated camera renders on demand)."""
        for key, camera in self.cameras.items():
            if UnreadCameraKey(camera, ("fps",)):
                raise FieldError(
                    f"cameras.{key}.fps",
                    "the simulated station renders colour images on demand (only --hardware "
                    "grabs frames at fps); fps cannot be set",
                )

    def ToFTool(self, name: str) -> ToFToolConfig:
        """tof_tools[name] with its target_radius resolved: 0 means the station hose's
        radius (diameter / 2), or the sensor's default without a hose."""
        tool = self.tof_tools[name]
        if tool.target_radius or self.hose is None:
            return tool
        return dataclasses.replace(tool, target_radius=self.hose.diameter / 2)
