"""Analytic ray casting of the ToF cones against SceneGraph's primitive shapes.

A reading casts the cone rays of six sensors (6 x 19 rays, each a segment of max_range).
Sphere tracing (tof_tool_sensor_math.RayCaster) needs a distance query per step and ray,
and a hose of 60-100 capsules makes those steps short. Here every Box, Capsule, Cylinder,
HalfSpace and Sphere of the proximity role is intersected in closed form, vectorised over
all (sensor, shape) pairs that pass a broadphase: the axis-aligned box of each sensor's rays
against each shape's box. The shapes are read from the SceneGraph inspector once, at the
first reading and whenever the proximity geometry changes: the poses of those anchored to
the world (the hose, its brackets) then, those on other frames (the robot, the cell) from
the QueryObject at each reading, all in one vectorised step. Other shapes (Mesh, Convex,
Ellipsoid) are left to sphere tracing (SceneRayCaster). A ray starting inside a shape hits
at 0, as sphere tracing does. Numpy per-call overhead, not arithmetic, is the cost here,
so each step handles all shapes of a kind at once.
"""

from __future__ import annotations

import copy

import numpy as np
from pydrake.geometry import (
    Box,
    Capsule,
    Cylinder,
    GeometryId,
    HalfSpace,
    QueryObject,
    Role,
    SceneGraphInspector,
    Sphere,
)
from pydrake.math import RigidTransform

from guidedarm.systems.tof.tof_tool_sensor_math import RayCaster

# Shapes intersected in closed form, in this order in a ShapeTable.
SUPPORTED = (Box, Capsule, Cylinder, HalfSpace, Sphere)
_KINDS = ("box", "capsule", "cylinder", "halfspace", "sphere")


def ShapeSizes(shape) -> tuple[str, list[float], list[float]]:
    """(kind, sizes, half extents in G) of a SUPPORTED shape. Sizes: box half sizes;
    capsule or cylinder (radius, half length, 0) along G's z; sphere (radius, 0, 0);
    half-space (G's z <= 0) none. Half extents: of a box in G holding the shape (m)."""
    if isinstance(shape, Box):
        half = [shape.width() / 2, shape.depth() / 2, shape.height() / 2]
        return "box", half, half
    if isinstance(shape, Capsule | Cylinder):
        kind = "capsule" if isinstance(shape, Capsule) else "cylinder"
        r, h = shape.radius(), shape.length() / 2
        return kind, [r, h, 0.0], [r, r, h + r if kind == "capsule" else h]
    if isinstance(shape, Sphere):
        return "sphere", [shape.radius(), 0.0, 0.0], [shape.radius()] * 3
    return "halfspace", [0.0, 0.0, 0.0], [np.inf] * 3


class ShapeTable:
    """Shapes sorted by kind: frames G in W (R (N, 3, 3), p (N, 3)), sizes (N, 3) and
    bounds (N, 2, 3), axis-aligned boxes in W. Shapes on moving frames F keep X_FG and
    take X_WF at each Pose()."""

    def __init__(self, shapes: list[tuple[object, RigidTransform, int]]) -> None:
        """shapes: (shape, X_FG, frame index), frame index -1 for the world."""
        rows = sorted(
            ((*ShapeSizes(shape), X, frame) for shape, X, frame in shapes),
            key=lambda row: _KINDS.index(row[0]),
        )
        kinds = [row[0] for row in rows]
        self.slices = {
            kind: slice(kinds.index(kind), len(kinds) - kinds[::-1].index(kind))
            for kind in _KINDS
            if kind in kinds
        }
        self.R = np.array([row[3].rotation().matrix() for row in rows]).reshape(-1, 3, 3)
        self.p = np.array([row[3].translation() for row in rows]).reshape(-1, 3)
        self.sizes = np.array([row[1] for row in rows], float).reshape(-1, 3)
        self._extent_G = np.array([row[2] for row in rows], float).reshape(-1, 3)
        frame = np.array([row[4] for row in rows], int)
        self._moving = np.flatnonzero(frame >= 0)
        self._frame = frame[self._moving]
        self._R_FG, self._p_FG = self.R[self._moving], self.p[self._moving]
        self._bounded = np.isfinite(self._extent_G[:, 0])
        self.bounds = np.stack([np.full_like(self.p, -np.inf), np.full_like(self.p, np.inf)], 1)
        self._Bound(np.flatnonzero(self._bounded))

    def Pose(self, R_WF: np.ndarray, p_WF: np.ndarray) -> None:
        """Poses the shapes on moving frames from their frames' poses in W."""
        if len(self._moving) == 0:
            return
        R = R_WF[self._frame]
        self.R[self._moving] = R @ self._R_FG
        self.p[self._moving] = p_WF[self._frame] + np.einsum("nij,nj->ni", R, self._p_FG)
        self._Bound(self._moving[self._bounded[self._moving]])

    def _Bound(self, index: np.ndarray) -> None:
        extent = np.einsum("nij,nj->ni", np.abs(self.R[index]), self._extent_G[index])
        self.bounds[index, 0] = self.p[index] - extent
        self.bounds[index, 1] = self.p[index] + extent


