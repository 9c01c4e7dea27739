"""The perception node: synchronised RGB-D frames + camera_info (+ the camera pose from
/tf_static) → the RGB-D estimator for the episode's garment (perception.fallback.vision_estimator,
the layout's obstacles masked as the cell's fixtures) → cloth/keypoints (geometry_msgs/PoseArray,
world frame, corners in CORNER_LABELS order), cloth/mask (mono8) and cloth/state (the full
ClothState as JSON), all stamped with the frame's stamp so a consumer can match them to the
image."""

from __future__ import annotations

import json
import sys
import threading
from collections.abc import Sequence

import message_filters
import numpy as np
import rospy
from geometry_msgs.msg import PoseArray
from sensor_msgs.msg import CameraInfo, Image
from std_msgs.msg import String
from tf2_msgs.msg import TFMessage

from foldbot.errors import ConfigError
from foldbot.garments import GARMENTS
from foldbot.perception.fallback import vision_estimator
from foldbot.ros import CAMERA_FRAME, SYNC_SLOP_S, TOPICS, WORLD_FRAME, convert
from foldbot.ros.frames import StaticFrames
from foldbot.ros.node_args import FOLD_ARGS_PARAM, parse_fold_args
from foldbot.ros.publish import wait_for_listed_subscribers
from foldbot.sim.layout import Obstacle, obstacle_from_table
from foldbot.types import Observation


class PerceptionNode:
    """Runs the vision estimator for `garment` on every synchronised frame (images in, values
    out), the cell's `fixtures` (its layout's obstacles) masked as what is not cloth."""

    def __init__(
        self,
        garment: str = "towel",
        queue_size: int = 200,
        sync_slop: float = SYNC_SLOP_S,
        fixtures: Sequence[Obstacle] = (),
    ) -> None:
        self.fixtures = tuple(fixtures)
        self.estimator = vision_estimator(garment, self.fixtures)
        self.T_world_camera: np.ndarray | None = None
        self.frames = StaticFrames()
        self.depth_info: CameraInfo | None = None
        """The depth camera's newest camera_info: where it is not the colour camera's, the depth
        image is registered onto the colour camera (convert.camera_images)."""
        self._lock = threading.Lock()
        self._pending: list[tuple[Image, Image, CameraInfo]] = []
        """Frames that came before the camera pose (or, for a depth image in its own frame,
        before its camera_info and transform); estimated once they arrive."""
        # Latched: a planner or task node that subscribes late still gets the newest frame's
        # corners, mask and state (the task node's connection to these came up after the first
        # frame's estimate in most runs, which then waited 10 s for a re-send).
        self.pub_keypoints = rospy.Publisher(
            TOPICS["keypoints"], PoseArray, queue_size=50, latch=True
        )
        self.pub_mask = rospy.Publisher(TOPICS["mask"], Image, queue_size=50, latch=True)
        self.pub_state = rospy.Publisher(TOPICS["state"], String, queue_size=50, latch=True)
        self._listeners_connected = False
        """Whether the first estimate has waited for its listed subscribers (a recorder among
        them) to connect, so a bag holds it too (foldbot.ros.publish)."""
        rospy.Subscriber(TOPICS["tf_static"], TFMessage, self._on_tf)
        rospy.Subscriber(TOPICS["depth_info"], CameraInfo, self._on_depth_info, queue_size=5)
        subs = [
            message_filters.Subscriber(
                TOPICS["color"], Image, queue_size=queue_size, buff_size=2**26
            ),
            message_filters.Subscriber(
                TOPICS["depth"], Image, queue_size=queue_size, buff_size=2**26
            ),
            message_filters.Subscriber(TOPICS["color_info"], CameraInfo, queue_size=queue_size),
        ]
        # A real camera stamps its colour and depth frames apart by a few milliseconds; the sim
        # stamps them alike, and the nearest stamps are paired first.
        message_filters.ApproximateTimeSynchronizer(subs, queue_size, sync_slop).registerCallback(
            self._on_frame
        )

    def _on_depth_info(self, msg: CameraInfo) -> None:
        with self._lock:
            self.depth_info = msg
        self._flush()

    def _on_tf(self, msg: TFMessage) -> None:
        with self._lock:
            self.frames.add(msg)
            # The camera's pose: world → camera_color_optical_frame, given directly (the sim) or
            # through the camera's own frames (a driver's camera_link under a calibrated pose).
            T = self.frames.transform(WORLD_FRAME, CAMERA_FRAME)
            if T is not None:
                self.T_world_camera = T
        self._flush()

    def _waiting_for(self, depth: Image, info: CameraInfo) -> str | None:
        """What a frame still needs before it can be estimated (None: nothing): the camera's
        pose and, for a depth image in another frame than the colour one, its camera_info and
        the transform between the two."""
        if self.T_world_camera is None:
            return f"the camera's pose ({WORLD_FRAME} → {CAMERA_FRAME} on /tf_static)"
        if depth.header.frame_id == info.header.frame_id:
            return None
        if convert.info_for(depth, self.depth_info) is None:
            return (
                f"the depth camera's camera_info ({TOPICS['depth_info']}): its images are in "
                f"{depth.header.frame_id!r}, the colour images in {info.header.frame_id!r}"
            )
        if self.frames.transform(info.header.frame_id, self.depth_info.header.frame_id) is None:
            return (
                f"a transform from {self.depth_info.header.frame_id!r} to "
                f"{info.header.frame_id!r} on /tf_static"
            )
        return None

    def _ready(self, depth: Image, info: CameraInfo) -> bool:
        return self._waiting_for(depth, info) is None

    def _flush(self) -> None:
        with self._lock:
            ready = [f for f in self._pending if self._ready(f[1], f[2])]
            self._pending = [f for f in self._pending if not self._ready(f[1], f[2])]
            T = self.T_world_camera
        for frame in ready:
            self._estimate(*frame, T)

    def _on_frame(self, color: Image, depth: Image, info: CameraInfo) -> None:
        with self._lock:
            T = self.T_world_camera
            waiting_for = self._waiting_for(depth, info)
            if waiting_for is not None:
                self._pending = [*self._pending[-20:], (color, depth, info)]
        if waiting_for is not None:
            rospy.logwarn_throttle(10.0, f"perception holds its frames until it has {waiting_for}")
            return
        self._estimate(color, depth, info, T)

    def _estimate(self, color: Image, depth: Image, info: CameraInfo, T: np.ndarray) -> None:
        stamp = color.header.stamp.to_sec()
        with self._lock:
            depth_info = self.depth_info
        rgb, z, intrinsics = self.frames.camera_images(color, depth, info, depth_info)
        obs = Observation(
            rgb=rgb,
            depth=z,
            intrinsics=intrinsics,
            T_world_camera=T,
            stamp=stamp,
        )
        state = self.estimator.estimate(obs)
        if not self._listeners_connected:
            pubs = [self.pub_mask, self.pub_state, self.pub_keypoints]
            wait_for_listed_subscribers(pubs, "publishing the first estimate")
            self._listeners_connected = True
        try:
            self.pub_mask.publish(
                convert.image_msg(
                    state.mask.astype(np.uint8) * 255, "mono8", stamp, color.header.frame_id
                )
            )
            self.pub_state.publish(String(data=convert.state_json(state, self.fixtures)))
            self.pub_keypoints.publish(convert.keypoints_msg(state, stamp, WORLD_FRAME))
        except rospy.ROSException:
            # A frame estimated while the launch shuts the node down (the fold done) has nowhere
            # to go: rospy closes the topics before it reports the shutdown (is_shutdown), and
            # its "publish() to a closed topic" in that window is no error of the run.
            if not rospy.core.is_shutdown_requested():
                raise


