"""The `foldbot` command: subcommands over the library (fold, eval-perception, score)."""

from __future__ import annotations

import argparse
import contextlib
import os
import signal
import sys
import threading
from collections.abc import Iterator, Sequence
from typing import Any

from foldbot import __version__
from foldbot.errors import FoldbotError


def build_parser() -> argparse.ArgumentParser:
    """The argument parser with every subcommand."""
    from foldbot.commands import (
        bench,
        calibrate,
        check_layout,
        compare,
        eval_perception,
        export_bag,
        fold,
        print_board,
        ros_calibrate,
        ros_cell,
        ros_check,
        ros_fold,
        ros_replay,
        score,
    )

    parser = argparse.ArgumentParser(
        prog="foldbot",
        description="foldbot: a cloth-folding robot stack on a simulated UR5 cell (PyBullet).",
    )
    parser.add_argument("--version", action="version", version=f"foldbot {__version__}")
    sub = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")
    commands = {
        "fold": (fold, "fold a garment once and write the episode folder"),
        "eval-perception": (eval_perception, "measure perception accuracy on randomised scenes"),
        "bench": (bench, "run fold episodes over many seeds and summarise them"),
        "compare": (compare, "two benchmark runs of the same towels, episode by episode"),
        "score": (score, "recompute an episode's metrics from cloth.npz and result.json"),
        "ros-fold": (ros_fold, "fold over ROS 1 topics (roslaunch) and write the episode folder"),
        "ros-cell": (ros_cell, "the simulated cell alone, served as a real one (drivers, camera)"),
        "ros-calibrate": (
            ros_calibrate,
            "find the camera's pose on a running cell from a board the arm holds (ROS)",
        ),
        "ros-check": (ros_check, "is a running cell ready to fold? ask it for all a fold needs"),
        "ros-replay": (ros_replay, "replay a recorded bag through perception; compare keypoints"),
        "calibrate": (
            calibrate,
            "find the camera's pose from a board the arm holds (simulated cell)",
        ),
        "check-layout": (
            check_layout,
            "can the arm reach, and the camera see, every point of a layout's workspace?",
        ),
        "print-board": (
            print_board,
            "the calibration board (chessboard or ChArUco) as a PNG to print at full size",
        ),
        "export-bag": (export_bag, "write an episode folder as a ROS 1 bag (no ROS needed)"),
    }
    for name, (module, help_text) in commands.items():
        p = sub.add_parser(
            name,
            help=help_text,
            description=module.__doc__,
            formatter_class=argparse.RawDescriptionHelpFormatter,
        )
        module.add_arguments(p)
        p.set_defaults(run=module.run)
    return parser


class Terminated(BaseException):
    """SIGTERM, raised where the command is (as Ctrl-C raises KeyboardInterrupt), so what it
    was writing is discarded on the way out instead of left half-written."""


RESEND_S = 0.01
"""How long after a swallowed Terminated (or KeyboardInterrupt) its signal is sent again
(sigterm_raises)."""


def _terminate(signum: int, frame: object) -> None:
    raise Terminated


@contextlib.contextmanager
def sigterm_raises() -> Iterator[None]:
    """While inside (in the main thread): SIGTERM raises Terminated where the command is, as
    Ctrl-C raises KeyboardInterrupt. A Terminated the interpreter cannot raise, because the
    signal came while it ran a callback of its own (an at-fork handler as a subprocess starts,
    an object's __del__: it prints "Exception ignored" and goes on), is sent again a moment
    later from another thread (RESEND_S), until it is raised where the command is: not lost.
    So is a Ctrl-C's KeyboardInterrupt lost so."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    previous, previous_hook = signal.signal(signal.SIGTERM, _terminate), sys.unraisablehook

    def hook(unraisable: Any) -> None:
        lost = unraisable.exc_value
        if isinstance(lost, Terminated | KeyboardInterrupt):
            # Not from here: a signal sent now would be handled inside this hook, swallowed too.
            signum = signal.SIGTERM if isinstance(lost, Terminated) else signal.SIGINT
            resend = threading.Timer(RESEND_S, os.kill, (os.getpid(), signum))
            resend.daemon = True
            resend.start()
            return
        previous_hook(unraisable)

    sys.unraisablehook = hook
    try:
        yield
    finally:
        sys.unraisablehook = previous_hook
        signal.signal(signal.SIGTERM, previous)


def main(argv: Sequence[str] | None = None) -> int:
    """Entry point: parse, run, and turn foldbot's deliberate errors into one clear line."""
    parser = build_parser()
    args = parser.parse_args(argv)
    # A `kill` or `timeout` stops a command as Ctrl-C does: staged output is cleaned up.
    try:
        with sigterm_raises():
            return int(args.run(args) or 0)
    except FoldbotError as exc:
        print(f"foldbot {args.command}: error: {exc}", file=sys.stderr)
        for note in getattr(exc, "__notes__", ()):  # e.g. where a failed episode's video went
            print(f"foldbot {args.command}: {note}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print(f"foldbot {args.command}: interrupted", file=sys.stderr)
        return 130
    except Terminated:
        print(f"foldbot {args.command}: terminated (SIGTERM)", file=sys.stderr)
        return 128 + signal.SIGTERM


if __name__ == "__main__":
    sys.exit(main())
