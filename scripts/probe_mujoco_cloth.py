"""Would another physics engine lift the targets Bullet's cloth holds foldbot under? A probe of
MuJoCo's flex cloth (MuJoCo ≥ 4.0), for comparison only: nothing in foldbot uses it.

The same towels as `scripts/measure_two_grippers.py` (`towel_loop`'s sizes and odd-count meshes,
laid flat at the workspace centre unrotated) become a MuJoCo `flexcomp` (the mesh's own vertices
and triangles; 0.1 kg; collision radius 5 mm, so 10 mm thick as foldbot's cloth; self-collision;
MuJoCo's shell elasticity with its drape example's values: Young 2e4 Pa, Poisson 0.2, 1 mm
membrane, damping 1e-4; `--young` changes the modulus) on a rigid table. Four measurements:

- `fold`: ideal grippers fold the towel as the PyBullet probe does: each stage planned by
  `planning.recipes.plan_stage` on GROUND-TRUTH corners; each action holds the vertex nearest its
  grasp point (an equality `connect` to a mocap body) along `planning.motion.carry_arc` at
  `MotionConfig.cartesian_speed`, lowered onto the place point at a third of that, then released.
  Scored by `metrics.score_episode`, as the episodes are.
- `heap`: a crumple like `sim.crumple`'s "fold" style (one vertex picked by the seed lifted 20–35
  cm, dragged 20–60 % of the diagonal across the cloth, let go 2–8 cm up), 2 s of settling, then
  4 s of rest with nothing touching: the fastest vertex's speed (median over the rest), the
  deepest vertex centre under the table top, and whether the cloth stayed finite and in place.
- `flatten`: `towel_crumpled`'s towels crumpled as `heap` does, then flattened by foldbot's
  corner-pulling oracle (`sim.flatten_oracle`, ground truth) with an ideal holder, within
  `FlattenConfig`'s budget and target coverage.
- `spread`: the same crumpled towels flattened by two ideal holders lifting two adjacent corners
  (ground truth) until the towel hangs free, spreading them one edge apart, and laying it down
  at 45°; `scripts/measure_spread.py` is its PyBullet twin.
- Each reports simulated / wall seconds (one core).

    pip install "mujoco>=4"        # not a foldbot dependency
    python scripts/probe_mujoco_cloth.py fold --recipe half --grippers 2 --seeds 0-4
    python scripts/probe_mujoco_cloth.py heap --seeds 0-7
    python scripts/probe_mujoco_cloth.py flatten --seeds 0-9 --timestep 0.005 --young 1e5
    python scripts/probe_mujoco_cloth.py spread --seeds 0-19 --timestep 0.005 --young 1e5

One JSON line per seed on stdout, a summary line on stderr.
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
from measure_two_grippers import _timed_path as timed_path

try:
    import mujoco
except ImportError:  # pragma: no cover - a probe, not a dependency
    sys.exit("this probe needs MuJoCo: pip install 'mujoco>=4' (not a foldbot dependency)")

TABLE_TOP = 0.0
RADIUS = 0.005
"""Flex collision radius (m): a 10 mm thick sheet, as foldbot's cloth."""
REST_S = 4.0
SPREAD_LAY_SPEED = 0.1
"""m/s at which `spread` lays the hanging towel down (after 1 s hanging still)."""


def towel_mesh(seed: int, suite: str = "towel_loop"):
    """`suite`'s towel for this seed (its size and mesh), unrotated, centred at the origin."""
    from foldbot.bench.suite import load_suite
    from foldbot.garments.towel import make_towel
    from foldbot.pipeline import seeded_towel

    spec = next(e for e in load_suite(suite).episodes if e.seed == seed)
    towel = seeded_towel(spec.to_config())
    return towel, make_towel(towel)


ELASTICITY = {"young": 2e4, "elastic2d": "both"}
"""The shell elasticity used (the command line may change it)."""


