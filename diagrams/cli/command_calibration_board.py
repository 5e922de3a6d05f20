"""`guidedarm calibration-board BOARD.yaml --out board.png --dpi N`: the printable ChArUco
board of a board file (a white margin of one square around it; the PNG carries its dpi,
so printing at 100 % scale gives the board's size)."""

from __future__ import annotations

import argparse
from pathlib import Path

from PIL import Image

from guidedarm.diagrams.calibration.calibration_files import LoadBoardSpec
from guidedarm.systems.calibration.charuco_board import BoardImage
from guidedarm.systems.errors import ConfigurationError

INCH_M = 0.0254


def register(subparsers: argparse._SubParsersAction) -> None:
    parser = subparsers.add_parser(
        "calibration-board", help="print a ChArUco calibration board (PNG) from BOARD.yaml"
    )
    parser.add_argument("board", type=Path, help="BOARD.yaml")
    parser.add_argument("--out", type=Path, required=True, help="PNG file to write")
    parser.add_argument("--dpi", type=int, default=300, help="printer dots per inch (300)")
    parser.set_defaults(func=board_command)


def board_command(args: argparse.Namespace) -> int:
    spec = LoadBoardSpec(args.board)
    if not 50 <= args.dpi <= 2400:
        raise ConfigurationError(f"--dpi {args.dpi}: must be in [50, 2400]")
    if args.out.suffix.lower() != ".png":
        raise ConfigurationError(f"--out {args.out}: must be a .png file")
    pixels_per_m = args.dpi / INCH_M
    image = BoardImage(spec, pixels_per_m, margin_px=round(spec.square_m * pixels_per_m))
    try:
        Image.fromarray(image).save(args.out, dpi=(args.dpi, args.dpi))
    except OSError as e:
        raise ConfigurationError(f"--out {args.out}: cannot write ({e.strerror})") from None
    width, height = spec.size_m()
    print(
        f"wrote {args.out}: {spec.squares_x} x {spec.squares_y} squares of {spec.square_m * 1e3:g}"
        f" mm ({width * 1e3:g} x {height * 1e3:g} mm plus a margin), {spec.dictionary}; "
        "print at 100 % scale and measure a square before calibrating"
    )
    return 0
