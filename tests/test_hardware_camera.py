"""OpenCV camera driver on a video file written by the test (frame k has colour k mod 3)."""

from __future__ import annotations

import numpy as np
import pytest
from hardware_doubles import VIDEO_COLOURS_BGR, WriteTestVideo
from pydrake.systems.analysis import Simulator

from guidedarm.systems.errors import ConfigurationError, HardwareFaultError
from guidedarm.systems.hardware.opencv_camera import FrameGrabber, OpenCvCamera

FPS = 20.0


@pytest.fixture(scope="module")
def video(tmp_path_factory):
    path = tmp_path_factory.mktemp("camera") / "colours.avi"
    WriteTestVideo(path, 64, 48, FPS, 12)
    return str(path)


def _Run(camera: OpenCvCamera, t_final: float) -> np.ndarray:
    simulator = Simulator(camera)
    simulator.set_target_realtime_rate(1.0)
    simulator.AdvanceTo(t_final)
    return camera.get_output_port().Eval(simulator.get_context()).data


def test_frames_arrive_as_rgba_images_at_the_file_rate(video):
    grabber = FrameGrabber(video)
    camera = OpenCvCamera(grabber, 64, 48, period=0.01, watchdog=1.0)
    image = _Run(camera, 0.33)
    assert image.shape == (48, 64, 4)
    assert np.all(image[..., 3] == 255)
    # About 0.33 s * 20 fps frames have been played; the image is the newest one's colour.
    assert 4 <= grabber.frames <= 9
    b, g, r = VIDEO_COLOURS_BGR[(grabber.frames - 1) % 3]
    np.testing.assert_allclose(image[24, 32, :3], [r, g, b], atol=6)
    grabber.close()


def test_end_of_video_trips_the_watchdog(video):
    camera = OpenCvCamera(FrameGrabber(video), 64, 48, period=0.05, watchdog=0.2)
    with pytest.raises(
        HardwareFaultError, match=r"at t = .* s: no frame for 0\.2\d* s \(watchdog 0.2 s\)"
    ):
        _Run(camera, 3.0)


def test_frame_size_other_than_the_scenario_fails(video):
    camera = OpenCvCamera(FrameGrabber(video), 640, 480, period=0.05, watchdog=1.0)
    with pytest.raises(
        HardwareFaultError, match="delivers 64x48 frames, the scenario expects 640x480"
    ):
        _Run(camera, 0.2)


def test_unopenable_source_is_a_configuration_error(tmp_path):
    with pytest.raises(ConfigurationError, match="cannot be opened by OpenCV"):
        FrameGrabber(str(tmp_path / "missing.avi"))
