"""Surfaces of the cell the follower knows, and the readings they give: a reading at the
range of a known surface is not the hose.

A hose lying on the table leaves the table inside the sensors' span: a cone that misses
the hose meets the table at 40-95 mm (the tool rolled about the hose, docs/path_following.md
"Scene variants"), ranges the estimators would otherwise take for the hose. The table is a
plane of the nominal cell (world z = 0 under the hose) and the follower knows the tool's
pose X_WT from the measured joints, so it knows the range each cone would read off that
plane: a reading within `tolerance` of it is the table, and the estimators see it as a
cone without the hose (which, lying on the table, cannot be behind it).

Frames: world W, tool T, sensor S (+z the line of sight). Units: m, rad.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from pydrake.math import RigidTransform

# A surface's range is matched within this many noise standard deviations, plus the
# reading's quantisation step.
NOISE_SIGMAS = 3.0


@dataclass(frozen=True)
class KnownPlane:
    """The plane n . p = offset (m) in W, free space on the side n (unit) points to."""

    normal_W: tuple[float, float, float] = (0.0, 0.0, 1.0)
    offset: float = 0.0


def PlaneRange(p_WS: np.ndarray, axis_W: np.ndarray, cone_angle: float, plane: KnownPlane) -> float:
    """The nearest return (m) a cone of full angle cone_angle (rad) from emitter p_WS
    looking along axis_W (unit) gets from `plane`: the height over it when the cone holds
    the plane's normal, else along the cone's edge nearest to it; math.inf when the cone
    never meets the plane (it looks away, or the emitter is behind it)."""
    n = np.asarray(plane.normal_W, float)
    height = float(n @ np.asarray(p_WS, float)) - plane.offset
    return _ConeRange(height, -float(n @ np.asarray(axis_W, float)), cone_angle)


def _ConeRange(height: float, facing: float, cone_angle: float) -> float:
    """PlaneRange from the emitter's height over the plane (m) and the cosine between the
    line of sight and the plane's inward normal (facing)."""
    if height <= 0:
        return math.inf
    beta = math.acos(max(-1.0, min(1.0, facing)))
    off = max(beta - cone_angle / 2, 0.0)
    return height / math.cos(off) if off < math.pi / 2 - 1e-9 else math.inf


@dataclass(frozen=True)
class KnownSurfaces:
    """The known planes and the tool's sensors (X_TS: the six sensor frames in T; cone_angle:
    their full cone angle, rad, 0 a single ray); tolerance: how close (m) a reading must be
    to a plane's range to be that plane."""

    planes: tuple[KnownPlane, ...]
    X_TS: tuple[RigidTransform, ...]
    cone_angle: float
    tolerance: float

    def __post_init__(self) -> None:
        # The emitters and their lines of sight in T (rows), and the planes' normals
        # (columns) and offsets: Ranges takes every height and facing cosine in two
        # products per reading (it runs on every reading of a run).
        p_TS = np.array([X.translation() for X in self.X_TS])
        z_TS = np.array([X.rotation().matrix()[:, 2] for X in self.X_TS])
        normals = np.array([q.normal_W for q in self.planes], float).T
        object.__setattr__(self, "_p_TS", p_TS)
        object.__setattr__(self, "_z_TS", z_TS)
        object.__setattr__(self, "_normals", normals)
        object.__setattr__(self, "_offsets", np.array([q.offset for q in self.planes]))

    @staticmethod
    def Table(
        X_TS: tuple[RigidTransform, ...],
        cone_angle: float | None,
        noise_std: float,
        quantization: float,
    ) -> KnownSurfaces:
        """The cell's table top, world z = 0, matched within NOISE_SIGMAS noise_std plus one
        quantization step (m) of a reading."""
        return KnownSurfaces(
            (KnownPlane(),),
            tuple(X_TS),
            float(cone_angle or 0.0),
            NOISE_SIGMAS * noise_std + quantization,
        )

    def Ranges(self, X_WT: RigidTransform) -> np.ndarray:
        """(6,) the range (m) each sensor would read off the nearest known plane with the
        tool at X_WT (math.inf where none is in its cone)."""
        R_WT = X_WT.rotation().matrix()
        heights = (self._p_TS @ R_WT.T + X_WT.translation()) @ self._normals - self._offsets
        facing = -(self._z_TS @ R_WT.T) @ self._normals
        return np.array(
            [
                min(_ConeRange(h, f, self.cone_angle) for h, f in zip(hs, fs, strict=True))
                for hs, fs in zip(heights.tolist(), facing.tolist(), strict=True)
            ]
        )

    def HoseReadings(
        self, X_WT: RigidTransform, ranges: np.ndarray, valid: np.ndarray
    ) -> np.ndarray:
        """valid (bool, 6) without the readings of a known surface: those within tolerance
        of its range (Ranges) with the tool at X_WT."""
        known = np.abs(np.asarray(ranges, float) - self.Ranges(X_WT)) <= self.tolerance
        return np.asarray(valid, bool) & ~known
