import dataclasses
import json
import os
import subprocess
import sys
from pathlib import Path

import imageio.v3 as iio
import numpy as np
import pybullet as p
import pytest
from scipy.spatial import cKDTree

from foldbot.errors import ConfigError
from foldbot.garments.towel import TowelSpec
from foldbot.io.episode import REQUIRED_RESULT_KEYS, load_episode, rescore
from foldbot.metrics import FoldLine, fold_goal
from foldbot.perception.overlay import GRASP_RGB, PLACE_RGB
from foldbot.pipeline import EpisodeConfig, run_episode
from foldbot.sim.cloth import MAX_SLIDE_SPEED


def run_cli(*args: str) -> subprocess.CompletedProcess:
    """`foldbot …` in a fresh process: Bullet's soft-body solver keeps process-global random
    state, so an episode is reproducible only as the first simulation in its process."""
    return subprocess.run(
        [sys.executable, "-m", "foldbot.cli", *args],
        capture_output=True,
        text=True,
        timeout=900,
        check=True,
    )


@pytest.fixture(scope="module")
def half_fold_episode(tmp_path_factory):
    """One half fold of the 30 cm, 16×16 towel with the UR5 (the README's headline case)."""
    out = tmp_path_factory.mktemp("episodes") / "half"
    run_cli("fold", "--seed", "0", "--video-fps", "2", "--out", str(out))
    return out, json.loads((out / "result.json").read_text())


@pytest.mark.slow
def test_half_fold_meets_target(half_fold_episode):
    _out, result = half_fold_episode
    assert result["normalized_performance"] >= 0.85
    assert result["fold_error_mm"] <= 10.0
    assert result["success"] is True
    assert all(a["grasp_success"] for a in result["actions"])


@pytest.mark.slow
def test_folded_layers_stay_apart_and_above_the_table(half_fold_episode):
    out, result = half_fold_episode
    episode = load_episode(out)
    _goal, layers = fold_goal(episode.initial, result["fold_lines"], episode.thickness)
    final, top = episode.final, layers > 0
    table = EpisodeConfig().sim.layout.table_height
    assert final[:, 2].min() > table - 0.001, "no vertex passes through the table"
    # Each vertex of the folded-over layer lies above the lower-layer vertex beneath it.
    dist, idx = cKDTree(final[~top, :2]).query(final[top, :2])
    beneath = dist < 0.015
    gap = final[top][beneath, 2] - final[~top][idx[beneath], 2]
    assert beneath.sum() > 0.8 * top.sum()
    assert (gap > 0).mean() >= 0.99, f"layers interpenetrate: min gap {gap.min() * 1000:.1f} mm"


@pytest.mark.slow
def test_episode_folder_follows_the_contract(half_fold_episode):
    out, _result = half_fold_episode
    assert {p.name for p in out.iterdir()} >= {"result.json", "cloth.npz", "video.mp4"}
    stored = json.loads((out / "result.json").read_text())
    assert set(REQUIRED_RESULT_KEYS) <= stored.keys()
    assert stored["grasp_points_source"] == "vision"
    assert "faults" not in stored  # none injected
    # This process imported foldbot before numpy and cv2 (tests/conftest.py): the cap held.
    assert stored["simd_uncapped"] == []
    # The corners the fold was planned from, against the towel's own (README: p95 ≤ 8 mm).
    first = stored["first_frame_keypoint_error_mm"]
    assert set(first) == {"near_left", "near_right", "far_right", "far_left"}
    assert max(first.values()) < 3.0, first
    episode = load_episode(out)
    assert episode.faces.shape[1] == 3 and episode.initial.shape == episode.final.shape
    # Every metric can be recomputed from cloth.npz and fold_lines alone.
    again = rescore(out)
    assert again.fold_error_mm == pytest.approx(stored["fold_error_mm"])
    assert again.normalized_performance == pytest.approx(stored["normalized_performance"])
    assert again.perfect_normalized == pytest.approx(stored["perfect_normalized"])
    # A half fold's cloth lies on itself, not through itself; its best score is nearly 1.
    assert stored["self_crossings"] == again.self_crossings == 0
    assert stored["normalized_performance"] < stored["perfect_normalized"] < 1.0
    # The flat start is flat, the final state folded (half the area covered).
    assert np.ptp(episode.initial[:, 2]) < 0.003
    assert 0.4 < stored["coverage"] < 0.6
    for action in stored["actions"]:
        assert {
            "kind",
            "grasp",
            "place",
            "grasp_success",
            "retries",
            "sim_seconds",
        } <= action.keys()


