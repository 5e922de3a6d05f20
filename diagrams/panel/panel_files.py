"""Reading the camera file (CAMERA.yaml) and the panel file (PANEL.yaml) of the marker task.

Both are plain YAML loaded against the dataclasses of
systems/markers/marker_pose_estimator_math.py; a malformed file, an unknown key or a wrong
type fails with one line naming the file and the key."""

from __future__ import annotations

import copy
import dataclasses
from pathlib import Path
from typing import Any

from pydrake.math import RigidTransform
from pydrake.systems.sensors import CameraConfig

from guidedarm.diagrams.calibration.calibration_files import LoadHandEye
from guidedarm.diagrams.scenario_loading import ScenarioError, load_typed, read_raw_scenario
from guidedarm.diagrams.station.model_paths import MODELS_DIR
from guidedarm.systems.errors import ConfigurationError
from guidedarm.systems.markers.marker_pose_estimator_math import (
    CameraIntrinsics,
    GetDictionary,
    PanelSpec,
)

MODELS_PANEL_DIR = MODELS_DIR / "panel"
DEFAULT_PANEL_FILE = MODELS_PANEL_DIR / "panel.yaml"
DEFAULT_CAMERA_FILE = MODELS_PANEL_DIR / "c920_camera.yaml"


def ResolveModelFile(key: str, name: str | Path, example: str) -> Path:
    """A file given as a path (absolute, or relative to the working directory) or as a name
    under models/ (e.g. `example`); ConfigurationError naming `key` when neither is a
    file."""
    path = Path(name).expanduser()
    if path.is_file():
        return path.resolve()
    if not path.is_absolute() and (MODELS_DIR / path).is_file():
        return MODELS_DIR / path
    raise ConfigurationError(
        f"{key} '{name}': file not found (give a path, absolute or relative to the "
        f"working directory, or a name under models/ such as {example})"
    )


def ResolvePanelFile(name: str | Path) -> Path:
    """The PANEL.yaml `name` (ResolveModelFile of panel_file)."""
    return ResolveModelFile("panel_file", name, "panel/panel.yaml")


def RecordedModelFile(key: str, name: str, example: str) -> str:
    """A file setting as a run's scenario.yaml records it: empty as empty, a name under
    models/ as given, a path made absolute, so that the file repeats the run from any
    directory."""
    if not name:
        return name
    path = ResolveModelFile(key, name, example)
    return name if path == MODELS_DIR / name else str(path)


def RecordedPanelFile(name: str) -> str:
    """The panel file as a run's scenario.yaml records it (RecordedModelFile)."""
    return RecordedModelFile("panel_file", name, "panel/panel.yaml")


def RecordedCameraFiles(scenario: Any) -> Any:
    """`scenario` with its panel_file and its estimator's camera files (where it has them)
    as a run's scenario.yaml records them (RecordedModelFile)."""
    files = {"panel_file": RecordedPanelFile(scenario.panel_file)}
    for key, example in CAMERA_FILE_EXAMPLES.items():
        if hasattr(scenario, key):
            files[key] = RecordedModelFile(key, getattr(scenario, key), example)
    return dataclasses.replace(scenario, **files)


# The estimator's camera files a scenario may name, with an example name of each.
CAMERA_FILE_EXAMPLES = {
    "estimator_camera_file": "panel/c920_camera.yaml",
    "camera_mount_file": "hand_eye.yaml",
}


def LoadCameraIntrinsics(path: str | Path) -> CameraIntrinsics:
    """The intrinsics in a CAMERA.yaml file."""
    return load_typed(CameraIntrinsics, _ReadMapping(path), str(path))


def LoadEstimatorIntrinsics(
    camera_file: str, camera: CameraConfig, camera_name: str
) -> CameraIntrinsics | None:
    """The estimator's camera model in `camera_file` (a path, absolute or relative to the
    working directory, or a name under models/; None when empty), refused unless it is
    for the images of `camera` (width x height)."""
    if not camera_file:
        return None
    path = ResolveModelFile("estimator_camera_file", camera_file, "panel/c920_camera.yaml")
    intrinsics = LoadCameraIntrinsics(path)
    if (intrinsics.width, intrinsics.height) != (camera.width, camera.height):
        raise ConfigurationError(
            f"estimator_camera_file {camera_file} is for {intrinsics.width} x "
            f"{intrinsics.height} px images, camera '{camera_name}' renders "
            f"{camera.width} x {camera.height}"
        )
    return intrinsics


