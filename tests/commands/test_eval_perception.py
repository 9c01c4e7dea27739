"""`foldbot eval-perception`: a short run writes the summary; bad arguments write nothing."""

from __future__ import annotations

import argparse
import json
from pathlib import Path

import numpy as np
import pytest
from calibration_files import write_calibration

from foldbot.commands import eval_perception
from foldbot.garments import GARMENT_KEYPOINTS
from foldbot.sim.camera import CameraConfig
from foldbot.sim.perception_scenes import depth_sensor_config, sample_scene


def _args(*argv: str) -> argparse.Namespace:
    parser = argparse.ArgumentParser(prog="foldbot eval-perception")
    eval_perception.add_arguments(parser)
    return parser.parse_args(list(argv))


def test_three_scenes_write_the_summary(tmp_path: Path, capsys: pytest.CaptureFixture) -> None:
    out = tmp_path / "eval"
    args = _args(
        "--scenes", "3", "--seed", "3", "--out", str(out), "--save-overlays", "2",
        "--width", "320", "--height", "240", "--resolution", "10", "--folded-fraction", "0.5",
    )  # fmt: skip
    assert eval_perception.run(args) == 0
    summary = json.loads((out / "summary.json").read_text())
    for key in ("corner_error_mm", "detection_rate", "mask_iou", "ms_per_frame", "rows"):
        assert key in summary
    assert set(summary["corner_error_mm"]) >= {"median", "p95", "max"}
    assert set(summary["by_state"]) == {"all", "flat", "folded"}
    assert len(summary["rows"]) + len(summary["sim_failures"]) == 3
    assert summary["detection_rate"] == 1.0
    assert summary["mask_iou"] > 0.8
    assert len(list((out / "overlays").glob("scene_*.png"))) == 2
    assert [p.name for p in tmp_path.iterdir()] == ["eval"]  # no staging folder left behind
    printed = capsys.readouterr().out
    assert "median mm" in printed and "headline" in printed


@pytest.mark.parametrize(
    ("argv", "message"),
    [
        (["--scenes", "0"], "--scenes must be > 0"),
        (["--scenes", "-2"], "--scenes must be > 0"),
        (["--seed", "-1"], "--seed must be an integer ≥ 0, got -1"),
        (["--edge-length", "0.01"], "--edge-length is for --garment tshirt or pants"),
        (["--save-overlays", "-1"], "--save-overlays"),
        (["--width", "8"], "width"),
        (["--towel-sides", "0.5", "0.3"], "--towel-sides must be LO HI with 0.05 ≤ LO ≤ HI"),
        (["--towel-sides", "0.3", "0.9"], "got 0.3 0.9"),
        (["--garment", "pants", "--towel-sides", "0.3", "0.4"], "--towel-sides is for --garment"),
        (["--depth-sensor", "0"], "--depth-sensor must be in (0, 0.1] m, got 0.0"),
        (["--depth-sensor", "0.2"], "got 0.2"),
        (["--depth-sensor", "nan"], "got nan"),
    ],
)
def test_bad_arguments_write_nothing(
    tmp_path: Path, capsys: pytest.CaptureFixture, argv: list[str], message: str
) -> None:
    out = tmp_path / "eval"
    assert eval_perception.run(_args("--out", str(out), *argv)) == 2
    assert message in capsys.readouterr().err
    assert not out.exists() and list(tmp_path.iterdir()) == []


def test_a_depth_sensor_beside_the_camera_is_rendered_and_registered(tmp_path: Path) -> None:
    """`--depth-sensor M`: the depth comes from a sensor M m to the colour camera's left, smaller
    and wider, and is registered onto the colour image; the summary says so."""
    color = CameraConfig()
    cfg, T = depth_sensor_config(color, 0.025)
    assert (cfg.width, cfg.height) == (424, 240) and cfg.fx < color.fx
    np.testing.assert_allclose(T[:3, 3], [-0.025, 0.0, 0.0])
    np.testing.assert_allclose(cfg.T_world_camera, color.T_world_camera @ T, atol=1e-12)
    out = tmp_path / "eval"
    args = _args(
        "--scenes", "2", "--seed", "0", "--out", str(out), "--folded-fraction", "0",
        "--arm-fraction", "0", "--depth-sensor", "0.025",
    )  # fmt: skip
    assert eval_perception.run(args) == 0
    summary = json.loads((out / "summary.json").read_text())
    assert summary["depth_sensor_baseline_m"] == 0.025
    assert summary["detection_rate"] == 1.0
    assert summary["corner_error_mm"]["max"] < 5.0  # measured 0.35 mm median over 100 scenes