def _marked_pixels(frame: np.ndarray, rgb: tuple[int, int, int], tol: int = 60) -> int:
    """Pixels of `frame` within `tol` of `rgb` in every channel (the video is lossy)."""
    return int((np.abs(frame.astype(int) - np.array(rgb)) <= tol).all(axis=-1).sum())


@pytest.mark.slow
def test_video_shows_planned_marks_during_actions_and_none_after_parking(half_fold_episode):
    out, _result = half_fold_episode
    frames = iio.imread(out / "video.mp4")
    marked = [_marked_pixels(f, GRASP_RGB) + _marked_pixels(f, PLACE_RGB) for f in frames]
    assert max(marked) > 30, "the planned grasp and place points are drawn while folding"
    assert marked[-1] < 5, f"the parked arm's last frame still shows {marked[-1]} marked pixels"


@pytest.mark.parametrize(
    ("kwargs", "needle"),
    [
        ({"garment": "sock"}, "garment"),
        ({"robot": "kuka"}, "robot"),
        ({"recipe": "origami"}, "recipe"),
        ({"perception": "psychic"}, "perception"),
        ({"seed": -1}, "seed"),
        ({"park": "garage"}, "out_of_view"),
        ({"arms": 3}, "arms must be one of"),
        ({"arms": True}, "arms must be one of"),
        ({"jaw_catch": "glue"}, "unknown jaw_catch 'glue'; allowed: vertices, surface"),
    ],
)
def test_bad_episode_config(kwargs, needle):
    with pytest.raises(ConfigError, match=needle):
        EpisodeConfig(**kwargs)


def test_the_two_arm_cell_takes_crumpled_towels():
    # It flattens them by spreads (foldbot.flatten.run_spreads, tests/test_spread_loop.py).
    assert EpisodeConfig(start="crumpled", arms=2).arms == 2


@pytest.mark.slow
def test_failed_grasp_is_retried_after_reobserving(tmp_path):
    """Inject a grasp aimed 6 cm off the corner: the loop must see the failure and retry."""
    cfg = EpisodeConfig(
        recipe="diagonal",
        towel=TowelSpec(0.24, 0.24, 10),
        fault_grasp_offset=0.06,
        video_fps=0,
    )
    result = run_episode(cfg, tmp_path / "ep", log=lambda *_: None)
    first = result["actions"][0]
    assert first["retries"] == 1
    assert first["attempts"][0]["grasp_success"] is False
    assert "no cloth" in first["attempts"][0]["grasp_reason"]
    assert first["attempts"][1]["grasp_success"] is True
    assert first["grasp_success"] is True
    # The retry does not repeat the miss: it closes the jaws at the (perceived) table.
    table = cfg.sim.layout.table_height
    assert first["attempts"][1]["grasp"][2] <= table + cfg.motion.stack_grasp_height + 0.002


