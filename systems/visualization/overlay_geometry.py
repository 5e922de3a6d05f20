"""Drawing helpers shared by the overlay systems (plain functions, no Diagram needed).

Recording: Meshcat animations cannot add objects (SetObject is never recorded), so an
object that appears during a run is created at once and made visible in the recording
from its time on: hidden at time 0, shown at time t (SetRecordedVisibility).
"""

from __future__ import annotations

import numpy as np
from pydrake.geometry import Cylinder, Meshcat, Rgba, Sphere
from pydrake.math import RigidTransform, RotationMatrix
from pydrake.multibody.plant import MultibodyPlant
from pydrake.multibody.tree import Frame, ModelInstanceIndex

OVERLAYS = "/overlays"

# Meshcat frames every 32 ms: 16 steps of the default 2 ms plant, so a frame adds no
# simulator step of its own, and about the replay's 30 frames a second (Drake's 1/64 s
# falls between plant steps and records twice the frames the replay keeps).
VISUALIZATION_PERIOD = 0.032

# Colours chosen apart from the models' greys, blues and oranges.
PLAN_RGBA = Rgba(1.0, 0.0, 1.0, 1.0)  # magenta: what a planner commands
SENSED_RGBA = Rgba(0.0, 0.85, 0.2, 1.0)  # green: what a sensor detected
ERROR_RGBA = Rgba(0.95, 0.1, 0.1, 1.0)  # red: a detection error
TRUTH_RGBA = Rgba(1.0, 0.85, 0.0, 1.0)  # yellow: ground truth / a target
TOOL_RGBA = Rgba(0.0, 0.75, 1.0, 1.0)  # cyan: where the tool went
IDLE_RGBA = Rgba(0.55, 0.55, 0.55, 0.5)  # grey: nothing seen


def SetRecordedVisibility(meshcat: Meshcat, path: str, visible: bool, t: float) -> None:
    """Shows or hides `path` live and, when recording, in the animation from time t on."""
    meshcat.SetProperty(path, "visible", visible, t)


def AppearAt(meshcat: Meshcat, path: str, t: float) -> None:
    """Makes a just-created object appear at time t of the recording (hidden before)."""
    SetRecordedVisibility(meshcat, path, False, 0.0)
    SetRecordedVisibility(meshcat, path, True, t)


class RecordedPose:
    """Sets the pose of a Meshcat path at each call, live and into the recording, but only
    when it changed: a still tool costs no message. When it moves again, the last still
    pose is recorded at its last time first, so the replay does not glide across the pause
    (the animation interpolates between keyframes)."""

    def __init__(self, meshcat: Meshcat, path: str, tolerance: float = 1e-6) -> None:
        self._meshcat, self._path, self._tolerance = meshcat, path, tolerance
        self.Reset()

    def Reset(self) -> None:
        """Forgets the last pose (a new run starts)."""
        self._last: RigidTransform | None = None
        self._last_t = 0.0
        self._skipped = False

    def Set(self, X: RigidTransform, t: float) -> None:
        """Sets the pose X (in the parent path's frame) at time t (s)."""
        if self._last is not None and X.IsNearlyEqualTo(self._last, self._tolerance):
            self._last_t, self._skipped = t, True
            return
        if self._skipped:
            self._meshcat.SetTransform(self._path, self._last, self._last_t)
        self._meshcat.SetTransform(self._path, X, t)
        self._last, self._last_t, self._skipped = X, t, False


class GrowingPolyline:
    """A trail drawn while a run goes on: points are gathered and drawn as one line per
    `chunk_s` of simulated time, each chunk appearing in the recording at its end time.
    The points since the last chunk are drawn as the `tail` (live, it grows with every
    point); the recording holds only its final content, shown from the last chunk on.
    """

    def __init__(
        self,
        meshcat: Meshcat,
        path: str,
        rgba: Rgba,
        line_width: float = 3.0,
        chunk_s: float = 0.25,
        min_spacing: float = 5e-4,
    ) -> None:
        self._meshcat, self._path, self._rgba = meshcat, path, rgba
        self._line_width, self._chunk_s, self._min_spacing = line_width, chunk_s, min_spacing
        self.Reset()

    def Reset(self) -> None:
        """Removes the drawn trail (a new run starts)."""
        self._meshcat.Delete(self._path)
        self._pending: list[np.ndarray] = []
        self._last: np.ndarray | None = None
        self._chunk_start = 0.0
        self._count = 0

    def Append(self, p_W: np.ndarray, t: float) -> None:
        """Adds the point p_W (m, world) reached at time t (s)."""
        p_W = np.asarray(p_W, float).copy()
        moved = self._last is None or np.linalg.norm(p_W - self._last) >= self._min_spacing
        if moved:
            if not self._pending and self._last is not None:
                self._pending.append(self._last)
            self._pending.append(p_W)
            self._last = p_W
        if t - self._chunk_start >= self._chunk_s:
            self._Flush(t)
        elif moved and len(self._pending) >= 2:
            tail = f"{self._path}/tail"
            self._meshcat.SetLine(tail, np.array(self._pending).T, self._line_width, self._rgba)

    def _Flush(self, t: float) -> None:
        """Draws the gathered points as one chunk that appears at time t."""
        if self._chunk_s > 0:  # with chunks of 0 s every point flushes: there is no tail
            tail = f"{self._path}/tail"
            # Shown only from the latest chunk on: its earlier "shown" keyframe is
            # overwritten.
            SetRecordedVisibility(self._meshcat, tail, False, self._chunk_start)
            SetRecordedVisibility(self._meshcat, tail, True, t)
            self._meshcat.Delete(f"{tail}/<object>")
        self._chunk_start = t
        if len(self._pending) < 2:
            return
        chunk = f"{self._path}/{self._count:04d}"
        self._meshcat.SetLine(chunk, np.array(self._pending).T, self._line_width, self._rgba)
        AppearAt(self._meshcat, chunk, t)
        self._count += 1
        self._pending = []


