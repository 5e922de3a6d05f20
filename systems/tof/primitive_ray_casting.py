"""Analytic ray casting of the ToF cones against SceneGraph's primitive shapes.

A reading casts the cone rays of six sensors (6 x 19 rays, each a segment of max_range).
Sphere tracing (tof_tool_sensor_math.RayCaster) needs a distance query per step and ray,
and a hose of 60-100 capsules makes those steps short. Here every Box, Capsule, Cylinder,
HalfSpace and Sphere of the proximity role is intersected in closed form, vectorised over
all (ray, shape) pairs that pass a broadphase: the axis-aligned box of each sensor's rays
against each shape's box. Shapes anchored to the world (the hose, its brackets) are read
from the SceneGraph inspector once, at the first reading and whenever the geometry version
changes; shapes on moving frames (the robot, the cell) take their poses from the
QueryObject at each reading. Other shapes (Mesh, Convex, Ellipsoid) are left to sphere
tracing (SceneRayCaster). A ray starting inside a shape hits at 0, as sphere tracing does.
"""

from __future__ import annotations

import copy
from dataclasses import dataclass, field

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

# Shapes intersected in closed form; each is stored as a frame (R_WG, p_WG) and sizes.
SUPPORTED = (Box, Capsule, Cylinder, HalfSpace, Sphere)
_KINDS = ("box", "capsule", "cylinder", "halfspace", "sphere")


@dataclass
class Primitives:
    """Shapes of one kind: rotations R (N, 3, 3) and origins p (N, 3) of their frames G in
    W, and sizes (N, 3): box half sizes; capsule or cylinder (radius, half length, 0);
    sphere (radius, 0, 0); half-space unused (G's z = 0 plane, outward +z)."""

    kind: str
    R: np.ndarray = field(default_factory=lambda: np.zeros((0, 3, 3)))
    p: np.ndarray = field(default_factory=lambda: np.zeros((0, 3)))
    sizes: np.ndarray = field(default_factory=lambda: np.zeros((0, 3)))

    def Bounds(self) -> np.ndarray:
        """Axis-aligned boxes (N, 2, 3) in W holding each shape (m)."""
        if self.kind == "halfspace":
            lo = np.full_like(self.p, -np.inf)
            return np.stack([lo, -lo], axis=1)
        if self.kind == "box":
            extent = np.einsum("nij,nj->ni", np.abs(self.R), self.sizes)
        elif self.kind == "sphere":
            extent = np.repeat(self.sizes[:, :1], 3, axis=1)
        else:  # capsule, cylinder: the axis segment grown by the radius
            extent = np.abs(self.R[:, :, 2]) * self.sizes[:, 1:2] + self.sizes[:, :1]
        return np.stack([self.p - extent, self.p + extent], axis=1)


def CollectPrimitives(
    shapes: list[tuple[object, RigidTransform]], frames: list[int] | None = None
) -> dict[str, tuple[Primitives, np.ndarray]]:
    """Primitives by kind from (shape, X_FG) pairs of SUPPORTED shapes, each with the index
    of its frame F in `frames` order (all 0 when None)."""
    rows: dict[str, list] = {kind: [] for kind in _KINDS}
    for (shape, X), frame in zip(shapes, frames or [0] * len(shapes), strict=True):
        if isinstance(shape, Box):
            kind, sizes = "box", [shape.width() / 2, shape.depth() / 2, shape.height() / 2]
        elif isinstance(shape, Capsule | Cylinder):
            kind = "capsule" if isinstance(shape, Capsule) else "cylinder"
            sizes = [shape.radius(), shape.length() / 2, 0.0]
        elif isinstance(shape, Sphere):
            kind, sizes = "sphere", [shape.radius(), 0.0, 0.0]
        else:
            kind, sizes = "halfspace", [0.0, 0.0, 0.0]
        rows[kind].append((X.rotation().matrix(), X.translation(), sizes, frame))
    return {
        kind: (
            Primitives(
                kind,
                np.array([r[0] for r in items]).reshape(-1, 3, 3),
                np.array([r[1] for r in items]).reshape(-1, 3),
                np.array([r[2] for r in items], float).reshape(-1, 3),
            ),
            np.array([r[3] for r in items], int),
        )
        for kind, items in rows.items()
        if items
    }


