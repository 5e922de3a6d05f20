"""`guidedarm picture FILE.png`: Drake camera images of the three arms, side by side."""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np
from pydrake.common.schema import Transform
from pydrake.systems.sensors import CameraConfig

from guidedarm.diagrams.run_context import PrepareOutputDirectory
from guidedarm.diagrams.station.scenario import StationScenario
from guidedarm.diagrams.station.scene_views import (
    ARM_SCENES,
    SCENE_VIEWPOINTS,
    LookAt,
    SceneDirectives,
)
from guidedarm.diagrams.station.station import MakeStation
from guidedarm.systems.errors import ConfigurationError

CAMERA = "view"
MAX_VIEW_SIZE_PX = 8192
IMAGE_SUFFIXES = (".png", ".jpg", ".jpeg", ".bmp", ".tif", ".tiff", ".webp")


def register(subparsers: argparse._SubParsersAction) -> None:
    parser = subparsers.add_parser("picture", help="render the three arms into one PNG")
    parser.add_argument("output", type=Path, help="PNG file to write")
    parser.add_argument("--width", type=int, default=640, help="width of each view (px)")
    parser.add_argument("--height", type=int, default=480, help="height of each view (px)")
    parser.set_defaults(func=picture_command)


def RenderScene(scene: str, width: int, height: int) -> np.ndarray:
    """RGB image (height x width x 3, uint8) of a scene at its default configuration,
    rendered by the station's VTK renderer through a Drake RgbdSensor."""
    eye, target = SCENE_VIEWPOINTS[scene]
    camera = CameraConfig(width=width, height=height, name=CAMERA)
    camera.X_PB = Transform(LookAt(eye, target))
    station = MakeStation(
        StationScenario(directives=SceneDirectives(scene), cameras={CAMERA: camera})
    )
    image = station.GetOutputPort(f"{CAMERA}.rgb_image").Eval(station.CreateDefaultContext())
    return np.array(image.data[:, :, :3], copy=True)


def picture_command(args: argparse.Namespace) -> int:
    import cv2

    for flag, size in (("--width", args.width), ("--height", args.height)):
        if not 1 <= size <= MAX_VIEW_SIZE_PX:
            raise ConfigurationError(f"{flag} must be 1 .. {MAX_VIEW_SIZE_PX} px, got {size}")
    if args.output.suffix.lower() not in IMAGE_SUFFIXES:
        raise ConfigurationError(
            f"{args.output}: the name must end in an image type ({', '.join(IMAGE_SUFFIXES)})"
        )
    PrepareOutputDirectory(args.output.parent, "output")
    if args.output.is_dir():
        raise ConfigurationError(f"{args.output} is a directory")
    views = [RenderScene(ARM_SCENES[arm], args.width, args.height) for arm in ARM_SCENES]
    if not cv2.imwrite(str(args.output), cv2.cvtColor(np.hstack(views), cv2.COLOR_RGB2BGR)):
        raise ConfigurationError(f"cannot write {args.output}")
    print(f"wrote {args.output}")
    return 0