def FirstHits(o: np.ndarray, u: np.ndarray, kind: str, sizes: np.ndarray) -> np.ndarray:
    """Distance (P, K) along each of K unit rays from each of P origins to a shape's surface
    (m; 0 from inside, inf on a miss or behind the origin): o (P, 3) and u (P, K, 3) in the
    shape's frame G, sizes (P, 3) as Primitives holds them. Call within
    np.errstate(all="ignore"): a miss is a NaN square root or a division by zero, and a
    NaN compares false."""
    if kind == "box":
        return _Box(o[:, None, :], u, sizes[:, None, :])
    if kind == "halfspace":
        return _HalfSpace(o[:, 2:3], u[..., 2])
    ou = np.einsum("pj,pkj->pk", o, u)
    radius2 = (sizes[:, 0] ** 2)[:, None]
    if kind == "sphere":
        return _SphereEntry(ou, (np.sum(o * o, axis=1))[:, None] - radius2)
    half = sizes[:, 1:2]
    oz, uz = o[:, 2:3], u[..., 2]
    rho2 = (o[:, 0] ** 2 + o[:, 1] ** 2)[:, None]
    # The infinite cylinder x^2 + y^2 = r^2: a t^2 + 2 b t + c = 0.
    a = 1.0 - uz * uz
    b = ou - oz * uz
    t = (-b - np.sqrt(b * b - a * (rho2 - radius2))) / a
    z = oz + t * uz
    side = np.where((t >= 0) & (np.abs(z) <= half), t, np.inf)
    within = np.abs(oz) <= half
    if kind == "cylinder":
        # Only the flat end facing an origin beyond it can be entered.
        end = np.sign(oz) * half
        t_end = (end - oz) / uz
        x, y = o[:, 0:1] + t_end * u[..., 0], o[:, 1:2] + t_end * u[..., 1]
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
    """First t >= 0 with t^2 + 2 b t + c = 0 (a unit ray entering a sphere; c <= 0: the
    origin is inside, t = 0), inf on a miss."""
    t = -b - np.sqrt(b * b - c)
    return np.where(c <= 0, 0.0, np.where(t >= 0, t, np.inf))


def _Box(o: np.ndarray, u: np.ndarray, half: np.ndarray) -> np.ndarray:
    """Slab test of a box centred at G's origin with half sizes `half`."""
    inverse = 1.0 / u
    t1, t2 = (-half - o) * inverse, (half - o) * inverse
    near = np.maximum(np.max(np.fmin(t1, t2), axis=-1), 0.0)
    far = np.min(np.fmax(t1, t2), axis=-1)
    return np.where(far >= near, near, np.inf)


def _HalfSpace(oz: np.ndarray, uz: np.ndarray) -> np.ndarray:
    """The half-space z <= 0 of G."""
    return np.where(oz <= 0, 0.0, np.where(uz < 0, -oz / uz, np.inf))


