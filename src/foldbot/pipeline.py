"""One fold episode on the simulated cell: observe → estimate → plan → execute → re-observe → score.

The planner and the executor only see estimated keypoints (vision or, for comparison, the named
oracle); ground truth is read for scoring and recorded as such.
"""

from __future__ import annotations

import dataclasses
import math
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from scipy.spatial import ConvexHull

from foldbot.control.executor import ArmExecutor
from foldbot.errors import FoldbotError, UnreachableTargetError, require
from foldbot.garments.towel import TowelSpec, make_towel
from foldbot.io.episode import EpisodeWriter
from foldbot.metrics import score_episode
from foldbot.perception.estimator import VisionEstimator
from foldbot.perception.keypoints import label_corners, max_area_quad
from foldbot.perception.overlay import draw_overlay
from foldbot.perception.state import ClothState, fold_check_iou
from foldbot.planning.actions import FoldAction
from foldbot.planning.motion import MotionConfig, Segment, action_segments, line_path
from foldbot.planning.recipes import RECIPES, plan_stage, predicted_outline, recipe_stages
from foldbot.sim.camera import CameraConfig, RGBDCamera
from foldbot.sim.cloth import ClothConfig, DivergenceMonitor, SoftCloth, settle
from foldbot.sim.grasp import ClothGrasp
from foldbot.sim.oracle import GroundTruthOracle, OracleEstimator
from foldbot.sim.robots import ROBOT_NAMES, make_robot
from foldbot.sim.world import SimConfig, SimWorld

GARMENTS = ("towel",)
PERCEPTION_MODES = ("vision", "oracle")


@dataclass(frozen=True)
class EpisodeConfig:
    """Everything that defines one fold episode; the seed draws the cloth's pose on the table."""

    garment: str = "towel"
    """Garment kind; allowed: towel."""
    recipe: str = "half"
    """Fold recipe; see planning.recipes.RECIPES."""
    robot: str = "ur5"
    """Arm; allowed: ur5, panda."""
    perception: str = "vision"
    """Where keypoints come from: vision (RGB-D) or oracle (simulator ground truth, comparison)."""
    seed: int = 0
    """Randomisation seed: the same seed gives the same episode."""
    towel: TowelSpec = field(default_factory=TowelSpec)
    towel_size_range: tuple[float, float] | None = None
    """When set, each side of the towel is drawn uniformly from [lo, hi] m by the seed (the
    resolution stays `towel.resolution` vertices along the longer side)."""
    cloth: ClothConfig = field(default_factory=ClothConfig)
    sim: SimConfig = field(default_factory=SimConfig)
    motion: MotionConfig = field(default_factory=MotionConfig)
    camera: CameraConfig = field(default_factory=CameraConfig)
    position_jitter: float = 0.03
    """Cloth centre offset from the workspace centre, uniform in ±this (m)."""
    yaw_range: float = math.pi / 12
    """Cloth yaw, uniform in ±this (rad)."""
    retries: int = 1
    """Per action: re-observe and redo a failed grasp or an off placement at most this often."""
    place_tolerance: float = 0.03
    """A placed corner perceived farther than this from its place point is an off result (m)."""
    regrasp_radius: float = 0.06
    """A re-observed corner is matched to a planned grasp within this radius (m) by position."""
    regrasp_label_radius: float = 0.25
    """… and by its label within this radius (m): a towel's corners are ≥ 0.25 m apart."""
    fault_grasp_offset: float = 0.0
    """Fault injection: the episode's first grasp is aimed this far (m) outward from the perceived
    corner, onto bare table, to exercise the failure → re-observe → retry path."""
    verify_iou: float = 0.8
    """A stage is verified when the perceived mask matches the predicted outline this well."""
    closed_loop: bool = True
    """False: open loop, for comparison: plan every stage once from the first observation and
    execute all actions with no re-observation, regrasp, retry or stage verification."""
    video_fps: float = 10.0
    """Frames per simulated second in video.mp4 (0 = no video)."""

    def __post_init__(self) -> None:
        require(
            self.garment in GARMENTS,
            f"unknown garment {self.garment!r}; allowed: {', '.join(GARMENTS)}",
        )
        require(
            self.recipe in RECIPES, f"unknown recipe {self.recipe!r}; allowed: {', '.join(RECIPES)}"
        )
        require(
            self.robot in ROBOT_NAMES,
            f"unknown robot {self.robot!r}; allowed: {', '.join(ROBOT_NAMES)}",
        )
        require(
            self.perception in PERCEPTION_MODES,
            f"unknown perception {self.perception!r}; allowed: {', '.join(PERCEPTION_MODES)}",
        )
        require(
            isinstance(self.seed, int) and self.seed >= 0,
            f"seed must be an integer ≥ 0, got {self.seed!r}",
        )
        if self.towel_size_range is not None:
            lo, hi = self.towel_size_range
            require(
                0.05 <= lo <= hi <= 1.0,
                f"towel_size_range must satisfy 0.05 ≤ lo ≤ hi ≤ 1.0 m, got {self.towel_size_range!r}",
            )
        require(self.retries >= 0, f"retries must be ≥ 0, got {self.retries!r}")
        require(
            0.0 <= self.fault_grasp_offset <= 0.2,
            f"fault_grasp_offset must be in [0, 0.2] m, got {self.fault_grasp_offset!r}",
        )
        require(self.video_fps >= 0, f"video_fps must be ≥ 0, got {self.video_fps!r}")


