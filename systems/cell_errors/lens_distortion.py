"""LensDistortion: a camera's distorted colour image from a wider pinhole render."""

from pydrake.common.value import AbstractValue
from pydrake.systems.framework import Context, LeafSystem
from pydrake.systems.sensors import ImageRgba8U

from guidedarm.systems.cell_errors.lens_distortion_math import LensRemap, Remap
from guidedarm.systems.config_checks import CheckInstance


class LensDistortion(LeafSystem):
    """Input `pinhole_image` (ImageRgba8U of remap.render_width x render_height), output
    `color_image` (ImageRgba8U of the camera's size): the render seen through the lens
    (lens_distortion_math.Remap)."""

    def __init__(self, remap: LensRemap) -> None:
        super().__init__()
        CheckInstance("remap", remap, LensRemap)
        self._remap = remap
        self.DeclareAbstractInputPort(
            "pinhole_image",
            AbstractValue.Make(ImageRgba8U(remap.render_width, remap.render_height)),
        )
        height, width = remap.map_x.shape
        self.DeclareAbstractOutputPort(
            "color_image", lambda: AbstractValue.Make(ImageRgba8U(width, height)), self._Calc
        )

    def _Calc(self, context: Context, output: AbstractValue) -> None:
        pinhole = self.get_input_port().Eval(context)
        image = output.get_mutable_value()
        image.mutable_data[:] = Remap(pinhole.data, self._remap)
