"""The calibration board's model: models/calibration/charuco_board.sdf, a textured quad
(OBJ, MTL, PNG) generated from models/calibration/board.yaml.

The SDF's link `board` is the board frame B (charuco_board.py: origin at the outer corner
of the top-left square, x right, y down the printed page, z into the board); the print
(with a white margin of one square) faces -z, backed by a 5 mm grey plate. Visual only: a
calibration board is looked at, not touched.

Regenerate after editing board.yaml: .venv/bin/python -m guidedarm.diagrams.calibration.board_assets
"""

from __future__ import annotations

from pathlib import Path

from PIL import Image

from guidedarm.diagrams.calibration.calibration_files import LoadBoardSpec
from guidedarm.diagrams.station.model_paths import MODELS_DIR
from guidedarm.systems.calibration.charuco_board import BoardImage, BoardSpec

BOARD_DIR = MODELS_DIR / "calibration"
DEFAULT_BOARD_FILE = BOARD_DIR / "board.yaml"
TEXTURE_PX_PER_SQUARE = 300


def WriteBoardAssets(board_file: Path = DEFAULT_BOARD_FILE, out_dir: Path = BOARD_DIR) -> list:
    """Writes charuco_board.{png,obj,mtl,sdf} for the board in `board_file`; returns them."""
    spec = LoadBoardSpec(board_file)
    pixels_per_m = TEXTURE_PX_PER_SQUARE / spec.square_m
    texture = BoardImage(spec, pixels_per_m, margin_px=TEXTURE_PX_PER_SQUARE)
    paths = [out_dir / f"charuco_board.{e}" for e in ("png", "obj", "mtl", "sdf")]
    Image.fromarray(texture).save(paths[0])
    paths[1].write_text(_Obj(spec))
    paths[2].write_text(
        "newmtl charuco_board\nKa 1 1 1\nKd 1 1 1\nKs 0 0 0\nmap_Kd charuco_board.png\n"
    )
    paths[3].write_text(_Sdf(spec))
    return paths


def _Obj(spec: BoardSpec) -> str:
    """The printed quad in B, its margin included, facing -z (counter-clockwise seen from
    the viewer in front); texture v grows up the picture, y_B down."""
    width, height = spec.size_m()
    s = spec.square_m
    left, right, top, bottom = -s, width + s, -s, height + s
    return (
        "mtllib charuco_board.mtl\no charuco_board\n"
        f"v {left} {top} 0\nv {right} {top} 0\nv {right} {bottom} 0\nv {left} {bottom} 0\n"
        "vt 0 1\nvt 1 1\nvt 1 0\nvt 0 0\nvn 0 0 -1\nusemtl charuco_board\n"
        "f 1/1/1 4/4/1 3/3/1\nf 1/1/1 3/3/1 2/2/1\n"
    )


def _Sdf(spec: BoardSpec) -> str:
    width, height = spec.size_m()
    s = spec.square_m
    plate = f"{width + 2 * s:.4f} {height + 2 * s:.4f} 0.005"
    centre = f"{width / 2:.4f} {height / 2:.4f} 0.0026"
    return f"""<?xml version="1.0"?>
<!-- Generated from board.yaml by guidedarm.diagrams.calibration.board_assets: do not edit. -->
<sdf version="1.9">
  <model name="charuco_board">
    <link name="board">
      <visual name="print"><geometry><mesh><uri>charuco_board.obj</uri></mesh></geometry></visual>
      <visual name="plate"><pose>{centre} 0 0 0</pose>
        <geometry><box><size>{plate}</size></box></geometry>
        <material><diffuse>0.5 0.5 0.5 1</diffuse></material></visual>
    </link>
  </model>
</sdf>
"""


def main() -> None:
    for path in WriteBoardAssets():
        print(f"wrote {path}")


if __name__ == "__main__":
    main()