def node_garment() -> str:
    """The garment to perceive: the private parameter ~garment (a replay sets it), else the
    episode's (/foldbot/fold_args), else a towel."""
    garment = rospy.get_param("~garment", "")
    if garment:
        if garment not in GARMENTS:
            raise ConfigError(f"~garment {garment!r} is not one of {', '.join(GARMENTS)}")
        return garment
    if rospy.has_param(FOLD_ARGS_PARAM):
        return parse_fold_args(rospy.get_param(FOLD_ARGS_PARAM))[1].garment
    return "towel"


def node_fixtures() -> tuple[Obstacle, ...]:
    """The cell's fixtures: the private parameter ~fixtures (a list of layout `[[obstacles]]`
    tables, or that list as JSON; a replay sets it from the recorded states), else the
    episode's layout's obstacles (/foldbot/fold_args), else none."""
    value = rospy.get_param("~fixtures", None)
    if value is not None:
        if isinstance(value, str):
            try:
                value = json.loads(value) if value.strip() else []
            except json.JSONDecodeError as e:
                raise ConfigError(f"~fixtures is not JSON ({e}): {value!r}") from None
        if not isinstance(value, list):
            raise ConfigError(f"~fixtures must be a list of obstacle tables, got {value!r}")
        return tuple(obstacle_from_table(t, f"~fixtures[{i}]") for i, t in enumerate(value))
    if rospy.has_param(FOLD_ARGS_PARAM):
        return parse_fold_args(rospy.get_param(FOLD_ARGS_PARAM))[1].sim.layout.obstacles
    return ()


def main(argv: list[str] | None = None) -> int:
    rospy.init_node("foldbot_perception", argv=argv if argv is not None else sys.argv)
    slop = float(rospy.get_param("~sync_slop", SYNC_SLOP_S))
    if not 0.0 <= slop <= 1.0:
        raise ConfigError(f"~sync_slop must be in [0, 1] s, got {slop!r}")
    PerceptionNode(node_garment(), sync_slop=slop, fixtures=node_fixtures())
    rospy.spin()
    return 0
