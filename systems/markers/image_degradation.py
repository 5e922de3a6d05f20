"""ImageDegradation: pixel integration, lighting, lens blur and sensor noise on a render.

Rendered images are perfect; a webcam's are not. The model, applied in this order to the
RGB channels (alpha untouched):
  pixels    a renderer samples each pixel at its centre, so edges are aliased (an edge's
            position is quantised to whole pixels); a sensor pixel integrates light over
            its area. With `supersampling` k the input is rendered at k times the
            resolution and each k x k block is averaged (cv2.INTER_AREA) into one pixel,
  lighting  pixel values scaled by `lighting` (1 = as rendered; 0.3 = a dim room),
  blur      Gaussian blur of standard deviation `blur_sigma_px` (defocus, pixels),
  noise     additive Gaussian noise of standard deviation `noise_std` (grey levels of 255),
then rounded and clipped to uint8. Noise is seeded: the same seed, image and time give the
same result, so studies are repeatable.
"""

import dataclasses
from dataclasses import dataclass

import cv2
import numpy as np
from pydrake.common.value import AbstractValue
from pydrake.systems.framework import Context, LeafSystem
from pydrake.systems.sensors import CameraConfig, ImageRgba8U

from guidedarm.systems.config_checks import (
    CheckFields,
    CheckInstance,
    NonNegative,
    Positive,
)
from guidedarm.systems.drake_config_checks import CheckRenderSize
from guidedarm.systems.errors import ConfigurationError


@dataclass
class DegradationConfig:
    """The degradation of a rendered image (see the module docstring).

    supersampling: k >= 1; the input is k times the output's resolution, each k x k block
        is averaged into one pixel.
    lighting: scale of the pixel values (> 0; 1 = as rendered).
    blur_sigma_px: standard deviation of the Gaussian blur (>= 0, output pixels).
    noise_std: standard deviation of the additive Gaussian noise (>= 0, grey levels of 255).
    seed: seed of the noise generator; None: 0, or the task's random_seed in a scenario.
    """

    supersampling: int = Positive(1)
    lighting: float = Positive(1.0)
    blur_sigma_px: float = NonNegative(0.0)
    noise_std: float = NonNegative(0.0)
    seed: int | None = None

    def Validate(self) -> None:
        """Raises ConfigurationError naming the first bad parameter."""
        CheckFields(self)


def CheckRenderedSupersampling(
    degradation: DegradationConfig, camera: CameraConfig, supersampling: int
) -> None:
    """For a task whose top-level `supersampling` renders `camera` (and sets the
    degradation's): refuses a degradation.supersampling of its own, and a rendered image
    beyond MAX_RENDER_PIXELS (drake_config_checks.CheckRenderSize)."""
    if degradation.supersampling != 1:
        raise ConfigurationError(
            "set the camera's supersampling (>= 1) with the top-level key 'supersampling'"
        )
    CheckRenderSize(camera, supersampling, "supersampling")


def SeededDegradation(config: DegradationConfig, random_seed: int) -> DegradationConfig:
    """`config` with the noise seed of a scenario's `random_seed`; a seed set in `config`
    that differs is refused (ConfigurationError), never silently replaced."""
    if config.seed is not None and config.seed != random_seed:
        raise ConfigurationError(
            f"degradation.seed ({config.seed}) conflicts with the scenario's 'random_seed' "
            f"({random_seed}): set that only"
        )
    return dataclasses.replace(config, seed=random_seed)


def DegradeImage(image: np.ndarray, params: DegradationConfig, stream: int = 0) -> np.ndarray:
    """A degraded copy of a (kH) x (kW) x (3|4) uint8 image, H x W; `stream` varies the
    noise draw."""
    params.Validate()
    k = params.supersampling
    height, width = image.shape[:2]
    if height == 0 or width == 0 or height % k or width % k:
        raise ConfigurationError(
            f"the image is {width} x {height} px; its width and height must be positive "
            f"multiples of supersampling = {k}"
        )
    if k > 1:
        size = (image.shape[1] // k, image.shape[0] // k)
        image = cv2.resize(image, size, interpolation=cv2.INTER_AREA)
    rgb = image[..., :3].astype(np.float32) * params.lighting
    if params.blur_sigma_px > 0:
        rgb = cv2.GaussianBlur(rgb, (0, 0), params.blur_sigma_px)
    if params.noise_std > 0:
        rng = np.random.default_rng([params.seed or 0, stream])
        rgb += rng.normal(0.0, params.noise_std, rgb.shape).astype(np.float32)
    out = image.copy()
    out[..., :3] = np.clip(np.rint(rgb), 0, 255).astype(np.uint8)
    return out


class ImageDegradation(LeafSystem):
    """Input `color_image` (ImageRgba8U, supersampling x the output size) -> output
    `color_image` (ImageRgba8U), degraded as in DegradeImage; the noise stream is the
    context time in microseconds."""

    def __init__(self, params: DegradationConfig) -> None:
        super().__init__()
        CheckInstance("params", params, DegradationConfig)
        params.Validate()
        self._params = params
        self._input = self.DeclareAbstractInputPort(
            "color_image", AbstractValue.Make(ImageRgba8U())
        )
        self.DeclareAbstractOutputPort(
            "color_image",
            lambda: AbstractValue.Make(ImageRgba8U()),
            self.CalcImage,
            prerequisites_of_calc={self._input.ticket(), self.time_ticket()},
        )

    def CalcImage(self, context: Context, value: AbstractValue) -> None:
        source = self._input.Eval(context)
        degraded = DegradeImage(
            np.asarray(source.data), self._params, round(context.get_time() * 1e6)
        )
        image = ImageRgba8U(degraded.shape[1], degraded.shape[0])
        image.mutable_data[:] = degraded
        value.set_value(image)
