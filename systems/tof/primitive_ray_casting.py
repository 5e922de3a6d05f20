"""Analytic ray casting of the ToF cones against SceneGraph's primitive shapes.

A reading casts the cone rays of six sensors (6 x 19 rays, each a segment of max_range).
Sphere tracing (tof_tool_sensor_math.RayCaster) needs a distance query per step and ray,
and a hose of 60-100 capsules makes those steps short. Here every Box, Capsule, Cylinder,
HalfSpace and Sphere of the proximity role is intersected in closed form, each sensor's
rays with the shapes that pass a broadphase: the ball about the shape's origin that holds
it against the sensor's cone, truncated at max_range. The shapes are read from the
SceneGraph inspector once, at the first reading and whenever the proximity geometry
changes: the poses of those anchored to the world (the hose, its brackets) then, those on
other frames (the robot, the cell) from the QueryObject at each reading. Other shapes
(Mesh, Convex, Ellipsoid) are left to sphere tracing (SceneRayCaster). A ray starting
inside a shape hits at 0, as sphere tracing does.

The casting runs in a compiled kernel (csrc/cone_casting.c, CastCones, built by the
install): in numpy, vectorised over all sensors and shapes of a kind, a reading cost about
0.2 ms of per-call overhead, for work of a few microseconds. FirstHits is the numpy
reference of its intersections, which tests/test_tof_ray_casting.py holds it to.
"""

from __future__ import annotations

import copy
import math
from collections.abc import Callable
from typing import NamedTuple

import numpy as np
from pydrake.geometry import (
    Box,
    Capsule,
    Cylinder,
    FrameId,
    GeometryId,
    HalfSpace,
    QueryObject,
    Role,
    SceneGraphInspector,
    Sphere,
)
from pydrake.math import RigidTransform

from guidedarm.systems.tof._cone_casting import CastCones
from guidedarm.systems.tof.tof_tool_sensor_math import RayCaster

# Shapes intersected in closed form, in this order in a ShapeTable.
SUPPORTED = (Box, Capsule, Cylinder, HalfSpace, Sphere)
_KINDS = ("box", "capsule", "cylinder", "halfspace", "sphere")
_IDENTITY = np.eye(3, 4)


def ShapeSizes(shape) -> tuple[str, list[float], float]:
    """(kind, sizes, radius) of a SUPPORTED shape. Sizes: box half sizes; capsule or
    cylinder (radius, half length, 0) along G's z; sphere (radius, 0, 0); half-space (G's
    z <= 0) none. Radius: of the smallest ball about G's origin holding the shape (m)."""
    if isinstance(shape, Box):
        half = [shape.width() / 2, shape.depth() / 2, shape.height() / 2]
        return "box", half, float(np.linalg.norm(half))
    if isinstance(shape, Capsule | Cylinder):
        r, h = shape.radius(), shape.length() / 2
        if isinstance(shape, Capsule):
            return "capsule", [r, h, 0.0], h + r
        return "cylinder", [r, h, 0.0], float(np.hypot(r, h))
    if isinstance(shape, Sphere):
        return "sphere", [shape.radius(), 0.0, 0.0], shape.radius()
    return "halfspace", [0.0, 0.0, 0.0], np.inf


class ShapeTable:
    """Shapes sorted by kind, as the compiled kernel (csrc/cone_casting.c) reads them, all
    float64: kinds (M; the index in _KINDS), frames (M; the index of the shape's frame F in
    the caster's moving frames, -1 for the world), X_FG (M, 12: G in F, 3 x 4 row-major),
    sizes (M, 3) and rho (M: the radius of a ball about G's origin holding the shape, plus
    the broadphase's margin of 1 um)."""

    def __init__(self, shapes: list[tuple[object, RigidTransform, int]]) -> None:
        """shapes: (shape, X_FG, frame index), frame index -1 for the world."""
        rows = sorted(
            ((*ShapeSizes(shape), X, frame) for shape, X, frame in shapes),
            key=lambda row: _KINDS.index(row[0]),
        )
        self.kinds = np.array([_KINDS.index(row[0]) for row in rows], float)
        self.frames = np.array([row[4] for row in rows], float)
        self.X_FG = np.array([row[3].GetAsMatrix34() for row in rows], float).reshape(-1, 12)
        self.sizes = np.array([row[1] for row in rows], float).reshape(-1, 3)
        self.rho = np.array([row[2] for row in rows], float) + 1e-6

    def Cast(
        self,
        X_WF: np.ndarray,
        p_FS: np.ndarray,
        u_F: np.ndarray,
        z_F: np.ndarray,
        half_angle: float,
        reach: float,
        X_WM: np.ndarray,
    ) -> np.ndarray:
        """Nearest hit (m, inf for none within reach) of each of N sensors: origins p_FS
        (N, 3), axes z_F (N, 3) and K unit rays u_F (N, K, 3), all within half_angle of
        the axis, in a frame F at X_WF (3 x 4); X_WM (F, 3, 4): the moving frames in W. All
        contiguous float64 (csrc/cone_casting.c's CastCones)."""
        ranges = np.empty(len(p_FS))
        CastCones(
            X_WF,
            p_FS,
            u_F,
            z_F,
            half_angle,
            reach,
            self.kinds,
            self.frames,
            self.X_FG,
            self.sizes,
            self.rho,
            X_WM,
            ranges,
        )
        return ranges


