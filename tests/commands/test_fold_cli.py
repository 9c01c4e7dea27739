"""`foldbot fold` from the command line: help, and clear errors for bad input."""

import argparse
import dataclasses
import json
import math
import os
import subprocess
import sys

import pytest
from calibration_files import write_calibration

from foldbot.cli import main
from foldbot.commands.fold import add_arguments, config_from_args
from foldbot.errors import ConfigError
from foldbot.pipeline import seeded_pose
from foldbot.planning.motion import MotionConfig


def test_help_lists_subcommands(capsys):
    with pytest.raises(SystemExit) as exc:
        main(["--help"])
    assert exc.value.code == 0
    out = capsys.readouterr().out
    for cmd in ("fold", "eval-perception", "score"):
        assert cmd in out


@pytest.mark.parametrize(
    "cmd",
    [
        "fold",
        "eval-perception",
        "score",
        "calibrate",
        "ros-calibrate",
        "print-board",
        "check-layout",
        "ros-check",
    ],
)
def test_subcommand_help(cmd, capsys):
    with pytest.raises(SystemExit) as exc:
        main([cmd, "--help"])
    assert exc.value.code == 0
    assert "usage" in capsys.readouterr().out


@pytest.mark.parametrize(
    ("args", "needle"),
    [
        (["--robot", "kuka"], "kuka"),
        (["--garment", "sock"], "sock"),
        (["--width", "0"], "width"),
        (["--height", "-0.3"], "height"),
        (["--mass", "0"], "mass"),
        (["--mass", "-1"], "mass"),
        (["--time-step", "0"], "time_step"),
        (["--time-step", "0.05"], "time_step"),
        (["--out", ""], "argument --out: must name a folder or file, got ''"),
        (["--time-step", "1e-9"], "time_step must be in [0.0001, 0.02] s, got 1e-09"),
        (["--time-step", "nan"], "time_step must be in [0.0001, 0.02] s, got nan"),
        (["--speed-scale", "0.01"], "speed_scale must be in [0.05, 1] (a fraction of full"),
        (["--speed-scale", "2"], "speed_scale must be in [0.05, 1] (a fraction of full"),
        (
            ["--speed-scale", "nan"],
            "speed_scale must be in [0.05, 1] (a fraction of full speed), got nan",
        ),
        (["--video-fps", "1e9"], "video_fps must be frames per simulated second in [0, 60]"),
        (["--video-fps", "inf"], "(0: no video), got inf"),
        (["--jaw-catch", "glue"], "glue"),
        (["--resolution", "2"], "resolution"),
        (["--resolution", "99"], "resolution"),
        (["--garment-yaw", "0"], "turns a T-shirt or pants"),
        (["--garment", "pants", "--width", "0.4"], "--width shapes a towel; the pants' size"),
        (
            ["--garment", "tshirt", "--no-odd-grid", "--max-vertices", "99"],
            "--no-odd-grid, --max-vertices shape a towel; a T-shirt's size is the seed's draw",
        ),
        (["--garment-edge-length", "0.02"], "--garment-edge-length sets a tshirt's or pants'"),
        (["--replicate", "-1"], "replicate must be an integer in [0, 999]"),
        (["--loop-option", "top_layer_first"], "NAME=VALUE"),
        (["--loop-option", "stack_inset=-0.01"], "stack_inset = -0.01 must be a length in m"),
        (["--loop-option", "grip=true"], "unknown loop option 'grip'"),
        (["--loop-option", "relay_corners=false", "--loop-option", "relay_corners=true"], "twice"),
        (["--cloth", "margin_divisor=1"], "cloth margin_divisor must be in [2, 20]"),
        (["--cloth", "glue=1"], "unknown cloth option 'glue'"),
        (["--mass", "0.2", "--cloth", "mass=0.3"], "mass is given twice"),
        (
            ["--garment", "tshirt", "--loop-option", "crease_band=0.03"],
            "crease_band acts on towel folds only; the tshirt loop reads top_layer_first",
        ),
        (["--suite", "smoke", "--arms", "2"], "--suite smoke sets the episode; drop --arms"),
        (["--suite", "smoke", "--mass", "0.2"], "drop --mass"),
        (["--suite", "smoke", "--speed-scale", "0.5"], "drop --speed-scale"),
        (["--suite", "smoke", "--no-odd-grid"], "drop --no-odd-grid (beside --suite"),
        (["--suite", "nosuch"], "unknown suite 'nosuch'"),
        (["--suite", "smoke", "--seed", "-1"], "--seed must be an integer ≥ 0, got -1"),
        (
            ["--suite", "smoke", "--seed", "3", "--replicate", "2"],
            "suite 'smoke' has no episode with replicate 2, recipe any and perception vision; "
            "its replicates: 0–0",
        ),
        (
            ["--suite", "smoke", "--episode", "towel-half-vision-open-s0099-r3"],
            "has no episode 'towel-half-vision-open-s0099-r3'; its ids: towel-half-vision-closed-"
            "s0000,",
        ),
        (["--suite", "smoke"], "runs 2 episodes for seed 0: towel-half-vision-closed-s0000, "),
        (["--suite", "smoke", "--episode", "towel-half"], "has no episode 'towel-half'; its ids"),
        (
            ["--suite", "smoke", "--episode", "towel-half-vision-open-s0000", "--seed", "1"],
            "drop --seed",
        ),
        (["--episode", "towel-half-vision-open-s0000"], "give --suite too"),
        (["--layout", "nothere.toml"], "layout file 'nothere.toml' does not exist"),
        (["--fault-slip", "1"], "fault_slip must be in [0, 1)"),
        (["--fault-grasp-offset", "0.5"], "fault_grasp_offset must be in [0, 0.2] m, got 0.5"),
        (["--suite", "smoke", "--layout", "layouts/pedestal.toml"], "drop --layout"),
    ],
)
def test_bad_arguments_get_a_clear_error(tmp_path, capsys, args, needle):
    out = tmp_path / "ep"
    with pytest.raises(SystemExit) as exc:
        code = main(["fold", "--out", str(out), *args])
        raise SystemExit(code)
    assert exc.value.code == 2
    err = capsys.readouterr().err
    assert needle in err
    assert "Traceback" not in err
    assert not out.exists()


