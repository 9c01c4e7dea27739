"""`foldbot ros-fold`, `ros-replay` and `export-bag`: clear errors before anything starts (these
run with or without ROS installed)."""

import argparse
import json
import os

import pytest
from calibration_files import write_calibration

from foldbot.cli import main
from foldbot.commands.ros_fold import add_arguments, fold_args_text
from foldbot.ros.node_args import parse_fold_args


@pytest.mark.parametrize(
    ("args", "needle"),
    [
        (["ros-fold", "--out", "{tmp}/e", "--perception", "oracle"], "vision (RGB-D) only"),
        (["ros-fold", "--out", "{tmp}/e", "--gui"], "--gui is not available over ROS"),
        (["ros-fold", "--out", "{tmp}/e", "--record", "{tmp}/run.txt"], "must name a .bag"),
        (["ros-fold", "--out", "{tmp}/e", "--resolution", "2"], "resolution"),
        (["ros-fold", "--out", "{tmp}/e", "--port", "0"], "--port"),
        (["ros-fold", "--out", "{tmp}/e", "--camera-rate", "-1"], "must be ≥ 0 frames per"),
        (
            ["ros-fold", "--out", "{tmp}/e", "--camera-rate", "0"],
            "--camera-rate 0 streams no frames for the video (--video-fps 10)",
        ),
        (
            ["ros-fold", "--out", "{tmp}/e", "--video-fps", "0", "--arm-interface", "actions"],
            "--arm-interface actions folds from the camera's stream",
        ),
        (
            ["ros-fold", "--out", "{tmp}/e", "--start", "crumpled", "--garment", "pants"],
            "start 'crumpled' is for towels",
        ),
        (
            ["ros-fold", "--out", "{tmp}/e", "--garment", "pants", "--garment-edge-length", "1"],
            "garment_edge_length must be in [0.005, 0.1] m, got 1.0",
        ),
        (
            [
                "ros-fold",
                "--out",
                "{tmp}/e",
                "--suite",
                "smoke",
                "--episode",
                "towel-half-oracle-open-s0000",
            ],
            "--perception 'oracle' is not available over ROS",
        ),
        (["ros-fold", "--out", "{tmp}/e", "--suite", "smoke", "--arms", "2"], "drop --arms"),
        (
            [
                "ros-fold",
                "--out",
                "{tmp}/e",
                "--arm-interface",
                "actions",
                "--real-time-factor",
                "0",
            ],
            "--real-time-factor must be > 0, got 0.0",
        ),
        (
            ["ros-fold", "--out", "{tmp}/e", "--cell", "real", "--arm-interface", "topics"],
            "--cell real: --arm-interface topics: a real cell is driven through its drivers' "
            "actions",
        ),
        (
            ["ros-fold", "--out", "{tmp}/e", "--cell", "real", "--real-time-factor", "2"],
            "a real cell runs at its own pace",
        ),
        (
            ["ros-fold", "--out", "{tmp}/e", "--cell", "real", "--camera-rate", "5"],
            "--cell real: --camera-rate: a real cell's camera streams at its own rate",
        ),
        (
            ["ros-fold", "--out", "{tmp}/e", "--master-wait", "5"],
            "--master-wait is for --cell real (with --cell sim, ros-fold starts its own master)",
        ),
        (
            ["ros-fold", "--out", "{tmp}/e", "--cell", "real", "--master-wait", "-1"],
            "--master-wait must be seconds in [0, 3600], got -1.0",
        ),
        (
            ["ros-fold", "--out", "{tmp}/e", "--cell", "real", "--master-wait", "inf"],
            "--master-wait must be seconds in [0, 3600], got inf",
        ),
        (
            ["ros-fold", "--out", "{tmp}/e", "--cell", "real", "--master-wait", "1e9"],
            "--master-wait must be seconds in [0, 3600], got 1000000000.0",
        ),
        (
            ["ros-fold", "--out", "{tmp}/e", "--real-time-factor", "2"],
            "--real-time-factor paces the simulated cell's drivers: it applies with "
            "--arm-interface actions (the topics interface runs in lockstep, as fast as it can); "
            "got --arm-interface topics",
        ),
        (
            ["ros-fold", "--out", "{tmp}/e", "--arms", "2", "--together-lead", "0.5"],
            "--together-lead is for two arms through their drivers (--arms 2 --arm-interface "
            "actions), got --arms 2 and --arm-interface topics",
        ),
        (
            ["ros-fold", "--out", "{tmp}/e", "--cell", "real", "--arms", "2"]
            + ["--together-lead", "-0.1"],
            "--together-lead must be seconds in [0, 5], got -0.1",
        ),
        (
            ["ros-fold", "--out", "{tmp}/e", "--cloth-thickness", "0.003"],
            "--cloth-thickness is for --cell real (with --cell sim, the simulated cloth's own",
        ),
        (
            ["ros-fold", "--out", "{tmp}/e", "--cell", "real", "--cloth-thickness", "0"],
            "--cloth-thickness must be metres in (0, 0.05], got 0.0",
        ),
        (
            ["ros-fold", "--out", "{tmp}/e", "--cell", "real", "--cloth-thickness", "nan"],
            "--cloth-thickness must be metres in (0, 0.05], got nan",
        ),
        (["ros-cell", "--camera-rate", "0"], "--camera-rate must be > 0 frames per s, got 0.0"),
        (["ros-cell", "--real-time-factor", "-1"], "--real-time-factor must be > 0, got -1.0"),
        (["ros-cell", "--port", "0"], "--port must be in 1–65535, got 0"),
        (["ros-cell", "--speed-scale", "0.5"], "--speed-scale 0.5 is the folding side's"),
        (
            ["ros-fold", "--out", "{tmp}/e", "--speed-scale", "0"],
            "speed_scale must be in [0.05, 1]",
        ),
        (
            ["ros-fold", "--out", "{tmp}/e", "--dry-run", "--start", "crumpled", "--arms", "2"],
            "--dry-run plans a crumpled towel's first flattening pull with one arm; two arms",
        ),
        (
            ["ros-fold", "--out", "{tmp}/e", "--dry-run", "--fault-slip", "0.3"],
            "--fault-slip act on a motion, and a dry run moves nothing",
        ),
        (
            ["ros-fold", "--out", "{tmp}/e", "--dry-run", "--confirm"],
            "--confirm asks before each motion, and --dry-run makes none",
        ),
        (
            ["ros-fold", "--out", "{tmp}/e", "--cell", "real", "--fault-slip", "0.3"],
            "--fault-slip: faults are the simulated cell's, injected on the cell ros-fold starts",
        ),
        (
            ["ros-fold", "--out", "{tmp}/e", "--cell", "real", "--fault-grasp-offset", "0.05"],
            "(--cell sim, through either arm interface); got --cell real",
        ),
        (["ros-fold", "--out", "{tmp}/e", "--fault-slip", "1.5"], "fault_slip must be in [0, 1)"),
        (
            ["ros-fold", "--out", "{tmp}/e", "--finger-travel", "0.003"],
            "--finger-travel: the fingers are watched for a slip through the drivers' actions",
        ),
        (
            ["ros-fold", "--out", "{tmp}/e", "--arm-interface", "actions", "--finger-travel", "0"],
            "--finger-travel must be > 0, got 0.0",
        ),
        (
            ["ros-fold", "--out", "{tmp}/e", "--gripper-effort", "40"],
            "--gripper-effort: the effort goes in the drivers' GripperCommand goals",
        ),
        (
            ["ros-fold", "--out", "{tmp}/e", "--arm-interface", "actions", "--gripper-effort"]
            + ["nan"],
            "--gripper-effort must be newtons in [0, 1000] (0: no limit), got nan",
        ),
        (
            ["ros-fold", "--out", "{tmp}/e", "--arm-interface", "actions", "--gripper-effort"]
            + ["-5"],
            "--gripper-effort must be newtons in [0, 1000] (0: no limit), got -5.0",
        ),
        (
            ["ros-fold", "--out", "{tmp}/e", "--arm-interface", "actions"]
            + ["--finger-joints", "finger_joint,,x"],
            "finger joints must be comma-separated joint names, 'none', or empty",
        ),
        (
            ["ros-cell", "--calibration-board", "right"],
            "--calibration-board right is for a two-arm cell (--arms 2)",
        ),
        (
            ["ros-calibrate", "--out", "{tmp}/e", "--arm", "right"],
            "--arm right is for a two-arm cell",
        ),
        (
            ["ros-calibrate", "--out", "{tmp}/e", "--views", "2"],
            "views must be an integer in [4, 12]",
        ),
        (["ros-calibrate", "--out", "{tmp}/e", "--board", "9x5"], "odd in all"),
        (["ros-calibrate", "--out", "{tmp}/e", "--port", "70000"], "--port must be in 1–65535"),
        (
            ["ros-calibrate", "--out", "{tmp}/e", "--master-wait", "inf"],
            "--master-wait must be seconds in [0, 3600], got inf",
        ),
        (
            ["ros-calibrate", "--out", "{tmp}/e", "--master-wait", "1e9"],
            "--master-wait must be seconds in [0, 3600], got 1000000000.0",
        ),
        (
            ["ros-check", "--out", "{tmp}/e", "--master-wait", "inf"],
            "--master-wait must be seconds in [0, 3600], got inf",
        ),
        (
            ["ros-check", "--out", "{tmp}/e", "--master-wait", "nan"],
            "--master-wait must be seconds in [0, 3600], got nan",
        ),
        (["ros-check", "--out", "{tmp}/e", "--port", "0"], "--port must be in 1–65535, got 0"),
        (["ros-replay", "{tmp}/missing.bag", "--rate", "0"], "--rate"),
        (
            ["ros-replay", "{tmp}/missing.bag", "--rate", "inf"],
            "--rate must be a play rate in [0.01, 100] (1: as recorded), got inf",
        ),
        (
            ["ros-replay", "{tmp}/missing.bag", "--rate", "1e-6"],
            "--rate must be a play rate in [0.01, 100] (1: as recorded), got 1e-06",
        ),
        (
            ["ros-replay", "{tmp}/missing.bag", "--port", "70000"],
            "--port must be in 1–65535, got 70000",
        ),
        (["ros-replay", "{tmp}/missing.bag", "--port", "0"], "--port must be in 1–65535, got 0"),
        (["export-bag", "{tmp}", "--out", "{tmp}/x.txt"], "must end in .bag"),
    ],
)
def test_bad_input_is_named(args, needle, tmp_path, capsys, no_launch):
    code = main([a.replace("{tmp}", str(tmp_path)) for a in args])
    assert code == 2
    err = capsys.readouterr().err
    assert needle in err
    assert not (tmp_path / "e").exists()


