"""`guidedarm estimate-marker-pose`: JSON on a rendered image; one-line errors on bad input."""

from __future__ import annotations

import dataclasses
import json

import cv2
import numpy as np
import pytest
from pydrake.common.yaml import yaml_load_typed
from pydrake.systems.sensors import CameraConfig

from guidedarm.diagrams.panel.panel_camera_rig import LookAt, PanelCameraRig
from guidedarm.diagrams.panel.panel_files import DEFAULT_CAMERA_FILE, DEFAULT_PANEL_FILE
from guidedarm.systems.cell_errors.camera_errors import CameraErrors

C920 = "{width: 1920, height: 1080, focal: !FocalLength {x: 1360.2, y: 1360.2}}"
X_PC = LookAt([0.02, -0.01, 0.28], [0.06, 0.0, 0.0])


@pytest.fixture(scope="module")
def files(tmp_path_factory):
    """A rendered panel image, the camera file that matches it, and a blank image."""
    root = tmp_path_factory.mktemp("cli")
    rig = PanelCameraRig(yaml_load_typed(schema=CameraConfig, data=C920))
    rgba = rig.Render(X_PC)
    cv2.imwrite(str(root / "panel.png"), cv2.cvtColor(rgba, cv2.COLOR_RGBA2BGR))
    cv2.imwrite(str(root / "blank.png"), np.full((1080, 1920, 3), 220, np.uint8))
    cv2.imwrite(str(root / "small.png"), np.full((480, 640, 3), 220, np.uint8))
    camera = dataclasses.asdict(rig.intrinsics)
    (root / "camera.yaml").write_text("".join(f"{k}: {v}\n" for k, v in camera.items()))
    (root / "not_an_image.png").write_text("hello")
    return root


def test_prints_pose_of_rendered_panel(run_cli, files):
    code, out, err = run_cli(
        "estimate-marker-pose",
        files / "panel.png",
        "--camera",
        files / "camera.yaml",
        "--panel",
        DEFAULT_PANEL_FILE,
    )
    assert code == 0, err
    result = json.loads(out)
    assert set(result) == {
        "X_CP",
        "ids",
        "reprojection_error_px",
        "std_mm",
        "std_deg",
        "model_check",
        "valid",
        "why_invalid",
    }
    assert max(result["std_mm"]) < 0.5 and max(result["std_deg"]) < 0.5
    assert result["model_check"]["fits"] is True and result["why_invalid"] == ""
    assert result["ids"] == [7, 42] and result["valid"] is True
    X_CP = np.array(result["X_CP"])
    assert X_CP.shape == (4, 4)
    truth = X_PC.inverse().GetAsMatrix4()
    assert np.max(np.abs(X_CP[:3, 3] - truth[:3, 3])) < 1e-3
    assert np.max(np.abs(X_CP[:3, :3] - truth[:3, :3])) < 0.01
    assert 0 < result["reprojection_error_px"] < 1


def _bad_panel(tmp_path, text):
    path = tmp_path / "panel.yaml"
    path.write_text(text)
    return path


