"""`foldbot eval-perception`: score the vision estimator against simulator ground truth.

Renders N randomised scenes and compares `VisionEstimator` with the `GroundTruthOracle`:
- Randomised per scene: towel size (0.2–0.45 m per side, independent, so the aspect varies;
  `--towel-sides LO HI` draws from another range),
  position within the workspace, rotation over the full circle, cloth and table colour (a quarter
  of the scenes with a cloth colour close to the table's, where depth alone must find it),
  lighting (direction, colour, ambient/diffuse/specular, shadows), camera pose jitter (±3 cm
  eye and target, ±3° roll), depth noise (σ = a·z², a ≤ 0.0015 /m), depth dropouts, RGB noise,
  flat or folded in half (a mesh whose one half is already reflected onto the other, settled), and
  an arm over the workspace in some scenes (otherwise parked out of view, pan turned by π).
- Corner error (mm): 3-D distance between each vision corner and the oracle's corner of the same
  label. Flat scenes are compared with the mesh's corner vertices; folded scenes with the corners
  of the cloth's top-view outline (`GroundTruthOracle.outline_corners`), since two of a folded
  towel's four outline corners are fold-line ends, not mesh corners. The headline
  `corner_error_mm` is over flat scenes (the targets are for flat towels); `by_state` has both.
- `mask_iou`: vision mask vs the cloth pixels of the simulator's segmentation buffer, over the
  pixels the robot does not cover (the vision mask includes cloth hidden under the arm;
  undetected scenes count 0).
- `ms_per_frame`: wall time of `VisionEstimator.estimate` only (no rendering, no physics), mean
  over scenes after one warm-up call; `ms_per_frame_best`: the mean of each frame's fastest of
  3 runs, less sensitive to other work on the machine.
- `label_agreement`: share of detected scenes whose label matching is also the best cyclic
  matching (a flip near the rule's 45° ties shows up here and as a large corner error).
- Scenes whose physics diverges are reported in `sim_failures` and left out of every figure.

`--garment tshirt` / `--garment pants` scores `GarmentEstimator` instead, on flat garments:
- Randomised per scene: a garment drawn from its children's-size ranges (`TShirtSpec.sample`,
  `PantsSpec.sample`), yaw 90° ± 15° (top towards the robot, as the fold pipeline places it),
  centre within 3 cm of the workspace centre, settled; colours, lighting, camera jitter and
  noise as for towels; no arm unless `--arm-fraction` asks for it (`--arm-pose home`: the
  gripper where the one-arm cell parks while it looks, 25 cm over the workspace centre, so over
  the garment's top, as in the garment suites' frames); never folded.
- Per keypoint (`by_keypoint`): `detection_rate` (share of scenes where it was found) and
  `error_mm` (3-D distance to the mesh keypoint of the same name, `GroundTruthOracle
  .keypoint_positions`: median, mean, p95, max); overall `keypoint_error_mm` and
  `keypoint_detection_rate`; `mask_iou` and `ms_per_frame` as above.
  Measured (seed 0, 20 scenes each, 640×480): T-shirt median 0.31 mm, p95 1.11 mm, max 1.64 mm;
  pants median 0.29 mm, p95 1.01 mm, max 2.74 mm (the crotch); every keypoint found. With the
  arm at home in every scene (`--arm-fraction 1 --arm-pose home --scenes 40`): every garment
  recognised, pants max 4.8 mm; T-shirts max 1.9 mm, the neck left out on the 2 whose neckline
  the gripper hides (a keypoint the arm hides that no other outline gives is not guessed).

`--layout FILE.toml` (either kind): the scenes in that cell, as `foldbot fold --layout` builds
it (the towel on its table in its workspace, its arm, its obstacles, the camera moved with the
workspace); the estimator knows the obstacles as the cell's fixtures, as a fold's does.
`layouts/cloth_tray.toml` (a low tray in the image), 40 scenes, seed 0: max 6.59 mm, mask IoU
0.996; with the tray unknown 5 scenes read the tray as the towel, 460–630 mm off.
`--camera-pose CALIBRATION.json`: every scene seen from the camera a calibration found
(`foldbot ros-calibrate`: its pose, and its image size and intrinsics where the file keeps
them), without the ±3 cm jitter: perception's accuracy from where a real camera stands. A
calibration solved on the simulated cell (`foldbot calibrate`) also knows where the camera truly
stood (its `truth`): the scenes are rendered from there and perceived from the pose the
calibration found, so the calibration's own error counts in the figures; any other calibration's
pose is taken as exact.

`--depth-sensor M` (either kind): the depth comes from a sensor M m beside the colour camera, as
on a real RGB-D camera (`depth_sensor_config`), registered onto the colour image
(`perception.register`) before the estimator sees it. Measured at 25 mm: flat towels median
0.35 mm, p95 1.74 mm (seed 1, 100 scenes); T-shirts 0.40 / 2.48 mm, pants 0.40 / 1.57 mm.
"""