class _VideoRecorder:
    """World step hook: renders the camera every 1/fps simulated seconds with the latest overlay."""

    def __init__(self, camera: RGBDCamera, writer: EpisodeWriter, fps: float) -> None:
        self.camera = camera
        self.writer = writer
        self.period = 1.0 / fps
        self.next_time = 0.0
        self.overlay_args: dict = {}
        self.state: ClothState | None = None

    def __call__(self, world) -> None:
        if world.sim_time + 1e-9 < self.next_time:
            return
        self.next_time = world.sim_time + self.period
        self.capture()

    def capture(self) -> None:
        obs = self.camera.observe()
        frame = obs.rgb
        if self.state is not None and self.state.detected:
            frame = draw_overlay(obs, self.state, **self.overlay_args)
        self.writer.add_frame(frame)


def _seeded_towel(cfg: EpisodeConfig) -> TowelSpec:
    """The towel of this episode: `cfg.towel`, or with sides drawn from `towel_size_range`."""
    if cfg.towel_size_range is None:
        return cfg.towel
    # A separate stream, so turning size randomisation on leaves the seed's pose unchanged.
    rng = np.random.default_rng([cfg.seed, 1])
    lo, hi = cfg.towel_size_range
    width, height = (float(v) for v in rng.uniform(lo, hi, size=2))
    return dataclasses.replace(cfg.towel, width=width, height=height)


def _seeded_pose(
    cfg: EpisodeConfig, center: tuple[float, float]
) -> tuple[tuple[float, float], float]:
    rng = np.random.default_rng(cfg.seed)
    dx, dy = rng.uniform(-cfg.position_jitter, cfg.position_jitter, size=2)
    yaw = float(rng.uniform(-cfg.yaw_range, cfg.yaw_range))
    return (center[0] + float(dx), center[1] + float(dy)), yaw


def _corners(state: ClothState) -> dict[str, np.ndarray]:
    return {name: xyz for name, (xyz, _conf) in state.keypoints.items()}