def test_odd_grid_flag_reaches_the_towel():
    parser = argparse.ArgumentParser()
    add_arguments(parser)
    cfg = config_from_args(parser.parse_args(["--out", "x"]))
    assert cfg.towel.odd_grid is True and cfg.towel.grid_shape == (17, 17)  # the CLI's default
    cfg = config_from_args(parser.parse_args(["--out", "x", "--no-odd-grid"]))
    assert cfg.towel.odd_grid is False and cfg.towel.grid_shape == (16, 16)


def test_max_vertices_reaches_the_towel():
    parser = argparse.ArgumentParser()
    add_arguments(parser)
    cfg = config_from_args(parser.parse_args(["--out", "x", "--resolution", "13"]))
    assert cfg.towel.max_vertices is None and cfg.towel.grid_shape == (13, 13)
    args = ["--out", "x", "--resolution", "13", "--max-vertices", "143"]
    cfg = config_from_args(parser.parse_args(args))
    assert cfg.towel.max_vertices == 143 and cfg.towel.grid_shape == (11, 11)


def test_replicate_reaches_the_episode():
    parser = argparse.ArgumentParser()
    add_arguments(parser)
    assert config_from_args(parser.parse_args(["--out", "x"])).replicate == 0
    assert config_from_args(parser.parse_args(["--out", "x", "--replicate", "2"])).replicate == 2


def test_jaw_catch_reaches_the_episode():
    parser = argparse.ArgumentParser()
    add_arguments(parser)
    assert config_from_args(parser.parse_args(["--out", "x"])).jaw_catch == "vertices"
    cfg = config_from_args(parser.parse_args(["--out", "x", "--jaw-catch", "surface"]))
    assert cfg.jaw_catch == "surface"