from __future__ import annotations

import argparse
import heapq
import json
import math
import shutil
import sys
import time
from dataclasses import asdict
from pathlib import Path
from typing import TYPE_CHECKING, Any

import imageio.v3 as iio
import numpy as np

from foldbot.calibration.hand_eye import pose_error_record
from foldbot.errors import ConfigError, FoldbotError, SimulationDivergedError
from foldbot.garments import GARMENT_KEYPOINTS
from foldbot.garments.towel import TowelSpec
from foldbot.garments.tshirt import TShirtSpec
from foldbot.io.staging import commit_output, output_path, prepare_output
from foldbot.metrics import keypoint_errors_mm
from foldbot.perception.estimator import EstimatorConfig, VisionEstimator
from foldbot.perception.garment_keypoints import GarmentEstimator, GarmentKeypointConfig
from foldbot.perception.keypoints import CORNER_LABELS
from foldbot.perception.overlay import draw_overlay
from foldbot.perception.segmentation import SegmentationConfig
from foldbot.perception.state import ClothState, mask_iou
from foldbot.sim.camera import CameraConfig
from foldbot.sim.layout import DEFAULT_LAYOUT, load_layout
from foldbot.sim.perception_scenes import (
    ARM_POSES,
    GARMENT_YAW,
    TOWEL_SIDES,
    GarmentScene,
    Scene,
    render_garment_scene,
    render_scene,
    sample_garment_scene,
    sample_scene,
)
from foldbot.types import Observation

if TYPE_CHECKING:
    from foldbot.layout_check import CameraPlacement

GARMENTS = ("towel", "tshirt", "pants")
"""Garments eval-perception can render."""
FOLDED_FRACTION = 0.3
"""Default share of folded towels (garments are always flat)."""
ARM_FRACTION = {"towel": 0.4, "tshirt": 0.0, "pants": 0.0}
"""Default share of scenes with the arm over the workspace, by garment."""
MAX_TOWEL_SIDE = 0.7
"""Largest towel side (m) `--towel-sides` accepts: a 70 cm towel fills the camera's view."""
MAX_DEPTH_BASELINE = 0.1
"""The farthest (m) eval-perception's depth sensor may sit from the colour camera."""
TIMING_REPEATS = 3
"""Each frame is estimated this many times: `ms` is the first run, `ms_best` the fastest."""


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Declare eval-perception's command-line options on `parser`."""
    parser.add_argument("--scenes", type=int, default=100, help="number of scenes (default 100)")
    parser.add_argument("--seed", type=int, default=0, help="random seed (default 0)")
    parser.add_argument("--out", type=output_path, required=True, help="output folder")
    parser.add_argument(
        "--save-overlays",
        type=int,
        default=0,
        metavar="K",
        help="write overlays of the K worst scenes to OUT/overlays (default 0)",
    )
    parser.add_argument("--garment", choices=GARMENTS, default="towel", help="garment kind")
    parser.add_argument("--width", type=int, default=None, help="image width (px; default 640)")
    parser.add_argument("--height", type=int, default=None, help="image height (px; default 480)")
    parser.add_argument(
        "--layout",
        type=Path,
        default=None,
        metavar="FILE.toml",
        help="the cell's layout (as for foldbot fold): the scenes lie in its workspace on its "
        "table, its arm stands where it says, the camera moves with the workspace",
    )
    parser.add_argument(
        "--camera-pose",
        type=Path,
        default=None,
        metavar="CALIBRATION.json",
        help="render every scene from the camera a calibration found (its pose, and its image "
        "size and intrinsics where the file keeps them) instead of the default camera jittered "
        "±3 cm: perception's accuracy from where your camera is; a calibration solved on the "
        "simulated cell (foldbot calibrate) renders from its true pose and perceives from the "
        "one it found, so its error counts",
    )
    parser.add_argument(
        "--folded-fraction",
        type=float,
        default=None,
        help=f"share of scenes with the towel folded in half (default {FOLDED_FRACTION}; "
        "T-shirts and pants: 0, always flat)",
    )
    parser.add_argument(
        "--arm-fraction",
        type=float,
        default=None,
        help="share of scenes with the arm over the workspace (default 0.4 for towels, 0 for "
        "T-shirts and pants)",
    )
    parser.add_argument(
        "--arm-pose",
        choices=ARM_POSES,
        default="anywhere",
        help="where those scenes' arm is: its gripper anywhere over the workspace, 12–35 cm up "
        "(default), or at home, 25 cm over the workspace centre, where the one-arm cell parks "
        "while it looks (`--arm-fraction 1 --arm-pose home`: the garment suites' first frames)",
    )
    parser.add_argument(
        "--towel-sides",
        type=float,
        nargs=2,
        default=list(TOWEL_SIDES),
        metavar=("LO", "HI"),
        help="each towel side drawn uniformly from LO to HI m (default %(default)s: the suites' "
        f"25–45 cm and smaller; at most {MAX_TOWEL_SIDE} m, where a towel fills the view)",
    )
    parser.add_argument(
        "--resolution", type=int, default=16, help="towel mesh vertices per long side (default 16)"
    )
    parser.add_argument(
        "--edge-length",
        type=float,
        default=None,
        help="T-shirt / pants mesh edge length in m (default: the spec's, 0.025)",
    )
    parser.add_argument(
        "--depth-sensor",
        type=float,
        default=None,
        metavar="M",
        help="render depth with a sensor M metres to the colour camera's left, as on a real "
        "RGB-D camera (turned 1°, 424 × 240 at 640 × 480 with a wider view), and register it "
        f"onto the colour image as the perception node does (0 < M ≤ {MAX_DEPTH_BASELINE}; "
        "default: depth rendered at the colour camera, as the cell's)",
    )
    parser.add_argument(
        "--garment-yaw-range",
        type=float,
        default=math.degrees(GARMENT_YAW[1]),
        metavar="DEG",
        help="T-shirts and pants lie at yaw 90° ± DEG (default 15; 180: any direction)",
    )