def build(mesh, timestep: float, grippers: int, centre: tuple[float, float] = (0.0, 0.0)):
    """The MuJoCo model: table, the towel as a flex on the table top at `centre`, `grippers`
    mocap bodies with an inactive `connect` from every vertex to each (activated to hold it)."""
    v = mesh.vertices.copy()
    v[:, :2] += centre
    v[:, 2] = TABLE_TOP + RADIUS + 1e-4
    points = " ".join(f"{x:.6f} {y:.6f} {z:.6f}" for x, y, z in v)
    elements = " ".join(str(int(i)) for i in mesh.faces.ravel())
    mocaps = "".join(f'<body name="grip{g}" mocap="true" pos="{g} 0 2"/>' for g in range(grippers))
    connects = "".join(
        f'<connect body1="cloth_{i}" body2="grip{g}" anchor="0 0 0" active="false"/>'
        for g in range(grippers)
        for i in range(len(v))
    )
    xml = f"""
<mujoco>
  <option timestep="{timestep}" solver="CG" tolerance="1e-6" iterations="400"
          integrator="discrete"/>
  <size memory="200M"/>
  <worldbody>
    <geom name="table" type="box" size="1 1 0.02" pos="0 0 {TABLE_TOP - 0.02}"/>
    {mocaps}
    <flexcomp name="cloth" type="direct" dim="2" radius="{RADIUS}" mass="0.1"
              point="{points}" element="{elements}">
      <contact selfcollide="auto" solref="0.01 1" solimp=".95 .99 .0001" condim="3"/>
      <elasticity young="{ELASTICITY["young"]}" poisson="0.2" thickness="1e-3"
                  elastic2d="{ELASTICITY["elastic2d"]}" damping="1e-4"/>
    </flexcomp>
  </worldbody>
  <equality>{connects}</equality>
</mujoco>"""
    model = mujoco.MjModel.from_xml_string(xml)
    return model, mujoco.MjData(model)


class MjCloth:
    """The flex as foldbot's GroundTruthOracle reads a cloth: vertices in mesh order, the mesh."""

    def __init__(self, model, data, mesh) -> None:
        self.model, self.data, self.mesh = model, data, mesh
        self.bodies = np.array(
            [
                mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, f"cloth_{i}")
                for i in range(len(mesh.vertices))
            ]
        )
        mujoco.mj_forward(model, data)
        self.rest = data.xpos[self.bodies].copy()  # where each vertex body is at qpos0

    def sim_vertices(self) -> np.ndarray:
        return self.data.xpos[self.bodies].copy()


class Holder:
    """Mocap gripper `g`: holds one vertex by activating its `connect`, moves it along a path."""

    def __init__(self, model, data, cloth: MjCloth, g: int) -> None:
        self.model, self.data, self.cloth, self.g = model, data, cloth, g
        self.mocap = model.body_mocapid[
            mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, f"grip{g}")
        ]
        self.home = data.mocap_pos[self.mocap].copy()
        self.vertex: int | None = None

    def _eq(self, vertex: int) -> int:
        return self.g * len(self.cloth.bodies) + vertex

    def hold(self, vertex: int) -> None:
        self.vertex = vertex
        self.move_to(self.cloth.sim_vertices()[vertex])
        self.data.eq_active[self._eq(vertex)] = 1

    def move_to(self, pos: np.ndarray) -> None:
        """Put the held vertex's point of the mocap body at `pos` (its offset fixed at compile)."""
        offset = self.cloth.rest[self.vertex] - self.home
        self.data.mocap_pos[self.mocap] = pos - offset

    def release(self) -> None:
        if self.vertex is not None:
            self.data.eq_active[self._eq(self.vertex)] = 0
        self.vertex = None


def carry(model, data, cloth: MjCloth, holders: list[Holder], vertices, paths) -> None:
    """Hold each vertex with its holder, move them along their paths (one position per step) on
    one clock, a path that ends first waiting at its end, then let go."""
    for holder, vertex in zip(holders, vertices, strict=False):
        holder.hold(int(vertex))
    for k in range(max(len(q) for q in paths)):
        for holder, path in zip(holders, paths, strict=False):
            holder.move_to(path[min(k, len(path) - 1)])
        step(model, data, 1, cloth)
    for holder in holders:
        holder.release()


def step(model, data, n: int, cloth: MjCloth) -> None:
    for _ in range(n):
        mujoco.mj_step(model, data)
    v = cloth.sim_vertices()
    if not np.isfinite(v).all() or np.abs(v[:, :2]).max() > 1.0 or v[:, 2].max() > 1.5:
        raise FloatingPointError("the cloth diverged")


