"""`foldbot calibrate`: the simulated camera's pose found from the board the arm holds, written
as a real cell publishes it; bad options refused by name with no folder left."""

import json
import re

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from foldbot.cli import main


def test_a_moved_camera_is_found_from_the_held_board(tmp_path, capsys):
    out = tmp_path / "cal"
    # The camera off to the side and lower than the default: the calibration is not told where.
    args = ["calibrate", "--out", str(out), "--views", "6", "--camera-eye", "0.95", "0.4", "1.6"]
    assert main(args) == 0
    record = json.loads((out / "calibration.json").read_text())
    assert record["views_used"] >= 5 and record["reprojection_rms_px"] < 0.5
    truth = record["truth"]
    assert truth["translation_error_mm"] < 1.0 and truth["rotation_error_deg"] < 0.05
    assert truth["table_error_mm"] < 1.0
    assert np.allclose(record["translation_m"], [0.95, 0.4, 1.6], atol=2e-3)
    # The launch file publishes that pose, world → the colour camera's optical frame.
    launch = (out / "camera_pose.launch").read_text()
    args_text = re.search(r'args="([^"]+)"', launch).group(1).split()
    assert args_text[7:] == ["world", "camera_color_optical_frame"]
    xyz, quat = np.array(args_text[:3], float), np.array(args_text[3:7], float)
    T = np.array(record["T_world_camera"])
    assert np.allclose(xyz, T[:3, 3], atol=1e-6)
    assert np.allclose(Rotation.from_quat(quat).as_matrix(), T[:3, :3], atol=1e-6)
    assert (out / "views.png").stat().st_size > 10_000
    assert "against the simulated camera" in capsys.readouterr().out
    # The intrinsics the pose was solved with, which check-layout reads back with the pose.
    info = record["camera_info"]
    assert (info["width"], info["height"]) == (640, 480) and info["distortion"] == [0.0] * 5
    assert info["K"][0][0] == pytest.approx(880.0)
    check = ["check-layout", "--grid", "3", "--camera-pose", str(out / "calibration.json")]
    assert main(check) == 1  # from there the image misses corners of the workspace
    text = capsys.readouterr().out
    assert f"camera ({out / 'calibration.json'}): sees 6 of 9" in text
    assert "not seen: (0.750, -0.300), (0.750, 0.000), (0.150, 0.300)" in text


@pytest.mark.parametrize(
    ("extra", "needle"),
    [
        (["--board", "8x6"], "odd in all"),
        (["--board", "eight"], "--board must be COLUMNSxROWS"),
        (["--views", "3"], "views must be an integer in [4, 12]"),
        (["--camera-target", "0.4", "0", "0.75"], "--camera-target needs --camera-eye"),
        (["--look-from", "1", "0", "0.9"], "--look-from: the camera's rough position"),
        (["--camera-eye", "1", "0", "0.9"], "--camera-eye (the board turns to it): the camera's"),
        (
            ["--camera-eye", "0.45", "0", "1.75", "--camera-target", "0.45", "0", "1.75"],
            "camera eye [0.45, 0.0, 1.75] and target [0.45, 0.0, 1.75] (m) must differ",
        ),
        (["--out", ""], "argument --out: must name a folder or file, got ''"),
        (["--square", "0"], "square_m must be in"),
        (["--camera-noise", "-1"], "--camera-noise must be in [0, 64] intensity levels"),
        (["--arm", "right"], "--arm right is for a two-arm cell (--arms 2)"),
        (["--speed-scale", "0"], "speed_scale must be in [0.05, 1] (a fraction of full speed)"),
        (
            ["--board-turn", "0", "0", "200"],
            "--board-turn must be a rotation vector of at most 180°",
        ),
        (["--board-offset", "0.6", "0", "0"], "--board-offset must put the board within 0.5 m"),
        (["--marker", "0.02"], "--marker and --aruco-dictionary are for --board-pattern charuco"),
        (["--board-pattern", "charuco", "--marker", "0.035"], "marker_m must be 0.4–0.9"),
        (
            ["--board-pattern", "charuco", "--board", "12x10", "--square", "0.01"],
            "needs 60 markers, more than dictionary 4x4_50's 50",
        ),
        (
            ["--board-pattern", "charuco", "--board", "7x5", "--square", "0.03"],
            "at most 127 (PyBullet's links on one body); this 7 × 5 charuco needs 160",
        ),
    ],
)
def test_bad_options_are_refused_by_name_and_leave_no_folder(tmp_path, capsys, extra, needle):
    out = tmp_path / "cal"
    try:
        code = main(["calibrate", "--out", str(out), *extra])
    except SystemExit as exc:  # argparse's own errors
        code = exc.code
    assert code == 2
    assert needle in capsys.readouterr().err
    assert not out.exists() and list(tmp_path.iterdir()) == []


