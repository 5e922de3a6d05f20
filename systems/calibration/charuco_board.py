"""A ChArUco calibration board: its file (BOARD.yaml), OpenCV board object, printable image
and detection.

Frame B of the board (OpenCV's): origin at the outer corner of the top-left square as
printed, x along the squares_x direction (to the right), y along squares_y (down the
printed page), z into the board (away from a viewer in front of it). Metres.

No `from __future__ import annotations` here: yaml_load_typed reads the annotations.
"""

from dataclasses import dataclass

import cv2
import numpy as np

from guidedarm.systems.config_checks import CheckFields, InRange
from guidedarm.systems.errors import ConfigurationError
from guidedarm.systems.markers.marker_pose_estimator_math import GetDictionary

# The fewest inner corners a view must show for its board pose to be solved (OpenCV's
# calibrateCameraCharuco needs at least 4 per view; 6 keeps a view away from degenerate).
MIN_CORNERS_PER_VIEW = 6


@dataclass
class BoardSpec:
    """BOARD.yaml: a ChArUco board of squares_x x squares_y chessboard squares of side
    square_m (m), an ArUco marker of side marker_m (< square_m) in each white square, from
    the OpenCV dictionary named `dictionary` (e.g. DICT_5X5_100), ids 0, 1, ... in OpenCV's
    order (row by row from the top-left)."""

    squares_x: int = InRange(3, 100, 7)
    squares_y: int = InRange(3, 100, 5)
    square_m: float = InRange(1e-3, 10.0, 0.04)
    marker_m: float = InRange(1e-3, 10.0, 0.03)
    dictionary: str = "DICT_5X5_100"

    def Validate(self) -> None:
        """Raises ConfigurationError naming the first bad value."""
        CheckFields(self)
        if not self.marker_m < self.square_m:
            raise ConfigurationError(
                f"marker_m = {self.marker_m} must be smaller than square_m = {self.square_m}"
            )
        markers = self.marker_count()
        available = GetDictionary(self.dictionary).bytesList.shape[0]
        if markers > available:
            raise ConfigurationError(
                f"a {self.squares_x} x {self.squares_y} board needs {markers} markers, "
                f"{self.dictionary} has {available}"
            )

    def marker_count(self) -> int:
        """The number of markers (white squares) on the board."""
        return self.squares_x * self.squares_y // 2

    def corner_count(self) -> int:
        """The number of inner chessboard corners (ChArUco corners)."""
        return (self.squares_x - 1) * (self.squares_y - 1)

    def size_m(self) -> tuple[float, float]:
        """The board's width and height (m)."""
        return self.squares_x * self.square_m, self.squares_y * self.square_m


def MakeCharucoBoard(spec: BoardSpec) -> cv2.aruco.CharucoBoard:
    """OpenCV's board for `spec` (checked first)."""
    spec.Validate()
    return cv2.aruco.CharucoBoard(
        (spec.squares_x, spec.squares_y),
        spec.square_m,
        spec.marker_m,
        GetDictionary(spec.dictionary),
    )


def BoardImage(spec: BoardSpec, pixels_per_m: float, margin_px: int = 0) -> np.ndarray:
    """The printable board (greyscale uint8, white margin of margin_px around it) at
    pixels_per_m; squares are whole pixels only when square_m * pixels_per_m is whole."""
    width_m, height_m = spec.size_m()
    size = (round(width_m * pixels_per_m), round(height_m * pixels_per_m))
    if min(size) < 2 * max(spec.squares_x, spec.squares_y) or max(size) > 30_000:
        raise ConfigurationError(
            f"the board would be {size[0]} x {size[1]} px at {pixels_per_m:g} px/m "
            "(at least 2 px per square side, at most 30000 px)"
        )
    image = MakeCharucoBoard(spec).generateImage(size, marginSize=0, borderBits=1)
    return cv2.copyMakeBorder(image, *[margin_px] * 4, cv2.BORDER_CONSTANT, value=255)


class CharucoCornerDetector:
    """Finds the inner corners of one board in greyscale images."""

    def __init__(self, spec: BoardSpec) -> None:
        self.spec = spec
        self.board = MakeCharucoBoard(spec)
        parameters = cv2.aruco.CharucoParameters()
        detector = cv2.aruco.DetectorParameters()
        detector.cornerRefinementMethod = cv2.aruco.CORNER_REFINE_SUBPIX
        self._detector = cv2.aruco.CharucoDetector(self.board, parameters, detector)

    def Detect(self, gray: np.ndarray) -> tuple[np.ndarray, np.ndarray, int]:
        """(corner ids (N,), image corners (N x 2, px), markers of this board seen)."""
        corners, ids, _, marker_ids = self._detector.detectBoard(gray)
        markers = 0 if marker_ids is None else len(marker_ids)
        if ids is None or len(ids) == 0:
            return np.zeros(0, int), np.zeros((0, 2)), markers
        return ids.ravel().astype(int), corners.reshape(-1, 2).astype(float), markers

    def CornerPoints_B(self, ids: np.ndarray) -> np.ndarray:
        """The board points (N x 3, m, in B) of the inner corners `ids`."""
        return np.asarray(self.board.getChessboardCorners(), float)[ids]
