"""The perception node: synchronised RGB-D frames + camera_info (+ the camera pose from
/tf_static) → the RGB-D estimator for the episode's garment (perception.fallback.vision_estimator)
→ cloth/keypoints (geometry_msgs/PoseArray, world frame, corners
in CORNER_LABELS order), cloth/mask (mono8) and cloth/state (the full ClothState as JSON),
all stamped with the frame's stamp so a consumer can match them to the image."""

from __future__ import annotations

import sys
import threading

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
from foldbot.ros import CAMERA_FRAME, TOPICS, WORLD_FRAME, convert
from foldbot.ros.node_args import FOLD_ARGS_PARAM, parse_fold_args
from foldbot.types import Observation


class PerceptionNode:
    """Runs the vision estimator for `garment` on every synchronised frame (images in, values
    out)."""

    def __init__(self, garment: str = "towel", queue_size: int = 200) -> None:
        self.estimator = vision_estimator(garment)
        self.T_world_camera: np.ndarray | None = None
        self._lock = threading.Lock()
        self._pending: list[tuple[Image, Image, CameraInfo]] = []
        """Frames that came before the camera pose; estimated once it arrives."""
        # Latched: a planner node that subscribes late still gets the newest frame's corners.
        self.pub_keypoints = rospy.Publisher(
            TOPICS["keypoints"], PoseArray, queue_size=50, latch=True
        )
        self.pub_mask = rospy.Publisher(TOPICS["mask"], Image, queue_size=50)
        self.pub_state = rospy.Publisher(TOPICS["state"], String, queue_size=50)
        rospy.Subscriber(TOPICS["tf_static"], TFMessage, self._on_tf)
        subs = [
            message_filters.Subscriber(
                TOPICS["color"], Image, queue_size=queue_size, buff_size=2**26
            ),
            message_filters.Subscriber(
                TOPICS["depth"], Image, queue_size=queue_size, buff_size=2**26
            ),
            message_filters.Subscriber(TOPICS["color_info"], CameraInfo, queue_size=queue_size),
        ]
        message_filters.TimeSynchronizer(subs, queue_size).registerCallback(self._on_frame)

    def _on_tf(self, msg: TFMessage) -> None:
        for t in msg.transforms:
            if t.header.frame_id == WORLD_FRAME and t.child_frame_id == CAMERA_FRAME:
                with self._lock:
                    self.T_world_camera = convert.matrix_of(t)
                    pending, self._pending = self._pending, []
                for frame in pending:
                    self._estimate(*frame, self.T_world_camera)

    def _on_frame(self, color: Image, depth: Image, info: CameraInfo) -> None:
        with self._lock:
            T = self.T_world_camera
            if T is None:
                self._pending = [*self._pending[-20:], (color, depth, info)]
                return
        self._estimate(color, depth, info, T)

    def _estimate(self, color: Image, depth: Image, info: CameraInfo, T: np.ndarray) -> None:
        stamp = color.header.stamp.to_sec()
        rgb, z, intrinsics = convert.camera_images(color, depth, info)
        obs = Observation(
            rgb=rgb,
            depth=z,
            intrinsics=intrinsics,
            T_world_camera=T,
            stamp=stamp,
        )
        state = self.estimator.estimate(obs)
        self.pub_mask.publish(
            convert.image_msg(
                state.mask.astype(np.uint8) * 255, "mono8", stamp, color.header.frame_id
            )
        )
        self.pub_state.publish(String(data=convert.state_json(state)))
        self.pub_keypoints.publish(convert.keypoints_msg(state, stamp, WORLD_FRAME))


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


def main(argv: list[str] | None = None) -> int:
    rospy.init_node("foldbot_perception", argv=argv if argv is not None else sys.argv)
    PerceptionNode(node_garment())
    rospy.spin()
    return 0