def _stats(values: list[float]) -> dict[str, float | int | None]:
    if not values:
        return {"median": None, "p95": None, "max": None, "n": 0}
    a = np.asarray(values, dtype=float)
    return {
        "median": float(np.median(a)),
        "p95": float(np.percentile(a, 95)),
        "max": float(a.max()),
        "n": len(values),
    }


def _label_ok(state: ClothState, truth: dict[str, np.ndarray]) -> bool:
    est = np.array([state.keypoints[n][0] for n in CORNER_LABELS])
    gt = np.array([truth[n] for n in CORNER_LABELS])
    costs = [np.linalg.norm(est - np.roll(gt, s, axis=0), axis=1).sum() for s in range(4)]
    return int(np.argmin(costs)) == 0


def _group(rows: list[dict[str, Any]]) -> dict[str, Any]:
    detected = [r for r in rows if r["detected"]]
    errors = [e for r in detected for e in r["corner_error_mm"].values()]
    ms = [r["ms"] for r in rows]
    best = [r["ms_best"] for r in rows]
    return {
        "scenes": len(rows),
        "corner_error_mm": _stats(errors),
        "detection_rate": len(detected) / len(rows) if rows else None,
        "mask_iou": float(np.mean([r["mask_iou"] for r in rows])) if rows else None,
        "ms_per_frame": float(np.mean(ms)) if ms else None,
        "ms_per_frame_p95": float(np.percentile(ms, 95)) if ms else None,
        "ms_per_frame_best": float(np.mean(best)) if best else None,
        "label_agreement": (
            float(np.mean([r["label_ok"] for r in detected])) if detected else None
        ),
    }