def run_episode(cfg: EpisodeConfig, out_dir: Path, overwrite: bool = False, log=print) -> dict:
    """Run one fold episode and write the episode folder (result.json, cloth.npz, video.mp4)."""
    writer = EpisodeWriter(out_dir, overwrite=overwrite, fps=max(cfg.video_fps, 1.0))
    wall0 = time.perf_counter()
    with writer, SimWorld(cfg.sim) as world:
        layout = world.layout
        robot = make_robot(cfg.robot, world.client, layout)
        center, yaw = _seeded_pose(cfg, layout.workspace_center_xy)
        towel = _seeded_towel(cfg)
        mesh = make_towel(towel)
        cloth = SoftCloth(world.client, mesh, cfg.cloth, layout.table_height, center, yaw)
        world.add_step_hook(DivergenceMonitor(cloth, layout.workspace_center_xy, radius=1.0))
        camera = RGBDCamera(world.client, cfg.camera)
        oracle = GroundTruthOracle(cloth, camera)
        estimator = VisionEstimator() if cfg.perception == "vision" else OracleEstimator(oracle)
        grasp = ClothGrasp(world, robot, cloth)
        executor = ArmExecutor(world, robot, grasp)
        recorder = None
        if cfg.video_fps > 0:
            recorder = _VideoRecorder(camera, writer, cfg.video_fps)
            world.add_step_hook(recorder)
        log(f"settling the cloth ({mesh.vertices.shape[0]} vertices)…")
        settle(world, cloth)
        initial = oracle.cloth_vertices()
        park = robot.home_q  # joint-space park: the arm at home hides ~3 % of the workspace

        def observe() -> tuple[ClothState, object]:
            obs = camera.observe(robot.joint_positions(), stamp=world.sim_time)
            state = estimator.estimate(obs)
            if recorder is not None:
                recorder.state = state
            return state, obs

        fold_lines: list[tuple[float, float, float, float]] = []
        action_logs: list[dict] = []
        stage_logs: list[dict] = []
        executor.move_joints(park, "park")
        state, obs = observe()
        if not cfg.closed_loop:
            _run_open_loop(
                cfg,
                executor,
                robot,
                writer,
                recorder,
                log,
                state,
                obs,
                fold_lines,
                action_logs,
                stage_logs,
                cloth.thickness,
            )
        for stage in range(recipe_stages(cfg.recipe) if cfg.closed_loop else 0):
            # From stage 2 on, the previous stage's closing observation (arm parked, cloth
            # settled) is where this stage starts, except for the oracle, which then switches
            # from the mesh's corner vertices (now stacked in pairs) to the folded outline's.
            if stage > 0 and isinstance(estimator, OracleEstimator):
                estimator.corners = "outline"
                state, obs = observe()
            if not state.detected:
                raise FoldbotError(f"no cloth found before fold stage {stage + 1}: {state.reason}")
            if cfg.perception == "vision":
                _require_in_view(state)
            latest = state
            corners = _corners(state)
            plan = plan_stage(cfg.recipe, stage, corners, cfg.motion.place_lift)
            predicted = predicted_outline(cfg.recipe, stage, corners)
            fold_lines.append(plan.fold_lines[0])
            if stage == 0:
                writer.write_image(
                    "overlay_initial.png",
                    draw_overlay(
                        obs,
                        state,
                        grasp_points=[a.grasp for a in plan.actions],
                        place_points=[a.place for a in plan.actions],
                        fold_line=_line_points(plan.fold_lines[0], layout.table_height),
                    ),
                )
            for i, planned in enumerate(plan.actions):
                log(
                    f"stage {stage + 1}, action {i + 1}/{len(plan.actions)}: "
                    f"{planned.label} → place"
                )
                entry, latest = _closed_loop_action(
                    cfg,
                    world,
                    executor,
                    robot,
                    planned,
                    observe,
                    park,
                    recorder,
                    log,
                    latest,
                    inject_fault=cfg.fault_grasp_offset > 0 and not action_logs,
                )
                action_logs.append(entry)
            executor.move_joints(park, "park")
            world.step(round(0.3 / world.time_step))
            state, obs = observe()
            iou = (
                fold_check_iou(state.mask, predicted, obs.intrinsics, obs.T_world_camera)
                if state.detected
                else 0.0
            )
            stage_logs.append(
                {
                    "stage": stage,
                    "fold_line": list(plan.fold_lines[0]),
                    "predicted_outline": predicted.tolist(),
                    "mask_iou_vs_predicted": iou,
                    "verified": iou >= cfg.verify_iou,
                }
            )
            log(f"stage {stage + 1} done: mask IoU with the predicted shape {iou:.2f}")
        executor.move_joints(park, "park")
        world.step(round(0.5 / world.time_step))
        final_state, final_obs = observe()
        final = oracle.cloth_vertices()
        score = score_episode(initial, final, mesh.faces, fold_lines, cloth.thickness)
        writer.write_image("overlay_final.png", draw_overlay(final_obs, final_state))
        if recorder is not None:
            recorder.capture()
        writer.write_cloth(mesh.faces, initial, final, cloth.thickness)
        result = {
            **score.as_dict(),
            "fold_lines": [list(line) for line in fold_lines],
            "stages": stage_logs,
            "garment": cfg.garment,
            "recipe": cfg.recipe,
            "robot": cfg.robot,
            "seed": cfg.seed,
            "perception": cfg.perception,
            "closed_loop": cfg.closed_loop,
            "grasp_points_source": "oracle" if cfg.perception == "oracle" else "vision",
            "towel": dataclasses.asdict(towel),
            "cloth_pose": {"x": center[0], "y": center[1], "yaw": yaw},
            "actions": action_logs,
            "sim_seconds": world.sim_time,
            "wall_seconds": time.perf_counter() - wall0,
        }
        writer.write_result(result)
        path = writer.commit()
    result["out_dir"] = str(path)
    return result


