"""Benchmark: marker detection + PnP on a 1920 x 1080 frame, and VTK rendering per frame.

Goal (issue 5): detection plus PnP at >= 30 frames/s on one core. Run:
    .venv/bin/python tests/benchmarks/bench_marker_pose.py
"""

from __future__ import annotations

import time

import cv2
import numpy as np
from pydrake.common.yaml import yaml_load_typed
from pydrake.systems.sensors import CameraConfig

from guidedarm.diagrams.panel.panel_camera_rig import LookAt, PanelCameraRig
from guidedarm.diagrams.panel.panel_files import DEFAULT_PANEL_FILE, LoadPanelSpec
from guidedarm.systems.markers.marker_pose_estimator_math import MarkerPoseSolver

C920 = "{width: 1920, height: 1080, focal: !FocalLength {x: 1360.2, y: 1360.2}}"
REPEATS = 40


def _time(function, repeats: int) -> float:
    """Median wall time of `function()` in ms."""
    samples = []
    for _ in range(repeats):
        start = time.perf_counter()
        function()
        samples.append(1e3 * (time.perf_counter() - start))
    return float(np.median(samples))


def main() -> None:
    cv2.setNumThreads(1)
    camera = yaml_load_typed(schema=CameraConfig, data=C920)
    X_PC = LookAt([0.04, -0.01, 0.30], [0.06, 0.0, 0.0])
    for supersampling in (1, 3):
        rig = PanelCameraRig(camera, supersampling)
        rig.Render(X_PC)  # the first render sets up VTK
        poses = iter(LookAt([0.04 + 1e-4 * i, -0.01, 0.30], [0.06, 0, 0]) for i in range(999))
        ms = _time(lambda rig=rig, poses=poses: rig.Render(next(poses)), 5)
        print(
            f"render 1920 x 1080 (supersampling {supersampling}, incl. pixel integration): "
            f"{ms:.1f} ms/frame"
        )
    image = rig.Render(X_PC)
    solver = MarkerPoseSolver(rig.intrinsics, LoadPanelSpec(DEFAULT_PANEL_FILE))
    assert solver.estimate(image).valid
    ms = _time(lambda: solver.estimate(image), REPEATS)
    print(f"detection + PnP, 1920 x 1080, 2 markers, 1 thread: {ms:.1f} ms = {1e3 / ms:.0f} fps")
    gray = cv2.cvtColor(image, cv2.COLOR_RGBA2GRAY)
    ms_detect = _time(lambda: solver.detect(gray), REPEATS)
    print(f"  of which detection with edge refinement: {ms_detect:.1f} ms")


if __name__ == "__main__":
    main()
