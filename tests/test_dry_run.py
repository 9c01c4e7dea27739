"""`foldbot fold --dry-run` (foldbot.dry_run): one look, every stage and motion planned in the
simulated cell, nothing moved; plan.json says what each pick-and-place would do or why it
cannot; its folder written whole, an earlier dry run replaced only when asked."""

from __future__ import annotations

import contextlib
import json
from pathlib import Path

import imageio.v3 as iio
import numpy as np
import pytest

from foldbot.cli import main
from foldbot.dry_run import plan_pair
from foldbot.garments.towel import TowelSpec
from foldbot.perception.overlay import EXPECTED_RGB
from foldbot.pipeline import EpisodeConfig, build_sim_cell, episode_cell
from foldbot.planning.actions import FoldAction
from foldbot.sim.cloth import settle
from foldbot.sim.world import SimWorld

SMALL = ["--resolution", "9", "--video-fps", "0"]


def expected_pixels(png: Path) -> int:
    """Pixels of a dry run's picture in the colour of an expected outline (EXPECTED_RGB)."""
    image = iio.imread(png)[..., :3].astype(int)
    return int((np.abs(image - EXPECTED_RGB) <= 10).all(-1).sum())


def test_a_dry_run_plans_every_stage_and_moves_nothing(tmp_path, capsys):
    out = tmp_path / "plan"
    assert main(["fold", "--dry-run", "--recipe", "quarter", *SMALL, "--out", str(out)]) == 0
    said = capsys.readouterr().out
    plan = json.loads((out / "plan.json").read_text())
    assert sorted(p.name for p in out.iterdir()) == [
        "overlay_plan1.png",
        "overlay_plan2.png",
        "plan.json",
    ]  # no result.json: no episode ran
    assert plan["dry_run"] and plan["feasible"] and plan["recipe"] == "quarter"
    assert plan["planned_recipe"] == "quarter_y"  # the stage order the fold would take
    assert [s["stage"] for s in plan["stages"]] == [1, 2]
    # Carried as the fold carries it: the folded stack by its edge's middle, one action, the
    # jaws closing at the table (4 mm up) under both layers, 1 cm inside the edge.
    assert [a["stage"] for a in plan["actions"]] == [1, 1, 2]
    assert [s["by_edge_middle"] for s in plan["stages"]] == [False, True]
    stack = plan["actions"][2]
    assert stack["label"].startswith("middle_") and stack["layers"] == 2
    assert stack["grasp"][2] == pytest.approx(0.754, abs=1e-6)
    # Stage 2's picture draws the outline it was planned on (the half-folded towel), stage 1's
    # none: the frame shows stage 1's.
    expected = [expected_pixels(out / f"overlay_plan{k}.png") for k in (1, 2)]
    assert expected[0] == 0 and expected[1] > 40
    assert plan["arm_moved_rad"] == 0.0  # ground truth: the simulated arm stood still
    for action in plan["actions"]:
        names = [s["name"] for s in action["steps"]]
        assert names[0] == "approach" and "descend" in names and names[-1] == "retreat"
        assert action["motion_seconds"] == pytest.approx(sum(s["seconds"] for s in action["steps"]))
    assert plan["motion_seconds"] == pytest.approx(
        sum(a["motion_seconds"] for a in plan["actions"])
    )
    assert "every motion feasible" in said and f"plan written to {out}" in said


def test_two_arms_are_planned_carrying_a_stages_corners_together(tmp_path, capsys):
    # As the two-arm fold carries quarter: stage 1's corners together, one arm each, coming
    # down pair_descent onto them; the stack by its edge's middle, one arm.
    out = tmp_path / "plan"
    args = ["fold", "--dry-run", "--arms", "2", "--recipe", "quarter", *SMALL]
    assert main([*args, "--out", str(out)]) == 0
    plan = json.loads((out / "plan.json").read_text())
    assert plan["arms"] == 2 and plan["feasible"] and plan["arm_moved_rad"] == 0.0
    assert [s["together"] for s in plan["stages"]] == [True, False]
    first, second, stack = plan["actions"]
    assert first["together"] and second["together"] and "together" not in stack
    assert {first["arm"], second["arm"]} == {0, 1}
    assert first["descent_m"] == second["descent_m"] == 0.04 and stack["descent_m"] is None
    # The pair's steps run on one clock: each as long as the longer arm's.
    steps = list(zip(first["steps"], second["steps"], strict=True))
    assert [a["name"] for a, _ in steps] == [b["name"] for _, b in steps]
    assert first["pair_seconds"] == pytest.approx(
        sum(max(a["seconds"], b["seconds"]) for a, b in steps)
    )
    assert "pair_seconds" not in second
    assert plan["motion_seconds"] == pytest.approx(first["pair_seconds"] + stack["motion_seconds"])
    assert "3 pick-and-place(s) (1 pair(s) by two arms together)" in capsys.readouterr().out


