"""`guidedarm calibrate camera` and `calibration-board`: intrinsics and distortion recovered
from board photos rendered through a known lens; bad input refused or reported."""

from __future__ import annotations

import json

import cv2
import numpy as np
import pytest
import yaml
from PIL import Image

from guidedarm.diagrams.calibration.calibration_files import LoadBoardSpec
from guidedarm.diagrams.panel.panel_files import LoadCameraIntrinsics
from guidedarm.systems.calibration.board_projection import BoardPhotos
from guidedarm.systems.calibration.calibration_views import CalibrationViews
from guidedarm.systems.calibration.charuco_board import BoardSpec, CharucoCornerDetector
from guidedarm.systems.markers.marker_pose_estimator_math import CameraIntrinsics

BOARD = "squares_x: 8\nsquares_y: 6\nsquare_m: 0.03\nmarker_m: 0.022\ndictionary: DICT_5X5_100\n"
# C920-like lenses (1920 x 1080, ~78 deg diagonal field): focal lengths a few px apart,
# principal point off the centre, barrel distortion.
LENSES = {
    "k1=-0.1": CameraIntrinsics(
        fx=1352.0, fy=1349.0, cx=951.3, cy=547.8, distortion=[-0.1, 0.02, 0.0, 0.0, 0.0]
    ),
    "k1=-0.3": CameraIntrinsics(
        fx=1372.0, fy=1366.0, cx=966.2, cy=533.1, distortion=[-0.3, 0.12, 5e-4, -4e-4, -0.02]
    ),
}


def _WritePhotos(folder, lens, count, seed=1, prefix="view"):
    folder.mkdir(exist_ok=True)
    spec = BoardSpec(**yaml.safe_load(BOARD))
    views = CalibrationViews(spec, lens, count, seed)
    for i, photo in enumerate(BoardPhotos(spec, lens, views)):
        cv2.imwrite(str(folder / f"{prefix}{i:02d}.png"), photo)
    return folder


@pytest.fixture(scope="module")
def board_file(tmp_path_factory):
    path = tmp_path_factory.mktemp("board") / "board.yaml"
    path.write_text(BOARD)
    return path


@pytest.mark.parametrize("lens_name", list(LENSES))
def test_recovers_known_intrinsics(run_cli, board_file, tmp_path, lens_name):
    lens = LENSES[lens_name]
    photos = _WritePhotos(tmp_path / "photos", lens, 10)
    (photos / "notes.txt").write_text("not a photo")
    out = tmp_path / "camera.yaml"
    code, stdout, err = run_cli(
        "calibrate", "camera", "--images", photos, "--board", board_file, "--out", out
    )
    assert code == 0, err
    fit = LoadCameraIntrinsics(out)
    assert (fit.width, fit.height) == (1920, 1080)
    assert abs(fit.fx / lens.fx - 1) < 0.005 and abs(fit.fy / lens.fy - 1) < 0.005
    assert abs(fit.cx - lens.cx) < 3 and abs(fit.cy - lens.cy) < 3
    assert abs(fit.distortion[0] - lens.distortion[0]) < 0.02
    report = json.loads((tmp_path / "camera_report.json").read_text())
    assert report["views_used"] == 10 and report["rms_reprojection_error_px"] < 0.5
    assert report["rejected"] == {"notes.txt": "not an image file"}
    assert report["std_devs"]["fx"] < 3 and report["coverage"] > 0.5
    assert (tmp_path / "camera_coverage.png").stat().st_size > 10_000
    assert "rejected notes.txt: not an image file" in stdout


@pytest.fixture(scope="module")
def photos(tmp_path_factory):
    """Six good photos through the k1 = -0.3 lens."""
    return _WritePhotos(tmp_path_factory.mktemp("photos") / "good", LENSES["k1=-0.3"], 6)


def _CopyInto(folder, source, names):
    folder.mkdir()
    for name in names:
        (folder / name).write_bytes((source / name).read_bytes())
    return folder


@pytest.mark.parametrize(
    "case, message",
    [
        ("no_board", "no usable view of the board in"),
        ("too_few", "3 usable views of the board, at least 5 needed"),
        ("other_dictionary", "no usable view of the board"),
        ("other_layout", "but none where the board file puts them"),
        ("bad_board_file", "marker_m = 0.04 must be smaller than square_m = 0.03"),
        ("no_images", "no image file among the files given"),
    ],
)
def test_bad_input_is_one_line(run_cli, board_file, photos, tmp_path, case, message):
    folder, board = photos, board_file
    if case == "no_board":
        folder = tmp_path / "blank"
        folder.mkdir()
        for i in range(6):
            cv2.imwrite(str(folder / f"{i}.png"), np.full((1080, 1920), 200, np.uint8))
    elif case == "too_few":
        folder = _CopyInto(tmp_path / "few", photos, ["view00.png", "view01.png", "view02.png"])
    elif case in ("other_dictionary", "other_layout", "bad_board_file"):
        text = {
            "other_dictionary": BOARD.replace("DICT_5X5_100", "DICT_4X4_50"),
            "other_layout": BOARD.replace("squares_x: 8", "squares_x: 7"),
            "bad_board_file": BOARD.replace("marker_m: 0.022", "marker_m: 0.04"),
        }[case]
        board = tmp_path / "other.yaml"
        board.write_text(text)
    elif case == "no_images":
        folder = tmp_path / "texts"
        folder.mkdir()
        (folder / "a.txt").write_text("hello")
    code, out, err = run_cli(
        "calibrate", "camera", "--images", folder, "--board", board, "--out", tmp_path / "c.yaml"
    )
    assert code == 2 and out == ""
    lines = err.strip().splitlines()
    assert len(lines) == 1 and message in lines[0], err
    assert not (tmp_path / "c.yaml").exists()


def test_printed_board_is_detected_at_its_size(run_cli, board_file, tmp_path):
    out = tmp_path / "board.png"
    code, stdout, err = run_cli("calibration-board", board_file, "--out", out, "--dpi", 150)
    assert code == 0 and "print at 100 % scale" in stdout, err
    image = Image.open(out)
    assert image.info["dpi"] == pytest.approx((150, 150), abs=0.05)
    px_per_square = 0.03 / 0.0254 * 150
    margin = round(px_per_square)
    assert image.size == (
        round(8 * px_per_square) + 2 * margin,
        round(6 * px_per_square) + 2 * margin,
    )
    spec = LoadBoardSpec(board_file)
    ids, _, _ = CharucoCornerDetector(spec).Detect(np.asarray(image.convert("L")))
    assert sorted(ids) == list(range(spec.corner_count()))
