"""ToFToolOverlay: what the six-sensor ToF tool sees, drawn on Meshcat (Wawrzyniak et al.)."""

from __future__ import annotations

import numpy as np
from pydrake.geometry import Meshcat, Sphere
from pydrake.math import RigidTransform
from pydrake.multibody.tree import Frame
from pydrake.systems.framework import Context, EventStatus, LeafSystem

from guidedarm.systems.tof.detection_grid import DetectionGrid
from guidedarm.systems.visualization.frame_trail_overlay import OVERLAY_PERIOD
from guidedarm.systems.visualization.overlay_geometry import (
    ERROR_RGBA,
    IDLE_RGBA,
    SENSED_RGBA,
    ArmFramePoses,
    RecordedPose,
    SetRecordedVisibility,
)

# The three looks of a grid point: detected and consistent, a detection error, nothing.
GRID_STATES = {"detected": SENSED_RGBA, "error": ERROR_RGBA, "none": IDLE_RGBA}


class ToFToolOverlay(LeafSystem):
    """Input ports: `position` (the arm's joints, rad), `ranges` (6, m), `valid` (6),
    `detections` and `detection_errors` (9 each, row-major): e.g. the station's ToF ports, or
    the reading a PathFollower used (its step_record and grid outputs).

    Under `path`, in the tool frame T (placed from the arm's joints every `period` s):
    each sensor's cone as its rays up to max_range (grey); for a sensor with a return, the
    same rays up to the measured range (green) and the hit on its line of sight; the 3 x 3
    detection grid, each point green (detected), red (detection error) or grey (nothing).
    The readings are drawn every `sensor_period` s: a simulated reading casts rays (about
    10 ms), so drawing each frame would cost more than the run.
    """

    def __init__(
        self,
        meshcat: Meshcat,
        path: str,
        poses: ArmFramePoses,
        tool_frame: Frame,
        grid: DetectionGrid,
        rays_S: np.ndarray,
        max_range: float,
        period: float = OVERLAY_PERIOD,
        sensor_period: float = 0.1,
    ) -> None:
        super().__init__()
        self._meshcat, self._path, self._poses, self._tool = meshcat, path, poses, tool_frame
        self._position = self.DeclareVectorInputPort("position", poses.num_positions())
        self._ranges = self.DeclareVectorInputPort("ranges", 6)
        self._valid = self.DeclareVectorInputPort("valid", 6)
        self._detections = self.DeclareVectorInputPort("detections", 9)
        self._errors = self.DeclareVectorInputPort("detection_errors", 9)
        self._visible: dict[str, bool] = {}
        self._changed: set[str] = set()
        self._ranges_drawn = np.full(6, np.nan)
        # The paths drawn at each reading, formed once: each sensor's (hit rays, hit
        # point), each grid point's {state: path}, and the state each point shows.
        sensors = [f"{path}/sensor_{k + 1}" for k in range(6)]
        self._hit_paths = [(f"{sensor}/hit", f"{sensor}/hit_point") for sensor in sensors]
        self._state_paths = [
            {state: f"{path}/grid/p{n // 3 + 1}{n % 3 + 4}/{state}" for state in GRID_STATES}
            for n in range(9)
        ]
        self._states_drawn: list[str | None] = [None] * 9
        self._pose = RecordedPose(meshcat, path)
        self._Draw(grid, rays_S, max_range)
        self.DeclareInitializationPublishEvent(self._Start)
        self.DeclarePeriodicPublishEvent(period, 0.0, self._PublishPose)
        self.DeclarePeriodicPublishEvent(sensor_period, 0.0, self._PublishReading)

    def _Draw(self, grid: DetectionGrid, rays_S: np.ndarray, max_range: float) -> None:
        m, origin = self._meshcat, np.zeros((3, len(rays_S)))
        for k, X_TS in enumerate(grid.X_TS):
            sensor = f"{self._path}/sensor_{k + 1}"
            m.SetTransform(sensor, X_TS)
            m.SetLineSegments(f"{sensor}/cone", origin, max_range * rays_S.T, 1.0, IDLE_RGBA)
            m.SetLineSegments(f"{sensor}/hit/rays", origin, rays_S.T, 2.0, SENSED_RGBA)
            m.SetObject(f"{sensor}/hit_point", Sphere(0.003), SENSED_RGBA)
        for i in range(3):
            for j in range(3):
                point = f"{self._path}/grid/p{i + 1}{j + 4}"
                m.SetTransform(point, RigidTransform(grid.points[i, j]))
                for state, rgba in GRID_STATES.items():
                    m.SetObject(f"{point}/{state}", Sphere(0.0025), rgba)

    def _Set(self, path: str, visible: bool, t: float) -> None:
        """Shows or hides `path` from time t on, recording only changes. At the first
        change the value before it is recorded at time 0 too: a recording started after
        the initial value was set would otherwise show the new value from its start."""
        before = self._visible.get(path)
        if before == visible:
            return
        if before is not None and path not in self._changed:
            SetRecordedVisibility(self._meshcat, path, before, 0.0)
            self._changed.add(path)
        SetRecordedVisibility(self._meshcat, path, visible, t)
        self._visible[path] = visible

    def _Start(self, context: Context) -> EventStatus:
        self._visible.clear()
        self._changed.clear()
        self._ranges_drawn[:] = np.nan
        self._states_drawn = [None] * 9
        self._pose.Reset()
        self._PublishPose(context)
        return self._PublishReading(context)

    def _PublishPose(self, context: Context) -> EventStatus:
        (X_WT,) = self._poses.Poses(self._position.Eval(context), [self._tool])
        self._pose.Set(X_WT, context.get_time())
        return EventStatus.Succeeded()

    def _PublishReading(self, context: Context) -> EventStatus:
        t = context.get_time()
        m = self._meshcat
        ranges, valid = self._ranges.Eval(context), self._valid.Eval(context) > 0.5
        for k, (hit, hit_point) in enumerate(self._hit_paths):
            self._Set(hit, bool(valid[k]), t)
            self._Set(hit_point, bool(valid[k]), t)
            if valid[k] and ranges[k] != self._ranges_drawn[k]:
                r = float(ranges[k])
                m.SetProperty(hit, "scale", [r, r, r], t)
                # The keyword picks pybind's overload at once (a positional p tries others).
                m.SetTransform(hit_point, RigidTransform(p=[0.0, 0.0, r]), t)
                self._ranges_drawn[k] = r
        detected = self._detections.Eval(context) > 0.5
        errors = self._errors.Eval(context) > 0.5
        for n, paths in enumerate(self._state_paths):
            state = "error" if errors[n] else "detected" if detected[n] else "none"
            if state != self._states_drawn[n]:
                for name, point in paths.items():
                    self._Set(point, name == state, t)
                self._states_drawn[n] = state
        return EventStatus.Succeeded()