@pytest.mark.slow
def test_a_corner_that_slips_is_laid_back_and_the_stage_planned_again(tmp_path):
    """Inject a slip a third of the way through the first carry: the gripper reports it lost
    its hold, the arm lets go and lifts; the corner that fell is picked at the table inside it,
    lifted and laid back where it was grasped, and the stage is planned again from a fresh
    observation and folds."""
    cfg = EpisodeConfig(
        recipe="diagonal", towel=TowelSpec(0.24, 0.24, 10), fault_slip=0.3, video_fps=0
    )
    lines: list[str] = []
    result = run_episode(cfg, tmp_path / "ep", log=lines.append)
    assert result["faults"]["slipped"] is True
    first, again = result["actions"][:2]
    (slipped,) = first["attempts"]
    assert slipped["slipped"] is True and first["grasp_success"] is False
    assert first["plan_again"] is True and "plan_again" not in again
    laid = slipped["laid_back"]
    assert laid["grasp_success"] is True
    # Grasped at the table, 1 cm inside the corner (stack_inset), and that point released where
    # the slipped grasp had held the cloth: the corner itself lands 1 cm beyond
    # (loop.LAY_BACK_OUTWARD against the inset), about where it lay before the carry.
    table = cfg.sim.layout.table_height
    assert laid["grasp"][2] <= table + cfg.motion.stack_grasp_height + 0.002
    assert np.linalg.norm(np.subtract(laid["place"][:2], slipped["grasp"][:2])) < 0.002
    assert any("planned again from a fresh observation" in line for line in lines)
    # The stage planned again carries the same corner, from where it was laid, and folds.
    assert again["label"] == first["label"] and again["grasp_success"] is True
    assert np.linalg.norm(np.subtract(again["grasp"][:2], laid["place"][:2])) < 0.03
    # Scored against the goal planned before the first action; the stage's entry has the line
    # it was planned again with.
    (stage,) = result["stages"]
    assert len(result["fold_lines"]) == 1 and stage["fold_line"] != result["fold_lines"][0]
    assert result["success"] is True


@pytest.mark.slow
def test_without_laying_back_a_slipped_corner_is_seen_and_grasped_again(tmp_path):
    """With the lay-back off (LoopConfig.slip_lay_back; as for a stage's later carries), the
    loop re-observes and grasps the corner afresh where it fell (not at the table inside it, as
    after a miss), then folds."""
    cfg = EpisodeConfig(
        recipe="diagonal",
        towel=TowelSpec(0.24, 0.24, 10),
        fault_slip=0.3,
        video_fps=0,
        loop_options={"slip_lay_back": False},
    )
    result = run_episode(cfg, tmp_path / "ep", log=lambda *_: None)
    assert result["faults"] == {"grasp_offset_m": 0.0, "slip_fraction": 0.3, "slipped": True}
    first = result["actions"][0]
    slipped, again = first["attempts"]
    assert slipped["grasp_success"] is False and slipped["slipped"] is True
    assert "slipped from the jaws in the carry" in slipped["grasp_reason"]
    assert again["grasp_success"] is True and "slipped" not in again
    assert first["retries"] == 1 and first["grasp_success"] is True
    # The corner fell back about where it lay, and the retry aimed at it as seen there (a
    # miss's retry closes 1 cm inside it, at the table).
    np.testing.assert_allclose(again["grasp"], slipped["grasp"], atol=0.005)
    assert result["success"] is True


@pytest.mark.slow
def test_two_arms_carry_a_half_folds_corners_together(tmp_path):
    cfg = EpisodeConfig(arms=2, towel=TowelSpec(0.24, 0.24, 10), video_fps=0)
    result = run_episode(cfg, tmp_path / "ep", log=lambda *_: None)
    assert result["arms"] == 2
    assert result["time_step"] == pytest.approx(1 / 360), "the physics step is recorded"
    assert result["jaw_catch"] == "vertices", "what the jaws hold is recorded"
    # The monitor's fastest slide of the whole cloth is recorded, under its divergence limit.
    assert 0.0 < result["cloth_fastest_slide_mps"] < MAX_SLIDE_SPEED
    actions = result["actions"]
    # One stage, its two far corners carried at once, each by the arm on its side.
    assert [(a["label"], a["arm"]) for a in actions] == [("far_left", 0), ("far_right", 1)]
    assert all(a["together"] and a["grasp_success"] for a in actions)
    # Carried together, the corners came straight down the last 4 cm (LoopConfig.pair_descent).
    assert [a["descent_m"] for a in actions] == [pytest.approx(0.04)] * 2
    assert result["success"] is True
    assert result["fold_error_mm"] <= 10.0


