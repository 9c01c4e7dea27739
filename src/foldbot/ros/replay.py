"""Replay a recorded fold through a fresh perception node and compare its keypoints with the
ones the live run published (recorded in the same bag on cloth/state), frame by frame."""

from __future__ import annotations

import json
import math
import os
import subprocess
import sys
import threading
import time
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from foldbot.errors import ConfigError, FoldbotError
from foldbot.ros import SYNC_SLOP_S

INPUT_TOPICS = (
    "/tf_static",
    "/camera/color/image_raw",
    "/camera/color/camera_info",
    "/camera/depth/image_raw",
)
"""What a frame needs to be replayed (after /tf_static)."""

PLAYED_TOPICS = (*INPUT_TOPICS, "/camera/depth/camera_info")
"""What is played to the perception node: the inputs and, where the bag holds it, the depth
camera's own camera_info (a depth sensor beside the colour one is registered onto it)."""


MIN_RATE, MAX_RATE = 0.01, 100.0
"""The `rosbag play` rates a replay takes (1: as recorded)."""
PLAY_TIMEOUT_S = 600.0
"""The longest a replay's `rosbag play` may take (the bag's span over the rate)."""

SURE_CONFIDENCE = 0.5
"""A keypoint the live run perceived at this confidence or more counts as one it was sure of."""


@dataclass
class ReplayReport:
    """How the replayed keypoints compare with the live run's."""

    frames_in_bag: int
    frames_compared: int
    max_keypoint_difference_m: float
    labels_equal: bool
    detected_equal: bool
    max_sure_difference_m: float = 0.0
    """The largest difference over the keypoints the live run was sure of (confidence ≥
    SURE_CONFIDENCE): where a camera other than the recorded one (another encoding, rounded
    depth) still has to agree; a corner the gripper hides moves with any change."""

    @property
    def same(self) -> bool:
        return (
            self.frames_compared == self.frames_in_bag
            and self.labels_equal
            and self.detected_equal
            and self.max_keypoint_difference_m <= 1e-9
        )


def check_rate(rate: float) -> None:
    """ConfigError unless `rate` is a play rate in [MIN_RATE, MAX_RATE]."""
    if not (math.isfinite(rate) and MIN_RATE <= rate <= MAX_RATE):
        raise ConfigError(
            f"--rate must be a play rate in [{MIN_RATE:g}, {MAX_RATE:g}] (1: as recorded), "
            f"got {rate!r}"
        )


@contextmanager
def read_bag(bag_path: Path) -> Iterator[Any]:
    """The bag at `bag_path` (a rosbag.Bag), open for reading; FoldbotError naming the file
    where rosbag cannot read it (not a bag, an empty file, a recording cut short)."""
    import genpy
    import rosbag

    try:
        with rosbag.Bag(str(bag_path)) as bag:
            yield bag
    except rosbag.ROSBagUnindexedException:
        raise FoldbotError(
            f"{bag_path} is a bag without its index (a recording cut short): `rosbag reindex "
            f"{bag_path}` may recover it"
        ) from None
    except (rosbag.ROSBagException, genpy.DeserializationError, OSError) as exc:
        raise FoldbotError(
            f"{bag_path} is not a ROS bag that can be read ({exc}); ros-replay plays a bag "
            "recorded by `foldbot ros-fold --record`"
        ) from None


