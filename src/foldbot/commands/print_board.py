"""`foldbot print-board`: the calibration board (a chessboard, or `--board-pattern charuco` a
ChArUco board) as a PNG to print at 100 % (its resolution written into the file), for `foldbot
ros-calibrate` on a real cell.

Print it without scaling, check one square with a ruler (--square, 24 mm by default), and fix it
flat on a stiff plate to a bracket beside the jaws, its printed face up when the gripper points
down (calibration.views.BoardMount: about 6 cm above the TCP, reaching 5–28 cm out along the
tool's −x). The calibration solves where it really sits; the nominal place only aims the views.
"""

from __future__ import annotations

import argparse
from pathlib import Path

from foldbot.calibration.board import board_image
from foldbot.commands.calibrate import add_board_shape_arguments, board_from_args
from foldbot.errors import ConfigError, OutputError

INCH_M = 0.0254


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("file", type=Path, metavar="FILE.png", help="the picture to write")
    add_board_shape_arguments(parser)
    parser.add_argument("--dpi", type=int, default=300, help="print resolution (default 300)")


def run(args: argparse.Namespace) -> int:
    from PIL import Image

    if args.file.suffix.lower() != ".png":
        raise ConfigError(f"the board is written as a .png, got {str(args.file)!r}")
    if not 72 <= args.dpi <= 2400:
        raise ConfigError(f"--dpi must be in [72, 2400], got {args.dpi!r}")
    board = board_from_args(args)
    img = board_image(board, args.dpi / INCH_M)
    try:
        args.file.parent.mkdir(parents=True, exist_ok=True)
        Image.fromarray(img).save(args.file, dpi=(args.dpi, args.dpi))
    except OSError as exc:
        raise OutputError(f"cannot write {str(args.file)!r}: {exc.strerror or exc}") from None
    w_mm, h_mm = (1000.0 * v / (args.dpi / INCH_M) for v in (img.shape[1], img.shape[0]))
    name = "ChArUco board" if board.pattern == "charuco" else "chessboard"
    markers = (
        f" with {board.dictionary} ArUco markers of {1000 * board.marker_m:g} mm"
        if board.pattern == "charuco"
        else ""
    )
    print(
        f"print-board: a {name} of {board.squares_x} × {board.squares_y} squares of "
        f"{1000 * board.square_m:g} mm{markers}, {w_mm:.0f} × {h_mm:.0f} mm at {args.dpi} dpi: "
        f"{args.file} (print at 100 %, then measure a square)"
    )
    return 0