def test_a_loop_option_changes_what_the_dry_run_carries(tmp_path):
    # stack_edge_carry=false: the stack's two corners carried together by the two arms, each
    # by its top layer (recipes._GRASP_LAYERS), not at the table.
    out = tmp_path / "plan"
    args = ["fold", "--dry-run", "--arms", "2", "--recipe", "quarter", *SMALL]
    args += ["--loop-option", "stack_edge_carry=false"]
    assert main([*args, "--out", str(out)]) == 0
    plan = json.loads((out / "plan.json").read_text())
    assert [a["stage"] for a in plan["actions"]] == [1, 1, 2, 2]
    assert [s["by_edge_middle"] for s in plan["stages"]] == [False, False]
    for corner in plan["actions"][2:]:
        assert corner["together"] and corner["layers"] == 1 and corner["grasp"][2] > 0.756


def test_a_slowed_arm_is_planned_slower(tmp_path):
    full, slow = tmp_path / "full", tmp_path / "slow"
    assert main(["fold", "--dry-run", *SMALL, "--out", str(full)]) == 0
    assert main(["fold", "--dry-run", *SMALL, "--speed-scale", "0.5", "--out", str(slow)]) == 0
    a, b = (json.loads((d / "plan.json").read_text()) for d in (full, slow))
    assert b["speed_scale"] == 0.5 and a["stages"] == b["stages"]
    # Twice as long, but for the dwells (a place's settle), which keep their seconds.
    dwell = 2 * a["motion_seconds"] - b["motion_seconds"]
    assert 0.0 <= dwell < 0.25 * a["motion_seconds"]


LAMP = """[[obstacles]]
name = "lamp"
center_xyz = [0.66, 0.12, 1.11]
size_xyz = [0.12, 0.12, 0.10]
"""
"""A lamp hanging 31–41 cm over the table above the demo towel's far left corner."""


def test_an_action_into_a_layout_obstacle_is_named_and_the_rest_planned(tmp_path, capsys):
    layout = tmp_path / "lamp.toml"
    layout.write_text(LAMP)
    out = tmp_path / "plan"
    assert main(["fold", "--dry-run", "--layout", str(layout), *SMALL, "--out", str(out)]) == 1
    plan = json.loads((out / "plan.json").read_text())
    assert [(a["label"], a["feasible"]) for a in plan["actions"]] == [
        ("far_left", False),
        ("far_right", True),
    ]
    assert plan["actions"][0]["segment"] == "approach"
    assert "obstacle 'lamp' (at least 20 mm needed)" in plan["actions"][0]["reason"]
    assert "NOT feasible: stage 1 far_left" in capsys.readouterr().out


def test_an_obstacle_where_the_arm_rests_is_refused_before_anything_is_written(tmp_path, capsys):
    layout = tmp_path / "lamp.toml"
    layout.write_text(LAMP.replace("[0.66, 0.12, 1.11]", "[0.55, 0.10, 1.10]"))
    out = tmp_path / "ep"
    assert main(["fold", "--layout", str(layout), *SMALL, "--out", str(out)]) == 2
    assert "error: the arm's home posture meets an obstacle of the layout" in (
        capsys.readouterr().err
    )
    assert sorted(p.name for p in tmp_path.iterdir()) == ["lamp.toml"]


def test_an_action_out_of_reach_is_named_and_the_rest_planned(tmp_path, capsys):
    # A Panda (855 mm reach) and a 55 cm towel: the far corner's approach has no IK.
    out = tmp_path / "plan"
    args = ["fold", "--dry-run", "--robot", "panda", "--width", "0.55", "--height", "0.55"]
    assert main([*args, *SMALL, "--out", str(out)]) == 1
    plan = json.loads((out / "plan.json").read_text())
    bad = [a for a in plan["actions"] if not a["feasible"]]
    assert not plan["feasible"] and len(bad) == 1 and len(plan["actions"]) == 2
    assert bad[0]["segment"] == "approach" and "no IK solution" in bad[0]["reason"]
    assert f"NOT feasible: stage 1 {bad[0]['label']}" in capsys.readouterr().out


