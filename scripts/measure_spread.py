"""Would two corners lifted, spread and laid flatten a crumpled towel in Bullet's cloth? A probe
with ideal grippers, the PyBullet twin of `probe_mujoco_cloth.py spread`.

For each seed of `towel_crumpled` (its towel, pose and mesh): settle, crumple as the episode does
(`pipeline.crumple_start`), take the arm out of the world, then flatten with two kinematic
grippers (`measure_two_grippers.KinematicGripper`) holding two adjacent GROUND-TRUTH corner
vertices: lift until the towel hangs free (its other side + 10 cm), spread them one edge apart
over the far side of the workspace, hang still 1 s, then lay the towel at 45° towards the near
side at 0.1 m/s and let go 2 cm up. Repeated with the next edge while the coverage is under
FlattenConfig's target, within its budget. With `--grasp extremes` the two points are what a
top-down camera could pick instead: the ends of the top-view outline's longest chord (top layer),
spread to their true distance apart; with `--grasp vision`, the two adjacent corners the RGB-D
estimator sees on the heap (the cell's camera, the arm out of the world), also spread to their
true distance apart. Each pick's distance along the flat towel to the nearest true corner is
recorded (`pick_to_corner_mm`). With `--arms 1`, what one gripper can do instead: hang the
towel by one true corner (the corners in turn), at most 0.5 m up, still for 1 s, then lay it
along its diagonal towards the near side. `--shake A F AXIS` shakes both grippers before the
hang, `--drag D` runs the lay on past the towel's length by D × the hang, `--frames DIR` saves a
side-view picture sheet per spread, `--suite` takes another suite's towels. Each row records the
cloth's self-crossings (metrics.self_crossings) crumpled, lifted, hung and laid. One JSON line
per seed on stdout.

    .venv/bin/python scripts/measure_spread.py --seeds 0-19
    .venv/bin/python scripts/measure_spread.py --seeds 0-19 --drag 0.3
    .venv/bin/python scripts/measure_spread.py --seeds 6 --shake 0.03 3 z --frames runs/frames
    .venv/bin/python scripts/measure_spread.py --seeds 0-11 --grasp extremes
    .venv/bin/python scripts/measure_spread.py --seeds 0-19 --grasp vision
    .venv/bin/python scripts/measure_spread.py --seeds 0-19 --stretch 0.08
    .venv/bin/python scripts/measure_spread.py --seeds 0-19 --arms 1
"""

from __future__ import annotations

# isort: off
import foldbot  # noqa: F401  first: caps numpy's SIMD level before numpy loads (foldbot.simd)

# isort: on
import argparse
import json
import sys
import time
from pathlib import Path

import numpy as np

from foldbot.bench.suite import parse_seeds

sys.path.insert(0, str(Path(__file__).resolve().parent))
from measure_two_grippers import KinematicGripper, _timed_path
from per_seed import run_each_seed

HANG_S = 1.0
LAY_SPEED = 0.1
LIFT_SPEED = 0.25
MAX_HOLD = 0.5
"""Highest a corner is held above the table with one gripper (m): SpreadConfig.max_hold_height."""
CORNERS = ("corner_00", "corner_10", "corner_11", "corner_01")


def outline_extremes(v: np.ndarray) -> tuple[int, int]:
    """The two vertices a top-down camera could pick without knowing the corners: the ends of
    the top-view outline's longest chord, each the highest vertex within 1.5 cm of it (the top
    layer, where jaws closing from above take the cloth)."""
    import cv2

    hull = cv2.convexHull(v[:, :2].astype(np.float32), returnPoints=False).reshape(-1)
    pts = v[hull, :2]
    d = np.linalg.norm(pts[:, None] - pts[None], axis=2)
    i, j = np.unravel_index(int(d.argmax()), d.shape)
    picks = []
    for k in (hull[i], hull[j]):
        near = np.flatnonzero(np.linalg.norm(v[:, :2] - v[k, :2], axis=1) < 0.015)
        picks.append(int(near[v[near, 2].argmax()]))
    return picks[0], picks[1]