def _print_table(summary: dict[str, Any], worst: list[dict[str, Any]]) -> None:
    def fmt(v: Any, spec: str) -> str:
        if v is None:
            width = spec.lstrip("<>^").split(".")[0]
            return format("—", f">{width}") if width.isdigit() else "—"
        return format(v, spec)

    print(
        f"eval-perception: {summary['scenes']} scenes, seed {summary['seed']}, "
        f"{summary['width']}×{summary['height']}{_cell_words(summary)}"
    )
    header = (
        f"{'state':<8}{'scenes':>7}{'detect':>8}{'median mm':>11}{'p95 mm':>9}{'max mm':>9}"
        f"{'IoU':>7}{'labels':>8}{'ms/frame':>10}{'best ms':>9}"
    )
    print(header)
    print("-" * len(header))
    for name, g in summary["by_state"].items():
        ce = g["corner_error_mm"]
        print(
            f"{name:<8}{g['scenes']:>7}{fmt(g['detection_rate'], '>8.1%')}"
            f"{fmt(ce['median'], '>11.2f')}{fmt(ce['p95'], '>9.2f')}{fmt(ce['max'], '>9.2f')}"
            f"{fmt(g['mask_iou'], '>7.3f')}{fmt(g['label_agreement'], '>8.1%')}"
            f"{fmt(g['ms_per_frame'], '>10.1f')}{fmt(g['ms_per_frame_best'], '>9.1f')}"
        )
    ce = summary["corner_error_mm"]
    print(
        f"headline (flat towels): corner error median {fmt(ce['median'], '.2f')} mm, "
        f"p95 {fmt(ce['p95'], '.2f')} mm, max {fmt(ce['max'], '.2f')} mm; "
        f"detection {fmt(summary['detection_rate'], '.1%')}; "
        f"{fmt(summary['ms_per_frame'], '.1f')} ms/frame "
        f"(best of {TIMING_REPEATS}: {fmt(summary['ms_per_frame_best'], '.1f')})"
    )
    if worst:
        items = [
            f"#{r['index']} ("
            + ("not detected" if r["score"] is None else f"{r['score']:.1f} mm")
            + ")"
            for r in worst
        ]
        print("worst scenes: " + ", ".join(items))
    if summary["sim_failures"]:
        print(f"left out (physics diverged): {summary['sim_failures']}")


def _with_defaults(args: argparse.Namespace) -> argparse.Namespace:
    """A copy of `args` with the garment-dependent defaults (folded and arm fractions) filled in."""
    out = argparse.Namespace(**vars(args))
    garment = getattr(out, "garment", "towel")
    if getattr(out, "folded_fraction", None) is None:
        out.folded_fraction = FOLDED_FRACTION if garment == "towel" else 0.0
    if getattr(out, "arm_fraction", None) is None:
        out.arm_fraction = ARM_FRACTION.get(garment, 0.0)
    if not hasattr(out, "edge_length"):
        out.edge_length = None
    if not hasattr(out, "arm_pose"):
        out.arm_pose = "anywhere"
    if not hasattr(out, "garment_yaw_range"):
        out.garment_yaw_range = math.degrees(GARMENT_YAW[1])
    if not hasattr(out, "depth_sensor"):
        out.depth_sensor = None
    layout_file = getattr(out, "layout", None)
    out.cell_layout = DEFAULT_LAYOUT if layout_file is None else load_layout(layout_file)
    out.camera = None
    if getattr(out, "camera_pose", None) is not None:
        from foldbot.commands.check_layout import camera_placement

        if out.width is not None or out.height is not None:
            raise ConfigError(
                "--width and --height are the calibration's with --camera-pose (its camera_info, "
                "or 640 × 480 where it has none); give one or the other"
            )
        out.camera = camera_placement(out.camera_pose, out.cell_layout)
        out.width, out.height = out.camera.width, out.camera.height
    if out.width is None:
        out.width = 640
    if out.height is None:
        out.height = 480
    return out


