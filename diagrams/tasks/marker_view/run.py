"""Task `marker_view`: one view of the marker panel from a free camera.

The views of Tables 2-3 of Annusewicz-Mistal et al.

The paper's reference rig (an IRB 1600 holding the camera, section 3.2) in simulation:
PanelCameraRig renders the panel from the camera pose X_PC = LookAt(p_PC, origin of P),
p_PC = distance_m (sin a, 0, cos a) with a = angle_deg (a turn about the panel's y axis),
and MarkerPoseSolver estimates X_CP from the image. Ground truth is exact, so the metrics
are the estimator's errors:
  reference_mm, vision_mm, abs_error_mm, rel_error_pct   |p_CP| true and estimated;
  reference_deg, vision_deg, abs_angle_error_deg          the view angle a, true and
      estimated (from the panel normal seen by the camera);
  rotation_error_deg   angle of the whole rotation error; reprojection_error_px (RMS).
A view without a valid pose is a failed run (RunFailedError).
"""

from dataclasses import dataclass
from typing import Any

import cv2
import numpy as np

from guidedarm.diagrams.panel.panel_assets import GeneratedPanelModel
from guidedarm.diagrams.panel.panel_camera_rig import LookAt, PanelCameraRig
from guidedarm.diagrams.panel.panel_files import (
    LoadEstimatorIntrinsics,
    LoadPanelSpec,
    RecordedCameraFiles,
    ResolvePanelFile,
)
from guidedarm.diagrams.run_context import RunContext
from guidedarm.diagrams.tasks.marker_view.scenario import MarkerViewScenario
from guidedarm.diagrams.tasks.registry import TaskDefinition
from guidedarm.systems.cell_errors.distributions import DrawErrors
from guidedarm.systems.errors import RunFailedError
from guidedarm.systems.markers.image_degradation import DegradationConfig, SeededDegradation
from guidedarm.systems.markers.marker_pose_estimator_math import MarkerPoseSolver


@dataclass(frozen=True)
class PreparedView:
    """What a view checks before it runs and then uses: the rig rendering the panel, the
    estimator's solver and the image degradation seeded by the scenario."""

    rig: PanelCameraRig
    solver: MarkerPoseSolver
    degradation: DegradationConfig


def PrepareMarkerView(scenario: MarkerViewScenario) -> PreparedView:
    """The rig (the panel model generated from panel_file, the camera with its drawn
    errors), the solver (estimator_camera_file or the rig's intrinsics) and the seeded
    degradation (SeededDegradation refuses a seed of its own)."""
    panel_file = ResolvePanelFile(scenario.panel_file)
    degradation = SeededDegradation(scenario.degradation, scenario.random_seed)
    rig = PanelCameraRig(
        scenario.camera,
        scenario.supersampling,
        str(GeneratedPanelModel(panel_file)),
        errors=DrawErrors(scenario.camera_errors, None),
    )
    estimator = LoadEstimatorIntrinsics(scenario.estimator_camera_file, scenario.camera, "camera")
    solver = MarkerPoseSolver(estimator or rig.intrinsics, LoadPanelSpec(panel_file))
    return PreparedView(rig, solver, degradation)


def RunMarkerView(
    scenario: MarkerViewScenario, context: RunContext, prepared: PreparedView | None = None
) -> dict[str, Any]:
    """Renders the view (on `prepared`, default PrepareMarkerView(scenario)), estimates
    the panel pose and returns the errors (see above)."""
    prepared = prepared or PrepareMarkerView(scenario)
    a = np.radians(scenario.angle_deg)
    d = scenario.distance_m
    X_PC = LookAt(d * np.array([np.sin(a), 0.0, np.cos(a)]), [0.0, 0.0, 0.0])
    image = prepared.rig.Render(X_PC, prepared.degradation)
    path = context.out_dir / "view.png"
    cv2.imwrite(str(path), cv2.cvtColor(image, cv2.COLOR_RGBA2BGR))
    context.written.append(path)
    estimate = prepared.solver.estimate(image)
    if not estimate.valid:
        raise RunFailedError(
            f"no valid pose at {1e3 * d:.0f} mm, {scenario.angle_deg} deg (markers found: "
            f"{estimate.ids})"
        )
    measured = float(np.linalg.norm(estimate.X_CP.translation()))
    z_P = estimate.X_CP.inverse().rotation().matrix()[:, 2]  # P's normal seen from C
    angle = float(np.degrees(np.arctan2(-z_P[0], -z_P[2])))
    R_error = estimate.X_CP.rotation().inverse() @ X_PC.inverse().rotation()
    return {
        "success": True,
        "reference_mm": round(1e3 * d, 4),
        "vision_mm": round(1e3 * measured, 4),
        "abs_error_mm": round(1e3 * abs(measured - d), 4),
        "rel_error_pct": round(100 * abs(measured - d) / d, 5),
        "reference_deg": scenario.angle_deg,
        "vision_deg": round(angle, 5),
        "abs_angle_error_deg": round(abs(angle - scenario.angle_deg), 5),
        "rotation_error_deg": round(float(np.degrees(R_error.ToAngleAxis().angle())), 5),
        "reprojection_error_px": round(float(estimate.reprojection_error_px), 4),
        "ids": estimate.ids,
        "failure": None,
    }


# The numbers of RunMarkerView's summary (TaskDefinition.metrics); `ids.#` are the ids of
# the markers found.
MARKER_VIEW_METRICS = {
    "reference_mm": ("mm", "true distance of the camera from the panel frame P"),
    "vision_mm": ("mm", "the estimated distance (the norm of the estimated X_CP's translation)"),
    "abs_error_mm": ("mm", "|vision_mm - reference_mm|"),
    "rel_error_pct": ("%", "abs_error_mm over reference_mm"),
    "reference_deg": ("deg", "true turn of the camera about P's y axis (angle_deg)"),
    "vision_deg": ("deg", "the estimated turn about P's y axis"),
    "abs_angle_error_deg": ("deg", "|vision_deg - reference_deg|"),
    "rotation_error_deg": ("deg", "angle of the rotation between estimated and true X_CP"),
    "reprojection_error_px": ("px", "RMS distance of the detected corners from the reprojected"),
    "ids.#": ("id", "the ids of the markers found, one element each"),
}

TASK = TaskDefinition(
    name="marker_view",
    scenario_type=MarkerViewScenario,
    run=RunMarkerView,
    description="estimate the marker panel's pose from one free-camera view (markers paper)",
    simulates=False,
    metrics=MARKER_VIEW_METRICS,
    ground_truth_metrics=(
        "abs_error_mm",
        "rel_error_pct",
        "abs_angle_error_deg",
        "rotation_error_deg",
        "reference_mm",
        "reference_deg",
    ),
    resolve=RecordedCameraFiles,
    prepare=PrepareMarkerView,
)
