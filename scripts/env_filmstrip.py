"""One environment episode as a filmstrip: the reset's frame and each step's, captioned with the
environment's measure (coverage, or fold error) and the step's reward.

    .venv/bin/python scripts/env_filmstrip.py --env fold --recipe quarter --seed 3 \
        --out docs/env_towel_fold.png

The policy is the environment's baseline (evaluate.BASELINES); frames are the camera's full
frame, cropped to the table around the towel and scaled to `--width` px each.
"""

from __future__ import annotations

# isort: off
import foldbot  # noqa: F401  first: caps numpy's SIMD level before numpy loads (foldbot.simd)

# isort: on
import argparse
import sys
from pathlib import Path

import cv2
import imageio.v3 as iio
import numpy as np

from foldbot.envs.evaluate import BASELINES, ENVS, MEASURES, make_policy
from foldbot.planning.recipes import RECIPES

CROP = (40, 440, 100, 540)
"""Rows and columns (top, bottom, left, right) of the 480 × 640 frame kept: the table."""


def caption(frame: np.ndarray, lines: list[str]) -> np.ndarray:
    """`frame` with a white band under it holding `lines`."""
    band = np.full((22 * len(lines) + 8, frame.shape[1], 3), 255, np.uint8)
    for i, text in enumerate(lines):
        cv2.putText(band, text, (6, 22 * i + 20), cv2.FONT_HERSHEY_SIMPLEX, 0.55, (0, 0, 0), 1)
    return np.vstack([frame, band])


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--env", choices=tuple(ENVS), default="fold")
    parser.add_argument("--recipe", choices=RECIPES, default="half", help="--env fold only")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--resolution", type=int, default=None)
    parser.add_argument("--width", type=int, default=320, help="px per frame")
    parser.add_argument("--out", type=Path, required=True, help="a .png")
    args = parser.parse_args(argv)
    fields = {"resolution": args.resolution}
    if args.env == "fold":
        fields["recipe"] = args.recipe
    env = ENVS[args.env](**fields)
    measure = MEASURES[args.env]
    form = "coverage {:.2f}" if measure == "coverage" else "fold error {:.1f} mm"
    try:
        policy = make_policy(BASELINES[args.env], env, args.seed)
        _obs, info = env.reset(seed=args.seed)
        tiles = []

        def tile(lines: list[str]) -> None:
            top, bottom, left, right = CROP
            frame = np.asarray(env.unwrapped.observation.rgb)[top:bottom, left:right]
            h = round(frame.shape[0] * args.width / frame.shape[1])
            frame = cv2.resize(frame, (args.width, h), interpolation=cv2.INTER_AREA)
            tiles.append(caption(frame, lines))

        tile([f"seed {args.seed}: start", form.format(info[measure])])
        step = 0
        while (action := policy(info)) is not None:
            _obs, reward, terminated, truncated, info = env.step(action)
            step += 1
            if info.get("diverged") or info.get("failed"):
                print(f"step {step}: {info.get('diverged') or info.get('failed')}", file=sys.stderr)
                break
            held = "held" if info["grasp_success"] else "missed"
            tile(
                [
                    f"step {step}: grasp {held}",
                    f"{form.format(info[measure])}, reward {reward:+.3f}",
                ]
            )
            if terminated or truncated:
                break
    finally:
        env.close()
    strip = np.hstack(tiles)
    args.out.parent.mkdir(parents=True, exist_ok=True)
    iio.imwrite(args.out, strip)
    print(f"{len(tiles)} frames → {args.out}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
