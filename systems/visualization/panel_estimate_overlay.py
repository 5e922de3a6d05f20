"""PanelEstimateOverlay: the gripper camera's view and the panel pose it estimated."""

from __future__ import annotations

from pydrake.common.value import AbstractValue
from pydrake.geometry import Meshcat
from pydrake.math import RigidTransform
from pydrake.multibody.tree import Frame
from pydrake.systems.framework import Context, EventStatus, LeafSystem

from guidedarm.systems.markers.marker_pose_estimator_math import CameraIntrinsics
from guidedarm.systems.visualization.frame_trail_overlay import OVERLAY_PERIOD
from guidedarm.systems.visualization.overlay_geometry import (
    PLAN_RGBA,
    AppearAt,
    ArmFramePoses,
    DrawTriad,
    FrustumSegments,
    RecordedPose,
    SetRecordedVisibility,
)


class PanelEstimateOverlay(LeafSystem):
    """Input ports: `position` (the arm's joints, rad) and `X_WP_estimated` (the panel
    frame P as the camera measured it, X_WC X_CP; identity until the first measurement,
    e.g. PanelOperation's port of that name).

    Under `path`: `camera`, the camera's viewing pyramid up to `depth` (m) at the camera
    frame C (placed from the arm's joints); `estimated_panel`, a triad at the estimate,
    shown from the first measurement on and moved at each new one.
    """

    def __init__(
        self,
        meshcat: Meshcat,
        path: str,
        poses: ArmFramePoses,
        camera_frame: Frame,
        intrinsics: CameraIntrinsics,
        depth: float = 0.15,
        period: float = OVERLAY_PERIOD,
    ) -> None:
        super().__init__()
        self._meshcat, self._path, self._poses, self._camera = meshcat, path, poses, camera_frame
        self._position = self.DeclareVectorInputPort("position", poses.num_positions())
        self._X_WP = self.DeclareAbstractInputPort(
            "X_WP_estimated", AbstractValue.Make(RigidTransform())
        )
        c = intrinsics
        start, end = FrustumSegments(c.width, c.height, c.fx, c.fy, c.cx, c.cy, depth)
        meshcat.SetLineSegments(f"{path}/camera/frustum", start, end, 2.0, PLAN_RGBA)
        DrawTriad(meshcat, f"{path}/camera/axes", length=0.03, radius=0.0015)
        DrawTriad(meshcat, f"{path}/estimated_panel", length=0.06, radius=0.0025, opacity=0.6)
        self._estimate: RigidTransform | None = None
        self._camera_pose = RecordedPose(meshcat, f"{path}/camera")
        self.DeclareInitializationPublishEvent(self._Start)
        self.DeclarePeriodicPublishEvent(period, 0.0, self._Publish)

    def _Start(self, context: Context) -> EventStatus:
        self._estimate = None
        self._camera_pose.Reset()
        SetRecordedVisibility(self._meshcat, f"{self._path}/estimated_panel", False, 0.0)
        return self._Publish(context)

    def _Publish(self, context: Context) -> EventStatus:
        t = context.get_time()
        (X_WC,) = self._poses.Poses(self._position.Eval(context), [self._camera])
        self._camera_pose.Set(X_WC, t)
        X_WP = self._X_WP.Eval(context)
        if X_WP.IsExactlyIdentity():
            return EventStatus.Succeeded()
        if self._estimate is None or not X_WP.IsExactlyEqualTo(self._estimate):
            if self._estimate is None:
                AppearAt(self._meshcat, f"{self._path}/estimated_panel", t)
            self._meshcat.SetTransform(f"{self._path}/estimated_panel", X_WP, t)
            self._estimate = X_WP
        return EventStatus.Succeeded()
