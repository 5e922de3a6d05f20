"""Pose of a fiducial-marker panel in a camera frame, from one colour image, as in
Annusewicz-Mistal et al., "Autonomous Manipulator of a Mobile Robot Based on a Vision
System" (section 2.3).

Frames (all right-handed, metres):
  M  a marker: origin at its centre, x to the right and y up as printed, z out of the panel
     towards the viewer (OpenCV's convention).
  P  the panel: the frame of one marker (the left one on the paper's panel); every marker's
     pose X_PM is known.
  C  the camera: Drake's and OpenCV's optical frame, x right, y down, z forward.

Method: OpenCV's ArucoDetector with sub-pixel corner refinement finds the markers; markers
whose id is not on the panel are ignored. Each known marker gives an IPPE-square pose (two
candidates each); the candidate with the smallest reprojection error over the corners of
ALL known markers seeds a Levenberg-Marquardt refinement over those corners at once (up to
8 points with two markers, as in the paper).

The YAML schemas of the camera and panel files are the dataclasses below (loaded with
Drake's yaml_load_typed; no `from __future__ import annotations` here on purpose).
"""

from dataclasses import dataclass, field

import cv2
import numpy as np
from pydrake.common.schema import Transform
from pydrake.math import RigidTransform, RotationMatrix

from guidedarm.systems.config_checks import CheckFields, CheckInstance, InRange, Positive
from guidedarm.systems.errors import ConfigurationError
from guidedarm.systems.markers.pose_uncertainty import (
    CheckRadialModel,
    ModelCheck,
    PoseStdDevs,
)

# A pose whose corners reproject worse than this (RMS, pixels) is reported invalid: it means
# a misdetection or a wrong camera file, not image noise (rendered images give ~0.1 px).
MAX_VALID_REPROJECTION_ERROR_PX = 2.0
# The ranges in which a pose from PnP means something; outside them OpenCV overflows or
# fails. Image side (px): up to a 100 megapixel sensor's. Focal length (px): a 1 px focal
# length is a 90 deg view across 2 px; 1e6 px is a 0.1 deg view of a 2000 px image.
# Distortion: |k| <= 100 (calibrated lenses give |k| < 10). Marker side: 1 mm to 10 m;
# a marker's position on the panel within 100 m of P.
MAX_IMAGE_SIDE_PX = 100_000
FOCAL_LENGTH_RANGE_PX = (1.0, 1.0e6)
MAX_DISTORTION = 100.0
MARKER_SIZE_RANGE_M = (1.0e-3, 10.0)
MAX_MARKER_OFFSET_M = 100.0


@dataclass
class CameraIntrinsics:
    """Pinhole intrinsics of a camera image (pixels); distortion is OpenCV's k1 k2 p1 p2 k3.
    The principal point (cx, cy) lies inside the image; sides, focal lengths and distortion
    lie in the ranges above (MAX_IMAGE_SIDE_PX, FOCAL_LENGTH_RANGE_PX, MAX_DISTORTION)."""

    width: int = InRange(1, MAX_IMAGE_SIDE_PX, 1920)
    height: int = InRange(1, MAX_IMAGE_SIDE_PX, 1080)
    fx: float = InRange(*FOCAL_LENGTH_RANGE_PX, 1000.0)
    fy: float = InRange(*FOCAL_LENGTH_RANGE_PX, 1000.0)
    cx: float = 959.5
    cy: float = 539.5
    distortion: list[float] = InRange(-MAX_DISTORTION, MAX_DISTORTION, factory=lambda: [0.0] * 5)

    def Validate(self) -> None:
        """Raises ConfigurationError naming the first bad value."""
        CheckFields(self)
        for name, value, size in (("cx", self.cx, self.width), ("cy", self.cy, self.height)):
            if not -0.5 <= value <= size - 0.5:
                raise ConfigurationError(
                    f"{name} = {value} lies outside the image (-0.5 .. {size - 0.5} px)"
                )
        self.distortion_vector()

    def camera_matrix(self) -> np.ndarray:
        return np.array([[self.fx, 0, self.cx], [0, self.fy, self.cy], [0, 0, 1]], float)

    def distortion_vector(self) -> np.ndarray:
        if len(self.distortion) != 5:
            raise ConfigurationError(
                f"camera distortion needs 5 values (k1 k2 p1 p2 k3), got {len(self.distortion)}"
            )
        return np.asarray(self.distortion, float)


