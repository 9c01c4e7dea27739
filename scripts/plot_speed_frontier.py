"""Picture what a cell's speed costs in folds: for benchmark runs of one cell at different meshes
and physics steps, each recipe's success rate and mean fold error against the run's simulation
speed (simulated over wall seconds), with real time marked. Reads each run's summary.json.
Prints a line per point plotted; a group without a simulation speed or success rate is named on
stderr, and a picture with no point at all is refused (exit 1, nothing written).

    .venv/bin/python scripts/plot_speed_frontier.py runs/A="17 vertices, 1/360 s" runs/B --out fig.png
"""

from __future__ import annotations

# isort: off
import foldbot  # noqa: F401  first: caps numpy's SIMD level before numpy loads (foldbot.simd)

# isort: on
import argparse
import json
import sys
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
from matplotlib.ticker import NullFormatter, ScalarFormatter

from foldbot.bench.report import save_figure

MARKERS = {"half": "o", "diagonal": "^", "thirds": "s", "quarter": "D"}


def load_groups(run: Path) -> list[dict]:
    """The run's per-group figures (summary.json's `groups`); SystemExit naming the run when it
    has no summary."""
    path = run / "summary.json"
    if not path.is_file():
        raise SystemExit(
            f"plot_speed_frontier: {run} has no summary.json (run foldbot bench first)"
        )
    return json.loads(path.read_text())["groups"]


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("runs", nargs="+", help="benchmark run folders, each optionally RUN=LABEL")
    ap.add_argument("--out", type=Path, required=True, help="PNG to write")
    ap.add_argument("--title", default="", help="a title over both panels")
    args = ap.parse_args()
    if args.out.suffix.lower() != ".png":
        ap.error(f"--out must name a .png file, got {args.out}")
    fig, (ax_ok, ax_err) = plt.subplots(1, 2, figsize=(10, 4.2), constrained_layout=True)
    colours = plt.rcParams["axes.prop_cycle"].by_key()["color"]
    plotted = 0
    for i, spec in enumerate(args.runs):
        run, _, label = spec.partition("=")
        colour = colours[i % len(colours)]
        for g in load_groups(Path(run)):
            speed, rate = g.get("sim_speed"), g.get("success_rate")
            error = (g.get("fold_error_mm") or {}).get("mean")
            recipe = g.get("recipe", "?")
            if speed is None or rate is None:
                missing = " and ".join(k for k in ("sim_speed", "success_rate") if g.get(k) is None)
                print(
                    f"plot_speed_frontier: {run}: group {recipe!r} has no {missing}; not plotted",
                    file=sys.stderr,
                )
                continue
            marker = MARKERS.get(recipe, "x")
            ax_ok.scatter(speed, 100 * rate, color=colour, marker=marker, s=45)
            if error is not None:
                ax_err.scatter(speed, error, color=colour, marker=marker, s=45)
            plotted += 1
            shown = "no fold error" if error is None else f"fold error {error:g} mm"
            print(f"point: {label or run} {recipe}: speed {speed:g}, success {rate:g}, {shown}")
        ax_ok.scatter([], [], color=colour, marker="o", label=label or run)
    if not plotted:
        print(
            "plot_speed_frontier: no group of the runs has both a sim_speed and a success_rate: "
            "nothing to plot, nothing written",
            file=sys.stderr,
        )
        return 1
    for recipe, marker in MARKERS.items():
        ax_err.scatter([], [], color="grey", marker=marker, label=recipe)
    for ax in (ax_ok, ax_err):
        ax.axvline(1.0, color="black", lw=0.8, ls="--")
        ax.set_xlabel("simulation speed (× real time)")
        ax.grid(alpha=0.3)
    ax_ok.axhline(95, color="green", lw=0.8, ls=":")
    ax_ok.set_ylabel("success (%)")
    ax_ok.set_ylim(-5, 105)
    ax_ok.legend(fontsize=8, loc="lower left")
    ax_err.set_ylabel("fold error, mean (mm)")
    ax_err.set_yscale("log")
    ax_err.yaxis.set_major_formatter(ScalarFormatter())
    ax_err.yaxis.set_minor_formatter(NullFormatter())
    ax_err.set_yticks([2, 5, 10, 20, 50, 100])
    ax_err.legend(fontsize=8, loc="upper left")
    if args.title:
        fig.suptitle(args.title, fontsize=10)
    save_figure(fig, args.out)
    print(f"written: {args.out}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