def test_the_board_to_print_is_written_at_its_resolution(tmp_path, capsys):
    from PIL import Image

    out = tmp_path / "board.png"
    assert main(["print-board", str(out), "--dpi", "254"]) == 0
    with Image.open(out) as img:
        assert img.size == (2320, 1600)  # 232 × 160 mm at 10 px/mm
        assert tuple(round(v) for v in img.info["dpi"]) == (254, 254)
    assert "232 × 160 mm at 254 dpi" in capsys.readouterr().out
    assert main(["print-board", str(tmp_path / "b.jpg")]) == 2
    assert "written as a .png" in capsys.readouterr().err
    # A board metres across at a print resolution: refused before a byte is drawn.
    huge = ["print-board", str(tmp_path / "h.png"), "--board", "29x28", "--square", "0.2"]
    assert main([*huge, "--dpi", "2400"]) == 2
    assert "would be 551811 × 532913 px at 94488.2 px/m: at most 600 megapixels" in (
        capsys.readouterr().err
    )
    assert sorted(p.name for p in tmp_path.iterdir()) == ["board.png"]


def test_either_arm_of_two_holds_the_board(tmp_path):
    # At 60 % speed, as a first run on a real arm would move it: the same views, slower.
    out = tmp_path / "cal"
    args = ["calibrate", "--out", str(out), "--arms", "2", "--arm", "right", "--views", "5"]
    assert main([*args, "--speed-scale", "0.6"]) == 0
    record = json.loads((out / "calibration.json").read_text())
    assert (record["arms"], record["arm"]) == (2, 1) and record["views_used"] >= 4
    assert record["speed_scale"] == 0.6
    assert record["truth"]["translation_error_mm"] < 1.0


def test_a_ur5e_holds_the_board_and_the_fold_suggested_is_the_ur5es(tmp_path, capsys):
    out = tmp_path / "cal"
    assert main(["calibrate", "--out", str(out), "--robot", "ur5e", "--views", "5"]) == 0
    record = json.loads((out / "calibration.json").read_text())
    assert record["truth"]["translation_error_mm"] < 1.0
    suggested = f"foldbot fold --camera-pose {out}/calibration.json --robot ur5e --out DIR"
    assert suggested in capsys.readouterr().out


def test_the_operator_lets_each_move_run_or_stops_the_calibration(tmp_path, monkeypatch, capsys):
    import io
    import sys

    # The right arm of two, as the test above: each of its 4 views asked, then the way home.
    args = ["calibrate", "--arms", "2", "--arm", "right", "--views", "4", "--confirm"]
    monkeypatch.setattr(sys, "stdin", io.StringIO("\n" * 5))
    assert main([*args, "--out", str(tmp_path / "cal")]) == 0
    asked = [ln for ln in capsys.readouterr().out.splitlines() if ln.startswith("next: ")]
    assert [ln.split(":")[1].strip() for ln in asked] == [
        *(f"view {i} with arm 1" for i in range(4)),
        "home with arm 1",
    ]
    assert asked[0].endswith(" s") and "joint move holding the board up to the camera, " in asked[0]
    record = json.loads((tmp_path / "cal" / "calibration.json").read_text())
    assert record["operator"]["motions_confirmed"] == 5
    # Stopped before the second view: named, nothing written.
    monkeypatch.setattr(sys, "stdin", io.StringIO("\ns\n"))
    assert main([*args, "--out", str(tmp_path / "stopped")]) == 2
    err = capsys.readouterr().err
    assert "error: stopped by the operator before view 1 with arm 1: joint move" in err
    assert sorted(p.name for p in tmp_path.iterdir()) == ["cal"]


def test_a_dry_run_plans_every_views_move_and_names_those_an_obstacle_blocks(tmp_path, capsys):
    # A lamp 60 cm over the table, among the views: the forearm or wrist would pass within
    # 2 cm of it on the way to two of six.
    layout = tmp_path / "lamp.toml"
    layout.write_text(
        '[[obstacles]]\nname = "lamp"\ncenter_xyz = [0.50, 0.0, 1.35]\n'
        "size_xyz = [0.10, 0.10, 0.05]\n"
    )
    out = tmp_path / "plan"
    args = ["calibrate", "--dry-run", "--views", "6", "--layout", str(layout)]
    assert main([*args, "--out", str(out)]) == 1
    said = capsys.readouterr().out
    plan = json.loads((out / "plan.json").read_text())
    assert sorted(p.name for p in out.iterdir()) == ["plan.json"]  # nothing calibrated
    assert plan["dry_run"] and not plan["feasible"] and plan["cell"] == "sim"
    bad = [v for v in plan["views"] if not v["feasible"]]
    assert [v["view"] for v in bad] == ["view 1", "view 5"]
    assert all("obstacle 'lamp' (at least 20 mm needed)" in v["reason"] for v in bad)
    good = [v for v in plan["views"] if v["feasible"]]
    assert plan["motion_seconds"] == pytest.approx(
        sum(v["seconds"] for v in good) + plan["back_seconds"]
    )
    assert "dry run: view 1: NOT feasible: " in said
    assert "dry run: 4 of 6 views reachable" in said and "nothing moved" in said
    assert main([*args, "--confirm", "--out", str(tmp_path / "x")]) == 2
    assert "--confirm asks before each move, and --dry-run makes none" in capsys.readouterr().err
    assert not (tmp_path / "x").exists()


