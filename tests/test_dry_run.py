"""`foldbot fold --dry-run` (foldbot.dry_run): one look, every stage and motion planned in the
simulated cell, nothing moved; plan.json says what each pick-and-place would do or why it
cannot; its folder written whole, an earlier dry run replaced only when asked."""

from __future__ import annotations

import json

import pytest

from foldbot.cli import main

SMALL = ["--resolution", "9", "--video-fps", "0"]


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
    assert [a["stage"] for a in plan["actions"]] == [1, 1, 2, 2]
    assert plan["arm_moved_rad"] == 0.0  # ground truth: the simulated arm stood still
    for action in plan["actions"]:
        names = [s["name"] for s in action["steps"]]
        assert names[0] == "approach" and "descend" in names and names[-1] == "retreat"
        assert action["motion_seconds"] == pytest.approx(sum(s["seconds"] for s in action["steps"]))
    assert plan["motion_seconds"] == pytest.approx(
        sum(a["motion_seconds"] for a in plan["actions"])
    )
    assert "every motion feasible" in said and f"plan written to {out}" in said


def test_a_slowed_arm_is_planned_slower(tmp_path):
    full, slow = tmp_path / "full", tmp_path / "slow"
    assert main(["fold", "--dry-run", *SMALL, "--out", str(full)]) == 0
    assert main(["fold", "--dry-run", *SMALL, "--speed-scale", "0.5", "--out", str(slow)]) == 0
    a, b = (json.loads((d / "plan.json").read_text()) for d in (full, slow))
    assert b["speed_scale"] == 0.5 and a["stages"] == b["stages"]
    # Twice as long, but for the dwells (a place's settle), which keep their seconds.
    dwell = 2 * a["motion_seconds"] - b["motion_seconds"]
    assert 0.0 <= dwell < 0.25 * a["motion_seconds"]


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


@pytest.mark.parametrize(
    ("extra", "needle"),
    [
        (["--garment", "tshirt"], "--dry-run plans a towel's fold; got --garment tshirt"),
        (["--start", "crumpled"], "a crumpled start is flattened first"),
        (["--fault-slip", "0.3"], "--fault-slip act on a motion, and a dry run moves nothing"),
    ],
)
def test_what_a_dry_run_cannot_show_is_refused(tmp_path, capsys, extra, needle):
    out = tmp_path / "plan"
    towel = [] if "--garment" in extra else SMALL[:2]
    assert main(["fold", "--dry-run", *extra, *towel, "--out", str(out)]) == 2
    assert needle in capsys.readouterr().err
    assert list(tmp_path.iterdir()) == []


def test_a_dry_run_does_not_write_beside_an_episode(tmp_path, capsys):
    out = tmp_path / "episode"
    out.mkdir()
    (out / "result.json").write_text("{}")
    for overwrite in ([], ["--overwrite"]):
        assert main(["fold", "--dry-run", *SMALL, "--out", str(out), *overwrite]) == 2
        assert "holds no dry run (plan.json)" in capsys.readouterr().err
    assert sorted(p.name for p in out.iterdir()) == ["result.json"]