def test_loop_options_reach_the_episode():
    parser = argparse.ArgumentParser()
    add_arguments(parser)
    assert config_from_args(parser.parse_args(["--out", "x"])).loop_options == {}
    args = ["--out", "x", "--loop-option", "stack_edge_carry=false"]
    cfg = config_from_args(parser.parse_args([*args, "--loop-option", "pair_descent=0.02"]))
    assert cfg.loop_options == {"pair_descent": 0.02, "stack_edge_carry": False}


def test_flatten_options_reach_the_episode():
    parser = argparse.ArgumentParser()
    add_arguments(parser)
    assert config_from_args(parser.parse_args(["--out", "x"])).flatten_options == {}
    args = ["--out", "x", "--start", "crumpled", "--flatten-option", "grasp_layer=top"]
    cfg = config_from_args(parser.parse_args([*args, "--flatten-option", "finish_coverage=none"]))
    assert cfg.flatten_options == {"finish_coverage": None, "grasp_layer": "top"}
    with pytest.raises(ConfigError, match="act on crumpled starts only; this episode starts flat"):
        config_from_args(parser.parse_args(["--out", "x", "--flatten-option", "min_pull=0.03"]))


def test_a_layout_file_reaches_the_world(tmp_path):
    from foldbot.sim.layout import DEFAULT_LAYOUT

    parser = argparse.ArgumentParser()
    add_arguments(parser)
    assert config_from_args(parser.parse_args(["--out", "x"])).sim.layout == DEFAULT_LAYOUT
    path = tmp_path / "cell.toml"
    path.write_text("table_height = 0.72\nrobot_base_xyz = [0.0, 0.0, 0.72]\n")
    cfg = config_from_args(parser.parse_args(["--out", "x", "--layout", str(path)]))
    assert cfg.sim.layout.changes() == {"table_height": 0.72, "robot_base_xyz": [0.0, 0.0, 0.72]}
    assert cfg.cell_camera.eye[2] == pytest.approx(cfg.camera.eye[2] - 0.03)
    path.write_text("robot_base_xyz = [0.0, 0.0, 0.72]\n")  # 3 cm into the 0.75 m table
    with pytest.raises(ConfigError, match="stands inside the table"):
        config_from_args(parser.parse_args(["--out", "x", "--layout", str(path)]))


def test_time_step_reaches_the_world():
    parser = argparse.ArgumentParser()
    add_arguments(parser)
    cfg = config_from_args(parser.parse_args(["--out", "x"]))
    assert cfg.sim.time_step == pytest.approx(1 / 360)
    cfg = config_from_args(parser.parse_args(["--out", "x", "--time-step", "0.0020833"]))
    assert cfg.sim.time_step == pytest.approx(1 / 480, rel=1e-4)


def test_speed_scale_reaches_the_motion():
    parser = argparse.ArgumentParser()
    add_arguments(parser)
    assert config_from_args(parser.parse_args(["--out", "x"])).motion.speed_scale == 1.0
    cfg = config_from_args(parser.parse_args(["--out", "x", "--speed-scale", "0.3"]))
    assert cfg.motion.speed_scale == 0.3
    assert cfg.motion.cartesian_speed == MotionConfig().cartesian_speed  # the rest kept


def test_unwritable_output_folder(tmp_path, capsys):
    blocker = tmp_path / "a_file"
    blocker.write_text("not a folder")
    code = main(["fold", "--out", str(blocker / "ep")])
    assert code == 2
    err = capsys.readouterr().err
    assert str(blocker) in err and "Traceback" not in err