def _run_open_loop(
    cfg: EpisodeConfig,
    executor: ArmExecutor,
    robot,
    writer: EpisodeWriter,
    recorder,
    log,
    state: ClothState,
    obs,
    fold_lines: list,
    action_logs: list,
    stage_logs: list,
    thickness: float,
) -> None:
    """Open loop (the comparison baseline): plan every stage from the first observation — a later
    stage on the corners of the outline the plan predicts, one layer higher — then execute all
    actions back to back: no re-observation, regrasp, retry or stage verification."""
    if not state.detected:
        raise FoldbotError(f"no cloth found before fold stage 1: {state.reason}")
    if cfg.perception == "vision":
        _require_in_view(state)
    corners, plans = _corners(state), []
    for stage in range(recipe_stages(cfg.recipe)):
        if stage > 0:
            outline = predicted_outline(cfg.recipe, stage - 1, corners)
            if len(outline) > 4:  # an overhang of the mirrored part: its 4 dominant corners
                hull = outline[ConvexHull(outline[:, :2]).vertices]
                outline = hull[max_area_quad(hull[:, :2])]
            if len(outline) != 4:
                raise FoldbotError(
                    f"open loop: the outline predicted after stage {stage} has {len(outline)} "
                    "corners, 4 are needed to plan the next stage"
                )
            labels = label_corners(outline)
            corners = {n: outline[i] + [0.0, 0.0, thickness] for n, i in labels.items()}
        plans.append(plan_stage(cfg.recipe, stage, corners, cfg.motion.place_lift))
        stage_logs.append(
            {"stage": stage, "fold_line": list(plans[-1].fold_lines[0]), "verified": None}
        )
        fold_lines.append(plans[-1].fold_lines[0])
    first = plans[0]
    writer.write_image(
        "overlay_initial.png",
        draw_overlay(
            obs,
            state,
            grasp_points=[a.grasp for a in first.actions],
            place_points=[a.place for a in first.actions],
            fold_line=_line_points(first.fold_lines[0], executor.world.layout.table_height),
        ),
    )
    for plan in plans:
        for action in plan.actions:
            log(f"open loop: {action.label} → place")
            t_sim, t_wall = executor.world.sim_time, time.perf_counter()
            if recorder is not None:
                recorder.overlay_args = {
                    "grasp_points": [action.grasp],
                    "place_points": [action.place],
                    "fold_line": _line_points(action.fold_line, executor.world.layout.table_height),
                }
            outcome = _execute_action(executor, robot, action, cfg.motion)
            action_logs.append(
                {
                    **action.as_dict(),
                    "kind": "pick_and_place",
                    "grasp_success": outcome["grasp_success"],
                    "grasp_reason": outcome["grasp_reason"],
                    "grasped_vertices": outcome["grasped_vertices"],
                    "placed_error_m": None,
                    "retries": 0,
                    "attempts": [],
                    "max_tracking_error_m": outcome["max_tracking_error"],
                    "sim_seconds": executor.world.sim_time - t_sim,
                    "wall_seconds": time.perf_counter() - t_wall,
                }
            )


def _require_in_view(state: ClothState) -> None:
    """Refuse to plan from a cloth the camera sees only in part (its mask touches the border)."""
    m = state.mask
    if m.size and (m[0].any() or m[-1].any() or m[:, 0].any() or m[:, -1].any()):
        raise FoldbotError(
            "the cloth extends beyond the camera's view (its mask touches the image border), "
            "so its corners cannot be seen; use a smaller towel or move the camera"
        )


def _nearest_keypoint(state: ClothState, point: np.ndarray, radius: float) -> np.ndarray | None:
    """The perceived keypoint nearest `point` in the table plane, if within `radius`."""
    if not state.detected or not state.keypoints:
        return None
    pts = np.array([xyz for xyz, _conf in state.keypoints.values()])
    d = np.linalg.norm(pts[:, :2] - point[:2], axis=1)
    k = int(np.argmin(d))
    return pts[k] if d[k] <= radius else None