def vision_corners(camera, v: np.ndarray) -> tuple[int, int]:
    """The two adjacent corners the RGB-D estimator sees on the heap and is surest of (the pair,
    in its counter-clockwise order, with the larger smaller confidence), each taken at the
    highest vertex within 1.5 cm of it (the top layer; the nearest vertex if none)."""
    from foldbot.perception.estimator import VisionEstimator
    from foldbot.perception.keypoints import CORNER_LABELS

    state = VisionEstimator().estimate(camera.observe())
    if len(state.keypoints) != 4:
        raise RuntimeError(f"vision found no 4 corners: {state.reason}")
    pts = [state.keypoints[k] for k in CORNER_LABELS]
    best = max(range(4), key=lambda i: min(pts[i][1], pts[(i + 1) % 4][1]))
    picks = []
    for xyz, _conf in (pts[best], pts[(best + 1) % 4]):
        d = np.linalg.norm(v[:, :2] - xyz[:2], axis=1)
        near = np.flatnonzero(d < 0.015)
        picks.append(int(near[v[near, 2].argmax()]) if len(near) else int(d.argmin()))
    return picks[0], picks[1]


def side_view(client: int, centre: np.ndarray, table: float) -> np.ndarray:
    """An RGB picture of the workspace from beyond its far (+x) side, facing the hanging towel
    (for --frames)."""
    import pybullet as p

    target = [float(centre[0]), float(centre[1]), table + 0.25]
    view = p.computeViewMatrix([target[0] + 1.0, target[1], table + 0.35], target, [0, 0, 1])
    proj = p.computeProjectionMatrixFOV(50, 4 / 3, 0.05, 5.0)
    img = p.getCameraImage(
        320, 240, view, proj, renderer=p.ER_TINY_RENDERER, physicsClientId=client
    )[2]
    return np.asarray(img, dtype=np.uint8).reshape(240, 320, 4)[:, :, :3]


def save_sheet(shots: list[np.ndarray], path: Path) -> None:
    """The pictures in rows of six, as one PNG."""
    import imageio.v3 as iio

    path.parent.mkdir(parents=True, exist_ok=True)
    rows = [shots[k : k + 6] for k in range(0, len(shots), 6)]
    rows = [np.hstack(r + [np.zeros_like(shots[0])] * (6 - len(r))) for r in rows]
    iio.imwrite(path, np.vstack(rows))


def shake_offsets(amplitude: float, frequency: float, axis: str, dt: float) -> np.ndarray:
    """Offsets (m) at every physics step of a shake: `amplitude` × sin(2π f t) along `axis`
    (x: towards and away from the camera's near side, across the hanging towel; z: up and
    down) for a whole number of periods (at least 1 s), so the grippers end where they began."""
    if amplitude <= 0.0:
        return np.zeros((0, 3))
    periods = max(1, round(1.0 * frequency))
    t = np.arange(round(periods / frequency / dt)) * dt
    out = np.zeros((len(t), 3))
    out[:, "xyz".index(axis)] = amplitude * np.sin(2 * np.pi * frequency * t)
    return out