@pytest.mark.parametrize(
    ("perception", "needle"),
    [
        # Ground-truth corners lie beyond the arm's reach: IK rejects the action before motion.
        ("oracle", "infeasible (nothing moved)"),
        # The camera sees only part of the towel: no plan is made from invisible corners.
        ("vision", "beyond the camera's view"),
    ],
)
def test_oversized_towel_is_refused_before_anything_is_written(tmp_path, perception, needle):
    """A 1 m towel: larger than both the workspace and the camera's view."""
    out = tmp_path / "ep"
    env = {**os.environ, "PYTHONWARNINGS": "ignore"}
    args = ["fold", "--width", "1.0", "--height", "1.0", "--resolution", "8"]
    args += ["--video-fps", "0", "--perception", perception, "--out", str(out)]
    proc = subprocess.run(
        [sys.executable, "-m", "foldbot.cli", *args],
        capture_output=True,
        text=True,
        env=env,
        timeout=300,
    )
    assert proc.returncode == 2, proc.stderr
    assert "Traceback" not in proc.stderr
    assert needle in proc.stderr
    assert not out.exists()


def test_a_failed_fold_leaves_its_video_beside_the_episode_it_did_not_write(tmp_path):
    """The 1 m towel again, filmed: the camera saw it settle beyond its view. No episode folder;
    DIR.failed holds the video up to the error and error.json, and the error names it."""
    out = tmp_path / "ep"
    args = ["fold", "--width", "1.0", "--height", "1.0", "--resolution", "8"]
    args += ["--video-fps", "5", "--out", str(out)]
    proc = subprocess.run(
        [sys.executable, "-m", "foldbot.cli", *args],
        capture_output=True,
        text=True,
        env={**os.environ, "PYTHONWARNINGS": "ignore"},
        timeout=300,
    )
    assert proc.returncode == 2, proc.stderr
    assert "beyond the camera's view" in proc.stderr and "Traceback" not in proc.stderr
    failed = tmp_path / "ep.failed"
    assert not out.exists() and sorted(p.name for p in tmp_path.iterdir()) == ["ep.failed"]
    assert sorted(p.name for p in failed.iterdir()) == ["error.json", "video.mp4"]
    report = json.loads((failed / "error.json").read_text())
    assert report["error_type"] == "FoldbotError" and "camera's view" in report["error"]
    assert f"what the episode recorded up to the error: {failed}" in proc.stderr


@pytest.mark.parametrize(
    ("args", "park"),
    [
        ([], "home"),
        (["--garment", "tshirt"], "home"),
        (["--start", "crumpled"], "home"),
        (["--garment", "pants", "--park", "out_of_view"], "out_of_view"),
    ],
)
def test_the_arm_parks_at_home_unless_told(tmp_path, args, park):
    # Out of view measured worse for garments and crumpled towels (docs/experiments.md,
    # Where the arm parks).
    parser = argparse.ArgumentParser()
    add_arguments(parser)
    cfg = config_from_args(parser.parse_args(["--out", str(tmp_path / "ep"), *args]))
    assert cfg.park == park


def test_a_ur5e_folds_the_towel(tmp_path):
    # The e-Series arm in the cell: its own kinematics plan and move the fold (seed 1 at 9
    # vertices: 7.4 mm, where the UR5 folds the same towel to 12.8 mm).
    out = tmp_path / "ep"
    args = ["fold", "--robot", "ur5e", "--resolution", "9", "--video-fps", "0", "--seed", "1"]
    assert main([*args, "--out", str(out)]) == 0
    result = json.loads((out / "result.json").read_text())
    assert result["robot"] == "ur5e"
    assert result["success"] and result["fold_error_mm"] < 15.0


def test_garment_yaw_option_turns_the_garment(tmp_path):
    parser = argparse.ArgumentParser()
    add_arguments(parser)
    out = ["--out", str(tmp_path / "ep"), "--garment", "tshirt"]
    assert config_from_args(parser.parse_args(out)).garment_yaw == pytest.approx(math.pi / 2)
    cfg = config_from_args(parser.parse_args([*out, "--garment-yaw", "0"]))
    (_, _), yaw = seeded_pose(cfg, (0.45, 0.0))
    assert cfg.garment_yaw == 0.0 and abs(yaw) <= cfg.yaw_range
    # named in the degrees the option takes, not only the radians it is stored in
    with pytest.raises(ConfigError, match=r"garment_yaw must be within ±360° .*got 1000°"):
        config_from_args(parser.parse_args([*out, "--garment-yaw", "1000"]))