class ArmFramePoses:
    """Poses in world of frames of a plant from one arm's joint positions (its own
    context, so it may share a plant with other users). Overlays publishing at the same
    time ask with the same q: the context keeps its kinematics for it."""

    def __init__(self, plant: MultibodyPlant, arm: ModelInstanceIndex) -> None:
        self.plant = plant
        self._arm = arm
        self._context = plant.CreateDefaultContext()
        self._q: np.ndarray | None = None

    def num_positions(self) -> int:
        return self.plant.num_positions(self._arm)

    def Poses(self, q: np.ndarray, frames: list[Frame]) -> list[RigidTransform]:
        """X_WF of each frame with the arm at q (rad)."""
        if self._q is None or not np.array_equal(q, self._q):
            self.plant.SetPositions(self._context, self._arm, q)
            self._q = np.array(q)
        return [frame.CalcPoseInWorld(self._context) for frame in frames]


def DrawTriad(
    meshcat: Meshcat, path: str, length: float = 0.05, radius: float = 0.002, opacity: float = 1.0
) -> None:
    """Red, green, blue cylinders along the x, y, z axes of the frame at `path`."""
    for axis, rgb in enumerate(((1.0, 0.0, 0.0), (0.0, 0.8, 0.0), (0.0, 0.0, 1.0))):
        direction = np.eye(3)[axis]
        # A cylinder's axis is its z: turn z onto the axis, centred at half its length.
        R = RotationMatrix.MakeFromOneVector(direction, 2)
        name = f"{path}/{'xyz'[axis]}"
        meshcat.SetObject(name, Cylinder(radius, length), Rgba(*rgb, opacity))
        meshcat.SetTransform(name, RigidTransform(R, direction * length / 2))


def DrawPoint(meshcat: Meshcat, path: str, p: np.ndarray, radius: float, rgba: Rgba) -> None:
    """A sphere of `radius` (m) at p (m, in the frame of the parent path)."""
    meshcat.SetObject(path, Sphere(radius), rgba)
    meshcat.SetTransform(path, RigidTransform(np.asarray(p, float)))


def FrustumSegments(
    width: int, height: int, fx: float, fy: float, cx: float, cy: float, depth: float
) -> tuple[np.ndarray, np.ndarray]:
    """(start, end), each 3 x 8, of the edges of a pinhole camera's viewing pyramid up to
    `depth` (m) in the camera frame C (x right, y down, z forward; OpenCV pixels)."""
    # The image's outer pixel edges lie half a pixel beyond the outer pixel centres.
    left, top, right, bottom = -0.5, -0.5, width - 0.5, height - 0.5
    corners = [
        np.array([(u - cx) / fx, (v - cy) / fy, 1.0]) * depth
        for u, v in ((left, top), (right, top), (right, bottom), (left, bottom))
    ]
    start = [np.zeros(3)] * 4 + corners
    end = corners + corners[1:] + corners[:1]
    return np.array(start).T, np.array(end).T


def AimCamera(
    meshcat: Meshcat, points: np.ndarray, view_direction: np.ndarray, margin: float = 1.6
) -> tuple[np.ndarray, np.ndarray]:
    """Places Meshcat's camera to look at the centre of `points` (N x 3, m, world) from
    `view_direction` (from the target towards the camera), far enough to see them all
    (Meshcat's 75 deg vertical field of view, with `margin`); returns (camera, target)."""
    points = np.atleast_2d(points)
    target = 0.5 * (points.min(axis=0) + points.max(axis=0))
    radius = max(float(np.max(np.linalg.norm(points - target, axis=1))), 0.05)
    distance = margin * radius / np.tan(np.radians(75.0 / 2))
    direction = np.asarray(view_direction, float)
    direction /= np.linalg.norm(direction)
    meshcat.SetCameraPose(target + distance * direction, target)
    return target + distance * direction, target


def ViewFromBeyond(points: np.ndarray, p_WBase: np.ndarray, elevation: float = 0.8) -> np.ndarray:
    """A view direction (world) from beyond `points` as seen from a robot base at p_WBase,
    raised by `elevation` (rise over run): the robot and its work face the camera."""
    outward = np.mean(np.atleast_2d(points), axis=0) - np.asarray(p_WBase, float)
    outward[2] = 0.0
    norm = np.linalg.norm(outward)
    outward = outward / norm if norm > 1e-9 else np.array([1.0, 0.0, 0.0])
    return outward + [0.0, 0.0, elevation]
