"""`foldbot compare FIRST SECOND`: two benchmark runs of the same towels, episode by episode.

Pairs the episodes of two `foldbot bench --out` folders by id (the same towel folded twice: by
two versions of the code, or with two settings), and prints per group and overall how many came
out the same to the last digit, both success rates, and the fold error's paired difference with
its 95 % interval; then every pair that changed. For example, a loop option's trial against the
suite's own run:

    foldbot bench --suite pants --out runs/pants
    foldbot bench --suite pants --loop-option top_layer_first=false --out runs/p_nofirst
    foldbot compare runs/pants runs/p_nofirst --plot runs/p_nofirst/against_pants.png

`--plot FILE.png` also draws every pair, second run's fold error against the first's.
"""

from __future__ import annotations

import argparse
import json
import tempfile
from pathlib import Path

from foldbot.bench.compare import PAIRINGS, compare_runs, markdown, plot_pairs
from foldbot.errors import ConfigError, OutputError


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
    parser.add_argument(
        "--plot",
        type=Path,
        metavar="FILE.png",
        help="also draw every pair: the second run's fold error against the first's (PNG)",
    )


def _check_plot_path(plot: Path) -> None:
    """ConfigError (OutputError where the folder cannot be written) unless `plot` names a .png
    file that can be written: before any run is read, so a bad path costs nothing."""
    if plot.suffix.lower() != ".png":
        raise ConfigError(f"--plot {plot}: the picture is written as PNG; name a .png file")
    if plot.is_dir():
        raise ConfigError(f"--plot {plot} is a folder; name a .png file to write")
    if not plot.parent.is_dir():
        raise ConfigError(f"--plot {plot}: its folder {plot.parent} does not exist")
    try:  # the one sure test of a writable folder (read-only mounts, permissions, root)
        with tempfile.NamedTemporaryFile(dir=plot.parent, prefix=f".{plot.name}.probe-"):
            pass
    except OSError as exc:
        raise OutputError(
            f"--plot {plot}: cannot write in its folder {plot.parent} ({exc.strerror or exc}); "
            "name a .png file in a writable folder"
        ) from None


def run(args: argparse.Namespace) -> int:
    """Print the comparison."""
    plot = args.plot
    if plot is not None:
        _check_plot_path(plot)
    comparison = compare_runs(args.first, args.second, args.pair_by)
    print(json.dumps(comparison, indent=2) if args.json else markdown(comparison), end="")
    if args.json:
        print()
    if plot is not None:
        plot_pairs(comparison, plot)
        if not args.json:
            print(f"\nPairs drawn in {plot}")
    return 0