def fold(seed: int, recipe: str, grippers: int, timestep: float) -> dict:
    from foldbot import metrics
    from foldbot.planning.motion import MotionConfig, carry_arc, line_path
    from foldbot.planning.recipes import plan_stage, recipe_stages
    from foldbot.sim.oracle import GroundTruthOracle

    towel, mesh = towel_mesh(seed)
    model, data = build(mesh, timestep, grippers)
    cloth = MjCloth(model, data, mesh)
    oracle = GroundTruthOracle(cloth)
    holders = [Holder(model, data, cloth, g) for g in range(grippers)]
    mcfg = MotionConfig()
    up = np.array([0.0, 0.0, 1.0])
    out: dict = {"seed": seed, "recipe": recipe, "grippers": grippers, "timestep": timestep}
    wall = time.perf_counter()
    try:
        step(model, data, round(1.0 / timestep), cloth)  # settle
        initial = cloth.sim_vertices()
        lines = []
        for stage in range(recipe_stages(recipe)):
            corners = oracle.outline_corners() if stage else oracle.labelled_corners()
            plan = plan_stage(recipe, stage, corners)
            lines.append(plan.fold_lines[0])
            v = cloth.sim_vertices()
            grabs = [
                int(np.linalg.norm(v[:, :2] - a.grasp[:2], axis=1).argmin()) for a in plan.actions
            ]
            pairs = list(zip(plan.actions, grabs, strict=True))
            for i in range(0, len(pairs), grippers):
                v = cloth.sim_vertices()
                batch = []
                for action, grab in pairs[i : i + grippers]:
                    start = v[grab]
                    end = action.place.copy()
                    end[2] += max(0.0, start[2] - action.grasp[2])
                    pre = end + up * mcfg.place_height
                    arc = timed_path(carry_arc(start, pre, mcfg), mcfg.cartesian_speed, timestep)
                    lower = timed_path(
                        line_path(pre, end, 0.003), mcfg.cartesian_speed / 3, timestep
                    )
                    batch.append((grab, np.vstack([arc, lower])))
                grabs_now, paths = zip(*batch, strict=True)
                carry(model, data, cloth, holders, grabs_now, paths)
                step(model, data, round(0.3 / timestep), cloth)
            step(model, data, round(1.0 / timestep), cloth)
        final = cloth.sim_vertices()
        score = metrics.score_episode(initial, final, mesh.faces, lines, 2 * RADIUS)
        out.update(
            fold_error_mm=round(score.fold_error_mm, 2),
            normalized=round(score.normalized_performance, 3),
            success=bool(score.success),
            size_cm=[round(100 * towel.width, 1), round(100 * towel.height, 1)],
        )
    except FloatingPointError as exc:
        out["error"] = str(exc)
    out["sim_s"] = round(float(data.time), 2)
    out["speed"] = round(float(data.time) / (time.perf_counter() - wall), 2)
    return out


def crumple(model, data, cloth: MjCloth, holder: Holder, towel, rng, timestep: float) -> None:
    """Settle, then one pinch-lift-drag-drop like sim.crumple's fold style (drawn from `rng`),
    then 2 s of settling."""
    step(model, data, round(1.0 / timestep), cloth)
    v = cloth.sim_vertices()
    pick = int(rng.integers(len(v)))
    start = v[pick]
    centroid = v.mean(axis=0)
    heading = np.arctan2(*(centroid - start)[1::-1]) + rng.uniform(-np.pi / 4, np.pi / 4)
    diagonal = float(np.hypot(towel.width, towel.height))
    drag = rng.uniform(0.2, 0.6) * diagonal
    lift = start + [0, 0, rng.uniform(0.20, 0.35)]
    low = lift.copy()
    low[2] = TABLE_TOP + 0.12
    drop = low + drag * np.array([np.cos(heading), np.sin(heading), 0.0])
    drop[2] = TABLE_TOP + rng.uniform(0.02, 0.08)
    path = timed_path(np.array([start, lift, low, drop]), 0.4, timestep)
    carry(model, data, cloth, [holder], [pick], [path])
    step(model, data, round(2.0 / timestep), cloth)


def heap(seed: int, timestep: float) -> dict:
    """Crumple the settled towel once (seeded), let it settle, then rest and watch it."""
    towel, mesh = towel_mesh(seed)
    model, data = build(mesh, timestep, 1)
    cloth = MjCloth(model, data, mesh)
    holder = Holder(model, data, cloth, 0)
    rng = np.random.default_rng([seed, 2])
    out: dict = {"seed": seed, "timestep": timestep}
    wall = time.perf_counter()
    try:
        crumple(model, data, cloth, holder, towel, rng, timestep)
        speeds, deepest = [], 0.0
        prev = cloth.sim_vertices()
        every = max(1, round(0.01 / timestep))
        for _ in range(round(REST_S / (every * timestep))):
            step(model, data, every, cloth)
            now = cloth.sim_vertices()
            speeds.append(float(np.linalg.norm(now - prev, axis=1).max() / (every * timestep)))
            deepest = max(deepest, float(TABLE_TOP - now[:, 2].min()))
            prev = now
        from foldbot import metrics

        out.update(
            fastest_vertex_median_m_s=round(float(np.median(speeds)), 4),
            deepest_mm=round(1000 * deepest, 1),
            coverage=round(metrics.coverage(now, mesh.faces, mesh.area), 2),
        )
    except FloatingPointError as exc:
        out["error"] = str(exc)
    out["sim_s"] = round(float(data.time), 2)
    out["speed"] = round(float(data.time) / (time.perf_counter() - wall), 2)
    return out