def test_an_earlier_dry_run_is_replaced_only_when_asked(tmp_path, capsys):
    out = tmp_path / "plan"
    assert main(["fold", "--dry-run", "--recipe", "quarter", *SMALL, "--out", str(out)]) == 0
    assert main(["fold", "--dry-run", *SMALL, "--out", str(out)]) == 2
    assert "already holds a dry run; pass --overwrite" in capsys.readouterr().err
    assert main(["fold", "--dry-run", *SMALL, "--out", str(out), "--overwrite"]) == 0
    # The half fold's one stage: quarter's second picture is gone with its plan.
    assert sorted(p.name for p in out.iterdir()) == ["overlay_plan1.png", "plan.json"]
    assert sorted(p.name for p in tmp_path.iterdir()) == ["plan"]


GARMENT = ["--garment-edge-length", "0.03", "--video-fps", "0"]


def test_a_tshirts_fold_is_planned_as_its_loop_carries_it(tmp_path, capsys):
    # The retail fold's three stages planned at once from the flat T-shirt's keypoints; on two
    # arms each side's sleeve and hem corner together, the hem from its tip by one arm.
    out = tmp_path / "plan"
    args = ["fold", "--dry-run", "--garment", "tshirt", "--arms", "2", *GARMENT]
    assert main([*args, "--out", str(out)]) == 0
    plan = json.loads((out / "plan.json").read_text())
    assert plan["feasible"] and plan["planned_recipe"] == "retail" and plan["arm_moved_rad"] == 0
    assert [s["together"] for s in plan["stages"]] == [True, True, False]
    labels = [a["label"] for a in plan["actions"]]
    assert labels == ["left_sleeve", "left_hem", "right_sleeve", "right_hem", "hem", "hem_rest"]
    assert {"left_shoulder", "right_sleeve", "neck"} <= set(plan["perceived_keypoints"])
    assert sorted(p.name for p in out.iterdir()) == [
        "overlay_plan1.png",
        "overlay_plan2.png",
        "overlay_plan3.png",
        "plan.json",
    ]
    # A later stage's picture draws the pieces it was planned on (orange), the first's none.
    drawn = [expected_pixels(out / f"overlay_plan{k}.png") for k in (1, 2, 3)]
    assert drawn[0] == 0 and drawn[1] > 40 and drawn[2] > 40
    assert "3 stage(s), 6 pick-and-place(s) (2 pair(s) by two arms together)" in (
        capsys.readouterr().out
    )


def test_pants_are_planned_one_arm_at_a_time_on_one_arm(tmp_path):
    out = tmp_path / "plan"
    assert main(["fold", "--dry-run", "--garment", "pants", *GARMENT, "--out", str(out)]) == 0
    plan = json.loads((out / "plan.json").read_text())
    assert plan["planned_recipe"] == "leg_over_leg" and plan["feasible"]
    assert [a["stage"] for a in plan["actions"]] == [1, 1, 2, 2]
    assert not any(a.get("together") for a in plan["actions"])


@pytest.mark.parametrize(
    ("extra", "needle"),
    [
        (["--start", "crumpled", "--arms", "2"], "two arms spread it, each spread tried at"),
        (["--fault-slip", "0.3"], "--fault-slip act on a motion, and a dry run moves nothing"),
    ],
)
def test_what_a_dry_run_cannot_show_is_refused(tmp_path, capsys, extra, needle):
    out = tmp_path / "plan"
    assert main(["fold", "--dry-run", *extra, *SMALL[:2], "--out", str(out)]) == 2
    assert needle in capsys.readouterr().err
    assert list(tmp_path.iterdir()) == []