def _moving_side_tip(
    state: ClothState, line: tuple[float, float, float, float], near: np.ndarray, band: float
) -> np.ndarray | None:
    """The perceived outline's point on the moving side of `line` that lies farthest from it (within
    `band`, the one nearest `near`), or None when no cloth is left there.

    Once the stage's first corner is folded, the cloth still on the moving side is the part that
    hangs on the corner not yet carried, so its farthest point from the line is that corner, even
    where the first carry dragged it into a shape the four-corner detector fits poorly."""
    outline = np.asarray(state.outline_world, dtype=float).reshape(-1, 3)
    if not state.detected or len(outline) < 3:
        return None
    x, y, dx, dy = line
    normal = np.array([-dy, dx]) / max(float(np.hypot(dx, dy)), 1e-12)
    s = (outline[:, :2] - [x, y]) @ normal
    if s.max() <= band:
        return None
    cand = outline[s >= s.max() - band]
    k = int(np.argmin(np.linalg.norm(cand[:, :2] - near[:2], axis=1)))
    return cand[k]


def _regrasp_point(
    state: ClothState,
    label: str,
    planned: np.ndarray,
    radius: float,
    label_radius: float,
    line: tuple[float, float, float, float] | None = None,
    tip_gap: float = 0.015,
) -> np.ndarray | None:
    """Where to grasp a corner now: the keypoint with the planned label if it lies within
    `label_radius` of the plan (a fold drags the other corners by up to ~15 cm), else the
    keypoint nearest the plan within `radius`.

    With the stage's fold `line` given, a corner still on the moving side is checked against the
    outline: where the moving side's tip nearest that keypoint lies more than `tip_gap` from it, the
    keypoint is a poor fit of a dragged corner and the tip is taken instead, at the planned height
    (the corner not yet carried lies in one layer on the table)."""
    seen = None
    if state.detected and label in state.keypoints:
        xyz = np.asarray(state.keypoints[label][0])
        if np.linalg.norm(xyz[:2] - planned[:2]) <= label_radius:
            seen = xyz
    if seen is None:
        seen = _nearest_keypoint(state, planned, radius)
    if line is None:
        return seen
    x, y, dx, dy = line
    if (planned[1] - y) * dx - (planned[0] - x) * dy <= 0.01 * float(np.hypot(dx, dy)):
        return seen  # not a corner still to be carried (e.g. one placed off, to be re-placed)
    near = planned if seen is None else seen
    tip = _moving_side_tip(state, line, near, band=0.01)
    if tip is None or np.linalg.norm(tip[:2] - planned[:2]) > label_radius:
        return seen
    if seen is None or np.linalg.norm(tip[:2] - seen[:2]) > tip_gap:
        return np.array([tip[0], tip[1], planned[2]])
    return seen


def _stack_grasp_point(state: ClothState, point: np.ndarray, height: float) -> np.ndarray:
    """`point` lowered to `height` above the perceived table plane under it, so the jaws close
    under every layer of a stack (unchanged without a usable table plane)."""
    a, b, c, d = (float(v) for v in np.asarray(state.table_plane, dtype=float).reshape(4))
    if c < 0.5:
        return np.asarray(point, dtype=float)
    z_table = -(a * point[0] + b * point[1] + d) / c
    return np.array([point[0], point[1], min(float(point[2]), z_table + height)])