def recorded_states(bag_path: Path) -> dict[float, dict]:
    """The live run's perception outputs in the bag, by frame stamp, for the frames whose
    images and camera_info the bag holds; FoldbotError naming the file where it is no bag
    rosbag reads or its /cloth/state is not perception's."""
    out, inputs = {}, {t: set() for t in INPUT_TOPICS[1:]}
    with read_bag(bag_path) as bag:
        for topic, msg, _t in bag.read_messages(topics=["/cloth/state", *INPUT_TOPICS[1:]]):
            if topic == "/cloth/state":
                try:
                    d = json.loads(msg.data)
                    out[round(d["stamp"], 6)] = d
                except (ValueError, TypeError, KeyError) as exc:
                    raise FoldbotError(
                        f"{bag_path}: a /cloth/state message is not a foldbot perception "
                        f"node's state ({type(exc).__name__}: {exc})"
                    ) from None
            else:
                inputs[topic].add(round(msg.header.stamp.to_sec(), 6))
    # Only frames whose inputs the bag holds can be replayed (the recorder may join late); a real
    # camera's depth may be stamped a few milliseconds from its colour (the node pairs them).
    stamps = {t: np.array(sorted(s)) for t, s in inputs.items()}

    def has(topic: str, stamp: float) -> bool:
        a = stamps[topic]
        i = int(np.searchsorted(a, stamp))
        near = a[max(i - 1, 0) : i + 1]
        return near.size > 0 and float(np.abs(near - stamp).min()) <= SYNC_SLOP_S + 1e-9

    return {k: v for k, v in out.items() if all(has(t, k) for t in stamps)}


def recorded_garment(states: dict[float, dict]) -> str:
    """The garment the live run perceived, from its keypoint names (a towel's corners, or a
    T-shirt's / pants' named keypoints), so the replay runs the same estimator."""
    from foldbot.garments.pants import PANTS_KEYPOINTS
    from foldbot.garments.tshirt import TSHIRT_KEYPOINTS

    seen = {label for d in states.values() for label in d["keypoints"]}
    for garment, names in (("tshirt", TSHIRT_KEYPOINTS), ("pants", PANTS_KEYPOINTS)):
        if seen & set(names):
            return garment
    return "towel"


def recorded_fixtures(states: dict[float, dict]) -> list[dict]:
    """The cell's fixtures the live run's perception masked (layout `[[obstacles]]` tables, as
    its states name them), so the replay masks the same."""
    for d in states.values():
        if d.get("fixtures"):
            return list(d["fixtures"])
    return []


def recorded_seconds(bag_path: Path) -> float:
    """The seconds the bag's messages span (0 for one with none)."""
    with read_bag(bag_path) as bag:
        if bag.get_message_count() == 0:
            return 0.0
        return float(bag.get_end_time() - bag.get_start_time())


def _start(cmd: list[str], env: dict, log) -> subprocess.Popen:
    return subprocess.Popen(cmd, env=env, stdout=log, stderr=subprocess.STDOUT)


