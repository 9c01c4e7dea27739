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

from foldbot.control.executor import ArmExecutor
from foldbot.errors import FoldbotError, UnreachableTargetError, require
from foldbot.garments.towel import TowelSpec, make_towel
from foldbot.io.episode import EpisodeWriter
from foldbot.metrics import score_episode
from foldbot.perception.estimator import VisionEstimator
from foldbot.perception.overlay import draw_overlay
from foldbot.perception.state import ClothState
from foldbot.planning.actions import FoldAction
from foldbot.planning.motion import MotionConfig, Segment, action_segments, line_path
from foldbot.planning.recipes import RECIPES, plan_recipe
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
    perception: str = "oracle"
    """Where keypoints come from: vision (RGB-D) or oracle (simulator ground truth, comparison)."""
    seed: int = 0
    """Randomisation seed: the same seed gives the same episode."""
    towel: TowelSpec = field(default_factory=TowelSpec)
    cloth: ClothConfig = field(default_factory=ClothConfig)
    sim: SimConfig = field(default_factory=SimConfig)
    motion: MotionConfig = field(default_factory=MotionConfig)
    camera: CameraConfig = field(default_factory=CameraConfig)
    position_jitter: float = 0.03
    """Cloth centre offset from the workspace centre, uniform in ±this (m)."""
    yaw_range: float = math.pi / 12
    """Cloth yaw, uniform in ±this (rad)."""
    grasp_retries: int = 1
    """Re-observe and retry a failed grasp at most this many times per action."""
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
        require(self.grasp_retries >= 0, f"grasp_retries must be ≥ 0, got {self.grasp_retries!r}")
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
        mesh = make_towel(cfg.towel)
        center, yaw = _seeded_pose(cfg, layout.workspace_center_xy)
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
        park = robot.tcp_pose()[0]

        def observe() -> tuple[ClothState, object]:
            obs = camera.observe(robot.joint_positions(), stamp=world.sim_time)
            state = estimator.estimate(obs)
            if recorder is not None:
                recorder.state = state
            return state, obs

        state, obs = observe()
        if not state.detected:
            raise FoldbotError(f"no cloth found before the first action: {state.reason}")
        plan = plan_recipe(cfg.recipe, _corners(state))
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
        action_logs = []
        for i, planned in enumerate(plan.actions):
            log(f"action {i + 1}/{len(plan.actions)}: {planned.label} → place")
            t_sim, t_wall = world.sim_time, time.perf_counter()
            retries, outcome, action = 0, None, planned
            while True:
                if i > 0 or retries > 0:
                    # Re-observe: earlier actions move the cloth; grasp where the corner is now.
                    state, obs = observe()
                    if state.detected and planned.label in state.keypoints:
                        action = dataclasses.replace(
                            planned, grasp=np.asarray(state.keypoints[planned.label][0])
                        )
                if recorder is not None:
                    recorder.overlay_args = {
                        "grasp_points": [action.grasp],
                        "place_points": [action.place],
                        "fold_line": _line_points(action.fold_line, layout.table_height),
                    }
                outcome = _execute_action(executor, robot, action, cfg.motion)
                if outcome["grasp_success"] or retries >= cfg.grasp_retries:
                    break
                retries += 1
                log(f"  grasp failed ({outcome['grasp_reason']}); re-observing, retry {retries}")
            action_logs.append(
                {
                    "kind": "pick_and_place",
                    "label": action.label,
                    "grasp": [float(v) for v in action.grasp],
                    "place": [float(v) for v in action.place],
                    "grasp_success": outcome["grasp_success"],
                    "grasp_reason": outcome["grasp_reason"],
                    "grasped_vertices": outcome["grasped_vertices"],
                    "retries": retries,
                    "max_tracking_error_m": outcome["max_tracking_error"],
                    "sim_seconds": world.sim_time - t_sim,
                    "wall_seconds": time.perf_counter() - t_wall,
                }
            )
        _move_to(executor, robot, park, cfg.motion)
        world.step(round(0.5 / world.time_step))
        final_state, final_obs = observe()
        final = oracle.cloth_vertices()
        score = score_episode(initial, final, mesh.faces, plan.fold_lines, cloth.thickness)
        writer.write_image("overlay_final.png", draw_overlay(final_obs, final_state))
        if recorder is not None:
            recorder.capture()
        writer.write_cloth(mesh.faces, initial, final, cloth.thickness)
        result = {
            **score.as_dict(),
            "fold_lines": [list(line) for line in plan.fold_lines],
            "garment": cfg.garment,
            "recipe": cfg.recipe,
            "robot": cfg.robot,
            "seed": cfg.seed,
            "perception": cfg.perception,
            "grasp_points_source": "oracle" if cfg.perception == "oracle" else "vision",
            "towel": dataclasses.asdict(cfg.towel),
            "cloth_pose": {"x": center[0], "y": center[1], "yaw": yaw},
            "actions": action_logs,
            "sim_seconds": world.sim_time,
            "wall_seconds": time.perf_counter() - wall0,
        }
        writer.write_result(result)
        path = writer.commit()
    result["out_dir"] = str(path)
    return result


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
    path = line_path(robot.tcp_pose()[0], np.asarray(target, dtype=float))
    try:
        executor.run(Segment("move", path, motion.free_speed))
    except UnreachableTargetError as exc:
        raise UnreachableTargetError(
            f"cannot move to {np.round(target, 3).tolist()}: {exc}"
        ) from exc