def FirstHits(
    o: np.ndarray, u: np.ndarray, ou: np.ndarray, kind: str, sizes: np.ndarray
) -> np.ndarray:
    """Distance (C, N, K) along K unit rays from each of N origins to each of C shapes'
    surfaces (m; 0 from inside, inf on a miss or behind the origin): o (3, C, N, 1) and
    u (3, C, N, K), coordinates first, in each shape's frame G, and their dot products
    ou (C, N, K); sizes (C, 3) as ShapeSizes gives them. Call within
    np.errstate(all="ignore"): a miss is a NaN square root or a division by zero, and a
    NaN compares false."""
    if kind == "box":
        return _Box(o, u, sizes.T[:, :, None, None])
    ox, oy, oz = o
    ux, uy, uz = u
    if kind == "halfspace":
        return _HalfSpace(oz, uz)
    radius2 = sizes[:, 0, None, None] ** 2
    rho2 = ox * ox + oy * oy
    if kind == "sphere":
        c = rho2 + oz * oz - radius2
        return np.where(c <= 0, 0.0, _SphereEntry(ou, c))
    half = sizes[:, 1, None, None]
    # The infinite cylinder x^2 + y^2 = r^2: a t^2 + 2 b t + c = 0, with -a at hand.
    minus_a = uz * uz - 1.0
    b = ou - oz * uz
    t = (b + np.sqrt(b * b + minus_a * (rho2 - radius2))) / minus_a
    z = oz + t * uz
    side = np.where((t >= 0) & (np.abs(z) <= half), t, np.inf)
    if kind == "cylinder":
        within = np.abs(oz) <= half
        # Only the flat end facing an origin beyond it can be entered.
        end = np.sign(oz) * half
        t_end = (end - oz) / uz
        x, y = ox + t_end * ux, oy + t_end * uy
        cap = np.where((t_end >= 0) & (x * x + y * y <= radius2) & ~within, t_end, np.inf)
        inside = (rho2 <= radius2) & within
        return np.where(inside, 0.0, np.fmin(side, cap))
    # Capsule: past the side's span, the end sphere on that side (a ray that misses the
    # infinite cylinder misses both spheres inside it).
    centre = np.where(z > 0, half, -half)
    beyond = oz - centre
    end = _SphereEntry(ou - uz * centre, rho2 + beyond * beyond - radius2)
    inside = rho2 + np.maximum(np.abs(oz) - half, 0.0) ** 2 <= radius2
    return np.where(inside, 0.0, np.fmin(side, end))


def _SphereEntry(b: np.ndarray, c: np.ndarray) -> np.ndarray:
    """First t >= 0 with t^2 + 2 b t + c = 0 for an origin outside the sphere (c > 0; a
    unit ray entering it), inf on a miss."""
    t = -(b + np.sqrt(b * b - c))
    return np.where(t >= 0, t, np.inf)


def _Box(o: np.ndarray, u: np.ndarray, half: np.ndarray) -> np.ndarray:
    """Slab test of boxes centred at G's origin with half sizes `half` (3, C, 1, 1)."""
    inverse = 1.0 / u
    t1, t2 = (-half - o) * inverse, (half - o) * inverse
    near = np.maximum(np.fmin(t1, t2).max(axis=0), 0.0)
    far = np.fmax(t1, t2).min(axis=0)
    return np.where(far >= near, near, np.inf)


def _HalfSpace(oz: np.ndarray, uz: np.ndarray) -> np.ndarray:
    """The half-space z <= 0 of G."""
    return np.where(oz <= 0, 0.0, np.where(uz < 0, -oz / uz, np.inf))


def ProximityShapes(
    inspector: SceneGraphInspector, ignored: frozenset[GeometryId]
) -> tuple[list[GeometryId], list[GeometryId]]:
    """Proximity geometries not in `ignored`: (SUPPORTED shapes, other shapes)."""
    supported, other = [], []
    for g in inspector.GetAllGeometryIds(Role.kProximity):
        if g not in ignored:
            (supported if isinstance(inspector.GetShape(g), SUPPORTED) else other).append(g)
    return supported, other


