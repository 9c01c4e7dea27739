"""Would a second arm fold better? A physics probe with ideal grippers, one against two.

For each seed of `towel_loop` (its towel, pose and mesh): settle the towel, then fold it with
kinematic grippers that hold GROUND-TRUTH vertices (a probe for comparison, not the cell's
perception or arm). Each stage is planned by `planning.recipes.plan_stage` on the ground-truth
outline corners; each of its actions holds every vertex within `--reach` (table plane) of the
planned grasp point, all layers, and carries them along the planner's arc (`planning.motion`:
the carry arc at 0.25 m/s, the last 1 cm lowered at a third of that) onto the place point,
then lets go. With `--grippers 1` the actions run one after the other (what the one-arm cell
does, without its arm, perception or missed grasps); with `--grippers 2` a stage's two actions
run together, both grippers on the same clock. The fold is scored as the episodes are
(metrics.score_episode), with the error per goal layer and the staying cloth's drift (the
vertices no fold moves: how far they lie, in the table plane, from where they lay flat). Each
seed runs in its own process; one JSON line per seed on stdout.

`--grippers 2,1` sets the count stage by stage (the two-arm cell's quarter: its first stage
carried together, its second one corner at a time). `--pin D` adds a still hand that holds the
staying cloth D metres inside the fold line, halfway along it (every layer there, `--reach`
round, or a strip `--pin-length` long), through the stage (`--pin-stages` picks which) or, with
`--pin-release F`, for each carry afresh until F of its arc: a second arm pinning the stack
while the first folds it. `--mid-stages` carries the listed stages with one gripper midway
between their two grasps, onto the middle of their places (planning.actions.edge_middle: how
the one-arm cell carries quarter's stack).

    .venv/bin/python scripts/measure_two_grippers.py --recipe half --grippers 2 --seeds 0-9
    .venv/bin/python scripts/measure_two_grippers.py --recipe quarter --grippers 2,1 \
        --pin 0.04 --pin-stages 1 --seeds 0-19
"""

from __future__ import annotations

# isort: off
import foldbot  # noqa: F401  first: caps numpy's SIMD level before numpy loads (foldbot.simd)

# isort: on
import argparse
import json
import sys
from pathlib import Path

import numpy as np

from foldbot.bench.suite import parse_seeds

sys.path.insert(0, str(Path(__file__).resolve().parent))
from per_seed import run_each_seed
from trace_layers import staying_drift_mm

SETTLE_AFTER_STAGE_S = 1.0


def _smooth(u: np.ndarray) -> np.ndarray:
    """Cubic ease-in/out on [0, 1] (zero speed at both ends)."""
    return u * u * (3.0 - 2.0 * u)


def _timed_path(points: np.ndarray, speed: float, dt: float) -> np.ndarray:
    """Positions at every physics step along a polyline, eased, at `speed` nominal (m/s)."""
    seg = np.linalg.norm(np.diff(points, axis=0), axis=1)
    cum = np.concatenate([[0.0], np.cumsum(seg)])
    n = max(2, int(np.ceil(cum[-1] / speed / dt)) + 1)
    s = _smooth(np.linspace(0.0, 1.0, n)) * cum[-1]
    return np.column_stack([np.interp(s, cum, points[:, j]) for j in range(3)])


class KinematicGripper:
    """A collision-free body driven by a fixed constraint; cloth vertices are anchored to it."""

    def __init__(self, client: int, cloth) -> None:
        import pybullet as p

        self.p, self.client, self.cloth = p, client, cloth
        self.body = p.createMultiBody(0.05, -1, -1, [0, 0, 2.0], physicsClientId=client)
        self.cid = p.createConstraint(
            self.body, -1, -1, -1, p.JOINT_FIXED, [0, 0, 0], [0, 0, 0], [0, 0, 2.0],
            physicsClientId=client,
        )  # fmt: skip
        p.changeConstraint(self.cid, maxForce=500.0, physicsClientId=client)
        self.anchors: list[int] = []

    def move_to(self, pos: np.ndarray, teleport: bool = False) -> None:
        if teleport:
            self.p.resetBasePositionAndOrientation(
                self.body, pos.tolist(), [0, 0, 0, 1], physicsClientId=self.client
            )
        self.p.changeConstraint(
            self.cid, jointChildPivot=pos.tolist(), maxForce=500.0, physicsClientId=self.client
        )

    def hold(self, vertices: np.ndarray, at: np.ndarray) -> None:
        """Jump to `at` and anchor `vertices` there."""
        self.move_to(at, teleport=True)
        for v in vertices:
            self.anchors.append(self.cloth.anchor(int(v), self.body))

    def release(self) -> None:
        """Let go of every anchored vertex and move out of the way, 2 m up."""
        for a in self.anchors:
            self.cloth.release(a)
        self.anchors.clear()
        self.move_to(np.array([0.0, 0.0, 2.0]), teleport=True)

    def pin(self, vertices: np.ndarray, line, offset: float, reach: float, length: float) -> int:
        """Hold the staying cloth by `line` where it is now (pin_vertices); how many points."""
        pinned = pin_vertices(vertices, line, offset, reach, length)
        self.hold(pinned, vertices[pinned].mean(axis=0))
        return int(pinned.size)


