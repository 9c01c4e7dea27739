"""Probe for test_perception_node: a frame the perception node estimates while the node shuts
down (the fold done, roslaunch stopping it) is dropped without a traceback. Prints PROBE and
what happened as JSON."""

import json
import sys
from pathlib import Path

import foldbot  # noqa: F401  (before numpy: foldbot.simd)

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))  # tests/: rgbd_views

import numpy as np
import rospy
from rgbd_views import render_views

from foldbot.ros import CAMERA_FRAME, convert
from foldbot.ros.perception_node import PerceptionNode

rospy.init_node("shutdown_probe", disable_signals=True)
node = PerceptionNode()
color, _depth, _truth = render_views()
stamp = color.stamp
mm = np.nan_to_num(np.round(color.depth * 1000.0), nan=0.0).astype(np.uint16)
frame = (
    convert.image_msg(color.rgb[..., ::-1], "bgr8", stamp, CAMERA_FRAME),
    convert.image_msg(mm, "16UC1", stamp, CAMERA_FRAME),
    convert.camera_info_msg(color.intrinsics, stamp, CAMERA_FRAME),
)
node._listeners_connected = True  # nobody listens in this probe: publish at once
seen: dict = {}


def estimate_in_the_window(reason: str) -> None:
    """Run after rospy's own pre-shutdown clean-up closed the topics, before is_shutdown() is
    true: where roslaunch's stop met the node estimating a streamed frame."""
    seen["closed"] = node.pub_mask.impl.closed
    seen["shutdown"] = rospy.is_shutdown()
    try:
        node._estimate(*frame, color.T_world_camera)
    except Exception as exc:  # reported to the test
        seen["error"] = f"{type(exc).__name__}: {exc}"


rospy.core.add_preshutdown_hook(estimate_in_the_window)
rospy.signal_shutdown("the fold is done")
print("PROBE " + json.dumps(seen), flush=True)
