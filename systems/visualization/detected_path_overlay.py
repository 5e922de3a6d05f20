"""DetectedPathOverlay: the hose points the path follower detected, drawn on Meshcat."""

from __future__ import annotations

import numpy as np
from pydrake.geometry import Meshcat, Sphere
from pydrake.math import RigidTransform
from pydrake.systems.framework import Context, EventStatus, LeafSystem

from guidedarm.systems.path_following.path_follower_math import RECORD_FIELDS
from guidedarm.systems.visualization.frame_trail_overlay import OVERLAY_PERIOD
from guidedarm.systems.visualization.overlay_geometry import SENSED_RGBA, AppearAt, GrowingPolyline

_STEP, _DETECTED = RECORD_FIELDS.index("step"), RECORD_FIELDS.index("detected")
_S = slice(RECORD_FIELDS.index("S_x"), RECORD_FIELDS.index("S_z") + 1)


class DetectedPathOverlay(LeafSystem):
    """Input port `step_record` (PathFollower's RECORD_FIELDS of the latest step). Each
    step whose reading detected the hose adds its estimated centre S (m, world) under
    `path`: a green sphere, joined to the previous one by a green line."""

    def __init__(self, meshcat: Meshcat, path: str, period: float = OVERLAY_PERIOD) -> None:
        super().__init__()
        self._meshcat, self._path = meshcat, path
        self._record = self.DeclareVectorInputPort("step_record", len(RECORD_FIELDS))
        self._line = GrowingPolyline(meshcat, f"{path}/line", SENSED_RGBA, chunk_s=0.0)
        self._step = -1
        self.DeclareInitializationPublishEvent(self._Start)
        self.DeclarePeriodicPublishEvent(period, 0.0, self._Publish)

    def _Start(self, context: Context) -> EventStatus:
        self._meshcat.Delete(f"{self._path}/points")
        self._line.Reset()
        self._step = -1
        return self._Publish(context)

    def _Publish(self, context: Context) -> EventStatus:
        record = self._record.Eval(context)
        step = int(record[_STEP])
        if step < 0 or step == self._step:
            return EventStatus.DidNothing()
        self._step = step
        if record[_DETECTED] > 0.5:
            t = context.get_time()
            p_WS = np.asarray(record[_S])
            point = f"{self._path}/points/{step:04d}"
            self._meshcat.SetObject(point, Sphere(0.003), SENSED_RGBA)
            self._meshcat.SetTransform(point, RigidTransform(p=p_WS))
            AppearAt(self._meshcat, point, t)
            self._line.Append(p_WS, t)
        return EventStatus.Succeeded()