def _validate(args: argparse.Namespace) -> None:
    checks = [
        (
            isinstance(args.scenes, int) and args.scenes > 0,
            f"--scenes must be > 0, got {args.scenes}",
        ),
        (
            isinstance(args.seed, int) and args.seed >= 0,
            f"--seed must be an integer ≥ 0, got {args.seed}",
        ),
        (
            isinstance(args.save_overlays, int) and args.save_overlays >= 0,
            f"--save-overlays must be ≥ 0, got {args.save_overlays}",
        ),
        (args.garment in GARMENTS, f"--garment must be one of {GARMENTS}, got {args.garment!r}"),
        (
            0.0 <= args.folded_fraction <= 1.0,
            f"--folded-fraction must be in [0, 1], got {args.folded_fraction}",
        ),
        (
            args.garment == "towel" or args.folded_fraction == 0.0,
            f"--folded-fraction must be 0 for --garment {args.garment} (only towels are "
            f"rendered folded), got {args.folded_fraction}",
        ),
        (
            0.0 <= args.arm_fraction <= 1.0,
            f"--arm-fraction must be in [0, 1], got {args.arm_fraction}",
        ),
        (
            args.arm_pose in ARM_POSES,
            f"--arm-pose must be one of {ARM_POSES}, got {args.arm_pose!r}",
        ),
        (
            0.0 <= args.garment_yaw_range <= 180.0,
            f"--garment-yaw-range must be in [0, 180] degrees, got {args.garment_yaw_range}",
        ),
        (
            0.05 <= args.towel_sides[0] <= args.towel_sides[1] <= MAX_TOWEL_SIDE,
            f"--towel-sides must be LO HI with 0.05 ≤ LO ≤ HI ≤ {MAX_TOWEL_SIDE} m, "
            f"got {args.towel_sides[0]} {args.towel_sides[1]}",
        ),
        (
            args.garment == "towel" or list(args.towel_sides) == list(TOWEL_SIDES),
            f"--towel-sides is for --garment towel, got {args.towel_sides[0]} "
            f"{args.towel_sides[1]} with --garment {args.garment}",
        ),
        (
            args.depth_sensor is None
            or (math.isfinite(args.depth_sensor) and 0.0 < args.depth_sensor <= MAX_DEPTH_BASELINE),
            f"--depth-sensor must be in (0, {MAX_DEPTH_BASELINE}] m, got {args.depth_sensor}",
        ),
        (
            args.garment != "towel" or args.garment_yaw_range == math.degrees(GARMENT_YAW[1]),
            "--garment-yaw-range is for --garment tshirt or pants; towel scenes draw their own "
            f"yaw, got {args.garment_yaw_range}",
        ),
    ]
    for ok, message in checks:
        if not ok:
            raise ConfigError(message)
    CameraConfig(width=args.width, height=args.height)  # ConfigError names a bad size
    TowelSpec(resolution=args.resolution)
    if args.edge_length is not None and args.garment == "towel":
        raise ConfigError(
            f"--edge-length is for --garment tshirt or pants (a towel's mesh is set by "
            f"--resolution), got {args.edge_length} with --garment towel"
        )
    if args.edge_length is not None:
        # The specs' own checks name a bad edge length.
        TShirtSpec(edge_length=args.edge_length)


def run(args: argparse.Namespace) -> int:
    """Run the evaluation: 0 on success, 2 (message on stderr) for bad arguments or --out."""
    try:
        args = _with_defaults(args)
        _validate(args)
        out = Path(args.out)
        stage = prepare_output(out)
    except FoldbotError as exc:
        print(f"foldbot eval-perception: error: {exc}", file=sys.stderr)
        return 2
    try:
        _evaluate(args, stage)
        commit_output(stage, out)
    except OSError as exc:
        shutil.rmtree(stage, ignore_errors=True)
        print(f"foldbot eval-perception: error: cannot write {out}: {exc}", file=sys.stderr)
        return 2
    except BaseException:
        shutil.rmtree(stage, ignore_errors=True)
        raise
    return 0


