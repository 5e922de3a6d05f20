"""`guidedarm calibrate tof`: each sensor's offset against a flat target at known
distances, in simulation with the VL6180X preset's offsets and drift; the ToF tool's
calibration_file then takes them out of the readings."""

from __future__ import annotations

import json

import numpy as np
import pytest

from guidedarm.diagrams.calibration.calibration_files import LoadToFOffsets

SETTINGS = ["station.errors_preset=vl6180x", "random_seed=2"]


def _Calibrate(run_cli, out, *extra):
    flags = [a for s in [*SETTINGS, *extra] for a in ("--set", s)]
    return run_cli("calibrate", "tof", "path_following", "--out", out, *flags)


@pytest.mark.slow
def test_offsets_within_half_a_millimetre_and_taken_out_by_the_calibration_file(run_cli, tmp_path):
    code, out, err = _Calibrate(run_cli, tmp_path / "first")
    assert code == 0, err
    assert "truth" in out and "residual" in out
    report = json.loads((tmp_path / "first" / "tof_report.json").read_text())
    offset, truth = np.array(report["offset_m"]), np.array(report["true_offset_m"])
    assert np.max(np.abs(truth)) > 1e-3  # the preset's draw is not trivially small
    assert np.max(np.abs(offset - truth)) < 0.5e-3
    np.testing.assert_allclose(LoadToFOffsets(tmp_path / "first" / "tof_offsets.yaml"), offset)
    # Again through the calibrated readings: what is left is within the same 0.5 mm.
    calibrated = f"station.tof_tools.tof.calibration_file={tmp_path / 'first' / 'tof_offsets.yaml'}"
    code, _, err = _Calibrate(run_cli, tmp_path / "second", calibrated)
    assert code == 0, err
    second = json.loads((tmp_path / "second" / "tof_report.json").read_text())
    assert np.max(np.abs(np.array(second["offset_m"]))) < 0.5e-3


@pytest.mark.parametrize(
    "scenario, settings, message",
    [
        ("panel_operation", [], "needs a scenario whose station has one ToF tool, it has []"),
        (
            "path_following",
            ["station.tof_tools.tof.calibration_file=/nonexistent/tof_offsets.yaml"],
            "key 'station.tof_tools.tof.calibration_file': file not found",
        ),
        ("path_following", ["--hardware"], "the station has no 'tof_target' model"),
    ],
)
def test_bad_tof_input_is_one_line(run_cli, tmp_path, scenario, settings, message):
    flags = [a for s in settings for a in ("--set", s)] if settings != ["--hardware"] else settings
    code, out, err = run_cli("calibrate", "tof", scenario, "--out", tmp_path, *flags)
    assert code == 2 and out == "", err
    assert len(err.strip().splitlines()) == 1 and message in err, err