def flatten(seed: int, timestep: float) -> dict:
    """`towel_crumpled`'s towel crumpled (this probe's crumple), then flattened by the corner-
    pulling oracle (sim.flatten_oracle, ground truth) with an ideal holder: at most
    FlattenConfig.max_actions pulls, each along the planner's carry arc, until the coverage
    reaches FlattenConfig.target_coverage."""
    from types import SimpleNamespace

    from foldbot import metrics
    from foldbot.planning.flatten import FlattenConfig
    from foldbot.planning.motion import MotionConfig, carry_arc
    from foldbot.sim.flatten_oracle import CornerPullOracle

    towel, mesh = towel_mesh(seed, "towel_crumpled")
    cfg, mcfg = FlattenConfig(), MotionConfig()
    centre = (0.45, 0.0)  # the cell's workspace centre, which FlattenConfig.workspace is around
    model, data = build(mesh, timestep, 1, centre)
    cloth = MjCloth(model, data, mesh)
    holder = Holder(model, data, cloth, 0)
    rest = mesh.vertices.copy()
    rest[:, :2] += centre
    oracle = CornerPullOracle(cloth.sim_vertices, rest, mesh.keypoints)
    state = SimpleNamespace(table_plane=np.array([0.0, 0.0, 1.0, -TABLE_TOP]))
    out: dict = {"seed": seed, "timestep": timestep, "coverage": []}
    wall = time.perf_counter()
    try:
        crumple(model, data, cloth, holder, towel, np.random.default_rng([seed, 2]), timestep)
        coverage = metrics.coverage(cloth.sim_vertices(), mesh.faces, mesh.area)
        out["coverage"].append(round(coverage, 3))
        pulls = 0
        while coverage < cfg.target_coverage and pulls < cfg.max_actions:
            _outline, planned = oracle(state, cfg)
            if not planned:
                break
            action = planned[0].action
            v = cloth.sim_vertices()
            grab = int(np.linalg.norm(v[:, :2] - action.grasp[:2], axis=1).argmin())
            path = timed_path(
                carry_arc(v[grab], action.place, mcfg), mcfg.cartesian_speed, timestep
            )
            carry(model, data, cloth, [holder], [grab], [path])
            step(model, data, round((0.5 + cfg.settle_time) / timestep), cloth)
            pulls += 1
            coverage = metrics.coverage(cloth.sim_vertices(), mesh.faces, mesh.area)
            out["coverage"].append(round(coverage, 3))
        out.update(pulls=pulls, flattened=bool(coverage >= cfg.target_coverage))
    except FloatingPointError as exc:
        out["error"] = str(exc)
    out["sim_s"] = round(float(data.time), 2)
    out["speed"] = round(float(data.time) / (time.perf_counter() - wall), 2)
    return out