@pytest.mark.slow
def test_two_arms_redo_the_pair_after_an_injected_grasp_failure(tmp_path):
    """The first grasp aimed 6 cm off its corner: both arms let go, re-observe, and redo the pair."""
    cfg = EpisodeConfig(
        arms=2, towel=TowelSpec(0.24, 0.24, 10), fault_grasp_offset=0.06, video_fps=0
    )
    result = run_episode(cfg, tmp_path / "ep", log=lambda *_: None)
    first = result["actions"][0]
    attempts = first["attempts"]
    assert first["retries"] == 1 and len(attempts) == 2
    assert attempts[0]["grasp_success"][0] is False
    assert "no cloth" in attempts[0]["grasp_reasons"][0]
    assert attempts[1]["grasp_success"] == [True, True]
    # The redone grasp closes at the (perceived) table, as a one-arm retry does.
    table = cfg.sim.layout.table_height
    assert attempts[1]["grasps"][0][2] <= table + cfg.motion.stack_grasp_height + 0.002
    assert all(a["grasp_success"] and a["together"] for a in result["actions"][:2])


@pytest.mark.slow
def test_thirds_second_fold_leaves_the_laid_third_the_crease_room_seen_in_depth(tmp_path):
    """Thirds' second fold line lies on the free edge the first laid: it moves by the height that
    layer was seen to rise, and the far corners, laid that short of the stack's crease corners,
    are not checked against those corners (nor re-placed onto them)."""
    cfg = EpisodeConfig(recipe="thirds", arms=2, towel=TowelSpec(0.27, 0.27, 9), video_fps=0)
    result = run_episode(cfg, tmp_path / "ep", log=lambda *_: None)
    first, second = result["stages"]
    rise = first["laid_layer_rise_m"]
    assert rise is not None and 0.005 < rise < 0.03
    assert first["crease_room_m"] is None
    assert second["crease_room_m"] == pytest.approx(rise)
    stage2 = [a for a in result["actions"] if a["label"].startswith("far_")]
    assert [a["kind"] for a in stage2] == ["pick_and_place", "pick_and_place"]
    assert all(a["grasp_success"] and a["placed_error_m"] is None for a in stage2)
    assert np.isfinite(result["fold_error_mm"])


def unit(v) -> np.ndarray:
    """A 2-D vector, normalised."""
    v = np.asarray(v, dtype=float)
    return v / np.linalg.norm(v)


@pytest.mark.slow
def test_two_arms_fold_quarter_left_onto_right_first_then_carry_the_stack_by_its_edge(tmp_path):
    """A two-arm cell folds quarter as quarter_y: the first stage's corners carried together, then
    the stack by the middle of its far edge, one arm (27.2 mm here). In a fresh process: Bullet's
    soft body is reproducible only as the first simulation in its process."""
    args = ["fold", "--recipe", "quarter", "--arms", "2", "--width", "0.3", "--height", "0.3"]
    run_cli(*args, "--resolution", "11", "--video-fps", "0", "--out", str(tmp_path / "ep"))
    result = json.loads((tmp_path / "ep" / "result.json").read_text())
    assert result["recipe"] == "quarter" and result["planned_recipe"] == "quarter_y"
    actions = result["actions"]
    labels = [a["label"] for a in actions]
    assert labels == ["far_left", "near_left", "middle_far_left_far_right"]
    assert all(a["together"] and a["grasp_success"] for a in actions[:2])
    edge = actions[2]
    assert "together" not in edge and edge["arm"] in (0, 1) and edge["grasp_success"]
    # Left onto right first (a near–far line), then across it (lines from perceived corners).
    first, second = (unit(line[2:4]) for line in result["fold_lines"])
    assert abs(first[0]) > abs(first[1]) and abs(float(first @ second)) < 0.1
    assert result["fold_error_mm"] < 60.0