def test_a_board_mounted_elsewhere_is_found_where_it_is(tmp_path):
    # The board a quarter turn about the tool's axis on a shorter bracket: the views aim it
    # so, and the solve finds it there (and the camera) from the images alone.
    out = tmp_path / "cal"
    args = [
        "calibrate",
        "--out",
        str(out),
        "--views",
        "6",
        "--board-offset",
        "-0.2",
        "0.03",
        "-0.08",
    ]
    assert main([*args, "--board-turn", "0", "0", "90"]) == 0
    record = json.loads((out / "calibration.json").read_text())
    Y = np.array(record["T_tcp_board"])
    assert np.allclose(Y[:3, 3], [-0.2, 0.03, -0.08], atol=2e-3)
    assert np.allclose(Y[:3, :3], Rotation.from_euler("z", 90, degrees=True).as_matrix(), atol=5e-3)
    assert record["truth"]["translation_error_mm"] < 1.0


def test_a_camera_the_chessboard_runs_off_is_found_from_a_charuco_board(tmp_path, capsys):
    """A camera 30 cm nearer (0.9, 0, 1.45): half the views show the chessboard in part, and two
    of those it finds in the wrong order; a ChArUco board names its corners, so every view
    counts. The chessboard's two wrong views halve nothing one at a time: both are dropped
    together and the four that agree solved."""
    eye = ["--camera-eye", "0.9", "0.0", "1.45"]
    chess, charuco = tmp_path / "chessboard", tmp_path / "charuco"
    assert main(["calibrate", "--out", str(chess), *eye]) == 0
    record = json.loads((chess / "calibration.json").read_text())
    fates = [v["dropped"] or "used" for v in record["views"]]
    assert fates.count("the board was not seen whole") == 6 and record["views_used"] == 4
    assert sum("disagreed with the rest" in f for f in fates) == 2
    assert record["reprojection_rms_px"] < 0.5
    assert record["truth"]["translation_error_mm"] < 3.0
    assert main(["calibrate", "--out", str(charuco), *eye, "--board-pattern", "charuco"]) == 0
    record = json.loads((charuco / "calibration.json").read_text())
    assert record["board"] == {
        "pattern": "charuco",
        "squares": [6, 4],
        "square_m": 0.036,
        "marker_m": 0.027,
        "dictionary": "4x4_50",
    }
    assert record["views_used"] == 12
    seen = [v["corners_seen"] for v in record["views"]]
    assert min(seen) >= 6 and min(seen) < 15  # some views show the board only in part
    assert record["truth"]["translation_error_mm"] < 1.0
    assert record["truth"]["rotation_error_deg"] < 0.1
    assert "of 15 corners)" in capsys.readouterr().out


def test_the_charuco_board_to_print(tmp_path, capsys):
    from PIL import Image

    out = tmp_path / "charuco.png"
    assert main(["print-board", str(out), "--board-pattern", "charuco", "--dpi", "254"]) == 0
    with Image.open(out) as img:
        assert img.size == (2560, 1840)  # 6 × 36 + 40 by 4 × 36 + 40 mm at 10 px/mm
    assert "charuco" in capsys.readouterr().out


def test_a_board_too_large_to_simulate_leaves_no_pybullet_client_open(tmp_path, capsys):
    # Refused while the cell is built: its worlds are closed (a client left open would be the
    # next test's default client 0, where its unqualified PyBullet calls would land).
    import pybullet as p

    open_before = [c for c in range(16) if p.isConnected(c)]
    args = ["calibrate", "--out", str(tmp_path / "cal"), "--board-pattern", "charuco"]
    assert main([*args, "--board", "7x5", "--square", "0.03"]) == 2
    assert "this 7 × 5 charuco needs 160" in capsys.readouterr().err
    assert [c for c in range(16) if p.isConnected(c)] == open_before
