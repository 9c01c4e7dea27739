"""A calibration run's bookkeeping: a view that disagrees with the rest is dropped and the solve
run without it, too few seen views are an error naming why each was dropped, and what is
written says which views were used."""

import json

import numpy as np
import pytest
from test_hand_eye import X_TRUE, K, views

from foldbot.calibration.capture import (
    Capture,
    calibration_pose_words,
    calibration_record,
    contact_sheet,
    launch_text,
    solve_captures,
)
from foldbot.calibration.hand_eye import pose_error
from foldbot.calibration.views import CalibrationView
from foldbot.errors import ConfigError, PerceptionError
from foldbot.ros.camera_pose_node import parse_pose_args


def captures(n: int):
    board, A, B, corners = views(n, noise_px=0.1, seed=3)
    caps = [
        Capture(CalibrationView(f"view {i}", a[:3, 3], np.array([0, 0, 0, 1.0])), a, None, c, b)
        for i, (a, b, c) in enumerate(zip(A, B, corners, strict=True))
    ]
    return board, caps


def test_a_view_that_disagrees_is_dropped_and_the_rest_solved():
    board, caps = captures(8)
    caps[5].T_world_tcp = caps[5].T_world_tcp.copy()
    caps[5].T_world_tcp[:3, 3] += [0.0, 0.02, 0.0]  # the arm was not where its joints said
    sol = solve_captures(caps, board, K, np.zeros(5))
    assert "disagreed with the rest" in caps[5].dropped
    assert [c.dropped == "" for c in caps].count(True) == 7
    dt, dr = pose_error(sol.T_world_camera, X_TRUE)
    assert dt < 1e-3 and np.rad2deg(dr) < 0.05
    record = calibration_record(caps, sol, board)
    assert record["views_used"] == 7 and record["views"][5]["used"] is False
    sheet = contact_sheet(
        [
            Capture(c.view, c.T_world_tcp, np.zeros((480, 640, 3), np.uint8), c.corners)
            for c in caps
        ],
        sol,
        board,
        K,
        np.zeros(5),
    )
    assert sheet.shape == (2 * 240, 4 * 320, 3)
    # The launch file's arguments, as its node and static_transform_publisher read them.
    launch = launch_text(sol.T_world_camera)
    words = launch.split('args="')[1].split('"')[0].split()
    T, parent, child = parse_pose_args(words)
    assert (parent, child) == ("world", "camera_color_optical_frame")
    assert np.allclose(T, sol.T_world_camera, atol=1e-6)


def test_two_views_wrong_together_are_both_dropped():
    # Neither drop alone halves the error (the other wrong view stays): the fewest views that
    # agree are found instead.
    board, caps = captures(8)
    for k, shift in ((2, [0.03, 0.0, 0.0]), (6, [0.0, -0.04, 0.02])):
        caps[k].T_world_tcp = caps[k].T_world_tcp.copy()
        caps[k].T_world_tcp[:3, 3] += shift
    sol = solve_captures(caps, board, K, np.zeros(5))
    assert [k for k, c in enumerate(caps) if c.dropped] == [2, 6]
    assert all("disagreed with the rest" in caps[k].dropped for k in (2, 6))
    dt, dr = pose_error(sol.T_world_camera, X_TRUE)
    assert dt < 1e-3 and np.rad2deg(dr) < 0.05


def test_views_that_agree_on_nothing_are_refused_not_written():
    board, caps = captures(6)
    rng = np.random.default_rng(0)
    for cap in caps[1:]:
        cap.T_world_tcp = cap.T_world_tcp.copy()
        cap.T_world_tcp[:3, 3] += rng.uniform(-0.05, 0.05, 3)
    with pytest.raises(PerceptionError, match=r"no 4 or more views agree: .* px RMS") as err:
        solve_captures(caps, board, K, np.zeros(5))
    assert "view 0 " in str(err.value) and "--board-pattern charuco" in str(err.value)
    assert not any(c.dropped for c in caps)  # nothing marked: nothing was solved


def test_too_few_seen_views_name_why_the_others_were_dropped():
    board, caps = captures(5)
    caps[0].dropped = "the board was not seen whole"
    caps[1].dropped = "out of reach: waypoint 0"
    with pytest.raises(
        PerceptionError, match=r"only 3 of 5 views saw the board .*view 1: out of reach"
    ):
        solve_captures(caps, board, K, np.zeros(5))


def test_a_calibration_file_gives_the_pose_or_says_what_is_wrong(tmp_path):
    good = tmp_path / "calibration.json"
    T = np.eye(4)
    T[:3, 3] = [1.0, 0.0, 1.7]
    frames = {"parent_frame": "world", "child_frame": "camera_color_optical_frame"}
    good.write_text(json.dumps({"T_world_camera": T.tolist(), **frames}))
    words = calibration_pose_words(good)
    assert words[7:] == ["world", "camera_color_optical_frame"]
    assert [float(w) for w in words[:3]] == [1.0, 0.0, 1.7]
    # The nodes look the camera up as world → camera_color_optical_frame: other frames are named.
    bad = tmp_path / "bad.json"
    bad.write_text(json.dumps({"T_world_camera": T.tolist(), **frames, "child_frame": "cam"}))
    with pytest.raises(ConfigError, match="child_frame must be 'camera_color_optical_frame'"):
        calibration_pose_words(bad)
    bad.write_text(json.dumps({"T_world_camera": T.tolist(), **frames, "parent_frame": None}))
    with pytest.raises(ConfigError, match="parent_frame must name a frame, got null"):
        calibration_pose_words(bad)
    bad.write_text(json.dumps({"T_world_camera": [[None] * 4] * 4, **frames}))
    with pytest.raises(ConfigError, match=r"rigid 4 × 4 transform, got \[\[null, null"):
        calibration_pose_words(bad)
    with pytest.raises(ConfigError, match="no such file"):
        calibration_pose_words(tmp_path / "missing.json")
    bad.write_text(json.dumps({"views": []}))
    with pytest.raises(ConfigError, match=r"is not a calibration\.json"):
        calibration_pose_words(bad)
    T[0, 0] = 2.0
    bad.write_text(
        json.dumps({"T_world_camera": T.tolist(), "parent_frame": "world", "child_frame": "cam"})
    )
    with pytest.raises(ConfigError, match="must be a rigid 4 × 4 transform"):
        calibration_pose_words(bad)


def test_a_calibration_file_gives_the_distortion_it_was_solved_with(tmp_path):
    from foldbot.calibration.capture import calibration_distortion

    path = tmp_path / "calibration.json"
    frames = {"parent_frame": "world", "child_frame": "camera_color_optical_frame"}
    record = {"T_world_camera": np.eye(4).tolist(), **frames}
    path.write_text(json.dumps(record))
    assert calibration_distortion(path) is None  # a file written before 2026-11-30
    info = {"width": 640, "height": 480, "K": np.eye(3).tolist()}
    path.write_text(json.dumps({**record, "camera_info": info}))
    assert calibration_distortion(path) is None
    path.write_text(
        json.dumps({**record, "camera_info": {**info, "distortion": [-0.25, 0.1, 0, 0, 0]}})
    )
    np.testing.assert_array_equal(calibration_distortion(path), [-0.25, 0.1, 0, 0, 0])
    for bad, words in (("x", "must be a list of numbers"), ([float("nan")], "14 finite numbers")):
        path.write_text(json.dumps({**record, "camera_info": {**info, "distortion": bad}}))
        with pytest.raises(ConfigError, match=words):
            calibration_distortion(path)