def replay(
    bag_path: str | Path, port: int, rate: float = 1.0, timeout: float = PLAY_TIMEOUT_S
) -> ReplayReport:
    """Start roscore (if none on `port`), the perception node and `rosbag play` at `rate`;
    collect the node's cloth/state for every frame and compare with the recorded ones. Bad
    input (a port outside 1–65535, a rate outside [MIN_RATE, MAX_RATE], a file that is no bag
    of a recorded fold, one that would play for longer than `timeout` s) is refused
    (FoldbotError) before anything starts."""
    from foldbot.commands.ros_fold import ROS_PACKAGE_DIR, check_port, ros_env

    check_port(port)
    check_rate(rate)
    bag_path = Path(bag_path)
    if not bag_path.is_file():
        raise FoldbotError(f"no bag at {bag_path}")
    live = recorded_states(bag_path)
    if not live:
        raise FoldbotError(
            f"{bag_path} holds no /cloth/state messages (record a run with --record)"
        )
    seconds = recorded_seconds(bag_path)
    if seconds / rate > timeout:
        raise ConfigError(
            f"{bag_path} spans {seconds:.1f} s: at --rate {rate:g} it would play for "
            f"{seconds / rate:.0f} s, more than the {timeout:g} s a replay is given; pass a "
            f"--rate of at least {seconds / timeout:.3g}"
        )
    env = ros_env(port)
    os.environ.update({k: env[k] for k in ("ROS_MASTER_URI", "ROS_HOSTNAME", "ROS_PACKAGE_PATH")})
    import rosgraph
    import rospy
    from std_msgs.msg import String

    procs: list[subprocess.Popen] = []
    log = open(os.devnull, "w")  # noqa: SIM115 - closed in finally
    try:
        if not rosgraph.is_master_online(env["ROS_MASTER_URI"]):
            procs.append(_start(["roscore", "-p", str(port)], env, log))
            deadline = time.monotonic() + 30
            while not rosgraph.is_master_online(env["ROS_MASTER_URI"]):
                if time.monotonic() > deadline:
                    raise FoldbotError(f"roscore did not come up on port {port}")
                time.sleep(0.2)
        node = ROS_PACKAGE_DIR / "foldbot_ros" / "nodes" / "perception_node"
        procs.append(
            _start(
                [
                    sys.executable,
                    str(node),
                    "__name:=foldbot_perception_replay",
                    f"_garment:={recorded_garment(live)}",
                    f"_fixtures:={json.dumps(recorded_fixtures(live))}",
                ],
                env,
                sys.stderr,
            )
        )
        replayed: dict[float, dict] = {}
        lock = threading.Lock()

        def on_state(msg: String) -> None:
            d = json.loads(msg.data)
            with lock:
                replayed[round(d["stamp"], 6)] = d

        rospy.init_node("foldbot_replay_check", anonymous=True, disable_signals=True)
        rospy.Subscriber("/cloth/state", String, on_state, queue_size=1000)
        master = rosgraph.Master("/foldbot_replay_check")
        deadline = time.monotonic() + 60
        while True:  # wait until the perception node subscribes to the camera
            _pubs, subs, _srvs = master.getSystemState()
            if any(t == "/camera/color/image_raw" and n for t, n in subs):
                break
            if time.monotonic() > deadline:
                raise FoldbotError("the perception node did not start")
            time.sleep(0.2)
        # Every input topic has the perception node as subscriber: rosbag plays once each one's
        # connection is up, so no first frame is lost on a slow machine.
        try:
            play = subprocess.run(
                [
                    *("rosbag", "play", "-q", "--wait-for-subscribers", "-r", str(rate)),
                    *(str(bag_path), "--topics", *PLAYED_TOPICS),
                ],
                env=env,
                stdout=log,
                stderr=subprocess.STDOUT,
                timeout=timeout,
                check=False,
            )
        except subprocess.TimeoutExpired:
            raise FoldbotError(f"rosbag play of {bag_path} took more than {timeout:g} s") from None
        if play.returncode != 0:
            raise FoldbotError(f"rosbag play failed (exit code {play.returncode})")
        deadline = time.monotonic() + 60
        while time.monotonic() < deadline:
            with lock:
                if set(live) <= set(replayed):
                    break
            time.sleep(0.2)
        rospy.signal_shutdown("replay done")
    finally:
        for p in reversed(procs):
            p.terminate()
            try:
                p.wait(timeout=15)
            except subprocess.TimeoutExpired:
                p.kill()
        log.close()
    common = sorted(set(live) & set(replayed))
    diff, sure, labels_ok, detected_ok = 0.0, 0.0, True, True
    for stamp in common:
        a, b = live[stamp], replayed[stamp]
        detected_ok &= a["detected"] == b["detected"]
        labels_ok &= set(a["keypoints"]) == set(b["keypoints"])
        for label in set(a["keypoints"]) & set(b["keypoints"]):
            ka, kb = np.array(a["keypoints"][label]), np.array(b["keypoints"][label])
            d = float(np.abs(ka[:3] - kb[:3]).max())  # x, y, z (m); the 4th is the confidence
            diff = max(diff, d)
            if ka[3] >= SURE_CONFIDENCE:
                sure = max(sure, d)
    return ReplayReport(len(live), len(common), diff, labels_ok, detected_ok, sure)
