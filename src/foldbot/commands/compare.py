"""`foldbot compare FIRST SECOND`: two benchmark runs of the same towels, episode by episode.

Pairs the episodes of two `foldbot bench --out` folders by id (the same towel folded twice: by
two versions of the code, or with two settings), and prints per group and overall how many came
out the same to the last digit, both success rates, and the fold error's paired difference with
its 95 % interval; then every pair that changed. For example, a loop option's trial against the
suite's own run:

    foldbot bench --suite pants --out runs/pants
    foldbot bench --suite pants --loop-option top_layer_first=false --out runs/p_nofirst
    foldbot compare runs/pants runs/p_nofirst
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

from foldbot.bench.compare import PAIRINGS, compare_runs, markdown


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Options of `foldbot compare`."""
    parser.add_argument("first", type=Path, help="a run folder (`foldbot bench --out`): before")
    parser.add_argument("second", type=Path, help="a run folder of the same towels: after")
    parser.add_argument(
        "--pair-by",
        choices=PAIRINGS,
        default="id",
        help="pair episodes by id (default), or by seed within garment, perception and loop: "
        "two recipes on the same towels, e.g. a run of quarter against one of quarter_y",
    )
    parser.add_argument(
        "--json", action="store_true", help="print the comparison as JSON instead of Markdown"
    )


def run(args: argparse.Namespace) -> int:
    """Print the comparison."""
    comparison = compare_runs(args.first, args.second, args.pair_by)
    print(json.dumps(comparison, indent=2) if args.json else markdown(comparison), end="")
    if args.json:
        print()
    return 0