def test_unwritable_out_is_a_clear_error(tmp_path: Path, capsys: pytest.CaptureFixture) -> None:
    blocker = tmp_path / "file.txt"
    blocker.write_text("not a folder")
    assert eval_perception.run(_args("--scenes", "1", "--out", str(blocker / "eval"))) == 2
    assert "cannot write" in capsys.readouterr().err
    assert eval_perception.run(_args("--scenes", "1", "--out", str(blocker))) == 2
    assert "not a folder" in capsys.readouterr().err
    assert sorted(p.name for p in tmp_path.iterdir()) == ["file.txt"]


def test_tshirt_scenes_write_per_keypoint_figures(
    tmp_path: Path, capsys: pytest.CaptureFixture
) -> None:
    out = tmp_path / "eval"
    args = _args(
        "--garment", "tshirt", "--scenes", "2", "--seed", "1", "--out", str(out),
        "--save-overlays", "1", "--width", "320", "--height", "240", "--edge-length", "0.04",
    )  # fmt: skip
    assert eval_perception.run(args) == 0
    summary = json.loads((out / "summary.json").read_text())
    assert summary["garment"] == "tshirt" and summary["scenes"] == 2
    assert set(summary["by_keypoint"]) == set(GARMENT_KEYPOINTS["tshirt"])
    for figures in summary["by_keypoint"].values():
        assert figures["detection_rate"] == 1.0
        assert set(figures["error_mm"]) >= {"median", "mean", "p95", "max"}
    assert summary["detection_rate"] == 1.0 and summary["keypoint_detection_rate"] == 1.0
    assert summary["keypoint_error_mm"]["max"] < 10.0  # 320×240: 2.5 mm pixels
    assert summary["mask_iou"] > 0.95
    row = summary["rows"][0]
    assert row["scene"]["spec"]["edge_length"] == 0.04 and row["missing"] == []
    assert len(list((out / "overlays").glob("scene_*.png"))) == 1
    printed = capsys.readouterr().out
    assert "left_sleeve" in printed and "overall" in printed and "mean mm" in printed


@pytest.mark.parametrize(
    ("argv", "message"),
    [
        (["--garment", "pants", "--folded-fraction", "0.5"], "--folded-fraction must be 0"),
        (["--garment", "tshirt", "--edge-length", "0.5"], "edge_length"),
        (["--garment", "pants", "--arm-fraction", "2"], "--arm-fraction"),
        (["--garment", "pants", "--garment-yaw-range", "200"], "--garment-yaw-range"),
        (["--garment", "towel", "--garment-yaw-range", "90"], "is for --garment tshirt or pants"),
    ],
)
def test_bad_garment_arguments_write_nothing(
    tmp_path: Path, capsys: pytest.CaptureFixture, argv: list[str], message: str
) -> None:
    out = tmp_path / "eval"
    assert eval_perception.run(_args("--out", str(out), *argv)) == 2
    assert message in capsys.readouterr().err
    assert list(tmp_path.iterdir()) == []


def test_pants_under_the_parked_arm(tmp_path: Path) -> None:
    """The garment suites' first frame: pants with the gripper parked at home over the waist."""
    out = tmp_path / "eval"
    args = _args(
        "--garment", "pants", "--scenes", "1", "--seed", "2", "--out", str(out),
        "--width", "320", "--height", "240", "--edge-length", "0.04",
        "--arm-fraction", "1", "--arm-pose", "home",
    )  # fmt: skip
    assert eval_perception.run(args) == 0
    summary = json.loads((out / "summary.json").read_text())
    assert summary["arm_fraction"] == 1.0 and summary["arm_pose"] == "home"
    row = summary["rows"][0]
    assert row["scene"]["arm_target"] == pytest.approx([0.45, 0.0, 1.0])
    assert row["detected"] and row["missing"] == []
    assert max(row["keypoint_error_mm"].values()) < 10.0  # 320×240: 2.5 mm pixels


def test_a_worst_scene_says_what_was_not_found() -> None:
    verdict = eval_perception._garment_verdict
    assert verdict({"score": 4.25, "detected": True, "missing": []}) == "4.2 mm"
    assert verdict({"score": None, "detected": False, "missing": ["neck"]}) == "not recognised"
    assert verdict({"score": None, "detected": True, "missing": ["neck"]}) == "missing: neck"