@pytest.mark.slow
def test_one_arm_carries_quarters_stack_by_the_middle_of_its_edge(tmp_path):
    """One arm folds quarter as quarter_y (left onto right, corner after corner), then the stack
    in one carry, grasped midway along its far edge, at the table under both layers, and laid
    across the line: 32.9 mm (in quarter's order, far onto near first, this towel on an 11-vertex
    mesh ended 36.7 mm off; in quarter_y's order on that coarse mesh the stack slid toward the
    robot, 64.6 mm). In a fresh process, as the two-arm quarter above."""
    args = ["fold", "--recipe", "quarter", "--width", "0.3", "--height", "0.3"]
    proc = run_cli(*args, "--resolution", "13", "--video-fps", "0", "--out", str(tmp_path / "ep"))
    assert "recipe quarter: folded in quarter_y's stage order" in proc.stdout + proc.stderr
    result = json.loads((tmp_path / "ep" / "result.json").read_text())
    assert result["recipe"] == "quarter" and result["planned_recipe"] == "quarter_y"
    actions = result["actions"]
    labels = [a["label"] for a in actions]
    assert labels == ["far_left", "near_left", "middle_far_left_far_right"]
    edge = actions[-1]
    assert edge["grasp_success"] and edge["placed_error_m"] is None  # no corner to check there
    table = EpisodeConfig().sim.layout.table_height
    assert all(a["grasp"][2] < table + 0.01 for a in edge["attempts"])  # under both layers
    # Grasped on the moving side of the second fold line and laid across it.
    line = FoldLine.coerce(result["fold_lines"][1])
    sides = line.side(np.array([edge["grasp"][:2], edge["place"][:2]]))
    assert sides[0] * sides[1] < 0
    assert result["fold_error_mm"] < 60.0
    # The second stage's plan is pictured over the view it was planned from: stage 1's closing
    # view, with the edge's grasp, its place and the fold line drawn on it.
    ep = tmp_path / "ep"
    plan2, stage1 = (iio.imread(ep / f) for f in ("overlay_plan2.png", "overlay_stage1.png"))
    assert plan2.shape == stage1.shape
    for rgb in (GRASP_RGB, PLACE_RGB):
        assert _marked_pixels(plan2, rgb, tol=0) > 20 and _marked_pixels(stage1, rgb, tol=0) == 0


@pytest.mark.slow
def test_a_loop_option_switches_the_stack_carry_back_to_corner_after_corner(tmp_path):
    """`--loop-option stack_edge_carry=false`: quarter's stack is carried by its two corners,
    one after the other, as before the edge carry (the test above); result.json says so."""
    args = ["fold", "--recipe", "quarter", "--width", "0.24", "--height", "0.24"]
    args += ["--loop-option", "stack_edge_carry=false", "--resolution", "8"]
    run_cli(*args, "--video-fps", "0", "--out", str(tmp_path / "ep"))
    result = json.loads((tmp_path / "ep" / "result.json").read_text())
    assert result["loop_options"] == {"stack_edge_carry": False}
    labels = [a["label"] for a in result["actions"]]
    assert labels[:2] == ["far_left", "near_left"]
    assert labels[2:4] == ["far_left", "far_right"] or labels[2:4] == ["far_right", "far_left"]
    assert not any(label.startswith("middle_") for label in labels)


@pytest.mark.slow
def test_same_seed_same_episode(tmp_path):
    args = ["fold", "--recipe", "diagonal", "--seed", "3", "--width", "0.24", "--height", "0.24"]
    args += ["--resolution", "8", "--video-fps", "0", "--out"]
    run_cli(*args, str(tmp_path / "a"))
    run_cli(*args, str(tmp_path / "b"))
    a, b = load_episode(tmp_path / "a"), load_episode(tmp_path / "b")
    assert np.array_equal(a.initial, b.initial)
    assert np.array_equal(a.final, b.final)
    for key in ("fold_error_mm", "normalized_performance", "fold_lines", "cloth_pose", "actions"):
        if key == "actions":
            strip = [{k: v for k, v in x.items() if k != "wall_seconds"} for x in a.result[key]]
            assert strip == [
                {k: v for k, v in x.items() if k != "wall_seconds"} for x in b.result[key]
            ]
        else:
            assert a.result[key] == b.result[key]


REFERENCE_EPISODE = (
    "fold --recipe diagonal_corners --seed 3 --width 0.24 --height 0.24 --resolution 8"
    " --video-fps 0"
)
REFERENCE_FOLD_ERROR_MM = 3.9189327357348187
"""The reference episode's fold error, as every x86-64 machine with AVX2 and FMA computes it with
the versions in constraints.txt (3.788… with an AVX-512 machine's own kernels). A change to the
simulation, perception, planning or control changes it: then record the new value here. (The
recipe was "diagonal" until that name became the triangle fold, which folds this nearly square
perceived towel along a slightly different line: 4.69 mm.)"""