def test_arms_option_reaches_the_cell(tmp_path):
    parser = argparse.ArgumentParser()
    add_arguments(parser)
    out = ["--out", str(tmp_path / "ep")]
    assert config_from_args(parser.parse_args(out)).arms == 1
    assert config_from_args(parser.parse_args([*out, "--arms", "2"])).arms == 2
    with pytest.raises(SystemExit):
        parser.parse_args([*out, "--arms", "3"])


def test_a_suite_episode_is_the_one_bench_runs_with_a_video():
    """`--suite NAME --seed N` builds what `foldbot bench` runs for that seed (the towel's drawn
    size and pose, start, arms, cloth), only with this command's video rate and GUI."""
    from foldbot.bench.suite import load_suite

    parser = argparse.ArgumentParser()
    add_arguments(parser)
    args = ["--out", "x", "--suite", "towel_crumpled_two_arms", "--seed", "3"]
    cfg = config_from_args(parser.parse_args(args))
    (spec,) = [e for e in load_suite("towel_crumpled_two_arms").episodes if e.seed == 3]
    assert cfg == dataclasses.replace(spec.to_config(), video_fps=10.0)
    assert cfg.arms == 2 and cfg.cloth.layer_friction == 0.25 and cfg.start == "crumpled"
    args = ["--out", "x", "--suite", "smoke", "--episode", "towel-half-oracle-open-s0000"]
    cfg = config_from_args(parser.parse_args([*args, "--video-fps", "0"]))
    assert (cfg.perception, cfg.closed_loop, cfg.video_fps) == ("oracle", False, 0.0)
    cfg = config_from_args(parser.parse_args(["--out", "x", "--suite", "towel_loop", "--seed", "4",
                                              "--recipe", "thirds"]))  # fmt: skip
    assert (cfg.recipe, cfg.seed) == ("thirds", 4)


def test_a_suite_episode_takes_options_over_the_suites_own_as_bench_does():
    """`--suite NAME --seed N` with --loop-option, --cloth and --flatten-option is the episode
    `foldbot bench --suite NAME` runs with them: set over the suite's tables (its cloth's
    layer_friction kept beside a new mass), checked as bench checks them."""
    from foldbot.bench.suite import load_suite
    from foldbot.commands.bench import with_options

    parser = argparse.ArgumentParser()
    add_arguments(parser)
    options = ["--cloth", "mass=0.2", "--flatten-option", "finish_coverage=0.99",
               "--loop-option", "pair_descent=0.02"]  # fmt: skip
    base = ["--out", "x", "--suite", "towel_crumpled_two_arms", "--video-fps", "0"]
    cfg = config_from_args(parser.parse_args([*base, "--seed", "3", *options]))
    suite = with_options(
        load_suite("towel_crumpled_two_arms"),
        {"pair_descent": 0.02},
        {"mass": 0.2},
        {"finish_coverage": 0.99},
    )
    (spec,) = [e for e in suite.episodes if e.seed == 3]
    assert cfg == spec.to_config()
    assert cfg.cloth.mass == 0.2 and cfg.cloth.layer_friction == 0.25
    assert dict(cfg.flatten_options) == {"finish_coverage": 0.99}
    assert dict(cfg.loop_options)["pair_descent"] == 0.02
    # Checked as bench checks them: a flatten option for a suite of flat starts is refused.
    flat = ["--out", "x", "--suite", "towel_loop", "--seed", "4", "--recipe", "thirds"]
    with pytest.raises(ConfigError, match="finish_coverage"):
        config_from_args(parser.parse_args([*flat, "--flatten-option", "finish_coverage=0.99"]))