def test_a_layout_moves_the_scenes_and_the_camera_with_its_workspace(tmp_path: Path) -> None:
    """`--layout FILE`: the same draws as the default cell's, the towel and the camera moved
    with the workspace, the cloth on the layout's table; the summary names the layout."""
    from foldbot.sim.layout import load_layout

    layout_file = Path(__file__).resolve().parents[2] / "layouts" / "pedestal.toml"
    layout = load_layout(layout_file)
    shift = np.array(layout.workspace_shift())
    for i in range(10):
        a = sample_scene(np.random.default_rng([5, i]), i, 0.3, 0.4)
        b = sample_scene(np.random.default_rng([5, i]), i, 0.3, 0.4, layout=layout)
        assert (b.x - a.x, b.y - a.y) == pytest.approx(tuple(shift[:2]))
        np.testing.assert_allclose(np.subtract(b.eye, a.eye), shift, atol=1e-12)
        np.testing.assert_allclose(np.subtract(b.target, a.target), shift, atol=1e-12)
        assert b.towel_width == a.towel_width and b.yaw == a.yaw
    out = tmp_path / "eval"
    args = _args(
        "--scenes", "2", "--seed", "0", "--out", str(out), "--folded-fraction", "0",
        "--resolution", "10", "--layout", str(layout_file),
    )  # fmt: skip
    assert eval_perception.run(args) == 0
    summary = json.loads((out / "summary.json").read_text())
    assert summary["layout"]["table_height"] == 0.70
    assert summary["layout_file"] == str(layout_file)
    assert summary["camera"]["source"].startswith("the default camera, jittered")
    assert summary["detection_rate"] == 1.0
    assert summary["corner_error_mm"]["max"] < 3.0  # the corners found on the 0.70 m table


def two_flat_scenes_through(cal: Path, out: Path) -> dict:
    """eval-perception of two flat scenes, the arm parked, through the calibration `cal`: the
    summary it wrote into `out`."""
    args = _args(
        "--scenes", "2", "--seed", "0", "--out", str(out), "--folded-fraction", "0",
        "--resolution", "10", "--arm-fraction", "0", "--camera-pose", str(cal),
    )  # fmt: skip
    assert eval_perception.run(args) == 0
    return json.loads((out / "summary.json").read_text())


def test_a_calibrations_camera_renders_every_scene(
    tmp_path: Path, capsys: pytest.CaptureFixture
) -> None:
    """`--camera-pose CALIBRATION.json`: every scene seen from that camera, at its image size
    and intrinsics, none of the default camera's jitter; the summary keeps the camera."""
    from foldbot.sim.camera import DEFAULT_UP, look_at

    T = look_at((0.95, 0.4, 1.6), (0.45, 0.0, 0.75), DEFAULT_UP)
    cal = tmp_path / "calibration.json"
    write_calibration(cal, (0.0, 0.0, 0.0), truth=False, intrinsics=True, true_pose=T)
    summary = two_flat_scenes_through(cal, tmp_path / "eval")
    assert (summary["width"], summary["height"]) == (320, 240)
    assert summary["camera"]["source"] == str(cal)
    np.testing.assert_allclose(summary["camera"]["T_world_camera"], T)
    assert all("eye" not in row["scene"] for row in summary["rows"])
    assert summary["detection_rate"] == 1.0 and summary["corner_error_mm"]["max"] < 5.0
    assert f"camera: {cal}" in capsys.readouterr().out
    # The image size is the calibration's: --width beside it is refused, nothing written.
    again = tmp_path / "again"
    assert (
        eval_perception.run(_args("--out", str(again), "--camera-pose", str(cal), "--width", "320"))
        == 2
    )
    assert "--width and --height are the calibration's" in capsys.readouterr().err
    assert not again.exists()


@pytest.mark.parametrize(
    ("argv", "message"),
    [
        (["--layout", "missing.toml"], "layout file 'missing.toml' does not exist"),
        (["--camera-pose", "missing.json"], "'missing.json': no such file"),
    ],
)
def test_a_missing_layout_or_calibration_is_named(
    tmp_path: Path, capsys: pytest.CaptureFixture, monkeypatch, argv: list[str], message: str
) -> None:
    monkeypatch.chdir(tmp_path)
    assert eval_perception.run(_args("--out", str(tmp_path / "eval"), *argv)) == 2
    assert message in capsys.readouterr().err
    assert list(tmp_path.iterdir()) == []


def test_a_simulated_calibrations_error_counts_in_the_figures(
    tmp_path: Path, capsys: pytest.CaptureFixture
) -> None:
    """A calibration that knows where the camera truly stood (`foldbot calibrate`'s `truth`):
    the scenes are rendered from there and perceived from the pose it found, 5 mm off, so every
    corner is found about 5 mm off (within 3 mm from the true pose: the test above)."""
    from foldbot.sim.camera import DEFAULT_UP, look_at

    side = look_at((0.95, 0.4, 1.6), (0.45, 0.0, 0.75), DEFAULT_UP)
    cal = tmp_path / "calibration.json"
    true, found = write_calibration(cal, (0.0, 0.003, 0.004), true_pose=side)
    summary = two_flat_scenes_through(cal, tmp_path / "eval")
    camera = summary["camera"]
    np.testing.assert_allclose(camera["T_world_camera"], found)
    np.testing.assert_allclose(camera["true_T_world_camera"], true)
    assert camera["calibration_error_mm"] == pytest.approx(5.0)
    errors = summary["corner_error_mm"]
    assert summary["detection_rate"] == 1.0 and 3.0 < errors["median"] < 7.0, errors
    assert "perceived from the calibration's, 5.00 mm and 0.000° off it" in capsys.readouterr().out