def measure(
    seed: int,
    grasp: str = "corners",
    stretch: float = 0.0,
    arms: int = 2,
    shake: tuple[float, float, str] = (0.0, 0.0, "z"),
    suite: str = "towel_crumpled",
    frames: str | None = None,
    drag: float = 0.0,
    lay_speed: float = LAY_SPEED,
) -> dict:
    """One seed (runs in the calling process: the first simulation in it)."""
    import pybullet as p

    from foldbot import metrics
    from foldbot.bench.suite import load_suite
    from foldbot.pipeline import build_sim_cell, crumple_start
    from foldbot.planning.flatten import FlattenConfig
    from foldbot.sim.cloth import settle
    from foldbot.sim.world import SimWorld

    spec = next(e for e in load_suite(suite).episodes if e.seed == seed)
    cfg = spec.to_config()
    flat = FlattenConfig()
    out: dict = {"seed": seed, "grasp": grasp, "stretch": stretch, "arms": arms, "coverage": []}
    out.update(shake=list(shake), suite=suite, drag=drag, lay_speed=lay_speed)
    wall = time.perf_counter()
    shots: list[np.ndarray] = []
    with SimWorld(cfg.sim) as world:
        parts = build_sim_cell(cfg, world)
        parts.model_world.close()
        cloth, oracle, mesh = parts.cloth, parts.oracle, parts.mesh
        try:
            settle(world, cloth)
            crumple_start(cfg, world, cloth)
            p.removeBody(parts.robot.body_id, physicsClientId=world.client)  # ideal grippers only
            dt, table = world.time_step, cloth.table_height
            centre = np.asarray(cfg.sim.layout.workspace_center_xy, dtype=float)
            tools = [KinematicGripper(world.client, cloth) for _ in range(2)]
            corners = [mesh.keypoints[k] for k in CORNERS]
            coverage = metrics.coverage(oracle.cloth_vertices(), mesh.faces, mesh.area)
            out["coverage"].append(round(coverage, 3))
            out["crossings"] = [
                ["crumpled", metrics.self_crossings(oracle.cloth_vertices(), mesh.faces)]
            ]
            actions = 0
            while coverage < flat.target_coverage and actions < flat.max_actions:
                v = oracle.cloth_vertices()
                if arms == 1:  # hang the towel by one true corner and lay it along its diagonal
                    a = corners[actions % 4]
                    rest = mesh.vertices[:, :2]
                    depth = float(np.linalg.norm(rest - rest[a], axis=1).max())
                    lift = min(depth + 0.1, MAX_HOLD)
                    now, top = v[a], [centre[0] + depth / 2, centre[1], table + lift]
                    path = np.vstack(
                        [
                            _timed_path(
                                np.array([now, [now[0], now[1], table + lift], top]),
                                LIFT_SPEED,
                                dt,
                            ),
                            np.repeat(np.array([top]), round(HANG_S / dt), axis=0),
                            _timed_path(
                                np.array(
                                    [
                                        top,
                                        [top[0], top[1], table + min(depth, lift) * (1 + stretch)],
                                        [centre[0] - depth / 2, centre[1], table + 0.02],
                                    ]
                                ),
                                lay_speed,
                                dt,
                            ),
                        ]
                    )
                    tools[0].hold(np.array([a]), path[0])
                    for q in path:
                        tools[0].move_to(q)
                        world.step()
                    tools[0].release()
                    tools[0].move_to(np.array([0.0, 0.0, 2.0]), teleport=True)
                    world.step(round((0.5 + flat.settle_time) / dt))
                    actions += 1
                    coverage = metrics.coverage(oracle.cloth_vertices(), mesh.faces, mesh.area)
                    out["coverage"].append(round(coverage, 3))
                    continue
                if grasp == "corners":
                    a, b = corners[actions % 4], corners[(actions + 1) % 4]
                elif grasp == "vision":
                    a, b = vision_corners(parts.camera, v)
                else:
                    a, b = outline_extremes(v)
                edge = float(np.linalg.norm(mesh.vertices[a, :2] - mesh.vertices[b, :2]))
                depth = float(mesh.area / max(edge, 0.05))
                if grasp != "corners":
                    true = np.array([mesh.vertices[c] for c in corners])
                    out.setdefault("pick_to_corner_mm", []).append(
                        [
                            round(
                                float(np.linalg.norm(true - mesh.vertices[k], axis=1).min()) * 1000
                            )
                            for k in (a, b)
                        ]
                    )
                if grasp != "corners":  # the towel hangs down to its farthest point from them
                    rest = mesh.vertices[:, :2]
                    hang = np.minimum(
                        np.linalg.norm(rest - rest[a], axis=1),
                        np.linalg.norm(rest - rest[b], axis=1),
                    )
                    depth = float(hang.max())
                lift = depth + 0.1
                paths = []
                for vertex, y in ((a, -edge / 2), (b, edge / 2)):
                    now = v[vertex]
                    top = [centre[0] + depth / 2, centre[1] + y, table + lift]
                    up = _timed_path(
                        np.array([now, [now[0], now[1], table + lift], top]), LIFT_SPEED, dt
                    )
                    hang = np.repeat(np.array([top]), round(HANG_S / dt), axis=0)
                    jiggle = np.asarray(top) + shake_offsets(*shake, dt)
                    lay = _timed_path(
                        np.array(
                            [
                                top,
                                [top[0], top[1], table + depth * (1 + stretch) + 0.005],
                                [
                                    centre[0] - depth * (0.5 + stretch + drag),
                                    centre[1] + y,
                                    table + 0.02,
                                ],
                            ]
                        ),
                        lay_speed,
                        dt,
                    )
                    paths.append(np.vstack([up, jiggle, hang, lay]))
                for tool, vertex, path in zip(tools, (a, b), paths, strict=True):
                    tool.hold(np.array([vertex]), path[0])
                steps = max(len(q) for q in paths)
                marks = {len(up) - 1: "lifted", len(up) + len(jiggle) + len(hang) - 1: "hung"}
                for k in range(steps):
                    if k in marks:
                        out.setdefault("crossings", []).append(
                            [marks[k], metrics.self_crossings(oracle.cloth_vertices(), mesh.faces)]
                        )
                    for tool, path in zip(tools, paths, strict=True):
                        tool.move_to(path[min(k, len(path) - 1)])
                    world.step()
                    if frames and k % max(1, round(0.5 / dt)) == 0:
                        shots.append(side_view(world.client, centre, table))
                for tool in tools:
                    tool.release()
                    tool.move_to(np.array([0.0, 0.0, 2.0]), teleport=True)
                world.step(round((0.5 + flat.settle_time) / dt))
                actions += 1
                coverage = metrics.coverage(oracle.cloth_vertices(), mesh.faces, mesh.area)
                out["coverage"].append(round(coverage, 3))
                out.setdefault("crossings", []).append(
                    ["laid", metrics.self_crossings(oracle.cloth_vertices(), mesh.faces)]
                )
                if frames:
                    shots.append(side_view(world.client, centre, table))
                    save_sheet(shots, Path(frames) / f"seed{seed}_spread{actions}.png")
                    shots.clear()
            out.update(actions=actions, flattened=bool(coverage >= flat.target_coverage))
        except Exception as exc:  # a diverged cloth is a result here, not a crash
            out["error"] = f"{type(exc).__name__}: {exc}"[:200]
        out["sim_s"] = round(world.sim_time, 2)
    out["speed"] = round(out["sim_s"] / (time.perf_counter() - wall), 2)
    return out


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--seeds", default="0-9", help="seeds: '0-9', '0,3,5' or one seed")
    ap.add_argument(
        "--grasp", choices=("corners", "extremes", "vision"), default="corners",
        help="corners: two adjacent GROUND-TRUTH corners; extremes: the ends of the top-view "
        "outline's longest chord; vision: the two adjacent corners the RGB-D estimator is "
        "surest of; both spread to their true distance apart (default corners)",
    )  # fmt: skip
    ap.add_argument(
        "--stretch", type=float, default=0.0,
        help="the hanging towel is taken this much longer than its nominal side (fraction): the "
        "lay starts that much higher and ends that much further towards the near side "
        "(default 0; a towel hung by two corners hangs 6-8 %% longer)",
    )  # fmt: skip
    ap.add_argument(
        "--arms", type=int, choices=(1, 2), default=2,
        help="2: the spread; 1: one gripper hangs the towel by one true corner (corners in "
        "turn), at most 0.5 m up, and lays it along its diagonal towards the near side "
        "(default 2)",
    )  # fmt: skip
    ap.add_argument(
        "--shake", nargs=3, metavar=("AMPLITUDE", "HZ", "AXIS"), default=("0", "0", "z"),
        help="before the still hang, shake both grippers AMPLITUDE m at HZ along AXIS (x or z) "
        "for a whole number of periods, at least 1 s (default: none)",
    )  # fmt: skip
    ap.add_argument(
        "--suite", default="towel_crumpled", help="whose towels (default towel_crumpled)"
    )
    ap.add_argument(
        "--drag", type=float, default=0.0,
        help="the lay ends this fraction of the hang further towards the near side than the "
        "towel's length asks: the last of it is dragged along the table, taut (default 0)",
    )  # fmt: skip
    ap.add_argument(
        "--lay-speed", type=float, default=LAY_SPEED,
        help=f"the lay's speed, m/s (default {LAY_SPEED}, SpreadConfig.lay_speed)",
    )  # fmt: skip
    ap.add_argument("--frames", default=None, help="a side-view picture sheet per spread, in DIR")
    ap.add_argument("--one", type=int, help=argparse.SUPPRESS)  # child process: one seed
    args = ap.parse_args()
    if not 0.0 <= args.stretch <= 0.5:
        ap.error(f"--stretch must be in [0, 0.5], got {args.stretch}")
    amp, hz, axis = float(args.shake[0]), float(args.shake[1]), args.shake[2]
    if not (0.0 <= amp <= 0.1 and (amp == 0.0 or 0.2 <= hz <= 10.0) and axis in ("x", "z")):
        ap.error(
            f"--shake needs AMPLITUDE in [0, 0.1] m, HZ in [0.2, 10], AXIS x or z; got {args.shake}"
        )
    if args.one is not None:
        row = measure(
            args.one,
            args.grasp,
            args.stretch,
            args.arms,
            (amp, hz, axis),
            args.suite,
            args.frames,
            args.drag,
            args.lay_speed,
        )
        print(json.dumps(row), flush=True)
        return 0
    extra = ["--grasp", args.grasp, "--stretch", str(args.stretch), "--arms", str(args.arms)]
    extra += ["--shake", *args.shake, "--suite", args.suite]
    extra += ["--frames", args.frames] if args.frames else []
    extra += ["--drag", str(args.drag), "--lay-speed", str(args.lay_speed)]
    rows = run_each_seed(__file__, parse_seeds(args.seeds), extra)
    ok = [r for r in rows if "error" not in r]
    print(
        f"# spread: {len(rows) - len(ok)} of {len(rows)} diverged; flattened "
        f"{sum(r['flattened'] for r in ok)} of {len(rows)}",
        file=sys.stderr,
    )
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