@pytest.mark.parametrize(
    "case, message",
    [
        ("unreadable", "cannot read image"),
        ("size", "is 640 x 480 px, the camera file"),
        ("no_marker", "no marker of the panel"),
        ("dictionary", "unknown marker dictionary 'DICT_FOO'"),
        ("malformed", "malformed YAML"),
        ("unknown_key", "unknown key 'markers[0].sise_m'"),
        ("missing_camera", "file not found"),
        ("tiny_focal", "key 'fx': must be in [1, 1e+06], got 1e-300"),
        ("huge_focal", "key 'fx': must be in [1, 1e+06], got 1e+308"),
        ("huge_distortion", "key 'distortion[0]': must be in [-100, 100], got 1e+308"),
        ("huge_marker", "must be in [0.001, 10], got 1e+308"),
        ("far_marker", "the marker is 1e+10 m from the panel origin"),
    ],
)
def test_bad_input_is_one_line_and_nonzero(run_cli, files, tmp_path, case, message):
    image, camera, panel = files / "panel.png", files / "camera.yaml", DEFAULT_PANEL_FILE
    if case == "unreadable":
        image = files / "not_an_image.png"
    elif case == "size":
        image = files / "small.png"
    elif case == "no_marker":
        image = files / "blank.png"
    elif case == "dictionary":
        panel = _bad_panel(tmp_path, "dictionary: DICT_FOO\nmarkers: [{id: 7, size_m: 0.05}]\n")
    elif case == "malformed":
        panel = _bad_panel(tmp_path, "dictionary: [DICT_ARUCO_ORIGINAL\nmarkers: {\n")
    elif case == "unknown_key":
        panel = _bad_panel(tmp_path, "markers: [{id: 7, sise_m: 0.05}]\n")
    elif case == "missing_camera":
        camera = tmp_path / "nope.yaml"
    elif case in ("tiny_focal", "huge_focal", "huge_distortion"):
        value = {"tiny_focal": "fx: 1e-300", "huge_focal": "fx: 1e308"}
        line = value.get(case, "distortion: [1e308, 0, 0, 0, 0]")
        camera = tmp_path / "camera.yaml"
        kept = [t for t in (files / "camera.yaml").read_text().splitlines() if t[:2] not in line]
        camera.write_text("\n".join([*kept, line]) + "\n")
    elif case == "huge_marker":
        panel = _bad_panel(tmp_path, "markers: [{id: 7, size_m: 1.0e308}]\n")
    elif case == "far_marker":
        panel = _bad_panel(tmp_path, "markers: [{id: 7, X_PM: {translation: [1.0e10, 0, 0]}}]\n")
    code, out, err = run_cli("estimate-marker-pose", image, "--camera", camera, "--panel", panel)
    assert code == 2
    assert out == ""
    lines = err.strip().splitlines()
    assert len(lines) == 1 and message in lines[0], err


def test_example_camera_file_is_accepted(run_cli, files):
    code, out, _ = run_cli(
        "estimate-marker-pose",
        files / "panel.png",
        "--camera",
        DEFAULT_CAMERA_FILE,
        "--panel",
        DEFAULT_PANEL_FILE,
    )
    assert code == 0 and json.loads(out)["valid"]


def test_distorted_image_with_a_zero_distortion_file_is_not_valid(run_cli, tmp_path):
    """The issue's case: a lens with k1 = -0.25, k2 = 0.08 seen through a camera file
    without distortion fits to ~1 px but 7 deg off; the model check refuses it, and the
    right file gives a valid pose within 1 mm and 0.5 deg of the truth."""
    camera = CameraConfig(width=1920, height=1080)
    camera.focal = CameraConfig.FocalLength(x=1360.2, y=1360.2)
    true_lens = CameraErrors(distortion=[-0.25, 0.08, 0.0, 0.0, 0.0])
    rig = PanelCameraRig(camera, supersampling=3, errors=true_lens)
    X_PC_far = LookAt([0.06, 0.0, 0.45], [0.0, 0.05, 0.0])
    lens = dataclasses.replace(rig.intrinsics, distortion=true_lens.distortion)
    image = rig.Render(X_PC_far)
    cv2.imwrite(str(tmp_path / "distorted.png"), cv2.cvtColor(image, cv2.COLOR_RGBA2BGR))
    results = {}
    for name, distortion in (("zero", [0.0] * 5), ("right", lens.distortion)):
        camera = dataclasses.replace(lens, distortion=distortion)
        path = tmp_path / f"{name}.yaml"
        path.write_text("".join(f"{key}: {v}\n" for key, v in dataclasses.asdict(camera).items()))
        code, out, _ = run_cli(
            "estimate-marker-pose",
            tmp_path / "distorted.png",
            "--camera",
            path,
            "--panel",
            DEFAULT_PANEL_FILE,
        )
        results[name] = (code, json.loads(out))
    code, zero = results["zero"]
    assert code == 1 and zero["valid"] is False and zero["reprojection_error_px"] < 2
    assert (
        zero["model_check"]["fits"] is False
        and "the corners ask for k1 = -0.2" in zero["why_invalid"]
    )
    code, right = results["right"]
    assert code == 0 and right["valid"] is True and right["model_check"]["fits"] is True
    X_CP, truth = np.array(right["X_CP"]), X_PC_far.inverse().GetAsMatrix4()
    assert np.linalg.norm(X_CP[:3, 3] - truth[:3, 3]) < 1e-3
    angle = np.arccos((np.trace(X_CP[:3, :3].T @ truth[:3, :3]) - 1) / 2)
    assert np.degrees(angle) < 0.5
    wrong = np.arccos(
        np.clip((np.trace(np.array(zero["X_CP"])[:3, :3].T @ truth[:3, :3]) - 1) / 2, -1, 1)
    )
    assert np.degrees(wrong) > 3  # the pose the check refuses is really off