def CastCones(
    X_WS: tuple[np.ndarray, np.ndarray],
    rays_S: np.ndarray,
    cone_bounds: np.ndarray,
    table: ShapeTable,
) -> np.ndarray:
    """Nearest hit (m, inf for none) of each sensor's cone rays against the table's shapes.
    X_WS: rotations (N, 3, 3) and origins (N, 3) of N sensors; rays_S (K, 3) unit
    directions in a sensor frame; cone_bounds (N, 2, 3) each sensor's ray box, tested
    against each shape's box before any intersection."""
    R_WS, p_WS = X_WS
    best = np.full(len(p_WS), np.inf)
    overlap = np.all(
        (table.bounds[:, None, 0] <= cone_bounds[None, :, 1])
        & (cone_bounds[None, :, 0] <= table.bounds[:, None, 1]),
        axis=2,
    )
    shapes, sensors = np.nonzero(overlap)  # sorted by shape, so by kind
    for kind, part in table.slices.items():
        lo, hi = np.searchsorted(shapes, [part.start, part.stop])
        if lo == hi:
            continue
        shape, sensor = shapes[lo:hi], sensors[lo:hi]
        # Each pair's origin and rays in the shape's frame G.
        R_GW = table.R[shape].transpose(0, 2, 1)
        o = np.einsum("pij,pj->pi", R_GW, p_WS[sensor] - table.p[shape])
        u = (R_GW @ R_WS[sensor] @ rays_S.T).transpose(0, 2, 1)
        with np.errstate(all="ignore"):
            hits = FirstHits(o, u, kind, table.sizes[shape]).min(axis=1)
        np.minimum.at(best, sensor, hits)
    return best


def ProximityShapes(
    inspector: SceneGraphInspector, ignored: frozenset[GeometryId]
) -> tuple[list[GeometryId], list[GeometryId]]:
    """Proximity geometries not in `ignored`: (SUPPORTED shapes, other shapes)."""
    supported, other = [], []
    for g in inspector.GetAllGeometryIds(Role.kProximity):
        if g not in ignored:
            (supported if isinstance(inspector.GetShape(g), SUPPORTED) else other).append(g)
    return supported, other


class SceneRayCaster:
    """Nearest returns of cone rays against a SceneGraph scene: the primitive shapes in
    closed form (CastCones), any other shape by sphere tracing (RayCaster), the geometries
    in `ignored` not at all. Ranges in m, poses in the world W. Its table of shapes is
    rewritten at each reading: one caster serves one thread."""

    def __init__(
        self, rays_S: np.ndarray, max_range: float, ignored: frozenset[GeometryId]
    ) -> None:
        self.rays_S = rays_S
        self.max_range = max_range
        self.ignored = ignored
        self._version = None
        self._table = ShapeTable([])
        self._frames: list = []
        self._tracer: RayCaster | None = None

    def Ranges(self, query: QueryObject, poses: list[RigidTransform]) -> np.ndarray:
        """Nearest return within each sensor's cone (m), or inf when nothing is in range."""
        self._Refresh(query.inspector())
        if self._frames:
            X_WF = np.array([query.GetPoseInWorld(f).GetAsMatrix34() for f in self._frames])
            self._table.Pose(X_WF[:, :, :3], X_WF[:, :, 3])
        X_WS = np.array([X.GetAsMatrix34() for X in poses])
        R_WS, p_WS = X_WS[:, :, :3], X_WS[:, :, 3]
        # A sensor's rays lie in the box of its origin and their far ends.
        ends = p_WS[:, None, :] + self.max_range * (R_WS @ self.rays_S.T).transpose(0, 2, 1)
        lower = np.minimum(ends.min(axis=1), p_WS)
        cone_bounds = np.stack([lower, np.maximum(ends.max(axis=1), p_WS)], axis=1)
        ranges = CastCones((R_WS, p_WS), self.rays_S, cone_bounds, self._table)
        ranges[ranges > self.max_range] = np.inf
        if self._tracer is not None:
            traced = [self._tracer.Range(query, X_WS) for X_WS in poses]
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