@pytest.mark.parametrize("command", [["ros-fold", "--out", "{tmp}/e"], ["ros-cell"]])
def test_a_layout_the_cell_cannot_start_in_is_named_before_anything_launches(
    command, tmp_path, capsys, no_launch
):
    # A lamp 32 cm over the workspace, where the arm's home holds its gripper: the nodes would
    # refuse it as they start, and the launch would end unexplained.
    layout = tmp_path / "lamp.toml"
    layout.write_text(
        '[[obstacles]]\nname = "lamp"\ncenter_xyz = [0.55, 0.10, 1.10]\n'
        "size_xyz = [0.30, 0.30, 0.08]\n"
    )
    args = [a.replace("{tmp}", str(tmp_path)) for a in command]
    assert main([*args, "--layout", str(layout)]) == 2
    err = capsys.readouterr().err
    assert "error: the arm's home posture meets an obstacle of the layout" in err
    assert "obstacle 'lamp'" in err and not (tmp_path / "e").exists()


@pytest.mark.parametrize(
    ("args", "needle"),
    [
        (
            ["ros-fold", "--out", "{tmp}/afile"],
            "episode output '{tmp}/afile' exists and is not a folder; allowed: a new path, an "
            "empty folder, or a previous episode folder",
        ),
        (
            ["ros-fold", "--out", "{tmp}/afile/e"],
            "cannot create the parent folder of episode output '{tmp}/afile/e'",
        ),
        (
            ["ros-fold", "--out", "{tmp}/junk", "--overwrite"],
            "episode output '{tmp}/junk' is a non-empty folder that is not a foldbot episode",
        ),
        (
            ["ros-fold", "--out", "{tmp}/episode"],
            "--out {tmp}/episode already holds an episode; pass --overwrite to replace it",
        ),
        (  # a plan beside an episode's result.json would read as that episode's
            ["ros-fold", "--dry-run", "--out", "{tmp}/episode", "--overwrite"],
            "--out {tmp}/episode is a non-empty folder that holds no dry run (plan.json)",
        ),
        (  # a real cell's earlier fold: result.json unscored, no cloth.npz
            ["ros-fold", "--cell", "real", "--out", "{tmp}/real"],
            "--out {tmp}/real already holds an episode; pass --overwrite to replace it",
        ),
        (
            ["ros-fold", "--out", "{tmp}/e", "--record", "{tmp}/afile/run.bag"],
            "--record {tmp}/afile/run.bag: '{tmp}/afile' is a file, not a folder",
        ),
        (
            ["ros-fold", "--out", "{tmp}/e", "--record", "{tmp}/afile/sub/run.bag"],
            "--record {tmp}/afile/sub/run.bag: cannot write a bag in '{tmp}/afile/sub' (Not a "
            "directory); allowed: a .bag path in a folder that can be written",
        ),
        (
            ["ros-fold", "--out", "{tmp}/e", "--record", "{tmp}/folder.bag", "--overwrite"],
            "--record {tmp}/folder.bag is a folder; allowed: a .bag file's path",
        ),
        (["ros-check", "--out", "{tmp}/afile"], "--out {tmp}/afile exists and is not a folder"),
        (
            ["ros-calibrate", "--out", "{tmp}/afile"],
            "--out {tmp}/afile exists and is not a folder",
        ),
    ],
)
def test_an_output_that_cannot_be_written_is_named_before_anything_starts(
    args, needle, tmp_path, capsys, no_launch
):
    """An --out or --record the run could not write is refused up front (ros-check and
    ros-calibrate: before the master is waited for), as `foldbot fold` refuses it, and the
    check leaves nothing behind."""
    (tmp_path / "afile").write_text("not a folder")
    (tmp_path / "junk").mkdir()
    (tmp_path / "junk" / "notes.txt").write_text("not an episode")
    (tmp_path / "episode").mkdir()
    (tmp_path / "episode" / "result.json").write_text("{}")
    (tmp_path / "episode" / "cloth.npz").write_bytes(b"")
    (tmp_path / "real").mkdir()
    (tmp_path / "real" / "result.json").write_text('{"scored": false}')
    (tmp_path / "folder.bag").mkdir()
    before = sorted(tmp_path.rglob("*"))
    code = main([a.replace("{tmp}", str(tmp_path)) for a in args])
    assert code == 2
    assert needle.replace("{tmp}", str(tmp_path)) in capsys.readouterr().err
    assert sorted(tmp_path.rglob("*")) == before


