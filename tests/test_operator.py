"""`--confirm` (foldbot.operator): the operator's go or stop before each pick-and-place, on the
gate's own streams and through a whole fold in process (over ROS: tests/ros/test_ros_confirm.py)."""

from __future__ import annotations

import io
import json
import re
import sys

import numpy as np
import pytest

from foldbot.cli import main
from foldbot.errors import OperatorStopped
from foldbot.operator import ArmMove, OperatorGate, PlannedMotion

SMALL = ["--resolution", "9", "--video-fps", "0"]


def motion(label: str = "far_left", arm: int = 0) -> PlannedMotion:
    return PlannedMotion(
        label, arm, np.array([0.64, 0.096, 0.757]), np.array([0.35, 0.17, 0.761]), 5, 4.66
    )


def gate(answers: str) -> tuple[OperatorGate, io.StringIO]:
    out = io.StringIO()
    return OperatorGate(io.StringIO(answers), out), out


def test_enter_lets_the_motion_run_and_is_counted():
    g, out = gate("\n")
    g.ask([motion()])
    said = out.getvalue()
    assert said.startswith(
        "next: far_left with arm 0: grasp (0.640, 0.096, 0.757) m → place (0.350, 0.170, 0.761) m, "
        "5 steps, 4.7 s\n  Enter: move · s: stop the fold > "
    )
    assert g.record()["motions_confirmed"] == 1 and g.record()["wait_seconds"] >= 0.0


def test_stop_ends_the_fold_naming_the_motion_and_nothing_is_counted():
    g, _out = gate("s\n")
    with pytest.raises(
        OperatorStopped, match=r"^stopped by the operator before far_left with arm 0"
    ):
        g.ask([motion()])
    assert g.record()["motions_confirmed"] == 0


def test_closed_input_stops_rather_than_moving():
    g, _out = gate("")
    with pytest.raises(OperatorStopped, match=r"no answer \(input closed\) before far_left"):
        g.ask([motion()])


def test_another_answer_is_asked_again():
    g, out = gate("maybe\nyes\n")
    g.ask([motion()])
    said = out.getvalue()
    assert "'maybe': answer Enter (or y, yes, go) to move" in said
    assert said.count("next: far_left") == 2 and g.confirmed == 1


def test_two_arms_moving_together_are_one_question():
    g, out = gate("\n")
    g.ask([motion("far_left", 1), motion("near_left", 0)])
    assert "far_left with arm 1: " in out.getvalue()
    assert " together with near_left with arm 0: " in out.getvalue()
    assert out.getvalue().count("next:") == 1


def test_a_park_is_asked_naming_the_arms_it_moves():
    g, out = gate("\n")
    g.ask([ArmMove("park", (0, 1), "joint move to the park pose", 1.25)])
    assert out.getvalue().startswith(
        "next: park with arms 0 and 1: joint move to the park pose, 1.2 s\n"
    )
    assert g.confirmed == 1


def test_a_fold_asks_before_each_carry_and_records_it(tmp_path, monkeypatch, capsys):
    # Two arms' half fold: the two corners carried together are one question.
    monkeypatch.setattr(sys, "stdin", io.StringIO("\n" * 20))
    out = tmp_path / "ep"
    assert main(["fold", "--confirm", "--arms", "2", *SMALL, "--out", str(out)]) == 0
    said = capsys.readouterr().out
    result = json.loads((out / "result.json").read_text())
    asked = said.count("next: ")
    assert result["operator"]["motions_confirmed"] == asked >= 1
    assert said.count(" together with ") >= 1
    assert said.count("next: park with arms 0 and 1: joint move to the park pose") >= 1
    assert sum(1 for a in result["actions"] if a.get("together")) >= 2


def test_the_lift_after_a_miss_and_the_park_are_asked_and_a_stop_ends_the_fold_named(
    tmp_path, monkeypatch, capsys
):
    # The first grasp is aimed 5 cm off the corner (a miss): the carry, the lift that lets go,
    # the park, then the retry, where the operator stops.
    monkeypatch.setattr(sys, "stdin", io.StringIO("\n\n\ns\n"))
    out = tmp_path / "ep"
    argv = ["fold", "--confirm", "--fault-grasp-offset", "0.05", *SMALL, "--out", str(out)]
    assert main(argv) == 2
    captured = capsys.readouterr()
    asked = [line for line in captured.out.splitlines() if line.startswith("next: ")]
    assert [line.split(":")[1].strip() for line in asked] == [
        "far_left with arm 0",
        "lift after the missed grasp with arm 0",
        "park with arm 0",
        "far_left with arm 0",
    ], asked
    assert re.fullmatch(
        r"next: lift after the missed grasp with arm 0: open the jaws, straight up 0\.080 m, "
        r"\d+\.\d s",
        asked[1],
    ), asked[1]
    assert re.fullmatch(
        r"next: park with arm 0: joint move to the park pose, out of the camera's view, \d+\.\d s",
        asked[2],
    ), asked[2]
    assert "error: stopped by the operator before far_left with arm 0" in captured.err
    assert not out.exists()  # no episode: it was stopped
    failure = json.loads((tmp_path / "ep.failed" / "error.json").read_text())
    assert failure["error_type"] == "OperatorStopped"


def test_nothing_to_confirm_in_a_dry_run(tmp_path, capsys):
    out = tmp_path / "plan"
    assert main(["fold", "--confirm", "--dry-run", *SMALL, "--out", str(out)]) == 2
    assert "--confirm asks before each motion, and --dry-run makes none" in capsys.readouterr().err
    assert list(tmp_path.iterdir()) == []