def test_a_crumpled_towels_dry_run_plans_its_first_pull_and_moves_nothing(tmp_path, capsys):
    # The towel crumpled as the episode crumples it (seed 0), seen once: the first pull the
    # flattening makes from that heap (`foldbot fold --start crumpled` pulls corner_d first).
    out = tmp_path / "plan"
    assert main(["fold", "--dry-run", "--start", "crumpled", *SMALL, "--out", str(out)]) == 0
    said = capsys.readouterr().out
    plan = json.loads((out / "plan.json").read_text())
    assert sorted(p.name for p in out.iterdir()) == ["overlay_plan1.png", "plan.json"]
    assert plan["start"] == "crumpled" and plan["feasible"] and plan["stages"] == []
    flatten = plan["flatten"]
    assert flatten["pull_needed"] and flatten["target_coverage"] == 0.9
    assert 0.1 < flatten["perceived_coverage"] < 0.6  # a heap, not a flat towel
    first = plan["actions"][-1]
    assert first["feasible"] and first["kind"] == "flatten_pull" and first["stage"] == 0
    assert first["label"] == "pull corner_d" and first["shortfall_m"] > 0.05
    names = [s["name"] for s in first["steps"]]
    assert names[0] == "approach" and names[-1] == "retreat"
    assert plan["motion_seconds"] == pytest.approx(sum(s["seconds"] for s in first["steps"]))
    assert plan["arm_moved_rad"] == 0.0  # ground truth: the simulated arm stood still
    assert "dry run: the crumpled towel seen at coverage" in said
    assert "the first pull, pull corner_d, feasible:" in said
    assert "each later pull and the fold are planned from what the one before leaves" in said
    # The picture: the heap, the outline the pulls aim at, the pull's grasp and place.
    assert expected_pixels(out / "overlay_plan1.png") > 100


def test_a_dry_run_does_not_write_beside_an_episode(tmp_path, capsys):
    out = tmp_path / "episode"
    out.mkdir()
    (out / "result.json").write_text("{}")
    for overwrite in ([], ["--overwrite"]):
        assert main(["fold", "--dry-run", *SMALL, "--out", str(out), *overwrite]) == 2
        assert "holds no dry run (plan.json)" in capsys.readouterr().err
    assert sorted(p.name for p in out.iterdir()) == ["result.json"]


def test_a_pair_is_planned_one_arm_at_a_time_where_the_arms_would_meet(tmp_path):
    """plan_pair as carry_pair carries: arms that would meet either way round fall back to one
    arm at a time (each entry says why); a pair one arm cannot reach is infeasible whole."""
    cfg = EpisodeConfig(seed=0, towel=TowelSpec(0.24, 0.24, 8), video_fps=0.0, arms=2)
    with SimWorld(cfg.sim) as world, contextlib.ExitStack() as stack:
        parts = build_sim_cell(cfg, world)
        stack.callback(parts.model_world.close)
        settle(world, parts.cloth)
        cell = episode_cell(cfg, parts)
        cell.park()
        z, line = 0.76, (0.36, -0.04, 1.0, 0.0)

        def pair(xs: tuple[float, float], y: float) -> tuple[FoldAction, ...]:
            return tuple(
                FoldAction(np.array([x, y, z]), np.array([x, 0.0, z]), line, label=f"x{x:.2f}")
                for x in xs
            )

        said: list[str] = []
        close = pair((0.36, 0.50), -0.08)  # tests/test_carry.py: the arms meet either way
        entries = plan_pair(cell, 1, close, close, said.append)
        assert [e["label"] for e in entries] == ["x0.36", "x0.50"]
        for entry in entries:
            assert entry["feasible"] and "together" not in entry and "pair_seconds" not in entry
            assert "would" in entry["arms_would_meet"]
        assert "the arms would meet" in said[0] and "one arm at a time" in said[0]
        far = pair((0.45, 1.3), 0.0)  # 1.3 m out: beyond a UR5's reach
        entries = plan_pair(cell, 2, far, far, said.append)
        assert [(e["feasible"], e["together"]) for e in entries] == [(False, True)] * 2
        assert entries[0]["reason"] == entries[1]["reason"] and entries[0]["segment"]
        assert "NOT feasible together" in said[-1]


def test_a_heap_already_flat_enough_plans_no_pull():
    # dry_run_flatten on a towel lying flat: its coverage stops the flattening before any pull.
    from foldbot.dry_run import dry_run_flatten
    from foldbot.planning.flatten import FlattenConfig

    cfg = EpisodeConfig(seed=0, towel=TowelSpec(0.24, 0.24, 8), video_fps=0.0)
    said: list[str] = []
    with SimWorld(cfg.sim) as world, contextlib.ExitStack() as stack:
        parts = build_sim_cell(cfg, world)
        stack.callback(parts.model_world.close)
        settle(world, parts.cloth)
        run = dry_run_flatten(
            FlattenConfig(), episode_cell(cfg, parts), (0.24, 0.24), 1.0, said.append
        )
    assert run.record["flatten"]["pull_needed"] is False and run.record["feasible"]
    assert run.record["actions"] == [] and run.record["motion_seconds"] == 0.0
    assert run.record["flatten"]["perceived_coverage"] > 0.9
    assert said[0].endswith(": no pull needed")
    assert run.summary().endswith(
        "no pull needed: the fold is planned from what the camera then sees"
    )