def test_a_real_cells_earlier_fold_is_replaced_with_overwrite(tmp_path):
    # Its folder has no cloth.npz (no ground truth): with --overwrite it is an episode to
    # replace, as a scored one is, not "a folder that is not a foldbot episode".
    from foldbot.commands.ros_fold import check_episode_output

    out = tmp_path / "real"
    out.mkdir()
    (out / "result.json").write_text('{"scored": false}')
    (out / "overlay_final.png").write_bytes(b"png")
    check_episode_output(out, overwrite=True)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["real"]  # the probe left nothing


@pytest.mark.parametrize("option", ["--out", "--record"])
def test_an_empty_output_path_is_refused(option, tmp_path, capsys, no_launch):
    """An empty --out (or --record) is not taken as the current folder."""
    args = ["ros-fold", "--out", str(tmp_path / "e"), option, ""]
    with pytest.raises(SystemExit) as exit_:
        main(args)
    assert exit_.value.code == 2
    err = capsys.readouterr().err
    assert f"argument {option}: " in err and "got ''" in err  # io.staging.output_path's words
    assert list(tmp_path.iterdir()) == []


def test_the_bags_folder_is_checked_and_left_as_it_was(tmp_path):
    """--record's folder is made where missing and written in once (a probe file, removed)."""
    from foldbot.commands.ros_fold import check_bag_target
    from foldbot.errors import ConfigError, OutputError

    check_bag_target(tmp_path / "new" / "deep" / "run.bag", overwrite=False)
    assert (tmp_path / "new" / "deep").is_dir()
    assert list((tmp_path / "new" / "deep").iterdir()) == []
    (tmp_path / "run.bag").write_bytes(b"old")
    with pytest.raises(OutputError, match="already exists; pass --overwrite"):
        check_bag_target(tmp_path / "run.bag", overwrite=False)
    check_bag_target(tmp_path / "run.bag", overwrite=True)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["new", "run.bag"]
    with pytest.raises(ConfigError, match=r"must name a \.bag file"):
        check_bag_target(tmp_path / "run.txt", overwrite=False)