def _evaluate(args: argparse.Namespace, stage: Path) -> dict[str, Any]:
    if args.garment != "towel":
        return _evaluate_garment(args, stage)
    from tqdm import tqdm

    seg = SegmentationConfig(fixtures=args.cell_layout.obstacles)  # the cell's, known to it
    estimator = VisionEstimator(EstimatorConfig(segmentation=seg))
    rows: list[dict[str, Any]] = []
    failures: list[int] = []
    keep = int(args.save_overlays)
    worst_heap: list[tuple[float, int, Observation, ClothState, dict[str, np.ndarray]]] = []
    for i in tqdm(range(args.scenes), desc="eval-perception", unit="scene", file=sys.stderr):
        rng = np.random.default_rng([args.seed, i])
        scene = sample_scene(
            rng,
            i,
            args.folded_fraction,
            args.arm_fraction,
            args.arm_pose,
            tuple(args.towel_sides),
            args.cell_layout,
        )
        try:
            rendered = render_scene(
                scene,
                args.width,
                args.height,
                args.resolution,
                seed=args.seed * 100003 + i,
                depth_baseline=args.depth_sensor,
                layout=args.cell_layout,
                camera=args.camera,
            )
        except SimulationDivergedError:
            failures.append(i)
            continue
        obs, truth = rendered.obs, rendered.corners
        # The vision mask includes cloth hidden under the arm; score the pixels the arm leaves
        # visible, where the segmentation buffer knows the answer.
        seen = ~rendered.robot_mask
        if not rows:
            estimator.estimate(obs)  # warm-up (imports, caches): a running robot is warm
        times = []
        for _ in range(TIMING_REPEATS):
            t0 = time.perf_counter()
            state = estimator.estimate(obs)
            times.append(1000.0 * (time.perf_counter() - t0))
        row: dict[str, Any] = {
            "index": i,
            "state": scene.state,
            "detected": state.detected,
            "reason": state.reason,
            "ms": times[0],
            "ms_best": min(times),
            "mask_iou": mask_iou(state.mask & seen, rendered.cloth_mask) if state.detected else 0.0,
            "corner_error_mm": {},
            "confidence": {},
            "label_ok": False,
            "scene": _scene_record(scene, args.camera, ("index", "state")),
        }
        if state.detected:
            seen = {name: state.keypoints[name][0] for name in CORNER_LABELS}
            row["corner_error_mm"] = keypoint_errors_mm(seen, truth)
            row["confidence"] = {name: state.keypoints[name][1] for name in CORNER_LABELS}
            row["label_ok"] = _label_ok(state, truth)
        score = max(row["corner_error_mm"].values()) if state.detected else math.inf
        row["score"] = score if math.isfinite(score) else None  # None: not detected
        rows.append(row)
        if keep:
            item = (score, i, obs, state, truth)
            if len(worst_heap) < keep:
                heapq.heappush(worst_heap, item)
            elif score > worst_heap[0][0]:
                heapq.heapreplace(worst_heap, item)

    if not rows:
        raise ConfigError("every scene's physics diverged; nothing to score")
    flat = [r for r in rows if r["state"] == "flat"]
    folded = [r for r in rows if r["state"] == "folded"]
    everything = _group(rows)
    headline = _group(flat) if flat else everything
    summary: dict[str, Any] = {
        "scenes": len(rows),
        "seed": args.seed,
        "garment": args.garment,
        "width": args.width,
        "height": args.height,
        "folded_fraction": args.folded_fraction,
        "arm_fraction": args.arm_fraction,
        "arm_pose": args.arm_pose,
        "towel_sides_m": list(args.towel_sides),
        "depth_sensor_baseline_m": args.depth_sensor,
        **_cell_record(args),
        "corner_error_mm": headline["corner_error_mm"],
        "corner_error_scope": "flat scenes, vs mesh corners" if flat else "all scenes",
        "detection_rate": everything["detection_rate"],
        "mask_iou": everything["mask_iou"],
        "ms_per_frame": everything["ms_per_frame"],
        "ms_per_frame_p95": everything["ms_per_frame_p95"],
        "ms_per_frame_best": everything["ms_per_frame_best"],
        "label_agreement": everything["label_agreement"],
        "by_state": {"all": everything, "flat": _group(flat), "folded": _group(folded)},
        "sim_failures": failures,
        "rows": rows,
    }
    (stage / "summary.json").write_text(
        json.dumps(summary, indent=2, default=_json_default, allow_nan=False) + "\n"
    )
    worst = sorted(worst_heap, key=lambda t: (-t[0], t[1]))
    if worst:
        odir = stage / "overlays"
        odir.mkdir()
        for score, i, obs, state, truth in worst:
            del score
            img = draw_overlay(obs, state, reference=truth)
            iio.imwrite(odir / f"scene_{i:04d}.png", img)
    _print_table(summary, sorted(rows, key=_badness, reverse=True)[:5])
    return summary


def _scene_record(
    scene: Scene | GarmentScene, camera: CameraPlacement | None, leave: tuple[str, ...]
) -> dict[str, Any]:
    """A row's scene as summary.json keeps it: without `leave`, and without the jittered camera
    a fixed one (--camera-pose) replaced."""
    if camera is not None:
        leave = (*leave, "eye", "target", "roll")
    return {k: v for k, v in asdict(scene).items() if k not in leave}


def _cell_record(args: argparse.Namespace) -> dict[str, Any]:
    """The cell the scenes were rendered in: the layout's changes from the default cell's and the
    camera (`jittered`: the default camera, ±3 cm a scene; else the calibration's)."""
    camera: dict[str, Any] = {"source": "the default camera, jittered ±3 cm and ±3° a scene"}
    if args.camera is not None:
        camera = {
            "source": args.camera.source,
            "T_world_camera": args.camera.T_world_camera.tolist(),
            "K": args.camera.K.tolist(),
        }
        true = args.camera.true_T_world_camera
        if true is not None:
            camera |= {
                "true_T_world_camera": true.tolist(),
                **pose_error_record(args.camera.T_world_camera, true),
            }
    layout_file = getattr(args, "layout", None)
    return {
        "layout": args.cell_layout.changes(),
        "layout_file": None if layout_file is None else str(layout_file),
        "camera": camera,
    }