def test_faults_reach_the_episode_alone_or_with_a_suite_and_not_a_running_cell(no_launch, capsys):
    """--fault-slip and --fault-grasp-offset set the simulated cell's injected faults, also on
    a suite's episode (a trial of the loop's recovery); `ros-fold` hands them to its nodes
    (tests/commands/test_ros_cli.py), a running cell (`ros-cell`) has no such options."""
    from foldbot.bench.suite import load_suite

    parser = argparse.ArgumentParser()
    add_arguments(parser)
    cfg = config_from_args(parser.parse_args(["--out", "x"]))
    assert (cfg.fault_slip, cfg.fault_grasp_offset) == (0.0, 0.0)
    args = ["--out", "x", "--fault-slip", "0.3", "--fault-grasp-offset", "0.06"]
    cfg = config_from_args(parser.parse_args(args))
    assert (cfg.fault_slip, cfg.fault_grasp_offset) == (0.3, 0.06)
    cfg = config_from_args(parser.parse_args([*args, "--suite", "towel_loop", "--seed", "4",
                                              "--recipe", "thirds"]))  # fmt: skip
    (spec,) = [e for e in load_suite("towel_loop").episodes if (e.seed, e.recipe) == (4, "thirds")]
    assert cfg == dataclasses.replace(
        spec.to_config(), fault_slip=0.3, fault_grasp_offset=0.06, video_fps=10.0
    )
    with pytest.raises(SystemExit) as exc:  # a grasp aimed off the cloth is the fold's
        main(["ros-cell", "--fault-grasp-offset", "0.06"])  # ros-cell's fault is a slip
    assert exc.value.code == 2
    assert "unrecognized arguments: --fault-grasp-offset 0.06" in capsys.readouterr().err


def test_a_suite_episode_for_a_seed_the_suite_does_not_list():
    """A seed outside the suite's own (smoke lists 0–1) is the episode `bench --suite NAME
    --seeds N` runs: drawn as the suite draws it, by --seed or by the id such a run names."""
    from foldbot.bench.suite import load_suite

    parser = argparse.ArgumentParser()
    add_arguments(parser)
    base = ["--out", "x", "--suite", "towel_crumpled_two_arms", "--video-fps", "0"]
    by_seed = config_from_args(parser.parse_args([*base, "--seed", "24"]))
    episode = "towel-half-vision-closed-crumpled-s0024"
    by_id = config_from_args(parser.parse_args([*base, "--episode", episode]))
    (spec,) = load_suite("towel_crumpled_two_arms", [20, 24, 31]).episodes[1:2]
    assert spec.id == episode and by_seed == by_id == spec.to_config()
    assert 24 not in load_suite("towel_crumpled_two_arms").axes["seeds"]
    assert (by_seed.seed, by_seed.towel_size_range) == (24, (0.25, 0.45))  # drawn when it runs


def test_a_calibration_places_the_camera_and_perception_gets_its_pose(tmp_path, capsys):
    """`--camera-pose CALIBRATION.json`: a simulated cell's calibration places the camera where it
    truly stood and hands perception the pose it found; a real cell's (no truth) places the
    camera at its pose. Its intrinsics come too; beside --suite it is the suite's episode with
    that camera."""
    import numpy as np

    from foldbot.commands.fold import perceived_pose_line

    parser = argparse.ArgumentParser()
    add_arguments(parser)
    cal = tmp_path / "calibration.json"
    true, found = write_calibration(cal, intrinsics=True)
    cfg = config_from_args(parser.parse_args(["--out", "x", "--camera-pose", str(cal)]))
    np.testing.assert_allclose(cfg.camera.T_world_camera, true)
    np.testing.assert_allclose(cfg.camera.reported_T_world_camera, found)
    assert cfg.camera.reported_pose_source == str(cal)
    assert (cfg.camera.width, cfg.camera.height, cfg.camera.fx) == (320, 240, 440.0)
    assert cfg.cell_camera == cfg.camera  # a placed camera does not move with the layout
    assert perceived_pose_line(cfg.camera) == (
        f"camera: perceived from {cal}'s pose, 5.00 mm and 0.000° from where it truly stands"
    )
    bare = tmp_path / "real.json"
    _, found = write_calibration(bare, truth=False)
    cfg = config_from_args(parser.parse_args(["--out", "x", "--camera-pose", str(bare)]))
    np.testing.assert_allclose(cfg.camera.T_world_camera, found)
    assert cfg.camera.reported_pose is None and perceived_pose_line(cfg.camera) == ""
    suite = ["--out", "x", "--suite", "towel_loop", "--seed", "4", "--recipe", "thirds"]
    plain = config_from_args(parser.parse_args(suite))
    cfg = config_from_args(parser.parse_args([*suite, "--camera-pose", str(cal)]))
    assert cfg == dataclasses.replace(plain, camera=cfg.camera)
    np.testing.assert_allclose(cfg.camera.reported_T_world_camera, found)