def spread(seed: int, timestep: float) -> dict:
    """`towel_crumpled`'s towel crumpled as in `flatten`, then flattened by two ideal holders
    lifting two adjacent corners (GROUND TRUTH) until the towel hangs free, spreading them one
    edge apart in the air and laying the hanging towel down at 45° from the far side of the
    workspace to the near one; repeated with the next edge while under the target coverage,
    within FlattenConfig's budget."""
    from foldbot import metrics
    from foldbot.planning.flatten import FlattenConfig

    towel, mesh = towel_mesh(seed, "towel_crumpled")
    cfg = FlattenConfig()
    centre = np.array([0.45, 0.0])
    model, data = build(mesh, timestep, 2, tuple(centre))
    cloth = MjCloth(model, data, mesh)
    holders = [Holder(model, data, cloth, g) for g in range(2)]
    corners = [mesh.keypoints[k] for k in ("corner_00", "corner_10", "corner_11", "corner_01")]
    rest = mesh.vertices[:, :2]
    out: dict = {"seed": seed, "timestep": timestep, "coverage": []}
    wall = time.perf_counter()
    try:
        rng = np.random.default_rng([seed, 2])
        crumple(model, data, cloth, holders[0], towel, rng, timestep)
        coverage = metrics.coverage(cloth.sim_vertices(), mesh.faces, mesh.area)
        out["coverage"].append(round(coverage, 3))
        actions = 0
        while coverage < cfg.target_coverage and actions < cfg.max_actions:
            a, b = corners[actions % 4], corners[(actions + 1) % 4]  # an edge, then the next
            edge = float(np.linalg.norm(rest[a] - rest[b]))
            depth = float(mesh.area / edge)  # the towel's other side
            lift = depth + 0.1  # the towel hangs free of the table
            v = cloth.sim_vertices()
            # The corner that lies to the left in the flat towel (looking along +x) goes left.
            ya, yb = (-edge / 2, edge / 2)
            paths = []
            for vertex, y in ((a, ya), (b, yb)):
                now = v[vertex]
                waypoints = np.array(
                    [
                        now,
                        [now[0], now[1], TABLE_TOP + lift],
                        [centre[0] + depth / 2, centre[1] + y, TABLE_TOP + lift],
                        [centre[0] + depth / 2, centre[1] + y, TABLE_TOP + lift],  # hang still
                        # The free edge just touches the table at the far side, then the held
                        # edge comes down at 45° so the towel is laid, not heaped.
                        [centre[0] + depth / 2, centre[1] + y, TABLE_TOP + depth + RADIUS],
                        [centre[0] - depth / 2, centre[1] + y, TABLE_TOP + 0.02],
                    ]
                )
                paths.append(
                    np.vstack(
                        [
                            timed_path(waypoints[:3], 0.25, timestep),
                            np.repeat(waypoints[3:4], round(1.0 / timestep), axis=0),
                            timed_path(waypoints[3:], SPREAD_LAY_SPEED, timestep),
                        ]
                    )
                )
            carry(model, data, cloth, holders, (a, b), paths)
            step(model, data, round((0.5 + cfg.settle_time) / timestep), cloth)
            actions += 1
            coverage = metrics.coverage(cloth.sim_vertices(), mesh.faces, mesh.area)
            out["coverage"].append(round(coverage, 3))
        out.update(pulls=actions, flattened=bool(coverage >= cfg.target_coverage))
    except FloatingPointError as exc:
        out["error"] = str(exc)
    out["sim_s"] = round(float(data.time), 2)
    out["speed"] = round(float(data.time) / (time.perf_counter() - wall), 2)
    return out


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("what", choices=("fold", "heap", "flatten", "spread"))
    ap.add_argument("--recipe", default="half")
    ap.add_argument("--grippers", type=int, choices=(1, 2), default=2)
    ap.add_argument("--seeds", default="0-4")
    ap.add_argument("--timestep", type=float, default=0.002, help="s (default 0.002)")
    ap.add_argument("--young", type=float, default=2e4, help="Young's modulus, Pa (default 2e4)")
    ap.add_argument(
        "--elastic2d", choices=("both", "stretch", "bend", "none"), default="both",
        help="which shell terms act (default both)",
    )  # fmt: skip
    args = ap.parse_args()
    ELASTICITY.update(young=args.young, elastic2d=args.elastic2d)
    rows = []
    for seed in parse_seeds(args.seeds):
        if args.what == "fold":
            row = fold(seed, args.recipe, args.grippers, args.timestep)
        elif args.what == "heap":
            row = heap(seed, args.timestep)
        elif args.what == "flatten":
            row = flatten(seed, args.timestep)
        else:
            row = spread(seed, args.timestep)
        rows.append(row)
        print(json.dumps(row), flush=True)
    ok = [r for r in rows if "error" not in r]
    speed = np.median([r["speed"] for r in rows])
    if args.what == "fold" and ok:
        err = np.array([r["fold_error_mm"] for r in ok])
        print(
            f"# fold {args.recipe}, {args.grippers} gripper(s), dt {args.timestep}: "
            f"{len(rows) - len(ok)} of {len(rows)} diverged; success "
            f"{sum(r['success'] for r in ok)}; fold error mean {err.mean():.1f} / median "
            f"{np.median(err):.1f} mm; speed median {speed:.2f}x",
            file=sys.stderr,
        )
    elif args.what in ("flatten", "spread"):
        print(
            f"# {args.what}, dt {args.timestep}: {len(rows) - len(ok)} of {len(rows)} diverged; "
            f"flattened {sum(r['flattened'] for r in ok)} of {len(rows)}; coverage after "
            f"{np.round([r['coverage'][-1] for r in ok], 2).tolist()}; speed median {speed:.2f}x",
            file=sys.stderr,
        )
    elif ok:
        print(
            f"# heap, dt {args.timestep}: {len(rows) - len(ok)} of {len(rows)} diverged; fastest "
            f"vertex median {np.median([r['fastest_vertex_median_m_s'] for r in ok]):.3f} m/s; "
            f"deepest {max(r['deepest_mm'] for r in ok):.1f} mm; speed median {speed:.2f}x",
            file=sys.stderr,
        )
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