class SensorMount(NamedTuple):
    """Sensors fixed on one SceneGraph frame F (of their body, or of a body welded to it):
    F's id and the sensors' poses X_FS in it."""

    frame: FrameId
    X_FS: tuple[RigidTransform, ...]


class SceneRayCaster:
    """Nearest returns of cone rays against a SceneGraph scene: the primitive shapes in
    closed form (the compiled CastCones), any other shape by sphere tracing (RayCaster),
    the geometries in `ignored` not at all. Ranges in m, poses in the world W. Sensors on
    a `mount` are read from their frame's pose alone (MountedRanges), their rays in F
    computed once."""

    def __init__(
        self,
        rays_S: np.ndarray,
        max_range: float,
        ignored: frozenset[GeometryId],
        mount: SensorMount | None = None,
    ) -> None:
        self.rays_S = rays_S
        self.max_range = max_range
        self.ignored = ignored
        self.mount = mount
        self._half_angle = math.acos(min(1.0, rays_S[:, 2].min()))
        if mount is not None:
            X_FS = np.array([X.GetAsMatrix34() for X in mount.X_FS])
            # Contiguous, as the kernel reads them.
            self._p_FS = X_FS[:, :, 3].copy()
            self._u_F = rays_S @ X_FS[:, :, :3].transpose(0, 2, 1)  # (N, K, 3)
            self._z_F = X_FS[:, :, 2].copy()
        self._version = None
        self._table = ShapeTable([])
        self._frames: list = []
        self._tracer: RayCaster | None = None

    def Ranges(self, query: QueryObject, poses: list[RigidTransform]) -> np.ndarray:
        """Nearest return within each sensor's cone (m), or inf when nothing is in range."""
        X_WS = np.array([X.GetAsMatrix34() for X in poses])
        R_WS = X_WS[:, :, :3]
        u_W = self.rays_S @ R_WS.transpose(0, 2, 1)
        p_WS, z_WS = X_WS[:, :, 3].copy(), R_WS[:, :, 2].copy()
        return self._Cast(query, _IDENTITY, p_WS, u_W, z_WS, lambda: poses)

    def MountedPoses(self, query: QueryObject) -> list[RigidTransform]:
        """X_WS of the mount's sensors."""
        X_WF = query.GetPoseInWorld(self.mount.frame)
        return [X_WF @ X_FS for X_FS in self.mount.X_FS]

    def MountedRanges(self, query: QueryObject) -> np.ndarray:
        """Ranges(query, MountedPoses(query)), from one pose query."""
        # Row-major, as the kernel reads it (pydrake's matrices are column-major).
        X_WF = np.ascontiguousarray(query.GetPoseInWorld(self.mount.frame).GetAsMatrix34())
        return self._Cast(
            query, X_WF, self._p_FS, self._u_F, self._z_F, lambda: self.MountedPoses(query)
        )

    def _Cast(
        self,
        query: QueryObject,
        X_WF: np.ndarray,
        p_FS: np.ndarray,
        u_F: np.ndarray,
        z_F: np.ndarray,
        poses: Callable[[], list[RigidTransform]],
    ) -> np.ndarray:
        """Ranges of sensors at p_FS (N, 3) with axes z_FS (N, 3) and rays u_F (N, K, 3) in
        a frame F at X_WF (3 x 4); poses() gives their X_WS for sphere tracing."""
        self._Refresh(query.inspector())
        X_WM = np.array([query.GetPoseInWorld(f).GetAsMatrix34() for f in self._frames], float)
        ranges = self._table.Cast(X_WF, p_FS, u_F, z_F, self._half_angle, self.max_range, X_WM)
        if self._tracer is not None:
            traced = [self._tracer.Range(query, X_WS) for X_WS in poses()]
            ranges = np.minimum(ranges, traced)
        return ranges

    def _Refresh(self, inspector: SceneGraphInspector) -> None:
        """Reads the shapes once per proximity geometry version."""
        version = inspector.geometry_version()
        if self._version is not None and version.IsSameAs(self._version, Role.kProximity):
            return
        supported, other = ProximityShapes(inspector, self.ignored)
        world = inspector.world_frame_id()
        frames: dict = {}
        shapes = []
        for g in supported:
            frame = inspector.GetFrameId(g)
            index = -1 if frame == world else frames.setdefault(frame, len(frames))
            shapes.append((inspector.GetShape(g), inspector.GetPoseInFrame(g), index))
        self._table = ShapeTable(shapes)
        self._frames = list(frames)
        self._tracer = None
        if other:
            self._tracer = RayCaster(self.rays_S, self.max_range, self.ignored | set(supported))
        self._version = copy.copy(version)