def test_a_bag_the_recorder_did_not_write_is_no_success(tmp_path):
    """After the run, `bag recorded` only where the recorder left its bag: not where it wrote
    none, left it unfinished, or left the bag --overwrite was to replace as it was."""
    from foldbot.commands.ros_fold import check_bag_recorded, file_stamp
    from foldbot.errors import FoldbotError

    bag = tmp_path / "run.bag"
    with pytest.raises(FoldbotError) as none:
        check_bag_recorded(bag, None)
    assert str(none.value) == (
        f"--record {bag}: no bag was recorded (rosbag record failed: see its output above)"
    )
    (tmp_path / "run.bag.active").write_bytes(b"cut short")
    with pytest.raises(
        FoldbotError, match=r"left .*run\.bag\.active unfinished \(`rosbag reindex`"
    ):
        check_bag_recorded(bag, None)
    bag.write_bytes(b"old bag")
    old = file_stamp(bag)
    with pytest.raises(FoldbotError, match="no bag was recorded"):
        check_bag_recorded(bag, old)  # --overwrite's old bag, not replaced
    check_bag_recorded(bag, None)  # a new bag
    os.utime(bag, ns=(old + 10**9, old + 10**9))  # the old one, written over by the run
    check_bag_recorded(bag, old)


def write_bag(path, states, seconds=1.0):
    """A bag as ros-fold --record leaves one, in brief: /cloth/state messages (`states`, each
    as published) and a frame's camera topics at stamp 1 s, spanning `seconds`."""
    import rosbag
    import rospy
    from sensor_msgs.msg import CameraInfo, Image
    from std_msgs.msg import String

    with rosbag.Bag(str(path), "w") as bag:
        start = rospy.Time(1)
        for topic, msg in (
            ("/camera/color/image_raw", Image()),
            ("/camera/color/camera_info", CameraInfo()),
            ("/camera/depth/image_raw", Image()),
        ):
            msg.header.stamp = start
            bag.write(topic, msg, start)
        for text in states:
            bag.write("/cloth/state", String(data=text), start)
        bag.write("/cloth/state", String(data=states[-1]), start + rospy.Duration(seconds))