@dataclass
class MarkerSpec:
    """One square marker: its dictionary id, black-border side length (m, within
    MARKER_SIZE_RANGE_M), pose in P (within MAX_MARKER_OFFSET_M of P's origin)."""

    id: int = 0
    size_m: float = InRange(*MARKER_SIZE_RANGE_M, 0.05)
    X_PM: Transform = field(default_factory=Transform)

    def Validate(self) -> None:
        """Raises ConfigurationError naming the first bad value."""
        CheckFields(self)
        offset = np.linalg.norm(self.X_PM.GetDeterministicValue().translation())
        if not offset <= MAX_MARKER_OFFSET_M:
            raise ConfigurationError(
                f"X_PM: the marker is {offset:g} m from the panel origin, more than "
                f"{MAX_MARKER_OFFSET_M:g} m"
            )


@dataclass
class SwitchSpec:
    """A push switch: `position` is the centre of its cap face at rest, in P (m); the cap
    travels along -z_P up to `travel_m` and counts as switched on past `on_travel_m`."""

    name: str = ""
    position: list[float] = field(default_factory=lambda: [0.0, 0.0, 0.0])
    radius_m: float = Positive(0.007)
    travel_m: float = Positive(0.008)
    on_travel_m: float = Positive(0.004)

    def Validate(self) -> None:
        """Raises ConfigurationError naming the first bad value."""
        CheckFields(self)
        if len(self.position) != 3:
            raise ConfigurationError(f"position needs 3 values (m), got {self.position}")
        if not self.on_travel_m <= self.travel_m:
            raise ConfigurationError("on_travel_m must not exceed travel_m")


@dataclass
class PanelSpec:
    """A panel: the OpenCV dictionary name of its markers, the markers, and its switches."""

    dictionary: str = "DICT_ARUCO_ORIGINAL"
    markers: list[MarkerSpec] = field(default_factory=list)
    switches: list[SwitchSpec] = field(default_factory=list)


@dataclass
class MarkerPoseEstimate:
    """X_CP (None when no known marker was found), the known ids used, the RMS reprojection
    error of their corners (px, -1 if none) and whether the pose is trustworthy; with a
    pose, its standard deviations (std_mm: p_CP along C's x y z; std_deg: the rotation
    about C's axes; pose_uncertainty.py) and the camera model check (model_check: None
    with one marker; `why_invalid` says why a pose is not valid)."""

    X_CP: RigidTransform | None
    ids: list[int]
    reprojection_error_px: float
    valid: bool
    std_mm: list[float] = field(default_factory=list)
    std_deg: list[float] = field(default_factory=list)
    model_check: ModelCheck | None = None
    why_invalid: str = ""


def GetDictionary(name: str) -> cv2.aruco.Dictionary:
    """The predefined OpenCV dictionary called `name` (e.g. DICT_ARUCO_ORIGINAL)."""
    code = getattr(cv2.aruco, name, None) if name.startswith("DICT_") else None
    if not isinstance(code, int):
        raise ConfigurationError(f"unknown marker dictionary '{name}' (e.g. DICT_ARUCO_ORIGINAL)")
    return cv2.aruco.getPredefinedDictionary(code)


def MarkerCorners_M(size_m: float) -> np.ndarray:
    """The 4 corners in M, in OpenCV's order: top-left, top-right, bottom-right, bottom-left."""
    h = size_m / 2
    return np.array([[-h, h, 0], [h, h, 0], [h, -h, 0], [-h, -h, 0]], float)


