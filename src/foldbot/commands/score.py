"""`foldbot score`: recompute an episode's metrics from its cloth.npz and result.json alone."""

from __future__ import annotations

import argparse
import json
from pathlib import Path

from foldbot.io.episode import rescore


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Options of `foldbot score`."""
    parser.add_argument("episode", type=Path, help="an episode folder written by `foldbot fold`")


def run(args: argparse.Namespace) -> int:
    """Print the recomputed metrics as JSON."""
    print(json.dumps(rescore(args.episode).as_dict(), indent=2))
    return 0