def _cell_words(summary: dict[str, Any]) -> str:
    """The header's note of a layout or a calibration's camera, where the run had one."""
    words = ""
    if summary.get("layout_file"):
        words += f", layout {summary['layout_file']}"
    camera = summary.get("camera", {})
    if "T_world_camera" in camera:
        words += f"; camera: {camera['source']}"
        if "calibration_error_mm" in camera:
            words += (
                f" (rendered from the true pose, perceived from the calibration's, "
                f"{camera['calibration_error_mm']:.2f} mm and "
                f"{camera['calibration_error_deg']:.3f}° off it)"
            )
    return words


def _stats_mean(values: list[float]) -> dict[str, float | int | None]:
    """_stats plus the mean (the garment summary's error statistics)."""
    out = _stats(values)
    out["mean"] = float(np.mean(values)) if values else None
    return out


def _garment_summary(
    rows: list[dict[str, Any]], names: tuple[str, ...]
) -> tuple[dict[str, Any], dict[str, Any]]:
    """Per-keypoint (detection rate, error statistics) and overall figures of garment rows."""
    by_keypoint = {}
    for name in names:
        errors = [r["keypoint_error_mm"][name] for r in rows if name in r["keypoint_error_mm"]]
        by_keypoint[name] = {
            "detection_rate": len(errors) / len(rows) if rows else None,
            "error_mm": _stats_mean(errors),
        }
    errors = [e for r in rows for e in r["keypoint_error_mm"].values()]
    ms = [r["ms"] for r in rows]
    overall = {
        "scenes": len(rows),
        "keypoint_error_mm": _stats_mean(errors),
        "keypoint_detection_rate": len(errors) / (len(rows) * len(names)) if rows else None,
        "detection_rate": float(np.mean([r["detected"] for r in rows])) if rows else None,
        "mask_iou": float(np.mean([r["mask_iou"] for r in rows])) if rows else None,
        "ms_per_frame": float(np.mean(ms)) if ms else None,
        "ms_per_frame_p95": float(np.percentile(ms, 95)) if ms else None,
        "ms_per_frame_best": float(np.mean([r["ms_best"] for r in rows])) if rows else None,
    }
    return by_keypoint, overall


def _evaluate_garment(args: argparse.Namespace, stage: Path) -> dict[str, Any]:
    """eval-perception for flat T-shirts or pants: `GarmentEstimator` against the mesh keypoints."""
    from tqdm import tqdm

    names = GARMENT_KEYPOINTS[args.garment]
    seg = SegmentationConfig(fixtures=args.cell_layout.obstacles)
    estimator = GarmentEstimator(args.garment, GarmentKeypointConfig(segmentation=seg))
    rows: list[dict[str, Any]] = []
    failures: list[int] = []
    keep = int(args.save_overlays)
    worst_heap: list[tuple[float, int, Observation, ClothState, dict[str, np.ndarray]]] = []
    for i in tqdm(range(args.scenes), desc="eval-perception", unit="scene", file=sys.stderr):
        rng = np.random.default_rng([args.seed, i])
        scene = sample_garment_scene(
            rng,
            i,
            args.garment,
            args.arm_fraction,
            args.edge_length,
            math.radians(args.garment_yaw_range),
            args.arm_pose,
            args.cell_layout,
        )
        try:
            rendered = render_garment_scene(
                scene,
                args.width,
                args.height,
                seed=args.seed * 100003 + i,
                depth_baseline=args.depth_sensor,
                layout=args.cell_layout,
                camera=args.camera,
            )
        except SimulationDivergedError:
            failures.append(i)
            continue
        obs, truth = rendered.obs, rendered.corners
        if not rows:
            estimator.estimate(obs)  # warm-up
        times = []
        for _ in range(TIMING_REPEATS):
            t0 = time.perf_counter()
            state = estimator.estimate(obs)
            times.append(1000.0 * (time.perf_counter() - t0))
        seen = ~rendered.robot_mask
        row: dict[str, Any] = {
            "index": i,
            "state": "flat",
            "detected": state.detected,
            "reason": state.reason,
            "ms": times[0],
            "ms_best": min(times),
            "mask_iou": mask_iou(state.mask & seen, rendered.cloth_mask) if state.detected else 0.0,
            "keypoint_error_mm": {},
            "confidence": {},
            "missing": [n for n in names if n not in state.keypoints],
            "scene": _scene_record(scene, args.camera, ("index",)),
        }
        found = [name for name in names if name in state.keypoints]
        row["keypoint_error_mm"] = keypoint_errors_mm(
            {name: state.keypoints[name][0] for name in found}, truth
        )
        row["confidence"] = {name: state.keypoints[name][1] for name in found}
        score = max(row["keypoint_error_mm"].values()) if not row["missing"] else math.inf
        row["score"] = score if math.isfinite(score) else None  # None: a keypoint not found
        rows.append(row)
        if keep:
            item = (score, i, obs, state, truth)
            if len(worst_heap) < keep:
                heapq.heappush(worst_heap, item)
            elif score > worst_heap[0][0]:
                heapq.heapreplace(worst_heap, item)

    if not rows:
        raise ConfigError("every scene's physics diverged; nothing to score")
    by_keypoint, overall = _garment_summary(rows, names)
    summary: dict[str, Any] = {
        "scenes": len(rows),
        "seed": args.seed,
        "garment": args.garment,
        "width": args.width,
        "height": args.height,
        "arm_fraction": args.arm_fraction,
        "arm_pose": args.arm_pose,
        "garment_yaw_range_deg": args.garment_yaw_range,
        "depth_sensor_baseline_m": args.depth_sensor,
        **_cell_record(args),
        **{k: v for k, v in overall.items() if k != "scenes"},
        "by_keypoint": by_keypoint,
        "sim_failures": failures,
        "rows": rows,
    }
    (stage / "summary.json").write_text(
        json.dumps(summary, indent=2, default=_json_default, allow_nan=False) + "\n"
    )
    worst = sorted(worst_heap, key=lambda t: (-t[0], t[1]))
    if worst:
        odir = stage / "overlays"
        odir.mkdir()
        for _, i, obs, state, truth in worst:
            iio.imwrite(odir / f"scene_{i:04d}.png", draw_overlay(obs, state, reference=truth))
    _print_garment_table(summary, sorted(rows, key=_badness, reverse=True)[:5])
    return summary


