"""Lens distortion on a pinhole render: OpenCV's model k1 k2 p1 p2 k3, as a pixel remap.

A distorted camera of intrinsics K sees in its pixel (u, v) what a pinhole camera of the
same K sees at the undistorted point of (u, v). The pinhole render must cover every such
point, so it is made on a larger canvas (the margins of MakeLensRemap) with the principal
point moved by them; Remap then picks every distorted pixel from it.
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np

# The undistorted points are computed on a grid of this pitch (px) and interpolated in
# between: the map is smooth, and an exact map of a supersampled image costs seconds.
_GRID_PX = 8
# Extra pinhole pixels beyond the farthest undistorted point (bilinear interpolation
# reads one neighbour).
_MARGIN_PX = 2


@dataclass(frozen=True)
class LensRemap:
    """map_x, map_y (height x width, float32): where in the pinhole render each pixel of
    the distorted image lies; the render's size and intrinsics K_render (3 x 3, px)."""

    map_x: np.ndarray
    map_y: np.ndarray
    render_width: int
    render_height: int
    K_render: np.ndarray


def MakeLensRemap(K: np.ndarray, distortion: np.ndarray, width: int, height: int) -> LensRemap:
    """The remap of a width x height camera of intrinsics K (px) with OpenCV distortion
    [k1, k2, p1, p2, k3]."""
    us = np.r_[np.arange(0, width, _GRID_PX), width - 1].astype(float)
    vs = np.r_[np.arange(0, height, _GRID_PX), height - 1].astype(float)
    grid = np.stack(np.meshgrid(us, vs), axis=-1).reshape(-1, 1, 2)
    criteria = (cv2.TERM_CRITERIA_COUNT | cv2.TERM_CRITERIA_EPS, 100, 1e-12)
    normalized = cv2.undistortPointsIter(grid, K, distortion, None, None, criteria)
    pinhole = normalized.reshape(len(vs), len(us), 2) * [K[0, 0], K[1, 1]] + [K[0, 2], K[1, 2]]
    low = np.floor(pinhole.reshape(-1, 2).min(axis=0)) - _MARGIN_PX
    high = np.ceil(pinhole.reshape(-1, 2).max(axis=0)) + _MARGIN_PX
    left, top = max(0.0, -low[0]), max(0.0, -low[1])
    render_width = int(max(width, high[0] + 1) + left)
    render_height = int(max(height, high[1] + 1) + top)
    K_render = K.copy()
    K_render[0, 2] += left
    K_render[1, 2] += top
    fine_x, fine_y = _Interpolate(us, vs, pinhole, width, height)
    fine_x += np.float32(left)
    fine_y += np.float32(top)
    return LensRemap(
        fine_x,
        fine_y,
        render_width,
        render_height,
        K_render,
    )


def Remap(image: np.ndarray, remap: LensRemap) -> np.ndarray:
    """The distorted image (height x width x channels, same dtype) from the pinhole render."""
    return cv2.remap(image, remap.map_x, remap.map_y, cv2.INTER_LINEAR, cv2.BORDER_REPLICATE)


def DistortPixels(points_px: np.ndarray, K: np.ndarray, distortion: np.ndarray) -> np.ndarray:
    """Where pinhole pixel positions (N x 2) of a camera K appear with the lens (N x 2)."""
    points = np.asarray(points_px, float).reshape(-1, 2)
    normalized = (points - [K[0, 2], K[1, 2]]) / [K[0, 0], K[1, 1]]
    homogeneous = np.c_[normalized, np.ones(len(points))]
    projected, _ = cv2.projectPoints(homogeneous, np.zeros(3), np.zeros(3), K, distortion)
    return projected.reshape(-1, 2)


def _Interpolate(us, vs, coarse, width, height):
    """The coarse grid's values (len(vs) x len(us) x 2) at every pixel, bilinearly: first
    along v for each grid column, then along u, in float32 (a supersampled camera's maps
    have tens of millions of pixels)."""
    coarse = coarse.astype(np.float32)
    v = np.arange(height, dtype=np.float32)
    j = np.clip(np.searchsorted(vs, v, side="right") - 1, 0, len(vs) - 2)
    b = ((v - vs[j]) / (vs[j + 1] - vs[j])).astype(np.float32)[:, None, None]
    columns = (1 - b) * coarse[j] + b * coarse[j + 1]  # height x len(us) x 2
    u = np.arange(width, dtype=np.float32)
    i = np.clip(np.searchsorted(us, u, side="right") - 1, 0, len(us) - 2)
    a = ((u - us[i]) / (us[i + 1] - us[i])).astype(np.float32)
    fine = []
    for channel in range(2):
        values = columns[:, :, channel]
        fine.append(values[:, i] * (1 - a) + values[:, i + 1] * a)
    return fine[0], fine[1]