def Posed(primitives: Primitives, frame: np.ndarray, R_WF: np.ndarray, p_WF: np.ndarray):
    """The primitives given in their frames F (indices `frame` into R_WF, p_WF), in W."""
    R = R_WF[frame]
    return Primitives(
        primitives.kind,
        R @ primitives.R,
        p_WF[frame] + np.einsum("nij,nj->ni", R, primitives.p),
        primitives.sizes,
    )


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
    shapes: list[tuple[Primitives, np.ndarray]],
) -> np.ndarray:
    """Nearest hit (m, inf for none) of each sensor's cone rays against (primitives, their
    bounds) pairs. X_WS: rotations (N, 3, 3) and origins (N, 3) of N sensors; rays_S (K, 3)
    unit directions in a sensor frame; cone_bounds (N, 2, 3) each sensor's ray box, tested
    against each shape's box before any intersection."""
    R_WS, p_WS = X_WS
    best = np.full(len(p_WS), np.inf)
    for primitives, bounds in shapes:
        overlap = np.all(
            (cone_bounds[:, None, 0] <= bounds[None, :, 1])
            & (bounds[None, :, 0] <= cone_bounds[:, None, 1]),
            axis=2,
        )
        sensor, shape = np.nonzero(overlap)
        if len(sensor) == 0:
            continue
        # Each pair's origin and rays in the shape's frame G.
        R_GW = primitives.R[shape].transpose(0, 2, 1)
        o = np.einsum("pij,pj->pi", R_GW, p_WS[sensor] - primitives.p[shape])
        u = (R_GW @ R_WS[sensor] @ rays_S.T).transpose(0, 2, 1)
        with np.errstate(all="ignore"):
            hits = FirstHits(o, u, primitives.kind, primitives.sizes[shape]).min(axis=1)
        np.minimum.at(best, sensor, hits)
    return best


def ProximityShapes(
    inspector: SceneGraphInspector, ignored: frozenset[GeometryId]
) -> tuple[list[GeometryId], list[GeometryId], list[GeometryId]]:
    """Proximity geometries not in `ignored`, split into (anchored supported shapes, moving
    supported shapes, unsupported shapes)."""
    world = inspector.world_frame_id()
    anchored, moving, other = [], [], []
    for g in inspector.GetAllGeometryIds(Role.kProximity):
        if g in ignored:
            continue
        if not isinstance(inspector.GetShape(g), SUPPORTED):
            other.append(g)
        elif inspector.GetFrameId(g) == world:
            anchored.append(g)
        else:
            moving.append(g)
    return anchored, moving, other


def _Merge(shapes: list[tuple[Primitives, np.ndarray]]) -> list[tuple[Primitives, np.ndarray]]:
    """One (primitives, bounds) pair per kind: fewer, larger vectorised intersections."""
    kinds: dict[str, list] = {}
    for primitives, bounds in shapes:
        kinds.setdefault(primitives.kind, []).append((primitives, bounds))
    merged = []
    for kind, items in kinds.items():
        if len(items) == 1:
            merged.append(items[0])
            continue
        parts = [p for p, _ in items]
        primitives = Primitives(
            kind,
            np.concatenate([p.R for p in parts]),
            np.concatenate([p.p for p in parts]),
            np.concatenate([p.sizes for p in parts]),
        )
        merged.append((primitives, np.concatenate([b for _, b in items])))
    return merged