def ros_is_missing():
    from foldbot.commands.ros_fold import ros_missing

    return ros_missing()


STATE = json.dumps({"stamp": 1.0, "detected": True, "keypoints": {}})


@pytest.mark.skipif(ros_is_missing() is not None, reason="needs ROS 1")
@pytest.mark.parametrize(
    ("make", "needle"),
    [
        (
            lambda bag: bag.write_bytes(b"garbage!"),
            "{bag} is not a ROS bag that can be read (This does not appear to be a bag file); "
            "ros-replay plays a bag recorded by `foldbot ros-fold --record`",
        ),
        (
            lambda bag: bag.write_bytes(b""),
            "{bag} is not a ROS bag that can be read (empty file)",
        ),
        (
            lambda bag: (write_bag(bag, [STATE]), bag.write_bytes(bag.read_bytes()[:3000])),
            "{bag} is a bag without its index (a recording cut short): `rosbag reindex {bag}`",
        ),
        (
            lambda bag: write_bag(bag, ["{not json"]),
            "{bag}: a /cloth/state message is not a foldbot perception node's state "
            "(JSONDecodeError",
        ),
        (
            lambda bag: write_bag(bag, [json.dumps({"detected": True})]),
            "{bag}: a /cloth/state message is not a foldbot perception node's state (KeyError",
        ),
        (
            lambda bag: write_bag(bag, [STATE], seconds=12.0),
            "{bag} spans 12.0 s: at --rate 0.01 it would play for 1200 s, more than the 600 s a "
            "replay is given; pass a --rate of at least 0.02",
        ),
    ],
)
def test_a_bag_ros_replay_cannot_play_is_named(make, needle, tmp_path, capsys, no_launch):
    """A file that is no bag, an empty one, one cut short, one whose /cloth/state is not
    perception's, or one that would play for too long at --rate: named, exit code 2, before
    roscore or a node starts."""
    bag = tmp_path / "run.bag"
    make(bag)
    assert main(["ros-replay", str(bag), "--rate", "0.01"]) == 2
    assert needle.replace("{bag}", str(bag)) in capsys.readouterr().err


def test_export_of_a_folder_that_is_no_episode_names_it(tmp_path, capsys):
    (tmp_path / "ep").mkdir()
    assert main(["export-bag", str(tmp_path / "ep"), "--out", str(tmp_path / "x.bag")]) == 2
    assert f"{str(tmp_path / 'ep')!r} is not an episode folder; it must contain result.json" in (
        capsys.readouterr().err
    )
    assert not (tmp_path / "x.bag").exists()


def test_fold_options_reach_the_nodes():
    parser = argparse.ArgumentParser()
    add_arguments(parser)
    words = fold_args_text(parser.parse_args(["--out", "e"])).split()
    assert not {"--odd-grid", "--width", "--resolution"} & set(words)  # the nodes' defaults
    towel = ["--no-odd-grid", "--width", "0.28", "--resolution", "9", "--max-vertices", "60"]
    words = fold_args_text(parser.parse_args(["--out", "e", *towel])).split()
    assert all(word in words for word in towel)
    text = fold_args_text(parser.parse_args(["--out", "e", "--garment", "tshirt"]))
    # A garment gets no towel option, which its fold would refuse.
    assert parse_fold_args(text)[1].garment == "tshirt"


def test_a_layout_file_reaches_the_nodes_by_its_absolute_path(tmp_path, monkeypatch):
    (tmp_path / "cell.toml").write_text("table_height = 0.75\n")
    monkeypatch.chdir(tmp_path)  # the nodes run in another folder: the path is made absolute
    parser = argparse.ArgumentParser()
    add_arguments(parser)
    words = fold_args_text(parser.parse_args(["--out", "e", "--layout", "cell.toml"])).split()
    assert words[words.index("--layout") + 1] == str(tmp_path / "cell.toml")
    assert "--layout" not in fold_args_text(parser.parse_args(["--out", "e"])).split()


def test_a_crumpled_start_reaches_the_nodes():
    parser = argparse.ArgumentParser()
    add_arguments(parser)
    words = fold_args_text(parser.parse_args(["--out", "e", "--start", "crumpled"])).split()
    assert words[words.index("--start") + 1] == "crumpled"


def test_the_arm_count_reaches_the_nodes():
    parser = argparse.ArgumentParser()
    add_arguments(parser)
    for arms in ("1", "2"):
        words = fold_args_text(parser.parse_args(["--out", "e", "--arms", arms])).split()
        assert words[words.index("--arms") + 1] == arms


