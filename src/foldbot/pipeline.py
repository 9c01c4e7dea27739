"""One fold episode on the simulated cell: observe → estimate → plan → execute → re-observe → score.

The closed loop itself is foldbot.loop; this module builds the in-process cell it runs on
(`SimCell`), scores the result against ground truth and writes the episode folder.

The planner and the executor only see estimated keypoints (vision or, for comparison, the named
oracle); ground truth is read for scoring and recorded as such.
"""

from __future__ import annotations

import contextlib
import dataclasses
import math
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from foldbot.carry import nearest_arm
from foldbot.cell import FoldCell, StepLog, lift_move, park_move
from foldbot.cloth_options import changed_cloth_options
from foldbot.control.bimanual import check_arms_clear, check_clear_of_still_arms
from foldbot.control.executor import (
    ArmExecutor,
    PlannedSegment,
    check_arm_fits,
    joint_move_trajectories,
    move_joints_together,
    run_together,
)
from foldbot.dry_run import (
    DryRun,
    check_dry_run_config,
    check_dry_run_output,
    dry_run,
    dry_run_flatten,
    write_dry_run,
)
from foldbot.errors import UnreachableTargetError, add_facts, require
from foldbot.flatten import flatten_and_score
from foldbot.flatten_options import (
    FlattenOptionValue,
    check_flatten_options,
    flatten_configs,
    refused_flatten_options,
)
from foldbot.garment_loop import run_garment_fold
from foldbot.garments import sample_garment
from foldbot.garments.mesh import ClothMesh
from foldbot.garments.towel import TowelSpec, make_towel
from foldbot.io.episode import EpisodeWriter
from foldbot.loop import FoldRecord, LoopConfig, fold_and_picture, run_fold
from foldbot.loop_options import LoopOptionValue, apply_loop_options, check_loop_options
from foldbot.metrics import keypoint_errors_mm, score_episode
from foldbot.operator import OperatorGate
from foldbot.perception.fallback import vision_estimator
from foldbot.perception.keypoints import label_corners
from foldbot.perception.overlay import draw_overlay
from foldbot.perception.state import ClothState
from foldbot.planning.actions import FoldAction
from foldbot.planning.garment_recipes import GARMENT_RECIPES
from foldbot.planning.motion import MotionConfig, action_segments
from foldbot.planning.recipes import RECIPES, folded_as
from foldbot.planning.spread import SpreadAction, motion_segments
from foldbot.sim.camera import CameraConfig, RGBDCamera, camera_for_layout
from foldbot.sim.cloth import ClothConfig, DivergenceMonitor, SoftCloth, keep_table_grip, settle
from foldbot.sim.crossing_guard import CrossingGuard
from foldbot.sim.crumple import crumple
from foldbot.sim.flatten_oracle import CornerPullOracle
from foldbot.sim.garment_oracle import GarmentOracleEstimator
from foldbot.sim.grasp import JAW_CATCHES, ClothGrasp, SlipFault
from foldbot.sim.oracle import GroundTruthOracle, OracleEstimator
from foldbot.sim.robots import ROBOT_NAMES, make_robot
from foldbot.sim.world import SimConfig, SimWorld
from foldbot.simd import late_libraries
from foldbot.types import GraspResult, Observation

GARMENTS = ("towel", *GARMENT_RECIPES)
"""Garment kinds: the towel (planning.recipes) and the garments of planning.garment_recipes."""
GARMENT_YAW = math.pi / 2
"""A garment (not a towel) lies with this base yaw by default (EpisodeConfig.garment_yaw), so its
top (neck / waist, mesh +y) points at the robot (world −x): the hem-up and in-half folds then
carry far cloth toward the arm."""
PERCEPTION_MODES = ("vision", "oracle")
START_STATES = ("flat", "crumpled")
"""How an episode's cloth starts: settled flat, or crumpled (flattened by the robot first)."""
ARM_COUNTS = (1, 2)
"""Arms a cell can have: one, or two side by side (CellLayout.arm_layouts)."""
PARK_POSES = ("home", "out_of_view")
"""Where the arm waits while the camera looks: home (TCP 0.25 m over the workspace centre; from
the camera it hides the near edge of a large cloth) or out_of_view (TCP near the robot base,
outside the image; longer moves)."""
REPLICATE_NUDGE_M = 1e-4
"""How far (m) replicate k > 0 lays the seed's cloth from its drawn pose, in a direction drawn from
(seed, k): a tenth of a millimetre, nothing a robot could tell apart, yet a folded stack's outcome
changes with it (docs/experiments.md), so replicates measure what the seed's towel folds to."""
MAX_REPLICATE = 999
"""Largest replicate index."""


MAX_VIDEO_FPS = 60.0
"""Most video frames per simulated second an episode records (as a suite allows)."""