class SceneRayCaster:
    """Nearest returns of cone rays against a SceneGraph scene: the primitive shapes in
    closed form (CastCones), any other shape by sphere tracing (RayCaster), the geometries
    in `ignored` not at all. Ranges in m, poses in the world W."""

    def __init__(
        self, rays_S: np.ndarray, max_range: float, ignored: frozenset[GeometryId]
    ) -> None:
        self.rays_S = rays_S
        self.max_range = max_range
        self.ignored = ignored
        self._version = None
        self._anchored: list[tuple[Primitives, np.ndarray]] = []
        # Moving shapes in their frames F: the frames, and per kind (primitives in F,
        # frame index); each frame's shapes lie within a ball (centre in F, radius).
        self._frames: list = []
        self._moving: dict[str, tuple[Primitives, np.ndarray]] = {}
        self._balls = np.zeros((0, 4))
        self._tracer: RayCaster | None = None

    def Ranges(self, query: QueryObject, poses: list[RigidTransform]) -> np.ndarray:
        """Nearest return within each sensor's cone (m), or inf when nothing is in range."""
        self._Refresh(query.inspector())
        X_WS = np.array([X.GetAsMatrix34() for X in poses])
        R_WS, p_WS = X_WS[:, :, :3], X_WS[:, :, 3]
        # A sensor's rays lie in the box of its origin and their far ends.
        ends = p_WS[:, None, :] + self.max_range * (R_WS @ self.rays_S.T).transpose(0, 2, 1)
        lower = np.minimum(ends.min(axis=1), p_WS)
        cone_bounds = np.stack([lower, np.maximum(ends.max(axis=1), p_WS)], axis=1)
        shapes = _Merge(self._anchored + self._MovingShapes(query, cone_bounds))
        ranges = CastCones((R_WS, p_WS), self.rays_S, cone_bounds, shapes)
        ranges[ranges > self.max_range] = np.inf
        if self._tracer is not None:
            traced = [self._tracer.Range(query, X_WS) for X_WS in poses]
            ranges = np.minimum(ranges, traced)
        return ranges

    def _MovingShapes(
        self, query: QueryObject, cone_bounds: np.ndarray
    ) -> list[tuple[Primitives, np.ndarray]]:
        """The moving shapes posed at the query's configuration, only of frames whose ball
        meets a sensor's cone box."""
        if not self._frames:
            return []
        X_WF = np.array([query.GetPoseInWorld(f).GetAsMatrix34() for f in self._frames])
        R_WF, p_WF = X_WF[:, :, :3], X_WF[:, :, 3]
        centres = p_WF + np.einsum("fij,fj->fi", R_WF, self._balls[:, :3])
        radius = self._balls[:, 3:]
        near = np.any(
            np.all(
                (cone_bounds[:, None, 0] <= centres[None] + radius[None])
                & (centres[None] - radius[None] <= cone_bounds[:, None, 1]),
                axis=2,
            ),
            axis=0,
        )
        shapes = []
        for primitives, frame in self._moving.values():
            keep = near[frame]
            if keep.any():
                subset = Primitives(
                    primitives.kind, primitives.R[keep], primitives.p[keep], primitives.sizes[keep]
                )
                posed = Posed(subset, frame[keep], R_WF, p_WF)
                shapes.append((posed, posed.Bounds()))
        return shapes

    def _Refresh(self, inspector: SceneGraphInspector) -> None:
        """Reads the shapes once per proximity geometry version."""
        version = inspector.geometry_version()
        if self._version is not None and version.IsSameAs(self._version, Role.kProximity):
            return
        anchored, moving, other = ProximityShapes(inspector, self.ignored)
        posed = [(inspector.GetShape(g), inspector.GetPoseInFrame(g)) for g in anchored]
        self._anchored = [(p, p.Bounds()) for p, _ in CollectPrimitives(posed).values()]
        index: dict = {}
        for g in moving:
            index.setdefault(inspector.GetFrameId(g), len(index))
        self._frames = list(index)
        in_frame = [(inspector.GetShape(g), inspector.GetPoseInFrame(g)) for g in moving]
        frames = [index[inspector.GetFrameId(g)] for g in moving]
        self._moving = CollectPrimitives(in_frame, frames)
        self._balls = np.zeros((len(self._frames), 4))
        for i in range(len(self._frames)):
            boxes = [
                p.Bounds()[frame == i] for p, frame in self._moving.values() if (frame == i).any()
            ]
            box = np.concatenate(boxes)
            lo, hi = box[:, 0].min(axis=0), box[:, 1].max(axis=0)
            # A half-space has no ball: always near.
            radius = np.linalg.norm(hi - lo) / 2 if np.all(np.isfinite(box)) else np.inf
            self._balls[i] = [*((lo + hi) / 2 if np.isfinite(radius) else np.zeros(3)), radius]
        self._tracer = None
        if other:
            skipped = self.ignored | frozenset(anchored) | frozenset(moving)
            self._tracer = RayCaster(self.rays_S, self.max_range, skipped)
        self._version = copy.copy(version)