def _print_garment_table(summary: dict[str, Any], worst: list[dict[str, Any]]) -> None:
    def fmt(v: Any, spec: str) -> str:
        if v is None:
            width = spec.lstrip("<>^").split(".")[0]
            return format("—", f">{width}") if width.isdigit() else "—"
        return format(v, spec)

    print(
        f"eval-perception: {summary['scenes']} flat {summary['garment']} scenes, "
        f"seed {summary['seed']}, {summary['width']}×{summary['height']}{_cell_words(summary)}"
    )
    header = (
        f"{'keypoint':<17}{'detect':>8}{'median mm':>11}{'mean mm':>9}{'p95 mm':>9}{'max mm':>9}"
    )
    print(header)
    print("-" * len(header))
    rows = [*summary["by_keypoint"].items(), ("overall", None)]
    for name, g in rows:
        if g is None:
            rate, e = summary["keypoint_detection_rate"], summary["keypoint_error_mm"]
        else:
            rate, e = g["detection_rate"], g["error_mm"]
        print(
            f"{name:<17}{fmt(rate, '>8.1%')}{fmt(e['median'], '>11.2f')}{fmt(e['mean'], '>9.2f')}"
            f"{fmt(e['p95'], '>9.2f')}{fmt(e['max'], '>9.2f')}"
        )
    print(
        f"garment detection {fmt(summary['detection_rate'], '.1%')}; mask IoU "
        f"{fmt(summary['mask_iou'], '.3f')}; {fmt(summary['ms_per_frame'], '.1f')} ms/frame "
        f"(best of {TIMING_REPEATS}: {fmt(summary['ms_per_frame_best'], '.1f')})"
    )
    if worst:
        print("worst scenes: " + ", ".join(f"#{r['index']} ({_garment_verdict(r)})" for r in worst))
    if summary["sim_failures"]:
        print(f"left out (physics diverged): {summary['sim_failures']}")


def _garment_verdict(row: dict[str, Any]) -> str:
    """One scene in a word or two: its largest error, or what was not found (recognised, but
    a keypoint the arm hides left out; or not recognised at all)."""
    if row["score"] is not None:
        return f"{row['score']:.1f} mm"
    if not row["detected"]:
        return "not recognised"
    return "missing: " + ", ".join(row["missing"])


def _badness(row: dict[str, Any]) -> float:
    return math.inf if row["score"] is None else row["score"]


def _json_default(value: Any) -> Any:
    if isinstance(value, np.generic):
        return value.item()
    if isinstance(value, np.ndarray):
        return value.tolist()
    raise TypeError(f"not JSON serialisable: {type(value).__name__}")