def test_same_seed_same_episode_on_every_machine(tmp_path):
    """With the SIMD cap (foldbot.simd) and the constrained versions, the same seed gives the
    same episode, to the last bit, on any machine that can run the cap."""
    from importlib.metadata import PackageNotFoundError, version
    from pathlib import Path

    from foldbot import simd

    cap = simd.cap_simd_level({})  # what this machine's CPU is capped with
    if not cap or any(os.environ.get(k) != v for k, v in cap.items()):
        pytest.skip("this machine or environment does not run the SIMD cap")
    constraints = Path(__file__).resolve().parents[1] / "constraints.txt"
    for line in constraints.read_text().splitlines():
        name, sep, pinned = line.partition("==")
        if not sep or line.startswith("#"):
            continue
        try:
            installed = version(name.strip())
        except PackageNotFoundError:
            installed = None
        if installed != pinned.strip():
            pytest.skip(f"{name.strip()} {installed} is installed, constraints.txt pins {pinned}")
    run_cli(*REFERENCE_EPISODE.split(), "--out", str(tmp_path / "ep"))
    result = json.loads((tmp_path / "ep" / "result.json").read_text())
    assert result["fold_error_mm"] == pytest.approx(REFERENCE_FOLD_ERROR_MM, rel=0, abs=1e-9)


def test_infeasible_action_is_rejected_before_the_arm_moves(tmp_path):
    """A place point outside the arm's reach: IK fails during planning, nothing moves."""
    from foldbot.control.executor import ArmExecutor
    from foldbot.errors import UnreachableTargetError
    from foldbot.planning.actions import FoldAction
    from foldbot.planning.motion import MotionConfig, action_segments
    from foldbot.sim.robots import make_robot
    from foldbot.sim.world import SimWorld

    with SimWorld() as world:
        robot = make_robot("ur5", world.client, world.layout)
        q0 = robot.joint_positions()
        executor = ArmExecutor(world, robot, grasp=None)
        action = FoldAction(
            grasp=np.array([0.5, 0.0, 0.752]),
            place=np.array([1.6, 0.0, 0.752]),
            fold_line=(1.0, 0.0, 0.0, 1.0),
            label="far_left",
        )
        segments = action_segments(action, robot.tcp_pose()[0], MotionConfig())
        with pytest.raises(UnreachableTargetError, match="segment 'carry'"):
            executor.plan(segments)
        assert np.array_equal(robot.joint_positions(), q0)
        assert world.steps == 0


def test_two_arm_cell_hands_an_action_to_the_arm_that_can_do_it():
    """Arm 0 (left) cannot reach the table's far right corner; planning hands the action to arm 1
    before anything moves, and an action neither arm can do is refused naming the first's reason."""
    from foldbot.errors import UnreachableTargetError
    from foldbot.pipeline import SimCell, build_sim_cell
    from foldbot.planning.actions import FoldAction
    from foldbot.sim.world import SimWorld

    cfg = EpisodeConfig(arms=2, towel=TowelSpec(0.2, 0.2, 6), video_fps=0, jaw_catch="surface")
    with SimWorld(cfg.sim) as world:
        parts = build_sim_cell(cfg, world)
        try:
            arms = (parts.executor, *parts.more_executors)
            assert [ex.grasp.catch for ex in arms] == ["surface", "surface"]
            cell = SimCell(
                world, parts.robot, parts.executor, parts.camera, None, cfg.motion,
                more_executors=parts.more_executors,
            )  # fmt: skip
            z = world.layout.table_height + 0.004
            far_right = FoldAction(
                grasp=np.array([0.72, -0.28, z]),
                place=np.array([0.55, -0.28, z]),
                fold_line=(0.635, 0.0, 0.0, 1.0),
                label="far_right",
            )
            cell.use_arm(0)
            steps = cell.plan_action(far_right)
            assert cell.active_arm == 1 and len(steps) == 5
            beyond = dataclasses.replace(far_right, place=np.array([1.5, -0.28, z]))
            cell.use_arm(0)
            with pytest.raises(UnreachableTargetError, match="no IK solution"):
                cell.plan_action(beyond)
            assert world.steps == 0
        finally:
            parts.model_world.close()