def _closed_loop_action(
    cfg: EpisodeConfig,
    world,
    executor: ArmExecutor,
    robot,
    planned: FoldAction,
    observe,
    park: np.ndarray,
    recorder,
    log,
    latest: ClothState,
    inject_fault: bool = False,
) -> tuple[dict, ClothState]:
    """Execute one pick-and-place, re-observing to grasp the corner where it now is, and
    verifying the placement; a failed grasp or an off placement is redone (bounded).

    `latest` is the state of the newest observation (taken after the cloth last moved)."""
    t_sim, t_wall = world.sim_time, time.perf_counter()
    action, outcome, retries, attempts = planned, {}, 0, []
    state = latest
    while True:
        # Earlier actions move the cloth: grasp the corner where it is now.
        seen = _regrasp_point(
            state,
            planned.label,
            action.grasp,
            cfg.regrasp_radius,
            cfg.regrasp_label_radius,
            line=action.fold_line,
        )
        if seen is not None:
            action = dataclasses.replace(action, grasp=seen)
        if planned.layers > 1 and not (attempts and attempts[-1]["grasp_success"]):
            action = dataclasses.replace(
                action, grasp=_stack_grasp_point(state, action.grasp, cfg.motion.stack_grasp_height)
            )
        if inject_fault and not attempts:
            outward = action.grasp[:2] - state.keypoint_array().mean(axis=0)[:2]
            outward = outward / max(np.linalg.norm(outward), 1e-9) * cfg.fault_grasp_offset
            action = dataclasses.replace(action, grasp=action.grasp + [*outward, 0.0])
        if recorder is not None:
            recorder.overlay_args = {
                "grasp_points": [action.grasp],
                "place_points": [action.place],
                "fold_line": _line_points(action.fold_line, world.layout.table_height),
            }
        outcome = _execute_action(executor, robot, action, cfg.motion)
        placed_error = None
        executor.move_joints(park, "park")
        state, _obs = observe()
        if outcome["grasp_success"]:
            seen = _nearest_keypoint(state, action.place, 2 * cfg.regrasp_radius)
            placed_error = (
                None if seen is None else float(np.linalg.norm(seen[:2] - action.place[:2]))
            )
        ok = outcome["grasp_success"] and (
            placed_error is None or placed_error <= cfg.place_tolerance
        )
        attempts.append(
            {
                "grasp": [float(v) for v in action.grasp],
                "grasp_success": outcome["grasp_success"],
                "grasp_reason": outcome["grasp_reason"],
                "placed_error_m": placed_error,
            }
        )
        if ok or retries >= cfg.retries:
            break
        retries += 1
        if outcome["grasp_success"]:
            # Off placement: pick the misplaced corner where it lies and place it again.
            log(f"  placed {placed_error * 1000:.0f} mm off; re-grasping, retry {retries}")
            action = dataclasses.replace(action, grasp=seen)
        else:
            log(f"  grasp failed ({outcome['grasp_reason']}); re-observed, retry {retries}")
    return {
        "kind": "pick_and_place",
        "label": planned.label,
        "grasp": [float(v) for v in action.grasp],
        "place": [float(v) for v in action.place],
        "grasp_success": outcome["grasp_success"],
        "grasp_reason": outcome["grasp_reason"],
        "grasped_vertices": outcome["grasped_vertices"],
        "placed_error_m": attempts[-1]["placed_error_m"],
        "retries": retries,
        "attempts": attempts,
        "max_tracking_error_m": outcome["max_tracking_error"],
        "sim_seconds": world.sim_time - t_sim,
        "wall_seconds": time.perf_counter() - t_wall,
    }, state


def _line_points(line: tuple[float, float, float, float], z: float) -> np.ndarray:
    """The fold line's segment across the cloth as two world points (the planner's line runs from
    one folded edge's midpoint to the other's), for drawing."""
    x, y, dx, dy = line
    return np.array([[x, y, z], [x + dx, y + dy, z]])


def _execute_action(executor: ArmExecutor, robot, action: FoldAction, motion: MotionConfig) -> dict:
    """Plan the whole pick-and-place (IK on every waypoint), then run it; stop after a failed grasp."""
    try:
        planned = executor.plan(action_segments(action, robot.tcp_pose()[0], motion))
    except UnreachableTargetError as exc:
        raise UnreachableTargetError(
            f"action '{action.label}' is infeasible (nothing moved): {exc}"
        ) from exc
    grasp_result, max_err = None, 0.0
    for seg in planned:
        seg_log = executor.run(seg)
        max_err = max(max_err, seg_log.max_tracking_error)
        if seg_log.grasp is not None:
            grasp_result = seg_log.grasp
            if not grasp_result.success:
                executor.grasp.open()
                _move_to(
                    executor, robot, robot.tcp_pose()[0] + [0, 0, motion.retreat_height], motion
                )
                break
    ok = bool(grasp_result and grasp_result.success)
    return {
        "grasp_success": ok,
        "grasp_reason": grasp_result.reason if grasp_result else "no grasp attempted",
        "grasped_vertices": list(grasp_result.vertex_ids) if grasp_result else [],
        "max_tracking_error": max_err,
    }


def _move_to(executor: ArmExecutor, robot, target: np.ndarray, motion: MotionConfig) -> None:
    start = robot.tcp_pose()[0]
    if np.linalg.norm(start - target) < 0.002:
        return
    path = line_path(start, np.asarray(target, dtype=float))
    try:
        executor.run(Segment("move", path, motion.free_speed))
    except UnreachableTargetError as exc:
        raise UnreachableTargetError(
            f"cannot move to {np.round(target, 3).tolist()}: {exc}"
        ) from exc