def pin_vertices(
    vertices: np.ndarray, line, offset: float, reach: float, length: float = 0.0
) -> np.ndarray:
    """Vertices (all layers) within `reach` of a point `offset` inside the staying side of
    `line`, halfway along the cloth's span of the line: where a second hand pins the stack.
    With `length`, a strip that long along the line instead (jaws closing along it)."""
    s = line.side(vertices)  # > 0 on the moving side
    norm = float(np.hypot(line.dx, line.dy))
    along = ((vertices[:, 0] - line.x) * line.dx + (vertices[:, 1] - line.y) * line.dy) / norm
    staying = s < 0
    mid = 0.5 * (along[staying].min() + along[staying].max())
    dist = np.hypot(-s / norm - offset, np.maximum(np.abs(along - mid) - length / 2, 0.0))
    pick = np.flatnonzero(staying & (dist <= reach))
    return pick if pick.size else np.array([int(np.where(staying, dist, np.inf).argmin())])


def measure(
    seed: int,
    recipe: str,
    grippers: list[int],
    reach: float,
    pin: float = 0.0,
    pin_stages: list[int] | None = None,
    pin_length: float = 0.0,
    pin_release: float | None = None,
    mid_stages: list[int] | None = None,
) -> dict:
    """One seed's fold with ideal grippers (runs in the calling process)."""
    from foldbot import metrics
    from foldbot.bench.suite import load_suite
    from foldbot.pipeline import build_sim_cell
    from foldbot.planning.actions import edge_middle
    from foldbot.planning.motion import MotionConfig, carry_arc, line_path
    from foldbot.planning.recipes import plan_stage, recipe_stages
    from foldbot.sim.cloth import settle
    from foldbot.sim.world import SimWorld

    spec = next(e for e in load_suite("towel_loop").episodes if e.seed == seed)
    cfg = spec.to_config()
    mcfg = MotionConfig()
    out: dict = {"seed": seed, "recipe": recipe, "grippers": grippers}
    try:
        with SimWorld(cfg.sim) as world:
            parts = build_sim_cell(cfg, world)
            parts.model_world.close()
            cloth, oracle = parts.cloth, parts.oracle
            settle(world, cloth)
            initial = oracle.cloth_vertices()
            tools = [KinematicGripper(world.client, cloth) for _ in range(max(grippers))]
            pinner = KinematicGripper(world.client, cloth) if pin > 0 else None
            dt = world.time_step
            lines, held = [], []
            up = np.array([0.0, 0.0, 1.0])
            for stage in range(recipe_stages(recipe)):
                n_grip = grippers[min(stage, len(grippers) - 1)]
                pins = pin > 0 and (pin_stages is None or stage in pin_stages)
                corners = oracle.outline_corners() if stage else oracle.labelled_corners()
                plan = plan_stage(recipe, stage, corners)
                lines.append(plan.fold_lines[0])
                actions = plan.actions
                if mid_stages and stage in mid_stages:  # one grasp midway along the carried edge
                    actions = (edge_middle(actions),)
                v = oracle.cloth_vertices()
                grabs = []
                for action in actions:  # held vertices chosen on the stage's start
                    d = np.linalg.norm(v[:, :2] - action.grasp[:2], axis=1)
                    grab = np.flatnonzero(d <= reach)
                    grabs.append(grab if grab.size else np.array([int(d.argmin())]))
                    held.append(int(grabs[-1].size))
                pairs = list(zip(actions, grabs, strict=True))
                line = metrics.FoldLine.coerce(plan.fold_lines[0])
                if pins and pin_release is None:  # a second hand holds the staying cloth
                    out.setdefault("pinned", []).append(pinner.pin(v, line, pin, reach, pin_length))
                for i in range(0, len(pairs), n_grip):
                    batch = []
                    v = oracle.cloth_vertices()
                    for action, grab in pairs[i : i + n_grip]:
                        start = v[grab].mean(axis=0)  # where the held cloth is now
                        end = action.place.copy()
                        end[2] += max(0.0, start[2] - action.grasp[2])
                        pre = end + up * mcfg.place_height
                        carry = _timed_path(carry_arc(start, pre, mcfg), mcfg.cartesian_speed, dt)
                        lower = _timed_path(
                            line_path(pre, end, 0.003), mcfg.cartesian_speed / 3, dt
                        )
                        batch.append((grab, np.vstack([carry, lower])))
                        carry_steps = len(carry)
                    for tool, (grab, path) in zip(tools, batch, strict=False):
                        tool.hold(grab, path[0])
                    let_go = -1  # the step at which a per-carry pin lets go
                    if pins and pin_release is not None:  # pinned for this carry only
                        out.setdefault("pinned", []).append(
                            pinner.pin(v, line, pin, reach, pin_length)
                        )
                        let_go = int(pin_release * carry_steps)
                    n = max(len(path) for _, path in batch)
                    for k in range(n):
                        if k == let_go:
                            pinner.release()
                        for tool, (_, path) in zip(tools, batch, strict=False):
                            tool.move_to(path[min(k, len(path) - 1)])
                        world.step()
                    for tool, _ in zip(tools, batch, strict=False):
                        tool.release()
                    world.step(round(0.3 / dt))
                if pins:
                    pinner.release()
                world.step(round(SETTLE_AFTER_STAGE_S / dt))
            final = oracle.cloth_vertices()
            score = metrics.score_episode(initial, final, parts.mesh.faces, lines, cloth.thickness)
            out.update(
                fold_error_mm=round(score.fold_error_mm, 2),
                normalized=round(score.normalized_performance, 3),
                success=bool(score.success),
                held_vertices=held,
                size_cm=[round(100 * parts.spec.width, 1), round(100 * parts.spec.height, 1)],
                sim_s=round(world.sim_time, 2),
            )
            # Where the error lies: per goal layer, and the staying cloth's (layer 0) drift in
            # the table plane from where it lay flat.
            goal, layers = metrics.fold_goal(initial, lines, cloth.thickness)
            err = np.linalg.norm(final - goal, axis=1) * 1000
            out["staying_drift_mm"] = staying_drift_mm(final, initial, layers == 0)
            out["layer_error_mm"] = {
                int(n): round(float(err[layers == n].mean()), 1) for n in np.unique(layers)
            }
    except Exception as exc:  # a diverged cloth is a result here, not a crash
        out["error"] = f"{type(exc).__name__}: {exc}"[:200]
    return out


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--recipe", default="half", help="a towel recipe (default half)")
    ap.add_argument(
        "--grippers", default="2",
        help="grippers carrying each stage, 1 or 2; a list ('2,1') gives stage by stage, the "
        "last repeating (default 2)",
    )  # fmt: skip
    ap.add_argument(
        "--pin-stages", help="stages (0-based, '1' or '0,1') the pin holds (default: all)"
    )
    ap.add_argument("--seeds", default="0-9", help="seeds: '0-9', '0,3,5' or one seed")
    ap.add_argument(
        "--reach", type=float, default=0.012,
        help="hold every vertex within this distance (m, table plane) of a grasp point",
    )  # fmt: skip
    ap.add_argument(
        "--pin", type=float, default=0.0,
        help="a third, still hand holds the staying cloth this far (m) inside each fold line "
        "while the stage is carried (0: none)",
    )  # fmt: skip
    ap.add_argument(
        "--pin-length", type=float, default=0.0,
        help="the pin holds a strip this long (m) along the line (0: a spot, --reach round)",
    )  # fmt: skip
    ap.add_argument(
        "--pin-release", type=float,
        help="pin each carry afresh and let go this far (fraction, 0-1) along its arc "
        "(default: held from the stage's start to its end)",
    )  # fmt: skip
    ap.add_argument(
        "--mid-stages",
        help="stages (0-based, '1' or '0,1') carried by one gripper midway between the stage's "
        "grasps, onto the midpoint of its places (default: none)",
    )
    ap.add_argument("--one", type=int, help=argparse.SUPPRESS)  # child process: one seed
    args = ap.parse_args()
    if args.one is not None:
        grippers = [int(g) for g in args.grippers.split(",")]
        if not grippers or any(g not in (1, 2) for g in grippers):
            ap.error(f"--grippers {args.grippers!r}: each value must be 1 or 2")
        stages = None if args.pin_stages is None else [int(s) for s in args.pin_stages.split(",")]
        mids = None if args.mid_stages is None else [int(s) for s in args.mid_stages.split(",")]
        row = measure(
            args.one, args.recipe, grippers, args.reach, args.pin, stages, args.pin_length,
            args.pin_release, mids,
        )  # fmt: skip
        print(json.dumps(row), flush=True)
        return 0
    extra = ["--recipe", args.recipe, "--grippers", str(args.grippers), "--reach", str(args.reach)]
    extra += ["--pin", str(args.pin)]
    if args.pin_stages is not None:
        extra += ["--pin-stages", args.pin_stages]
    extra += ["--pin-length", str(args.pin_length)]
    if args.pin_release is not None:
        extra += ["--pin-release", str(args.pin_release)]
    if args.mid_stages is not None:
        extra += ["--mid-stages", args.mid_stages]
    rows = run_each_seed(__file__, parse_seeds(args.seeds), extra)
    ok = [r for r in rows if "error" not in r]
    if ok:
        err = np.array([r["fold_error_mm"] for r in ok])
        print(
            f"# {args.recipe}, {args.grippers} gripper(s): {len(rows)} seeds, "
            f"{len(rows) - len(ok)} diverged; success {sum(r['success'] for r in ok)}; fold error "
            f"mean {err.mean():.1f} / median {np.median(err):.1f} mm",
            file=sys.stderr,
        )
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