def test_a_replicate_lays_the_seeds_cloth_a_tenth_of_a_millimetre_away():
    from foldbot.pipeline import REPLICATE_NUDGE_M, seeded_garment, seeded_pose

    centre = (0.45, 0.0)
    for seed in range(5):
        (x0, y0), yaw0 = seeded_pose(EpisodeConfig(seed=seed), centre)
        assert seeded_pose(EpisodeConfig(seed=seed, replicate=0), centre) == ((x0, y0), yaw0)
        directions = set()
        for k in (1, 2, 3):
            cfg = EpisodeConfig(seed=seed, replicate=k, towel_size_range=(0.25, 0.45))
            (x, y), yaw = seeded_pose(cfg, centre)
            assert yaw == yaw0 and np.hypot(x - x0, y - y0) == pytest.approx(REPLICATE_NUDGE_M)
            assert seeded_pose(cfg, centre) == ((x, y), yaw)  # the same replicate, the same pose
            # The same towel: its size and mesh do not depend on the replicate.
            assert (
                seeded_garment(cfg)[0] == seeded_garment(dataclasses.replace(cfg, replicate=0))[0]
            )
            directions.add((round(x - x0, 9), round(y - y0, 9)))
        assert len(directions) == 3
    for bad in (-1, 1000, 1.5, True):
        with pytest.raises(ConfigError, match=r"replicate must be an integer in \[0, 999\]"):
            EpisodeConfig(replicate=bad)


def test_towel_size_is_drawn_from_the_seed_within_range():
    from foldbot.pipeline import seeded_pose, seeded_towel

    sizes = set()
    for seed in range(20):
        cfg = EpisodeConfig(seed=seed, towel_size_range=(0.25, 0.45))
        towel = seeded_towel(cfg)
        assert 0.25 <= towel.width <= 0.45 and 0.25 <= towel.height <= 0.45
        assert towel == seeded_towel(cfg)  # same seed, same towel
        # Size randomisation leaves the seed's pose as it was.
        plain = EpisodeConfig(seed=seed)
        assert seeded_pose(cfg, (0.45, 0.0)) == seeded_pose(plain, (0.45, 0.0))
        sizes.add((round(towel.width, 4), round(towel.height, 4)))
    assert len(sizes) == 20
    with pytest.raises(ConfigError, match="towel_size_range"):
        EpisodeConfig(towel_size_range=(0.5, 0.2))


def test_a_cloth_option_reaches_the_simulated_cloth_and_the_record(tmp_path):
    """`--cloth margin_divisor=8`: the soft body's margin is an eighth of a mesh edge, so the
    layer thickness the goal uses (cloth.npz) is a quarter of one; result.json names the options
    (and, with `crossing_guard`, how many mesh points the guard put back)."""
    from foldbot.cli import build_parser
    from foldbot.commands.fold import config_from_args
    from foldbot.garments.towel import make_towel

    args = ["fold", "--width", "0.2", "--height", "0.2", "--resolution", "6", "--video-fps", "0"]
    args += ["--cloth", "margin_divisor=8", "--cloth", "crossing_guard=1"]
    args += ["--out", str(tmp_path / "ep")]
    run_cli(*args)
    result = json.loads((tmp_path / "ep" / "result.json").read_text())
    assert result["cloth_options"] == {"margin_divisor": 8.0, "crossing_guard": 1}
    assert isinstance(result["crossing_guard_restored"], int)  # the guard watched the fold
    edge = make_towel(config_from_args(build_parser().parse_args(args)).towel).edge_length
    thickness = float(np.load(tmp_path / "ep" / "cloth.npz")["thickness"])
    assert thickness == pytest.approx(edge / 4)


