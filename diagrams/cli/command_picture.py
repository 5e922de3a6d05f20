"""`guidedarm picture FILE.png`: Drake camera images of the three arms, side by side."""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np
from pydrake.common.schema import Transform
from pydrake.systems.sensors import CameraConfig

from guidedarm.diagrams.station.scenario import StationScenario
from guidedarm.diagrams.station.scene_views import (
    ARM_SCENES,
    SCENE_VIEWPOINTS,
    LookAt,
    SceneDirectives,
)
from guidedarm.diagrams.station.station import MakeStation

CAMERA = "view"


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

    views = [RenderScene(ARM_SCENES[arm], args.width, args.height) for arm in ARM_SCENES]
    args.output.parent.mkdir(parents=True, exist_ok=True)
    cv2.imwrite(str(args.output), cv2.cvtColor(np.hstack(views), cv2.COLOR_RGB2BGR))
    print(f"wrote {args.output}")
    return 0