def LoadCameraMount(mount_file: str, camera: CameraConfig) -> RigidTransform | None:
    """X_PC of a hand_eye.yaml `mount_file` (a path, absolute or relative to the working
    directory, or a name under models/; None when empty), refused when it names another
    base frame than the camera's X_PB."""
    if not mount_file:
        return None
    X_PC = LoadHandEye(ResolveModelFile("camera_mount_file", mount_file, "hand_eye.yaml")).X_PC
    if X_PC.base_frame and X_PC.base_frame != camera.X_PB.base_frame:
        raise ConfigurationError(
            f"camera_mount_file {mount_file}: X_PC is in {X_PC.base_frame}, the camera's "
            f"X_PB in {camera.X_PB.base_frame}"
        )
    return X_PC.GetDeterministicValue()


def LoadPanelSpec(path: str | Path) -> PanelSpec:
    """The panel in a PANEL.yaml file (its dictionary name is checked here)."""
    panel = load_typed(PanelSpec, _ReadMapping(path), str(path))
    try:
        GetDictionary(panel.dictionary)
    except ConfigurationError as e:
        raise ConfigurationError(f"{path}: {e}") from None
    return panel


# Pixel coordinates are OpenCV's (the centre of the top-left pixel is (0, 0)), as Drake's
# CameraInfo documents them: its default principal point is (w/2 - 0.5, h/2 - 0.5), the
# value camera files state (models/panel/c920_camera.yaml: 959.5, 539.5). Drake's VTK
# renderer draws the image half a pixel further up-left than its CameraInfo says (measured
# with sub-pixel shifted squares, tests/test_camera_convention.py): a camera configured
# with centre c renders images whose principal point is c - 0.5.
VTK_PRINCIPAL_POINT_OFFSET_PX = -0.5


def IntrinsicsFromCameraConfig(config: CameraConfig, supersampling: int = 1) -> CameraIntrinsics:
    """The intrinsics of the images rendered for `config` (no distortion), after averaging
    `supersampling` x `supersampling` blocks of pixels (see ImageDegradation)."""
    color, _ = config.MakeCameras()
    info = color.core().intrinsics()
    k = supersampling

    def down(c: float) -> float:
        return (c + VTK_PRINCIPAL_POINT_OFFSET_PX + 0.5) / k - 0.5

    return CameraIntrinsics(
        width=info.width() // k,
        height=info.height() // k,
        fx=info.focal_x() / k,
        fy=info.focal_y() / k,
        cx=down(info.center_x()),
        cy=down(info.center_y()),
    )


def SupersampledCameraConfig(config: CameraConfig, supersampling: int) -> CameraConfig:
    """A copy of `config` rendering `supersampling` times the resolution (same optics):
    averaged over k x k blocks, its images have the intrinsics of `config`'s CameraInfo."""
    color, _ = config.MakeCameras()
    info = color.core().intrinsics()
    k = supersampling
    result = copy.deepcopy(config)
    result.width, result.height = config.width * k, config.height * k
    result.focal = CameraConfig.FocalLength(x=info.focal_x() * k, y=info.focal_y() * k)
    # The renderer's half-pixel shift is compensated here, so the k x k averaged images
    # have their principal point where `config`'s CameraInfo (and the camera file) says.
    result.center_x = (info.center_x() + 0.5) * k - 0.5 - VTK_PRINCIPAL_POINT_OFFSET_PX
    result.center_y = (info.center_y() + 0.5) * k - 0.5 - VTK_PRINCIPAL_POINT_OFFSET_PX
    return result


def _ReadMapping(path: str | Path) -> dict:
    path = Path(path)
    if not path.is_file():
        raise ScenarioError(f"file not found: {path}")
    return read_raw_scenario(path)