@pytest.mark.slow
def test_a_cell_laid_out_by_a_file_folds_where_the_file_puts_it(tmp_path):
    """layouts/pedestal.toml: a lower table that starts ahead of the arms, which stand beside it
    on pedestals, the workspace further out and to the left. The cloth lies on that table in
    that workspace, the camera moved with it sees it, the two arms fold it as well as in the
    default cell, and result.json records the layout."""
    layout_file = Path(__file__).resolve().parents[1] / "layouts" / "pedestal.toml"
    out = tmp_path / "ep"
    args = ["fold", "--arms", "2", "--width", "0.24", "--height", "0.24", "--resolution", "10"]
    run_cli(*args, "--video-fps", "0", "--layout", str(layout_file), "--out", str(out))
    result = json.loads((out / "result.json").read_text())
    assert result["layout"] == {
        "table_height": 0.70,
        "table_size": [0.97, 1.2],
        "table_center_xy": [0.635, 0.0],
        "robot_base_xyz": [0.0, 0.0, 0.65],
        "workspace_center_xy": [0.50, 0.06],
    }
    initial = np.load(out / "cloth.npz")["initial"]
    assert np.all(np.abs(initial[:, 2] - 0.70) < 0.01)  # settled on the 0.70 m table
    centre = initial[:, :2].mean(axis=0)
    assert np.all(np.abs(centre - [0.50, 0.06]) <= 0.03 + 0.005)  # the seed's jitter: ±3 cm
    camera = np.array(result["camera"]["T_world_camera"])[:3, 3]
    assert camera == pytest.approx([1.05 + 0.05, 0.06, 1.75 - 0.05])
    assert all(a["grasp_success"] for a in result["actions"])
    assert result["success"] is True and result["fold_error_mm"] <= 10.0


def test_the_crossing_guard_watches_the_cloth_from_the_flat_start():
    """ClothConfig.crossing_guard: the cell's world steps a CrossingGuard on its cloth, from the
    moment the cloth is built (before a crumple or a fold), and a default cloth has none."""
    from foldbot.pipeline import build_sim_cell
    from foldbot.sim.cloth import ClothConfig
    from foldbot.sim.crossing_guard import CrossingGuard
    from foldbot.sim.world import SimWorld

    for every, guarded in ((0, False), (3, True)):
        cfg = EpisodeConfig(towel=TowelSpec(0.2, 0.2, 6), cloth=ClothConfig(crossing_guard=every))
        with SimWorld(cfg.sim) as world:
            parts = build_sim_cell(cfg, world)
            guards = [h for h in world._step_hooks if isinstance(h, CrossingGuard)]
            assert (parts.guard is not None) == guarded
            assert guards == ([parts.guard] if guarded else [])
            if guarded:
                assert parts.guard.cloth is parts.cloth and parts.guard.every == 3
                world.step(30)
                assert parts.guard.restored == 0  # a flat towel settling goes through nothing
            parts.model_world.close()


def test_a_cloth_whose_layers_slide_keeps_the_tables_grip():
    """layer_friction 0.25 lowers the soft body's coefficient to 0.5, which Bullet multiplies into
    cloth–table friction too: the cell raises the table's friction 2× to keep it."""
    from foldbot.pipeline import build_sim_cell
    from foldbot.sim.cloth import ClothConfig
    from foldbot.sim.world import SimWorld

    for cloth, table in [(ClothConfig(), 1.0), (ClothConfig(layer_friction=0.25), 2.0)]:
        cfg = EpisodeConfig(towel=TowelSpec(0.2, 0.2, 6), video_fps=0, cloth=cloth)
        with SimWorld(cfg.sim) as world:
            parts = build_sim_cell(cfg, world)
            try:
                info = p.getDynamicsInfo(world.table_id, -1, physicsClientId=world.client)
                assert info[1] == pytest.approx(table)
            finally:
                parts.model_world.close()


def test_a_folds_vision_knows_the_layouts_obstacles_as_fixtures():
    from foldbot.pipeline import make_estimator
    from foldbot.sim.layout import load_layout
    from foldbot.sim.world import SimConfig

    layout = load_layout(Path(__file__).resolve().parents[1] / "layouts" / "cloth_tray.toml")
    cfg = dataclasses.replace(EpisodeConfig(), sim=SimConfig(layout=layout))
    estimator = make_estimator(cfg, oracle=None)
    assert estimator.config.segmentation.fixtures == layout.obstacles
    assert make_estimator(EpisodeConfig(), oracle=None).config.segmentation.fixtures == ()