@dataclass(frozen=True)
class EpisodeConfig:
    """Everything that defines one fold episode; the seed draws the cloth's pose on the table."""

    garment: str = "towel"
    """Garment kind; allowed: towel, tshirt, pants."""
    recipe: str = "half"
    """Fold recipe: planning.recipes.RECIPES for a towel, GARMENT_RECIPES[garment] otherwise."""
    robot: str = "ur5"
    """Arm; allowed: ur5, ur5e, panda."""
    perception: str = "vision"
    """Where keypoints come from: vision (RGB-D) or oracle (simulator ground truth, comparison;
    from a crumpled start it also plans the flattening pulls: sim.flatten_oracle)."""
    seed: int = 0
    """Randomisation seed: the same seed gives the same episode."""
    towel: TowelSpec = field(default_factory=TowelSpec)
    towel_size_range: tuple[float, float] | None = None
    """When set, each side of the towel is drawn uniformly from [lo, hi] m by the seed (the
    resolution stays `towel.resolution` vertices along the longer side)."""
    garment_edge_length: float | None = None
    """Mesh edge length (m) of a T-shirt or pants; None = the garment module's default."""
    garment_yaw: float = GARMENT_YAW
    """Base yaw (rad) of a T-shirt or pants, to which the seed's yaw draw is added: π/2 (the
    default) turns its top (mesh +y) toward the robot, π or 0 lays it sideways (top toward −y or
    +y). Perception is not told it: the garment estimator finds the top from the shape."""
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
    fault_slip: float = 0.0
    """Fault injection: the episode's first carry (a fold's or a flattening pull's) loses its
    cloth this fraction of the way along (0: never), as a grasp that slips; the gripper reports
    it lost its hold and the loop lets go, re-observes and grasps again."""
    verify_iou: float = 0.8
    """A stage is verified when the perceived mask matches the predicted outline this well."""
    closed_loop: bool = True
    """False: open loop, for comparison: plan every stage once from the first observation and
    execute all actions with no re-observation, regrasp, retry or stage verification."""
    video_fps: float = 10.0
    """Frames per simulated second in video.mp4 (0 = no video)."""
    start: str = "flat"
    """flat, or crumpled: the seed crumples the settled cloth and the robot flattens it (until the
    perceived coverage reaches the target, or its action budget is spent) before folding."""
    park: str = "home"
    """Where the arm waits while the camera looks (PARK_POSES): home or out_of_view."""
    arms: int = 1
    """Arms in the cell: 1, or 2 side by side (CellLayout.arm_layouts), which carry a stage's
    two grasps together (a towel's corners, a garment side's hem and cuff, a pants leg's waist
    and hem; single actions use the arm on their side). Flat starts only."""
    jaw_catch: str = "vertices"
    """What the closed jaws hold (sim.grasp.JAW_CATCHES): "vertices", the cloth's mesh points
    between the pads; "surface", also cloth that passes between the pads between mesh points."""
    loop_options: dict[str, LoopOptionValue] = field(default_factory=dict)
    """The closed loop's switches set by name (loop_options.LOOP_OPTIONS: top_layer_first,
    stack_edge_carry, pair_descent, …); those not named keep LoopConfig's defaults."""
    flatten_options: dict[str, FlattenOptionValue] = field(default_factory=dict)
    """How a crumpled towel is flattened, set by name (flatten_options.FLATTEN_OPTIONS:
    finish_coverage, grasp_layer, spread_lay_speed, …); those not named keep FlattenConfig's and
    SpreadConfig's defaults. Crumpled starts only; the spread_ ones in a two-arm cell."""
    replicate: int = 0
    """0: the cloth lies exactly where the seed puts it; k > 0: the same cloth laid
    REPLICATE_NUDGE_M from there, in a direction the seed and k draw (seeded_pose)."""

    @property
    def cell_camera(self) -> CameraConfig:
        """The simulated camera as placed in this episode's cell: `camera`, moved with a
        layout whose workspace or table lies elsewhere (sim.camera.camera_for_layout)."""
        return camera_for_layout(self.camera, self.sim.layout)

    def __post_init__(self) -> None:
        require(
            self.garment in GARMENTS,
            f"unknown garment {self.garment!r}; allowed: {', '.join(GARMENTS)}",
        )
        recipes = garment_recipes(self.garment)
        require(
            self.recipe in recipes,
            f"unknown {self.garment} recipe {self.recipe!r}; allowed: {', '.join(recipes)}",
        )
        object.__setattr__(
            self, "loop_options", check_loop_options(self.loop_options, self.garment)
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
        require(
            isinstance(self.replicate, int)
            and not isinstance(self.replicate, bool)
            and 0 <= self.replicate <= MAX_REPLICATE,
            f"replicate must be an integer in [0, {MAX_REPLICATE}], got {self.replicate!r}",
        )
        if self.towel_size_range is not None:
            lo, hi = self.towel_size_range
            require(
                0.05 <= lo <= hi <= 1.0,
                f"towel_size_range must satisfy 0.05 ≤ lo ≤ hi ≤ 1.0 m, got {self.towel_size_range!r}",
            )
        if self.garment_edge_length is not None:
            require(
                self.garment != "towel",
                f"garment_edge_length ({self.garment_edge_length!r} m) sets a T-shirt's or pants' "
                "mesh; a towel's is towel.resolution's",
            )
            require(
                0.005 <= self.garment_edge_length <= 0.1,
                f"garment_edge_length must be in [0.005, 0.1] m, got {self.garment_edge_length!r}",
            )
        require(
            math.isfinite(self.garment_yaw) and abs(self.garment_yaw) <= 2 * math.pi,
            f"garment_yaw must be within ±360° (±2π rad), got {math.degrees(self.garment_yaw):g}° "
            f"({self.garment_yaw!r} rad)",
        )
        require(
            self.garment != "towel" or math.isclose(self.garment_yaw, GARMENT_YAW, abs_tol=1e-9),
            f"garment_yaw ({math.degrees(self.garment_yaw):g}°) turns a T-shirt or pants; a "
            "towel's yaw is the seed's draw within yaw_range alone",
        )
        require(self.retries >= 0, f"retries must be ≥ 0, got {self.retries!r}")
        require(
            0.0 <= self.fault_grasp_offset <= 0.2,
            f"fault_grasp_offset must be in [0, 0.2] m, got {self.fault_grasp_offset!r}",
        )
        require(
            0.0 <= self.fault_slip < 1.0,
            f"fault_slip must be in [0, 1) (the fraction of the first carry done when its "
            f"grasp slips; 0: none), got {self.fault_slip!r}",
        )
        require(
            0 <= self.video_fps <= MAX_VIDEO_FPS,
            f"video_fps must be frames per simulated second in [0, {MAX_VIDEO_FPS:g}] "
            f"(0: no video), got {self.video_fps!r}",
        )
        require(
            self.start in START_STATES,
            f"unknown start {self.start!r}; allowed: {', '.join(START_STATES)}",
        )
        require(
            self.start == "flat" or self.garment == "towel",
            f"start {self.start!r} is for towels (the flattening pulls toward a rectangle); "
            f"a {self.garment} garment starts flat",
        )
        require(
            self.park in PARK_POSES,
            f"unknown park {self.park!r}; allowed: {', '.join(PARK_POSES)}",
        )
        require(
            self.arms in ARM_COUNTS and not isinstance(self.arms, bool),
            f"arms must be one of {ARM_COUNTS}, got {self.arms!r}",
        )
        require(
            self.jaw_catch in JAW_CATCHES,
            f"unknown jaw_catch {self.jaw_catch!r}; allowed: {', '.join(JAW_CATCHES)}",
        )
        object.__setattr__(self, "flatten_options", check_flatten_options(self.flatten_options))
        refused = refused_flatten_options(
            self.flatten_options, self.start, self.arms, self.perception
        )
        require(refused is None, str(refused))


def garment_recipes(garment: str) -> tuple[str, ...]:
    """The fold recipes of a garment kind (ConfigError for an unknown kind)."""
    require(garment in GARMENTS, f"unknown garment {garment!r}; allowed: {', '.join(GARMENTS)}")
    return RECIPES if garment == "towel" else GARMENT_RECIPES[garment]


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


def spec_record(spec: object) -> dict:
    """The garment spec as result.json records it: its fields, a towel's vertex bound only where
    one is set (results from before the bound existed read the same)."""
    record = dataclasses.asdict(spec)  # type: ignore[call-overload]
    if isinstance(spec, TowelSpec) and spec.max_vertices is None:
        del record["max_vertices"]
    return record


def seeded_towel(cfg: EpisodeConfig) -> TowelSpec:
    """The towel of this episode: `cfg.towel`, or with sides drawn from `towel_size_range`."""
    if cfg.towel_size_range is None:
        return cfg.towel
    # A separate stream, so turning size randomisation on leaves the seed's pose unchanged.
    rng = np.random.default_rng([cfg.seed, 1])
    lo, hi = cfg.towel_size_range
    width, height = (float(v) for v in rng.uniform(lo, hi, size=2))
    return dataclasses.replace(cfg.towel, width=width, height=height)


def seeded_garment(cfg: EpisodeConfig) -> tuple[object, ClothMesh]:
    """The garment of this episode and its flat mesh: the (seeded) towel, or a T-shirt / pants
    whose size the seed draws from the garment module's realistic ranges."""
    if cfg.garment == "towel":
        towel = seeded_towel(cfg)
        return towel, make_towel(towel)
    rng = np.random.default_rng([cfg.seed, 1])
    return sample_garment(cfg.garment, rng, cfg.garment_edge_length)


def seeded_pose(
    cfg: EpisodeConfig, center: tuple[float, float]
) -> tuple[tuple[float, float], float]:
    """The cloth's centre (x, y) and yaw (rad) on the table for this episode's seed (a garment
    other than the towel adds `cfg.garment_yaw`); a replicate k > 0 moves the centre
    REPLICATE_NUDGE_M in a direction drawn from (seed, k)."""
    rng = np.random.default_rng(cfg.seed)
    dx, dy = rng.uniform(-cfg.position_jitter, cfg.position_jitter, size=2)
    yaw = float(rng.uniform(-cfg.yaw_range, cfg.yaw_range))
    if cfg.garment != "towel":
        yaw += cfg.garment_yaw
    if cfg.replicate > 0:
        angle = np.random.default_rng([cfg.seed, cfg.replicate, 3]).uniform(0.0, 2 * math.pi)
        dx += REPLICATE_NUDGE_M * math.cos(angle)
        dy += REPLICATE_NUDGE_M * math.sin(angle)
    return (center[0] + float(dx), center[1] + float(dy)), yaw


class SimCell(FoldCell):
    """The in-process cell: PyBullet world, arm, gripper, camera and an estimator, driven by
    direct calls (the ROS nodes offer the same cell over topics)."""

    def __init__(
        self,
        world: SimWorld,
        robot,
        executor: ArmExecutor,
        camera: RGBDCamera,
        estimator,
        motion: MotionConfig,
        recorder: _VideoRecorder | None = None,
        park: str = "home",
        more_executors: tuple[ArmExecutor, ...] = (),
    ) -> None:
        self.world = world
        self.executors = (executor, *more_executors)
        """One per arm (arm 0 first); `robot` and `executor` are the active arm's."""
        self.active = 0
        self.camera = camera
        self.estimator = estimator
        self.motion = motion
        self.recorder = recorder
        self.table_height = world.layout.table_height
        self.park_qs = tuple(
            e.robot.out_of_view_q if park == "out_of_view" else e.robot.home_q
            for e in self.executors
        )
        self.slip_fault = SlipFault()
        """Fault injection (EpisodeConfig.fault_slip): the first carry's grasp slips part of
        the way along it (none by default)."""

    @property
    def executor(self) -> ArmExecutor:
        return self.executors[self.active]

    @property
    def robot(self):
        return self.executor.robot

    @property
    def arms(self) -> int:
        return len(self.executors)

    @property
    def active_arm(self) -> int:
        return self.active

    def use_arm(self, arm: int) -> None:
        require(0 <= arm < self.arms, f"arm must be in [0, {self.arms - 1}], got {arm!r}")
        self.active = arm

    def arm_for(self, point: np.ndarray) -> int:
        return nearest_arm(point, tuple(e.robot.layout.robot_base_xyz[1] for e in self.executors))

    def plan_together(
        self, actions: list[tuple[int, FoldAction | SpreadAction]]
    ) -> list[list[PlannedSegment]]:
        plans = [
            self.executors[arm].plan(
                motion_segments(action, self.executors[arm].robot.tcp_pose()[0], self.motion)
            )
            for arm, action in actions
        ]
        check_arms_clear(
            [(self.executors[arm], plan) for (arm, _), plan in zip(actions, plans, strict=True)]
        )
        return plans

    def run_together(self, steps: list[tuple[int, PlannedSegment]]) -> list[StepLog]:
        return self._run_checked([(self.executors[arm], step) for arm, step in steps])

    def _run_checked(self, steps: list[tuple[ArmExecutor, PlannedSegment]]) -> list[StepLog]:
        """Run steps on one clock; a gripper that held cloth before its step and no longer
        holds what it grasped after it (ClothGrasp.holds_what_it_grasped), though the step did
        not open it, reports the grasp as slipped: a failed GraspResult, which the loops treat
        as a missed grasp (let go, lift, re-observe, retry)."""
        before = [ex.grasp.held for ex, _ in steps]
        hook = self._slip_hook(steps)
        try:
            logs = run_together(steps)
        finally:
            if hook is not None:
                self.world.remove_step_hook(hook)
        out = []
        for (ex, step), held, log in zip(steps, before, logs, strict=True):
            grasp = log.grasp
            if grasp is None and step.segment.gripper != "open":
                lost = ex.grasp.lost_hold(held, log.name)
                grasp = None if lost is None else GraspResult(False, (), lost)
            out.append(StepLog(log.name, log.max_tracking_error, grasp))
        return out

    def _slip_hook(self, steps: list[tuple[ArmExecutor, PlannedSegment]]):
        """The injected slip (slip_fault), on the first carry that holds cloth, added as a step
        hook; None when no slip is due."""
        carrying = [(ex, s) for ex, s in steps if s.segment.name == "carry" and ex.grasp.holding]
        if not carrying:
            return None
        ex, step = carrying[0]
        hook = self.slip_fault.hook(ex.grasp, step.points[0], step.points[-1])
        if hook is not None:
            self.world.add_step_hook(hook)
        return hook

    @property
    def sim_time(self) -> float:
        return self.world.sim_time

    def observe(self) -> tuple[ClothState, Observation]:
        robot = self.executors[0].robot
        obs = self.camera.observe(robot.joint_positions(), stamp=self.world.sim_time)
        state = self.estimator.estimate(obs)
        if self.recorder is not None:
            self.recorder.state = state
        return state, obs

    def start_stage(self, stage: int) -> bool:
        # The oracle switches from the mesh's corner vertices (stacked in pairs once folded)
        # to the folded outline's corners.
        if isinstance(self.estimator, OracleEstimator):
            self.estimator.corners = "outline"
            return True
        return False

    def plan_action(self, action: FoldAction) -> list[PlannedSegment]:
        # A two-arm cell: the active arm (the one on the grasp's side) first, else the other.
        return self.plan_on_an_able_arm(lambda arm: self._plan_with(arm, action))

    def _plan_with(self, arm: int, action: FoldAction) -> list[PlannedSegment]:
        ex = self.executors[arm]
        plan = ex.plan(action_segments(action, ex.robot.tcp_pose()[0], self.motion))
        if self.arms > 1:  # the other arms wait where they are: the moving one must clear them
            still = [(o, o.robot.joint_positions()) for o in self.executors if o is not ex]
            check_clear_of_still_arms(arm, (ex, plan), still)
        return plan

    def step_seconds(self, step: PlannedSegment) -> float:
        seg = step.segment
        return self.executor.duration_for(step.joint_path, step.points, seg.speed) + seg.dwell

    def run_step(self, step: PlannedSegment) -> StepLog:
        return self._run_checked([(self.executor, step)])[0]

    def release_and_lift(self) -> None:
        if self.gate is not None:
            height = self.motion.retreat_height
            up = self.executor.lift_segment(*self.robot.tcp_pose(), height, self.motion.free_speed)
            try:
                seconds = sum(self.step_seconds(s) for s in self.executor.plan([up]))
            except UnreachableTargetError as exc:
                raise UnreachableTargetError(
                    f"cannot move to {np.round(up.points[-1], 3).tolist()}: {exc}"
                ) from exc
            self.confirm_move(lift_move(self.active_arm, height, seconds))
        self.executor.grasp.open()
        lift = self.executor.lift_segment(
            *self.robot.tcp_pose(), self.motion.retreat_height, self.motion.free_speed
        )
        try:
            self.executor.run(lift)
        except UnreachableTargetError as exc:
            raise UnreachableTargetError(
                f"cannot move to {np.round(lift.points[-1], 3).tolist()}: {exc}"
            ) from exc

    def park(self) -> None:
        targets = list(zip(self.executors, self.park_qs, strict=True))
        trajs = joint_move_trajectories(targets)
        moving = [(arm, t.duration) for arm, t in enumerate(trajs) if t is not None]
        for arm, _ in moving:  # clear of the layout's obstacles (a no-op in a cell with none)
            ex, q = targets[arm]
            try:
                ex.check_joint_move(ex.robot.joint_positions(), q, table=False)
            except UnreachableTargetError as exc:
                raise UnreachableTargetError(f"park of arm {arm}: joint move: {exc}") from exc
        if moving:
            self.confirm_move(park_move(tuple(a for a, _ in moving), max(d for _, d in moving)))
        move_joints_together(targets, "park", trajs)

    def wait(self, seconds: float) -> None:
        self.world.step(round(seconds / self.world.time_step))

    def show(self, state: ClothState | None = None, **overlay) -> None:
        if self.recorder is not None:
            self.recorder.overlay_args = overlay


def planned_recipe(cfg: EpisodeConfig) -> str:
    """The recipe whose stage order the episode's cell folds in: a towel's as folded_as gives it
    (quarter is folded as quarter_y, in either cell); a garment's as given."""
    return folded_as(cfg.recipe) if cfg.garment == "towel" else cfg.recipe


def loop_config(cfg: EpisodeConfig, layer_thickness: float = 0.0) -> LoopConfig:
    """The closed loop's part of an episode configuration (its recipe: planned_recipe), with the
    episode's loop options set."""
    loop = LoopConfig(
        recipe=planned_recipe(cfg),
        retries=cfg.retries,
        place_tolerance=cfg.place_tolerance,
        regrasp_radius=cfg.regrasp_radius,
        regrasp_label_radius=cfg.regrasp_label_radius,
        fault_grasp_offset=cfg.fault_grasp_offset,
        verify_iou=cfg.verify_iou,
        place_lift=cfg.motion.place_lift,
        require_full_view=cfg.perception == "vision",
        closed_loop=cfg.closed_loop,
        layer_thickness=layer_thickness,
        stack_grasp_height=cfg.motion.stack_grasp_height,
    )
    return apply_loop_options(loop, cfg.loop_options)


def fold_fields(cfg: EpisodeConfig, record: FoldRecord) -> dict:
    """result.json's account of the fold itself, scored or not: its lines and stages, what was
    folded with which recipe, by which robot and arms, in a cell laid out how (`layout`: the
    fields that differ from the default cell's, where any do)."""
    layout = cfg.sim.layout.changes()
    return {
        "fold_lines": [list(line) for line in record.fold_lines],
        "stages": record.stages,
        "garment": cfg.garment,
        "recipe": cfg.recipe,
        "planned_recipe": planned_recipe(cfg),
        "robot": cfg.robot,
        "arms": cfg.arms,
        **({"layout": layout} if layout else {}),
    }


def episode_result(
    cfg: EpisodeConfig,
    spec: object,
    pose: tuple[tuple[float, float], float],
    score,
    record: FoldRecord,
    sim_seconds: float,
    wall_seconds: float,
    camera: CameraConfig,
) -> dict:
    """result.json's content (shared/notes/metrics.md's contract plus the episode's log)."""
    (x, y), yaw = pose
    return {
        **score.as_dict(),
        **fold_fields(cfg, record),
        "time_step": cfg.sim.time_step,
        "speed_scale": cfg.motion.speed_scale,
        "jaw_catch": cfg.jaw_catch,
        "loop_options": dict(cfg.loop_options),
        "cloth_options": changed_cloth_options(cfg.cloth),
        "flatten_options": dict(cfg.flatten_options),
        "simd_uncapped": late_libraries(),
        "seed": cfg.seed,
        "replicate": cfg.replicate,
        "perception": cfg.perception,
        "closed_loop": cfg.closed_loop,
        "grasp_points_source": "oracle" if cfg.perception == "oracle" else "vision",
        ("towel" if cfg.garment == "towel" else "garment_spec"): spec_record(spec),
        "cloth_pose": {"x": x, "y": y, "yaw": yaw},
        "camera": camera_record(camera),
        "actions": record.actions,
        "sim_seconds": sim_seconds,
        "wall_seconds": wall_seconds,
    }


def camera_record(camera: CameraConfig) -> dict[str, Any]:
    """result.json's camera: image size, intrinsics and where it stands; where perception was
    given a calibration's pose instead (--camera-pose), that pose, its file, and how far it lies
    from the true one."""
    out: dict[str, Any] = {
        "width": camera.width,
        "height": camera.height,
        "K": camera.K.tolist(),
        "T_world_camera": camera.T_world_camera.tolist(),
    }
    if camera.reported_pose is not None:
        from foldbot.calibration.hand_eye import pose_error_record

        out |= {
            "perceived_from": camera.reported_pose_source,
            "reported_T_world_camera": camera.reported_T_world_camera.tolist(),
            **pose_error_record(camera.reported_T_world_camera, camera.T_world_camera),
        }
    return out


def true_start_keypoints(
    cfg: EpisodeConfig, mesh: ClothMesh, initial: np.ndarray
) -> dict[str, np.ndarray] | None:
    """GROUND TRUTH, for the benchmark: the flat start's keypoints as perception names them (a
    towel's four corners by the shared labelling rule, a garment's named mesh points); None
    for a crumpled start, whose outline corners are not its mesh corners."""
    if cfg.start != "flat":
        return None
    v = np.asarray(initial, dtype=float)
    if cfg.garment != "towel":
        return {name: v[i].copy() for name, i in mesh.keypoints.items()}
    corners = np.array([v[i] for name, i in mesh.keypoints.items() if name.startswith("corner")])
    return {label: corners[i].copy() for label, i in label_corners(corners).items()}


def first_frame_keypoint_errors(
    cfg: EpisodeConfig, mesh: ClothMesh, initial: np.ndarray, seen: ClothState | None
) -> dict[str, float] | None:
    """Each keypoint the first stage was planned from against the cloth's own (mm, 3-D), where
    the benchmark's perception has to work: the cell's frame, the arm parked in it. None where
    the start was crumpled or nothing was perceived."""
    truth = true_start_keypoints(cfg, mesh, initial)
    if truth is None or seen is None or not seen.detected:
        return None
    return keypoint_errors_mm({n: xyz for n, (xyz, _conf) in seen.keypoints.items()}, truth)


@dataclass
class SimCellParts:
    """The simulated cell of one episode, built from its config (and seed) in a world."""

    world: SimWorld
    robot: object
    spec: object
    """The garment's spec (TowelSpec, or the garment module's spec)."""
    mesh: ClothMesh
    cloth: SoftCloth
    center: tuple[float, float]
    yaw: float
    camera: RGBDCamera
    oracle: GroundTruthOracle
    executor: ArmExecutor
    model_world: SimWorld
    """The planner's kinematic twin of the arm lives here (never stepped); close it with the cell."""
    more_executors: tuple[ArmExecutor, ...] = ()
    """A two-arm cell's second arm (its robot is `more_executors[0].robot`)."""
    monitor: DivergenceMonitor | None = None
    """The cloth's divergence monitor (a step hook of `world`)."""
    guard: CrossingGuard | None = None
    """The cloth's crossing guard (a step hook of `world`), where ClothConfig.crossing_guard
    asks for one."""


def build_sim_cell(cfg: EpisodeConfig, world: SimWorld) -> SimCellParts:
    """Arm, cloth (seeded size and pose), divergence monitor, camera, oracle and executor."""
    layout = world.layout
    arm_layouts = layout.arm_layouts(cfg.arms)
    robot = make_robot(cfg.robot, world.client, arm_layouts[0])
    others = [make_robot(cfg.robot, world.client, lay) for lay in arm_layouts[1:]]
    center, yaw = seeded_pose(cfg, layout.workspace_center_xy)
    spec, mesh = seeded_garment(cfg)
    cloth = SoftCloth(world.client, mesh, cfg.cloth, layout.table_height, center, yaw)
    keep_table_grip(world, cfg.cloth)  # a layer_friction of its own leaves cloth–table as it was
    monitor = DivergenceMonitor(cloth, layout.workspace_center_xy, radius=1.0)
    guard = None
    if cfg.cloth.crossing_guard:
        guard = CrossingGuard(cloth, every=int(cfg.cloth.crossing_guard))
        world.add_step_hook(guard)  # from the flat start, so it learns every side
    world.add_step_hook(monitor)
    camera = RGBDCamera(world.client, cfg.cell_camera)
    oracle = GroundTruthOracle(cloth, camera)
    model_world = SimWorld(dataclasses.replace(cfg.sim, gui=False))
    executors = [
        ArmExecutor(
            world,
            arm,
            ClothGrasp(world, arm, cloth, catch=cfg.jaw_catch),
            model=make_robot(cfg.robot, model_world.client, lay),
            model_table_id=model_world.table_id,
            speed_scale=cfg.motion.speed_scale,
            model_obstacle_ids=model_world.obstacle_ids,
        )
        for arm, lay in zip([robot, *others], arm_layouts, strict=True)
    ]
    for ex in executors:  # on the twins: IK on the simulated arms would change the cloth's run
        check_arm_fits(ex, cfg.robot, cfg.park)
    return SimCellParts(
        world,
        robot,
        spec,
        mesh,
        cloth,
        center,
        yaw,
        camera,
        oracle,
        executors[0],
        model_world,
        tuple(executors[1:]),
        monitor,
        guard,
    )


def make_estimator(cfg: EpisodeConfig, oracle: GroundTruthOracle):
    """The episode's eyes: vision (RGB-D only; the layout's obstacles known as fixtures) or the
    named ground-truth oracle, for its garment."""
    if cfg.perception == "vision":
        return vision_estimator(cfg.garment, cfg.sim.layout.obstacles)
    return OracleEstimator(oracle) if cfg.garment == "towel" else GarmentOracleEstimator(oracle)


def episode_cell(cfg: EpisodeConfig, parts: SimCellParts, recorder=None) -> SimCell:
    """The in-process cell on an episode's built parts (build_sim_cell): its estimator
    (make_estimator), motion and park pose; `recorder` films it where given."""
    return SimCell(
        parts.world,
        parts.robot,
        parts.executor,
        parts.camera,
        make_estimator(cfg, parts.oracle),
        cfg.motion,
        recorder,
        park=cfg.park,
        more_executors=parts.more_executors,
    )


def crumple_start(cfg: EpisodeConfig, world: SimWorld, cloth: SoftCloth) -> None:
    """Crumple the settled towel with the episode seed's own draw (the same in every process
    that runs the episode: `foldbot fold`, the ROS sim node)."""
    crumple(world, cloth, np.random.default_rng([cfg.seed, 2]))


def crumple_and_flatten(
    cfg: EpisodeConfig, parts: SimCellParts, cell: SimCell, writer: EpisodeWriter, log=print
) -> dict:
    """Crumple the settled towel (seeded), then flatten it from what the camera sees (with
    `perception = "oracle"`, by the ground-truth corner-pulling oracle); returns result.json's
    "flatten" entry, its coverage figures measured on GROUND TRUTH (for scoring)."""
    log("crumpling the towel…")
    crumple_start(cfg, parts.world, parts.cloth)
    oracle = CornerPullOracle.of(parts.oracle, parts.mesh) if cfg.perception == "oracle" else None
    pulls, spreads = flatten_configs(cfg.flatten_options, cfg.sim.layout)
    entry, _ = flatten_and_score(
        cell,
        (parts.spec.width, parts.spec.height),
        parts.oracle.cloth_vertices(),
        parts.oracle.cloth_vertices,
        parts.mesh.faces,
        parts.mesh.area,
        writer.write_image,
        log,
        oracle,
        cfg=pulls,
        spread=spreads,
    )
    return entry


def dry_run_episode(
    cfg: EpisodeConfig, out_dir: Path, overwrite: bool = False, log=print
) -> DryRun:
    """The episode's fold planned and not run (foldbot.dry_run): the cloth laid and settled,
    seen once with the arm where it starts, every stage and motion planned, nothing moved;
    plan.json and overlay_planK.png written into `out_dir`. The arm's joints are checked not
    to have moved (`arm_moved_rad` in plan.json). A crumpled start (one arm) is crumpled as
    the episode would be and its first flattening pull planned (dry_run.dry_run_flatten)."""
    check_dry_run_config(cfg.garment, cfg.start, injected_faults(cfg), cfg.arms)
    check_dry_run_output(out_dir, overwrite)
    with SimWorld(cfg.sim) as world, contextlib.ExitStack() as stack:
        parts = build_sim_cell(cfg, world)
        stack.callback(parts.model_world.close)
        log(f"settling the cloth ({parts.mesh.vertices.shape[0]} vertices)…")
        settle(world, parts.cloth)
        if cfg.start == "crumpled":
            log("crumpling the towel…")
            crumple_start(cfg, parts.world, parts.cloth)
        executors = [parts.executor, *parts.more_executors]
        cell = episode_cell(cfg, parts)
        q0 = [ex.robot.joint_positions() for ex in executors]
        if cfg.start == "crumpled":
            pulls, _spreads = flatten_configs(cfg.flatten_options, cfg.sim.layout)
            size = (parts.spec.width, parts.spec.height)
            run = dry_run_flatten(pulls, cell, size, cfg.motion.speed_scale, log)
        else:
            run = dry_run(
                loop_config(cfg, parts.cloth.thickness), cell, cfg.motion.speed_scale, log
            )
        moved = max(
            float(np.abs(ex.robot.joint_positions() - q).max())
            for ex, q in zip(executors, q0, strict=True)
        )
        run.record["arm_moved_rad"] = moved
        run.record["recipe"] = cfg.recipe
    write_dry_run(run, out_dir, overwrite)
    return run


FAULT_FIELDS = ("fault_grasp_offset", "fault_slip")
"""EpisodeConfig's injected faults (0: none)."""


def injected_faults(cfg: EpisodeConfig) -> list[str]:
    """The faults `cfg` injects, as their flags (--fault-slip, …)."""
    return [f"--{name.replace('_', '-')}" for name in FAULT_FIELDS if getattr(cfg, name) > 0]


def run_episode(
    cfg: EpisodeConfig,
    out_dir: Path,
    overwrite: bool = False,
    log=print,
    gate: OperatorGate | None = None,
) -> dict:
    """Run one fold episode and write the episode folder (result.json, cloth.npz, video.mp4).
    With a `gate` (`--confirm`) the operator lets each pick-and-place move or stops the fold."""
    writer = EpisodeWriter(out_dir, overwrite=overwrite, fps=max(cfg.video_fps, 1.0))
    wall0 = time.perf_counter()
    with writer, SimWorld(cfg.sim) as world, contextlib.ExitStack() as stack:
        parts = build_sim_cell(cfg, world)
        stack.callback(parts.model_world.close)
        cloth, mesh, camera, oracle = parts.cloth, parts.mesh, parts.camera, parts.oracle
        center, yaw, spec = parts.center, parts.yaw, parts.spec
        recorder = None
        if cfg.video_fps > 0:
            recorder = _VideoRecorder(camera, writer, cfg.video_fps)
            world.add_step_hook(recorder)
        log(f"settling the cloth ({mesh.vertices.shape[0]} vertices)…")
        settle(world, cloth)
        if planned_recipe(cfg) != cfg.recipe:
            log(f"recipe {cfg.recipe}: folded in {planned_recipe(cfg)}'s stage order")
        cell = episode_cell(cfg, parts, recorder)
        cell.slip_fault = SlipFault(cfg.fault_slip)
        cell.gate = gate
        flattened = None
        if cfg.start == "crumpled":
            flattened = crumple_and_flatten(cfg, parts, cell, writer, log)
        initial = oracle.cloth_vertices()
        fold = run_fold if cfg.garment == "towel" else run_garment_fold
        loop_cfg = loop_config(cfg, cloth.thickness)
        try:
            record = fold_and_picture(fold, loop_cfg, cell, writer.write_image, log)
        except Exception as exc:  # the error record keeps how the flattening went
            if flattened is not None:
                add_facts(exc, flatten=flattened)
            raise
        final = oracle.cloth_vertices()
        score = score_episode(initial, final, mesh.faces, record.fold_lines, cloth.thickness)
        if recorder is not None:
            recorder.capture()
        writer.write_cloth(mesh.faces, initial, final, cloth.thickness)
        result = episode_result(
            cfg,
            spec,
            (center, yaw),
            score,
            record,
            world.sim_time,
            time.perf_counter() - wall0,
            cfg.cell_camera,
        )
        if flattened is not None:
            result["flatten"] = flattened
        result["cloth_fastest_slide_mps"] = parts.monitor.fastest_slide
        if cfg.fault_grasp_offset > 0 or cfg.fault_slip > 0:
            result["faults"] = {
                "grasp_offset_m": cfg.fault_grasp_offset,
                "slip_fraction": cfg.fault_slip,
                "slipped": cell.slip_fault.slipped,
            }
        if parts.guard is not None:
            result["crossing_guard_restored"] = parts.guard.restored
        if gate is not None:
            result["operator"] = gate.record()
        result["first_frame_keypoint_error_mm"] = first_frame_keypoint_errors(
            cfg, mesh, initial, record.initial_state
        )
        writer.write_result(result)
        path = writer.commit()
    result["out_dir"] = str(path)
    return result
