"""Picture what metrics.md's layer rule asks of a fold against what a perfect fold lying flat can
give: for one episode folder, the cloth laid out flat (its start) coloured, vertex by vertex, by
the layer the rule puts it on in the goal, by the sheets physically beneath it there
(foldbot.metrics.physical_layers), and by the height between the two. Ground truth only
(cloth.npz and result.json's fold lines), for explaining the metric.

    .venv/bin/python scripts/plot_perfect_fold.py runs/tshirt/episodes/EPISODE --out fig.png
"""

from __future__ import annotations

# isort: off
import foldbot  # noqa: F401  first: caps numpy's SIMD level before numpy loads (foldbot.simd)

# isort: on
import argparse
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
from matplotlib.tri import Triangulation

from foldbot.errors import ConfigError
from foldbot.io.episode import load_episode
from foldbot.metrics import fold_goal, physical_layers


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("episode", type=Path, help="an episode folder (result.json, cloth.npz)")
    ap.add_argument("--out", type=Path, required=True, help="PNG to write")
    args = ap.parse_args()
    if args.out.suffix.lower() != ".png":
        ap.error(f"--out must name a .png file, got {args.out}")
    try:
        ep = load_episode(args.episode)
    except ConfigError as exc:
        ap.error(str(exc))
    result, t = ep.result, ep.thickness
    goal, layers = fold_goal(ep.initial, ep.fold_lines, t)
    resting = physical_layers(goal, layers, ep.faces)
    lacking_mm = (layers - resting) * t * 1000
    perfect = float(lacking_mm.mean())  # metrics.perfect_fold_error_mm, from the layers above

    tri = Triangulation(ep.initial[:, 0] * 100, ep.initial[:, 1] * 100, ep.faces)
    panels = (
        ("goal layer by the rule (metrics.md)", layers, "viridis", int(layers.max())),
        ("sheets beneath it in the goal, lying flat", resting, "viridis", int(layers.max())),
        ("height the rule asks above them (mm)", lacking_mm, "magma_r", None),
    )
    fig, axes = plt.subplots(1, 3, figsize=(13, 4.8), constrained_layout=True)
    for ax, (title, values, cmap, top) in zip(axes, panels, strict=True):
        art = ax.tripcolor(tri, values.astype(float), cmap=cmap, shading="flat", vmin=0, vmax=top)
        ax.triplot(tri, color="white", lw=0.2, alpha=0.5)
        ax.set_aspect("equal")
        ax.set_title(title)
        ax.set_xlabel("x (cm)")
        fig.colorbar(art, ax=ax, shrink=0.8)
    axes[0].set_ylabel("y (cm)")
    fig.suptitle(
        f"{result.get('garment')} {result.get('recipe')}, seed {result.get('seed')}, shown flat: "
        f"a perfect fold lying flat scores {perfect:.1f} mm "
        f"(cloth {t * 1000:.1f} mm thick); this episode {result['fold_error_mm']:.1f} mm"
    )
    args.out.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(args.out, dpi=90)
    print(
        f"wrote {args.out}: perfect fold {perfect:.1f} mm, episode {result['fold_error_mm']:.1f} mm"
    )
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