@pytest.mark.parametrize(
    ("content", "needle"),
    [
        (None, "no such file"),
        ('{"T_world_camera": 1}', "is not a calibration.json"),
        (
            '{"T_world_camera": [[1,0,0,0],[0,1,0,0],[0,0,1,0],[0,0,0,1]], "parent_frame": "w", '
            '"child_frame": "c", "truth": {"T_world_camera": [[2,0,0,0],[0,1,0,0],[0,0,1,0],'
            "[0,0,0,1]]}}",
            "truth's T_world_camera must be a rigid 4 × 4 transform",
        ),
    ],
)
def test_a_bad_calibration_is_named_before_anything_is_written(tmp_path, capsys, content, needle):
    cal = tmp_path / "calibration.json"
    if content is not None:
        cal.write_text(content)
    out = tmp_path / "ep"
    assert main(["fold", "--camera-pose", str(cal), "--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert needle in err and str(cal) in err and "Traceback" not in err
    assert not out.exists()


@pytest.mark.slow
def test_a_fold_perceives_from_the_calibrations_pose(tmp_path):
    """A calibration 5 mm off: the fold plans from corners seen 5 mm off (the first frame's
    keypoint error, 0.1–0.2 mm from the true pose), folds all the same, and result.json keeps
    both poses and the calibration's error."""
    import numpy as np

    cal = tmp_path / "calibration.json"
    true, found = write_calibration(cal)
    out = tmp_path / "ep"
    args = ["fold", "--resolution", "8", "--recipe", "diagonal", "--video-fps", "0"]
    proc = subprocess.run(
        [sys.executable, "-m", "foldbot.cli", *args, "--camera-pose", str(cal), "--out", str(out)],
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert proc.returncode == 0, proc.stderr[-3000:]
    assert f"camera: perceived from {cal}" in proc.stdout
    result = json.loads((out / "result.json").read_text())
    camera = result["camera"]
    np.testing.assert_allclose(camera["T_world_camera"], true)
    np.testing.assert_allclose(camera["reported_T_world_camera"], found)
    assert camera["perceived_from"].startswith(str(cal))
    assert camera["calibration_error_mm"] == pytest.approx(5.0)
    seen = result["first_frame_keypoint_error_mm"]
    assert all(4.0 < e < 6.0 for e in seen.values()), seen
    assert result["success"] and result["coverage"] < 0.6


def test_a_fold_stopped_by_sigterm_leaves_nothing_behind(tmp_path):
    """`kill` (or `timeout`) stops a fold as Ctrl-C does: its staged episode folder is removed,
    nothing at --out, exit 143 (128 + SIGTERM)."""
    import signal
    import time

    out = tmp_path / "ep"
    proc = subprocess.Popen(
        [sys.executable, "-m", "foldbot.cli", "fold", "--resolution", "5", "--out", str(out)],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        env={**os.environ, "PYTHONWARNINGS": "ignore"},
    )
    deadline = time.monotonic() + 120
    while not list(tmp_path.glob(".ep.partial-*")) and time.monotonic() < deadline:
        assert proc.poll() is None, proc.communicate()
        time.sleep(0.05)
    assert list(tmp_path.glob(".ep.partial-*")), "the fold never staged its episode"
    time.sleep(0.5)  # into the episode: the cloth settling, the video open
    proc.send_signal(signal.SIGTERM)
    _, err = proc.communicate(timeout=120)
    assert proc.returncode == 128 + signal.SIGTERM, err[-2000:]
    assert "terminated (SIGTERM)" in err
    assert list(tmp_path.iterdir()) == []
