"""`foldbot check-layout`: the verdict as an exit code, the report and its files, a calibration's
camera, and bad input refused by name with no folder left."""

import json

import numpy as np
import pytest

from foldbot.cli import main
from foldbot.sim.camera import CameraConfig


def test_the_default_cell_passes_and_its_check_is_written(tmp_path, capsys):
    out = tmp_path / "check"
    assert main(["check-layout", "--grid", "4", "--out", str(out)]) == 0
    text = capsys.readouterr().out
    assert "the default cell, 1 × ur5, 4 × 4 points" in text
    assert "grasps and places at 16 of 16 points" in text and "the layout can fold" in text
    record = json.loads((out / "layout_check.json").read_text())
    assert record["ok"] and record["points"] == 16 and record["layout"] == {}
    assert record["camera"]["source"] == "the simulated camera"
    assert (out / "layout_check.png").stat().st_size > 5_000
    assert sorted(p.name for p in tmp_path.iterdir()) == ["check"]


def test_a_layout_out_of_reach_exits_1_with_what_it_found(tmp_path, capsys):
    layout = tmp_path / "far.toml"
    layout.write_text(
        "table_size = [1.6, 1.2]\ntable_center_xy = [0.7, 0.0]\nworkspace_center_xy = [0.75, 0.0]\n"
    )
    out = tmp_path / "check"
    assert main(["check-layout", str(layout), "--grid", "3", "--out", str(out)]) == 1
    text = capsys.readouterr().out
    assert "(1.050, -0.300) m: at the grasp height (10 mm): no IK solution" in text
    assert "cannot fold everywhere in its workspace" in text
    record = json.loads((out / "layout_check.json").read_text())
    assert not record["ok"] and record["layout"]["workspace_center_xy"] == [0.75, 0.0]


def write_calibration(path, T, camera_info=None):
    record = {"T_world_camera": T.tolist(), "parent_frame": "world", "child_frame": "cam"}
    if camera_info is not None:
        record["camera_info"] = camera_info
    path.write_text(json.dumps(record))
    return path


def test_a_calibrations_camera_is_the_one_checked(tmp_path, capsys):
    cam = CameraConfig()
    # The simulated camera's pose, at half the resolution the calibration recorded.
    K = cam.K.copy()
    K[:2] /= 2
    info = {"width": 320, "height": 240, "K": K.tolist(), "distortion": [0.0] * 5}
    path = write_calibration(tmp_path / "calibration.json", cam.T_world_camera, info)
    out = tmp_path / "check"
    assert main(["check-layout", "--grid", "3", "--camera-pose", str(path), "--out", str(out)]) == 0
    record = json.loads((out / "layout_check.json").read_text())["camera"]
    assert record["source"] == str(path) and record["image_size"] == [320, 240]
    assert record["points_seen"] == 9
    assert record["mm_per_px"] == pytest.approx(2 * 1.32, abs=0.05)
    # Without intrinsics in the file, the simulated camera's are taken, and said so.
    bare = write_calibration(tmp_path / "old.json", cam.T_world_camera)
    assert main(["check-layout", "--grid", "3", "--camera-pose", str(bare)]) == 0
    assert "its file has no intrinsics: the simulated camera's" in capsys.readouterr().out
    # A camera beside the cell looking away from it sees none of the workspace.
    away = np.eye(4)
    away[:3, 3] = [2.0, 0.0, 1.5]
    away[:3, :3] = np.diag([1.0, -1.0, -1.0])  # looking up
    turned = write_calibration(tmp_path / "away.json", away, info)
    assert main(["check-layout", "--grid", "3", "--camera-pose", str(turned)]) == 1
    assert "sees 0 of 9 points" in capsys.readouterr().out


@pytest.mark.parametrize(
    ("extra", "needle"),
    [
        (["--grid", "1"], "--grid must be 2–41 points a side, got 1"),
        (["--grid", "-3"], "--grid must be 2–41 points a side, got -3"),
        (["missing.toml"], "layout file 'missing.toml' does not exist"),
        (["."], "layout file '.' is a folder, not a file"),
        (["--out", ""], "argument --out: must name a folder or file, got ''"),
        (["--camera-pose", "missing.json"], "'missing.json': no such file"),
    ],
)
def test_bad_input_is_refused_by_name_and_leaves_no_folder(
    tmp_path, capsys, monkeypatch, extra, needle
):
    monkeypatch.chdir(tmp_path)
    out = tmp_path / "check"
    try:
        code = main(["check-layout", "--out", str(out), *extra])
    except SystemExit as exc:  # argparse's own errors
        code = exc.code
    assert code == 2
    captured = capsys.readouterr()
    assert needle in captured.err
    assert "points" not in captured.out  # refused before anything is printed
    assert list(tmp_path.iterdir()) == []


def test_a_calibrations_bad_intrinsics_are_named(tmp_path, capsys):
    info = {"width": 640, "height": 480, "K": [[0, 0, 0], [0, 0, 0], [0, 0, 1]]}
    path = write_calibration(tmp_path / "calibration.json", np.eye(4), info)
    assert main(["check-layout", "--camera-pose", str(path)]) == 2
    assert "camera_info K must be a 3 × 3 camera matrix" in capsys.readouterr().err


@pytest.mark.parametrize("width", ["640", 640.5, True])
def test_a_calibrations_image_size_must_be_whole_pixels(tmp_path, capsys, width):
    K = [[554.0, 0, 319.5], [0, 554.0, 239.5], [0, 0, 1]]
    path = write_calibration(
        tmp_path / "calibration.json", np.eye(4), {"width": width, "height": 480, "K": K}
    )
    assert main(["check-layout", "--camera-pose", str(path)]) == 2
    assert "camera_info's width and height must be whole numbers of pixels, got " in (
        capsys.readouterr().err
    )
