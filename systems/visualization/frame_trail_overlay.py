"""FrameTrailOverlay: the path a frame of an arm travels, drawn on Meshcat as it goes."""

from __future__ import annotations

from pydrake.geometry import Meshcat, Rgba, Sphere
from pydrake.math import RigidTransform
from pydrake.multibody.tree import Frame
from pydrake.systems.framework import Context, EventStatus, LeafSystem

from guidedarm.systems.visualization.overlay_geometry import (
    VISUALIZATION_PERIOD,
    ArmFramePoses,
    GrowingPolyline,
    RecordedPose,
)

# The overlays draw with the station's MeshcatVisualizer: on the plant's steps, at about the
# replay's frame rate (publishing between the plant's steps splits them: at 1/30 s the
# path_following demo took 25.8 s of CPU instead of 22.4 s).
OVERLAY_PERIOD = VISUALIZATION_PERIOD


class FrameTrailOverlay(LeafSystem):
    """Input port `position` (the arm's joint positions, rad: e.g. a planner's
    `position_commanded` or the station's `<arm>.position_measured`). Draws the trail of
    `frame` (e.g. the TCP) under `path` as a growing line, and a small sphere at the
    frame's current position, every `period` (s) of simulated time."""

    def __init__(
        self,
        meshcat: Meshcat,
        path: str,
        poses: ArmFramePoses,
        frame: Frame,
        rgba: Rgba,
        period: float = OVERLAY_PERIOD,
    ) -> None:
        super().__init__()
        self._meshcat, self._path, self._poses, self._frame = meshcat, path, poses, frame
        self._position = self.DeclareVectorInputPort("position", poses.num_positions())
        self.trail = GrowingPolyline(meshcat, f"{path}/trail", rgba)
        meshcat.SetObject(f"{path}/head", Sphere(0.006), rgba)
        self._head = RecordedPose(meshcat, f"{path}/head")
        self.DeclareInitializationPublishEvent(self._Start)
        self.DeclarePeriodicPublishEvent(period, 0.0, self._Publish)

    def _Start(self, context: Context) -> EventStatus:
        self.trail.Reset()
        self._head.Reset()
        return self._Publish(context)

    def _Publish(self, context: Context) -> EventStatus:
        t = context.get_time()
        (X_WF,) = self._poses.Poses(self._position.Eval(context), [self._frame])
        p_WF = X_WF.translation()
        self.trail.Append(p_WF, t)
        # The keyword picks pybind's overload at once (a positional p tries others).
        self._head.Set(RigidTransform(p=p_WF), t)
        return EventStatus.Succeeded()
