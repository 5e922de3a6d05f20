"""OpenCvCamera: a camera read with cv2.VideoCapture (device index, video file or stream URL),
as the same `rgb_image` (ImageRgba8U) port a simulated RgbdSensor has.

A grabber thread keeps the newest frame (converted BGR -> RGBA) and its host time; video files
are played at their own frame rate, devices and streams as fast as they deliver. The system
samples the newest frame every `period` seconds.
"""

from __future__ import annotations

import threading
import time
from pathlib import Path

import cv2
import numpy as np
from pydrake.common.value import AbstractValue
from pydrake.systems.framework import Context, LeafSystem, State
from pydrake.systems.sensors import ImageRgba8U

from guidedarm.systems.errors import ConfigurationError
from guidedarm.systems.hardware.arm_link import FailStoppingAllArms


class FrameGrabber:
    """Reads frames of `source` in a thread; `latest()` is (RGBA frame, host time) or None."""

    def __init__(self, source: str) -> None:
        self.source = source
        target: int | str = int(source) if source.isdigit() else source
        self._capture = cv2.VideoCapture(target)
        if not self._capture.isOpened():
            raise ConfigurationError(f"camera source '{source}' cannot be opened by OpenCV")
        fps = self._capture.get(cv2.CAP_PROP_FPS)
        self._frame_period = 1.0 / fps if Path(source).is_file() and fps > 0 else 0.0
        self._lock = threading.Lock()
        self._latest: tuple[np.ndarray, float] | None = None
        self.frames = 0
        self._closing = threading.Event()
        self._thread = threading.Thread(target=self._Run, name="camera", daemon=True)
        self._thread.start()

    def _Run(self) -> None:
        next_time = time.monotonic()
        while not self._closing.is_set():
            ok, bgr = self._capture.read()
            if not ok:
                return  # end of file or lost stream: the system's watchdog reports it
            rgba = cv2.cvtColor(bgr, cv2.COLOR_BGR2RGBA)
            next_time += self._frame_period
            self._closing.wait(max(0.0, next_time - time.monotonic()))
            with self._lock:
                self._latest = (rgba, time.monotonic())
                self.frames += 1

    def latest(self) -> tuple[np.ndarray, float] | None:
        with self._lock:
            return self._latest

    def close(self) -> None:
        self._closing.set()
        self._thread.join(timeout=1.0)
        self._capture.release()


class OpenCvCamera(LeafSystem):
    """Output `rgb_image`: ImageRgba8U(width, height) of the newest frame, sampled every
    `period` s. A frame of another size, or no frame for `watchdog` s, stops every arm and
    fails the run with a HardwareFaultError."""

    def __init__(
        self, grabber: FrameGrabber, width: int, height: int, period: float, watchdog: float
    ) -> None:
        super().__init__()
        self._grabber = grabber
        self._size = (width, height)
        self._watchdog = watchdog
        self._start: float | None = None
        model = AbstractValue.Make(ImageRgba8U(width, height))
        self._image = self.DeclareAbstractState(model)
        self.DeclareAbstractOutputPort("rgb_image", model.Clone, self._CalcImage)
        self.DeclarePeriodicUnrestrictedUpdateEvent(period, 0.0, self._Sample)

    def _CalcImage(self, context: Context, output: AbstractValue) -> None:
        output.set_value(context.get_abstract_state(self._image).get_value())

    def _Sample(self, context: Context, state: State) -> None:
        now = time.monotonic()
        self._start = self._start or now
        latest = self._grabber.latest()
        last_time = latest[1] if latest else self._start
        device = f"camera '{self._grabber.source}'"
        if now - last_time > self._watchdog:
            FailStoppingAllArms(
                device,
                f"no frame for {now - last_time:.2f} s (watchdog {self._watchdog} s)",
                context.get_time(),
            )
        if latest is None:
            return
        frame = latest[0]
        if (frame.shape[1], frame.shape[0]) != self._size:
            FailStoppingAllArms(
                device,
                f"delivers {frame.shape[1]}x{frame.shape[0]} frames, the scenario expects "
                f"{self._size[0]}x{self._size[1]}",
                context.get_time(),
            )
        image = ImageRgba8U(*self._size)
        image.mutable_data[:] = frame
        state.get_mutable_abstract_state(self._image).set_value(image)