class MarkerPoseSolver:
    """Detects the markers of `panel` in images of a camera with `intrinsics`."""

    def __init__(self, intrinsics: CameraIntrinsics, panel: PanelSpec) -> None:
        """Bad arguments raise ConfigurationError naming them."""
        CheckInstance("intrinsics", intrinsics, CameraIntrinsics)
        CheckInstance("panel", panel, PanelSpec)
        intrinsics.Validate()
        CheckFields(panel)
        if not panel.markers:
            raise ConfigurationError("the panel has no markers")
        ids = [m.id for m in panel.markers]
        if len(set(ids)) != len(ids):
            raise ConfigurationError(f"marker ids on the panel must be unique, got {ids}")
        dictionary = GetDictionary(panel.dictionary)
        for m in panel.markers:
            if not 0 <= m.id < dictionary.bytesList.shape[0]:
                raise ConfigurationError(f"marker {m.id}: id outside {panel.dictionary}")
        self.intrinsics = intrinsics
        self._K = intrinsics.camera_matrix()
        self._dist = intrinsics.distortion_vector()
        parameters = cv2.aruco.DetectorParameters()
        parameters.cornerRefinementMethod = cv2.aruco.CORNER_REFINE_SUBPIX
        self._detector = cv2.aruco.ArucoDetector(dictionary, parameters)
        self._markers = {m.id: m for m in panel.markers}
        self._corners_P = {
            m.id: _Transform(m.X_PM.GetDeterministicValue(), MarkerCorners_M(m.size_m))
            for m in panel.markers
        }

    def detect(self, gray: np.ndarray) -> dict[int, np.ndarray]:
        """Image corners (4 x 2, px) of each known marker found in a greyscale image."""
        corners, ids, _ = self._detector.detectMarkers(gray)
        found = {}
        for c, i in zip(corners, [] if ids is None else ids.ravel(), strict=True):
            if int(i) in self._markers and int(i) not in found:
                found[int(i)] = RefineCornersOnEdges(gray, c.reshape(4, 2).astype(float))
        return found

    def estimate(self, image: np.ndarray) -> MarkerPoseEstimate:
        """The panel pose in an RGB(A) uint8 image (height x width x 3|4) or a grey one."""
        expected = (self.intrinsics.height, self.intrinsics.width)
        if image.shape[:2] != expected:
            raise ConfigurationError(
                f"image is {image.shape[1]} x {image.shape[0]} px, the camera file says "
                f"{expected[1]} x {expected[0]}"
            )
        found = self.detect(ToGray(image))
        if not found:
            return MarkerPoseEstimate(None, [], -1.0, False)
        ids = sorted(found)
        try:
            return self._solve(ids, found)
        except cv2.error:
            # OpenCV refuses degenerate input (corners it cannot undistort or fit a pose
            # to) by raising: the markers were seen, their pose cannot be trusted.
            return MarkerPoseEstimate(None, ids, -1.0, False)

    def _solve(self, ids: list[int], found: dict[int, np.ndarray]) -> MarkerPoseEstimate:
        """The panel pose from the image corners of the known markers `ids` (see the
        module docstring); cv2.error passes through."""
        points_P = np.vstack([self._corners_P[i] for i in ids])
        pixels = np.vstack([found[i] for i in ids])
        best = (np.inf, None, None)
        for i in ids:
            for rvec, tvec in self._ippe_square(i, found[i]):
                error = self._rms(points_P, pixels, rvec, tvec)
                if error < best[0]:
                    best = (error, rvec, tvec)
        if best[0] > MAX_VALID_REPROJECTION_ERROR_PX:
            # OpenCV's IPPE fails for some exactly symmetric views (a marker straight in
            # front of a camera whose principal point is the image centre): NaN, or a pose
            # hundreds of pixels off. SQPnP has no such degenerate case (it needs no planar
            # homography).
            ok, rvec, tvec = cv2.solvePnP(
                points_P, pixels, self._K, self._dist, flags=cv2.SOLVEPNP_SQPNP
            )
            error = self._rms(points_P, pixels, rvec, tvec) if ok else np.inf
            if error < best[0]:
                best = (error, rvec, tvec)
        if best[1] is None:
            return MarkerPoseEstimate(None, ids, -1.0, False)
        _, rvec, tvec = best
        rvec, tvec = cv2.solvePnPRefineLM(points_P, pixels, self._K, self._dist, rvec, tvec)
        error = self._rms(points_P, pixels, rvec, tvec)
        if not np.isfinite(error):
            return MarkerPoseEstimate(None, ids, -1.0, False)
        X_CP = RigidTransform(RotationMatrix(cv2.Rodrigues(rvec)[0]), tvec.ravel())
        std_mm, std_deg = PoseStdDevs(points_P, pixels, rvec, tvec, self._K, self._dist)
        size = (self.intrinsics.width, self.intrinsics.height)
        check = CheckRadialModel(points_P, pixels, rvec, tvec, self._K, self._dist, size)
        why = ""
        if error > MAX_VALID_REPROJECTION_ERROR_PX:
            why = (
                f"reprojection error {error:.2f} px, more than {MAX_VALID_REPROJECTION_ERROR_PX} px"
            )
        elif check is not None and not check.fits:
            why = check.Why()
        return MarkerPoseEstimate(X_CP, ids, error, not why, std_mm, std_deg, check, why)

    def _ippe_square(self, marker_id: int, pixels: np.ndarray) -> list[tuple]:
        """Both IPPE-square poses of one marker, expressed as panel poses (rvec, tvec of P)."""
        marker = self._markers[marker_id]
        _, rvecs, tvecs, _ = cv2.solvePnPGeneric(
            MarkerCorners_M(marker.size_m),
            pixels,
            self._K,
            self._dist,
            flags=cv2.SOLVEPNP_IPPE_SQUARE,
        )
        X_MP = marker.X_PM.GetDeterministicValue().inverse()
        candidates = []
        for rvec, tvec in zip(rvecs, tvecs, strict=True):
            if not (np.all(np.isfinite(rvec)) and np.all(np.isfinite(tvec))):
                continue
            X_CM = RigidTransform(RotationMatrix(cv2.Rodrigues(rvec)[0]), tvec.ravel())
            X_CP = X_CM @ X_MP
            r, _ = cv2.Rodrigues(X_CP.rotation().matrix())
            candidates.append((r, X_CP.translation().reshape(3, 1).copy()))
        return candidates

    def _rms(self, points: np.ndarray, pixels: np.ndarray, rvec, tvec) -> float:
        """RMS reprojection error (px); infinite for a pose that cannot be projected."""
        if not (np.all(np.isfinite(rvec)) and np.all(np.isfinite(tvec))):
            return np.inf
        projected, _ = cv2.projectPoints(points, rvec, tvec, self._K, self._dist)
        return float(np.sqrt(np.mean(np.sum((projected.reshape(-1, 2) - pixels) ** 2, axis=1))))


