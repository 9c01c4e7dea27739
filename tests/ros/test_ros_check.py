"""`foldbot ros-check` on a running cell (`foldbot ros-cell`): every check named, each failing
where the cell lacks what it asks for (a camera pose), or disagrees with the layout it is told
(a table 2 cm higher); no master, no check and no folder."""

import json
import subprocess
import sys

import imageio.v3 as iio
import numpy as np
from ros_helpers import free_port, requires_ros, start_cell, stop_cell, wait_for_master

from foldbot.sim.camera import CameraConfig

pytestmark = requires_ros


def foldbot(*args: str) -> subprocess.CompletedProcess:
    return subprocess.run(
        [sys.executable, "-m", "foldbot.cli", *args], capture_output=True, text=True, timeout=600
    )


def test_a_running_cell_is_checked_for_all_a_fold_needs(tmp_path):
    # The camera's true pose as a calibration would give it; the cell publishes none.
    calibration = tmp_path / "calibration.json"
    calibration.write_text(
        json.dumps(
            {
                "T_world_camera": CameraConfig().T_world_camera.tolist(),
                "parent_frame": "world",
                "child_frame": "camera_color_optical_frame",
                # The camera it was solved with: the cell's (ros-check compares them).
                "camera_info": {
                    "width": 640,
                    "height": 480,
                    "K": CameraConfig().K.tolist(),
                    "distortion": [0.0] * 5,
                },
            }
        )
    )
    # The same pose solved through a camera at twice the resolution: not the cell's camera now.
    other = json.loads(calibration.read_text())
    other["camera_info"].update(
        width=1280, height=960, K=(CameraConfig().K * [[2.0], [2.0], [1.0]]).tolist()
    )
    other_camera = tmp_path / "other_camera.json"
    other_camera.write_text(json.dumps(other))
    high = tmp_path / "high.toml"  # the table and the arm 2 cm higher than the cell's
    high.write_text("table_height = 0.77\nrobot_base_xyz = [0.0, 0.0, 0.77]\n")
    lamp = tmp_path / "lamp.toml"  # a lamp between the camera and the table's far middle
    lamp.write_text(
        '[[obstacles]]\nname = "lamp"\ncenter_xyz = [0.75, 0.0, 1.25]\n'
        "size_xyz = [0.12, 0.12, 0.05]\n"
    )
    low = tmp_path / "low.toml"  # a lamp 32 cm over the workspace: where the arm rests, and is
    low.write_text(
        '[[obstacles]]\nname = "lamp"\ncenter_xyz = [0.55, 0.10, 1.10]\n'
        "size_xyz = [0.30, 0.30, 0.08]\n"
    )
    cell, port = start_cell("--hide-camera-pose", "--resolution", "5", "--camera-rate", "2")
    runs = {}
    try:
        wait_for_master(port)
        for name, extra in (
            ("no_pose", []),
            ("calibrated", ["--camera-pose", str(calibration)]),
            ("high", ["--camera-pose", str(calibration), "--layout", str(high)]),
            ("lamp", ["--camera-pose", str(calibration), "--layout", str(lamp)]),
            ("low", ["--camera-pose", str(calibration), "--layout", str(low)]),
            ("ur5e", ["--camera-pose", str(calibration), "--robot", "ur5e"]),
        ):
            runs[name] = foldbot(
                "ros-check", "--out", str(tmp_path / name), "--port", str(port), *extra
            )
        # ros-fold on the cell refuses to perceive through intrinsics the pose was not solved
        # with, before it launches anything.
        runs["fold_other"] = foldbot(
            "ros-fold", "--cell", "real", "--camera-pose", str(other_camera), "--resolution",
            "5", "--out", str(tmp_path / "fold_other"), "--port", str(port),
        )  # fmt: skip
    finally:
        log = stop_cell(cell)
    no_pose, calibrated, wrong = runs["no_pose"], runs["calibrated"], runs["high"]
    assert no_pose.returncode == 1, no_pose.stdout + no_pose.stderr + log[-3000:]
    assert "ok   action /scaled_pos_joint_traj_controller/follow_joint_trajectory" in no_pose.stdout
    assert "ok   action /gripper_controller/gripper_cmd" in no_pose.stdout
    assert "ok   joints on /joint_states: all 6 arm joints of the ur5" in no_pose.stdout
    # The flange where the cell's controller puts it (base → tool0_controller on /tf).
    assert "ok   the arm as modelled: the ur5's kinematics put the flange 0.0 mm and 0.00° " in (
        no_pose.stdout
    )
    assert "ok   camera: colour rgb8 and depth 32FC1, 640 × 480 px" in no_pose.stdout
    assert "ok   world → base_link: at (0.000, 0.000, 0.750) m" in no_pose.stdout
    assert "FAIL world → camera_color_optical_frame: not on /tf_static" in no_pose.stdout
    assert "1 of 7 checks failed" in no_pose.stdout
    assert not (tmp_path / "no_pose" / "ros_check.png").exists()  # no pose: nothing to draw

    assert calibrated.returncode == 0, calibrated.stdout + calibrated.stderr
    assert "ros-check: the cell is ready to fold" in calibrated.stdout
    record = json.loads((tmp_path / "calibrated" / "ros_check.json").read_text())
    assert record["ok"] and len(record["checks"]) == 12
    assert "ok   the camera as calibrated: 640 × 480 px, fx " in calibrated.stdout
    assert "as the calibration was solved with, its distortion too" in calibrated.stdout
    # The cell's towel, as the fold's first look will see it, drawn on the picture too.
    assert "ok   the towel: found, 4 keypoints," in calibrated.stdout
    assert sorted(record["keypoints"]) == ["far_left", "far_right", "near_left", "near_right"]
    table = next(c for c in record["checks"] if c["name"] == "the table in depth")
    assert "(-0.0 mm from the layout's 0.75)" in table["detail"]
    assert "169 of 169 workspace points inside the image" in calibrated.stdout
    assert (tmp_path / "calibrated" / "ros_check.png").stat().st_size > 10_000
    np.testing.assert_allclose(record["T_world_camera"], CameraConfig().T_world_camera)

    assert wrong.returncode == 1
    assert "FAIL world → base_link: at (0.000, 0.000, 0.750) m, 20 mm from the layout's" in (
        wrong.stdout
    )
    assert (
        "FAIL the table in depth: at 0.7500 m over the workspace centre (-20.0 mm" in wrong.stdout
    )
    assert "2 of 12 checks failed: world → base_link, the table in depth" in wrong.stdout

    # Told the arm is a UR5e, the check finds the UR5's lengths in what its controller reports.
    e = runs["ur5e"]
    assert e.returncode == 1, e.stdout + e.stderr
    assert "FAIL the arm as modelled: the ur5e's kinematics put the flange " in e.stdout
    assert "off: the arm is a ur5 (--robot ur5)" in e.stdout

    lamped = runs["lamp"]
    assert lamped.returncode == 1, lamped.stdout + lamped.stderr
    assert "FAIL the workspace in view: 139 of 169 workspace points inside the image and not " in (
        lamped.stdout
    )
    assert "behind an obstacle (30 behind one)" in lamped.stdout
    assert "ok   the layout's obstacles: 'lamp': no arm rests or stands in one" in lamped.stdout
    # The running cell has no lamp: the camera sees the table where the file puts one.
    assert "FAIL the obstacles in view: 'lamp' NOT there: seen on 0 % of the " in lamped.stdout
    assert "the camera sees past 'lamp'" in lamped.stdout
    # The picture draws it where the file puts it, red: the camera sees past it.
    picture = iio.imread(tmp_path / "lamp" / "ros_check.png")
    assert (picture[..., :3] == (230, 25, 75)).all(axis=-1).sum() > 200

    refused = runs["fold_other"]
    assert refused.returncode == 2, refused.stdout + refused.stderr
    assert (
        f"--camera-pose {other_camera}: the camera as calibrated: its camera_info is 640 × 480"
        in (refused.stderr)
    )
    assert "the calibration's 1280 × 960 px, fx 1760.0 px: calibrate again" in refused.stderr
    assert not (tmp_path / "fold_other").exists()

    low_run = runs["low"]
    assert low_run.returncode == 1, low_run.stdout + low_run.stderr
    line = next(ln for ln in low_run.stdout.splitlines() if "the layout's obstacles" in ln)
    assert line.startswith("FAIL the layout's obstacles: arm: the arm's home posture meets an")
    assert "obstacle 'lamp'" in line


def test_no_master_no_check_and_no_folder(tmp_path):
    out = tmp_path / "check"
    port = free_port()
    proc = foldbot("ros-check", "--out", str(out), "--port", str(port), "--master-wait", "0.5")
    assert proc.returncode == 2
    assert f"no ROS master answers at http://localhost:{port}" in proc.stderr
    assert not out.exists() and list(tmp_path.iterdir()) == []
    proc = foldbot("ros-check", "--out", str(out), "--layout", str(tmp_path / "no.toml"))
    assert proc.returncode == 2 and "does not exist" in proc.stderr