def test_garment_options_reach_the_nodes():
    parser = argparse.ArgumentParser()
    add_arguments(parser)
    args = ["--out", "e", "--garment", "tshirt", "--garment-edge-length", "0.03"]
    words = fold_args_text(parser.parse_args([*args, "--park", "out_of_view"])).split()
    # A garment's own default recipe, its mesh and the park pose reach every node.
    assert words[words.index("--recipe") + 1] == "retail"
    assert words[words.index("--garment-edge-length") + 1] == "0.03"
    assert words[words.index("--park") + 1] == "out_of_view"


def test_the_nodes_take_a_two_arm_crumpled_start():
    # The two-arm cell flattens by spreads over ROS too (the planner node plans them).
    from foldbot.ros.node_args import parse_fold_args

    _args, cfg = parse_fold_args("--out e --start crumpled --arms 2")
    assert cfg.start == "crumpled" and cfg.arms == 2


def test_the_nodes_get_the_loop_options():
    # The task node builds its loop from the same options (pipeline.loop_config).
    from foldbot.pipeline import loop_config
    from foldbot.ros.node_args import parse_fold_args

    _args, cfg = parse_fold_args("--out e --garment pants --loop-option top_layer_first=false")
    assert loop_config(cfg).top_layer_first is False


def test_ros_fold_hands_the_nodes_every_option_that_shapes_the_episode(tmp_path):
    """The nodes parse the options ros-fold passes them (fold_args_text): with every episode
    option set away from its default, their EpisodeConfig is the one `foldbot fold` builds."""
    import argparse

    from foldbot.commands import fold, ros_fold
    from foldbot.ros.node_args import parse_fold_args

    parser = argparse.ArgumentParser()
    ros_fold.add_arguments(parser)
    args = parser.parse_args(
        [
            *("--out", str(tmp_path / "e"), "--garment", "towel", "--recipe", "quarter"),
            *("--robot", "panda", "--start", "flat", "--park", "out_of_view", "--arms", "2"),
            *("--seed", "7", "--replicate", "3", "--width", "0.33", "--height", "0.27"),
            *("--resolution", "11", "--no-odd-grid", "--mass", "0.2", "--time-step", "0.002"),
            *("--max-vertices", "100", "--speed-scale", "0.4"),
            *("--jaw-catch", "surface", "--video-fps", "0"),
            *("--loop-option", "stack_edge_carry=false", "--loop-option", "pair_descent=0.02"),
            *("--cloth", "friction=0.8", "--cloth", "margin_divisor=6.5"),
            *("--fault-slip", "0.3", "--fault-grasp-offset", "0.05"),
        ]
    )
    _node_args, node_cfg = parse_fold_args(ros_fold.fold_args_text(args))
    assert node_cfg == fold.config_from_args(args)
    assert (node_cfg.fault_slip, node_cfg.fault_grasp_offset) == (0.3, 0.05)
    assert node_cfg.replicate == 3 and node_cfg.jaw_catch == "surface"
    assert node_cfg.towel.max_vertices == 100 and node_cfg.motion.speed_scale == 0.4
    assert node_cfg.loop_options == {"stack_edge_carry": False, "pair_descent": 0.02}
    assert (node_cfg.cloth.mass, node_cfg.cloth.friction) == (0.2, 0.8)
    assert node_cfg.cloth.margin_divisor == 6.5


def test_ros_fold_hands_the_nodes_the_flatten_options(tmp_path):
    """A crumpled start's flatten options reach the nodes' EpisodeConfig (the task node
    flattens by flatten_options.flatten_configs of it, as `foldbot fold` does)."""
    import argparse

    from foldbot.commands import fold, ros_fold
    from foldbot.flatten_options import flatten_configs
    from foldbot.ros.node_args import parse_fold_args

    parser = argparse.ArgumentParser()
    ros_fold.add_arguments(parser)
    args = parser.parse_args(
        [
            *("--out", str(tmp_path / "e"), "--start", "crumpled", "--arms", "2"),
            *("--flatten-option", "finish_coverage=none"),
            *("--flatten-option", "spread_lay_speed=0.05"),
        ]
    )
    _node_args, node_cfg = parse_fold_args(ros_fold.fold_args_text(args))
    assert node_cfg == fold.config_from_args(args)
    assert node_cfg.flatten_options == {"finish_coverage": None, "spread_lay_speed": 0.05}
    pulls, spreads = flatten_configs(node_cfg.flatten_options)
    assert pulls.finish_coverage is None and spreads.lay_speed == 0.05


def test_a_replay_that_misses_frames_says_where_to_look():
    from foldbot.commands.ros_replay import report_lines
    from foldbot.ros.replay import ReplayReport

    held = report_lines(ReplayReport(1, 0, 0.0, True, True))
    assert held[0].startswith("replayed 0 of 1 frames")
    assert "gave no keypoints for 1 frame(s)" in held[1] and "depth camera_info" in held[1]
    assert held[-1] == "NOT the same as the live run"
    same = report_lines(ReplayReport(5, 5, 0.0, True, True))
    assert len(same) == 2 and same[-1] == "same keypoints as the live run"