def RefineCornersOnEdges(gray: np.ndarray, corners: np.ndarray, reach_px: float = 3.0):
    """Corners (4 x 2, px) re-placed at the intersections of the four outer edges.

    ArUco's contour corners sit on the outermost dark pixels, about half a pixel inside the
    true outline (a 0.5 % size error, i.e. 2 mm at 420 mm). Here each side is sampled
    across its middle 70 %; along the side's normal the intensity profile (bilinear) crosses
    the mid level between the dark and the light side at the edge, a line is fitted through
    those crossings, and adjacent lines intersect at the corners. A side without enough
    contrast keeps the detector's corners.
    """
    image = gray.astype(np.float32)
    offsets = np.arange(-reach_px, reach_px + 1e-9, 0.25)
    lines = []
    for k in range(4):
        a, b = corners[k], corners[(k + 1) % 4]
        side = b - a
        length = float(np.linalg.norm(side))
        if length < 8.0:
            return corners
        t = side / length
        n = np.array([-t[1], t[0]])
        s = np.linspace(0.15, 0.85, max(int(0.7 * length), 4))
        base = a + s[:, None] * side
        samples = base[:, None, :] + offsets[None, :, None] * n
        profiles = cv2.remap(
            image,
            samples[..., 0].astype(np.float32),
            samples[..., 1].astype(np.float32),
            cv2.INTER_LINEAR,
            borderMode=cv2.BORDER_REPLICATE,
        )
        low, high = profiles.min(axis=1), profiles.max(axis=1)
        level = ((low + high) / 2)[:, None]
        above = profiles > level
        change = above[:, 1:] != above[:, :-1]
        middle = np.abs(offsets[:-1] + 0.125)
        cost = np.where(change, middle[None, :], np.inf)
        j = np.argmin(cost, axis=1)
        rows = np.arange(len(s))
        ok = np.isfinite(cost[rows, j]) & (high - low > 20.0)
        if ok.sum() < 4:
            return corners
        p0, p1 = profiles[rows, j], profiles[rows, j + 1]
        fraction = (level[:, 0] - p0) / np.where(p1 != p0, p1 - p0, 1.0)
        offset = offsets[j] + 0.25 * fraction
        points = base + offset[:, None] * n
        points = points[ok]
        centre = points.mean(axis=0)
        _, _, vt = np.linalg.svd(points - centre)
        lines.append((centre, vt[0]))
    refined = np.empty_like(corners)
    for k in range(4):
        (c1, d1), (c2, d2) = lines[k - 1], lines[k]
        A = np.column_stack([d1, -d2])
        if abs(np.linalg.det(A)) < 1e-6:
            return corners
        u = np.linalg.solve(A, c2 - c1)
        refined[k] = c1 + u[0] * d1
    if np.max(np.linalg.norm(refined - corners, axis=1)) > reach_px:
        return corners
    return refined


def ToGray(image: np.ndarray) -> np.ndarray:
    """Greyscale uint8 view of an RGB(A) or grey image."""
    if image.ndim == 2:
        return image
    if image.shape[2] == 4:
        return cv2.cvtColor(image, cv2.COLOR_RGBA2GRAY)
    return cv2.cvtColor(image, cv2.COLOR_RGB2GRAY)


def _Transform(X_AB: RigidTransform, points_B: np.ndarray) -> np.ndarray:
    return (X_AB.rotation().matrix() @ points_B.T).T + X_AB.translation()