def test_ros_fold_hands_the_nodes_a_suite_episode(tmp_path, monkeypatch):
    """`ros-fold --suite NAME --seed N` gives the nodes the suite's file by its absolute path
    (they run in another folder) and the options that pick the episode: their EpisodeConfig is
    the one `foldbot fold --suite` builds, the suite's drawn towel size among it."""
    import argparse

    from foldbot.commands import fold, ros_fold
    from foldbot.ros.node_args import parse_fold_args

    parser = argparse.ArgumentParser()
    ros_fold.add_arguments(parser)
    out = str(tmp_path / "e")
    args = parser.parse_args(["--out", out, "--suite", "towel_crumpled_two_arms", "--seed", "5"])
    text = ros_fold.fold_args_text(args)
    monkeypatch.chdir(tmp_path)  # where suites/ is not
    _node_args, node_cfg = parse_fold_args(text)
    assert node_cfg == fold.config_from_args(args)
    assert node_cfg.towel_size_range == (0.25, 0.45) and node_cfg.cloth.layer_friction == 0.25
    args = parser.parse_args(["--out", out, "--suite", "smoke", "--episode",
                              "towel-half-vision-open-s0000", "--video-fps", "2"])  # fmt: skip
    _node_args, node_cfg = parse_fold_args(ros_fold.fold_args_text(args))
    assert node_cfg == fold.config_from_args(args) and not node_cfg.closed_loop
    # So do the faults a suite's episode is tried with.
    args = parser.parse_args(["--out", out, "--suite", "towel_loop", "--seed", "3", "--recipe", "half",
                              "--fault-slip", "0.3"])  # fmt: skip
    _node_args, node_cfg = parse_fold_args(ros_fold.fold_args_text(args))
    assert node_cfg == fold.config_from_args(args) and node_cfg.fault_slip == 0.3
    # Options set over the suite's own reach the nodes too.
    args = parser.parse_args(["--out", out, "--suite", "towel_crumpled_two_arms", "--seed", "5",
                              "--flatten-option", "spread_hang_time=0.8"])  # fmt: skip
    _node_args, node_cfg = parse_fold_args(ros_fold.fold_args_text(args))
    assert node_cfg == fold.config_from_args(args)
    assert dict(node_cfg.flatten_options) == {"spread_hang_time": 0.8}


def test_a_real_cells_master_is_the_environments_unless_a_port_is_given(monkeypatch):
    """`ros-fold --cell real` joins the running cell's master: ROS_MASTER_URI as the shell
    has it (a real robot's master may be another machine), or the local --port asked for."""
    from foldbot.commands.ros_fold import ros_env

    monkeypatch.setenv("ROS_MASTER_URI", "http://robot-pc:11311")
    assert ros_env(None)["ROS_MASTER_URI"] == "http://robot-pc:11311"
    assert ros_env(12345)["ROS_MASTER_URI"] == "http://localhost:12345"
    monkeypatch.delenv("ROS_MASTER_URI")
    assert ros_env(None)["ROS_MASTER_URI"] == "http://localhost:11311"


def test_ros_cell_lays_the_cloth_ros_fold_would(tmp_path):
    """`ros-cell` takes `foldbot fold`'s cloth options but no episode folder: the sim node it
    starts builds the EpisodeConfig `ros-fold` would hand it for the same options."""
    from foldbot.commands import ros_cell, ros_fold
    from foldbot.ros.node_args import parse_fold_args

    cell_parser, fold_parser = argparse.ArgumentParser(), argparse.ArgumentParser()
    ros_cell.add_arguments(cell_parser)
    ros_fold.add_arguments(fold_parser)
    options = ["--seed", "4", "--width", "0.28", "--resolution", "9", "--cloth", "friction=0.8"]
    with pytest.raises(SystemExit):  # no episode folder to name
        cell_parser.parse_args([*options, "--out", str(tmp_path)])
    cell_args = cell_parser.parse_args(options)
    cell_args.out = tmp_path / "unused"
    fold_args = fold_parser.parse_args([*options, "--out", str(tmp_path / "unused")])
    assert (
        parse_fold_args(fold_args_text(cell_args))[1]
        == parse_fold_args(fold_args_text(fold_args))[1]
    )


def test_ros_cell_names_the_options_only_the_fold_reads():
    # The same options go to the cell and to `ros-fold --cell real`; those only the folding
    # side reads are named (and ignored) by the cell, not silently dropped.
    from foldbot.commands import ros_cell

    parser = argparse.ArgumentParser()
    ros_cell.add_arguments(parser)
    assert ros_cell.folding_options_given(parser.parse_args(["--resolution", "5"])) == []
    args = ["--recipe", "quarter", "--flatten-option", "finish_coverage=none", "--video-fps", "0"]
    given = ros_cell.folding_options_given(parser.parse_args([*args, "--seed", "3"]))
    assert given == ["--recipe", "--flatten-option", "--video-fps"]


def test_the_gripper_lead_is_seconds_or_off(capsys):
    from foldbot.commands.ros_fold import gripper_lead

    assert gripper_lead("0.05") == 0.05 and gripper_lead("0") == 0.0
    assert gripper_lead("off") is None and gripper_lead(" OFF ") is None
    with pytest.raises(SystemExit):
        main(["ros-fold", "--out", "unused", "--gripper-lead", "2"])
    assert "--gripper-lead: must be seconds in [0, 1] or off, got '2'" in capsys.readouterr().err


def test_a_calibration_reaches_the_simulated_cells_nodes(tmp_path, monkeypatch):
    """`ros-fold --camera-pose` on the simulated cell, and `ros-cell --camera-pose`: the sim node
    places its camera as `foldbot fold --camera-pose` does (the calibration's absolute path, the
    nodes running elsewhere), so the pose it publishes is the calibration's; on a real cell the
    calibration is published instead and no node builds a camera from it."""
    from foldbot.commands import fold, ros_cell, ros_fold
    from foldbot.ros.node_args import parse_fold_args

    write_calibration(tmp_path / "calibration.json")
    monkeypatch.chdir(tmp_path)
    fold_parser, cell_parser, plain = (argparse.ArgumentParser() for _ in range(3))
    ros_fold.add_arguments(fold_parser)
    ros_cell.add_arguments(cell_parser)
    fold.add_arguments(plain)
    options = ["--resolution", "9", "--camera-pose", "calibration.json"]
    absolute = ["--resolution", "9", "--camera-pose", str(tmp_path / "calibration.json")]
    expected = fold.config_from_args(plain.parse_args([*absolute, "--out", "e"]))
    assert expected.camera.reported_pose is not None
    args = fold_parser.parse_args([*options, "--out", "e"])
    args.camera_calibration = args.camera_pose  # as ros_fold.run sets it for the sim cell
    words = fold_args_text(args).split()
    assert words[words.index("--camera-pose") + 1] == str(tmp_path / "calibration.json")
    assert parse_fold_args(fold_args_text(args))[1].camera == expected.camera
    cell_args = cell_parser.parse_args(options)
    cell_args.out = tmp_path / "unused"
    assert parse_fold_args(fold_args_text(cell_args))[1].camera == expected.camera
    real = fold_parser.parse_args([*options, "--out", "e", "--cell", "real"])
    real.camera_calibration = None  # ros_fold.run: a real cell's camera is where it is
    assert "--camera-pose" not in fold_args_text(real).split()


def test_the_driver_options_reach_roslaunch_only_where_given():
    from foldbot.commands.ros_fold import check_finger_watch

    parser = argparse.ArgumentParser()
    add_arguments(parser)
    args = parser.parse_args(["--out", "e"])
    assert check_finger_watch(args, "actions") == []  # the launch file's defaults
    given = ["--finger-joints", "finger_joint", "--finger-travel", "0.02", "--gripper-effort", "40"]
    args = parser.parse_args(["--out", "e", *given])
    assert check_finger_watch(args, "actions") == [
        "finger_joints:=finger_joint",
        "finger_travel:=0.02",
        "gripper_effort:=40.0",
    ]


def test_finger_joints_are_the_robots_none_or_named():
    from foldbot.ros.node_args import finger_joint_names

    robot = ("left_finger_joint", "right_finger_joint")
    assert finger_joint_names("", robot) == robot
    assert finger_joint_names("none", robot) == ()
    assert finger_joint_names("finger_joint", robot) == ("finger_joint",)
    assert finger_joint_names("a, b", robot) == ("a", "b")


def test_finger_travel_is_given_or_a_quarter_of_the_cloth_for_the_robots_fingers():
    """A slip closes each of the robot model's fingers by half the gap the cloth held open:
    the default watch counts a quarter of the cloth's thickness (at most 2 mm), so a towel
    thinner than 8 mm is not missed; another gripper's joints (units unknown) keep 0.002."""
    from foldbot.ros.node_args import SLIP_FINGER_TRAVEL, finger_travel_for

    assert finger_travel_for(0.004, "", 0.003) == (0.004, "given")
    assert finger_travel_for(None, "", 0.003) == (pytest.approx(0.00075), "cloth thickness")
    assert finger_travel_for(None, "", 0.0089) == (SLIP_FINGER_TRAVEL, "cloth thickness")
    assert finger_travel_for(None, "finger_joint", 0.003) == (SLIP_FINGER_TRAVEL, "default")
    assert finger_travel_for(0.02, "finger_joint", 0.003) == (0.02, "given")
