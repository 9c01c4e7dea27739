"""The camera pose node: publishes one static transform on /tf_static, latched, from the same
arguments tf2_ros's static_transform_publisher takes (x y z qx qy qz qw parent child), so a cell
without tf2_ros publishes a calibrated camera's pose (`foldbot ros-calibrate`'s
camera_pose.launch; `foldbot ros-fold --cell real --camera-pose`)."""

from __future__ import annotations

import math
import shlex
import sys

import numpy as np
from scipy.spatial.transform import Rotation

from foldbot.errors import ConfigError

USAGE = "x y z qx qy qz qw parent_frame child_frame (metres; a quaternion)"


def parse_pose_args(words: list[str]) -> tuple[np.ndarray, str, str]:
    """The 4 × 4 transform and the two frames a static_transform_publisher's words give."""
    if len(words) != 9:
        raise ConfigError(f"a static transform is {USAGE}; got {len(words)} words: {words}")
    try:
        values = [float(w) for w in words[:7]]
    except ValueError:
        raise ConfigError(f"a static transform is {USAGE}; got {words}") from None
    q = np.array(values[3:7])
    if not all(math.isfinite(v) for v in values) or np.linalg.norm(q) < 1e-9:
        raise ConfigError(
            f"a static transform needs finite numbers and a non-zero quaternion, got {words}"
        )
    T = np.eye(4)
    T[:3, :3] = Rotation.from_quat(q / np.linalg.norm(q)).as_matrix()
    T[:3, 3] = values[:3]
    return T, words[7], words[8]


def main(argv: list[str] | None = None) -> int:
    import rospy
    from tf2_msgs.msg import TFMessage

    from foldbot.ros import TOPICS, convert

    rospy.init_node("foldbot_camera_pose", anonymous=True)
    words = rospy.myargv(argv if argv is not None else sys.argv)[1:]
    if len(words) == 1:  # one quoted string, as a launch file's args may give them
        words = shlex.split(words[0])
    try:
        T, parent, child = parse_pose_args(words)
    except ConfigError as exc:
        print(f"camera_pose: {exc}", file=sys.stderr)
        return 2
    pub = rospy.Publisher(TOPICS["tf_static"], TFMessage, queue_size=1, latch=True)
    pub.publish(TFMessage(transforms=[convert.transform_msg(T, parent, child, 0.0)]))
    rospy.spin()
    return 0


if __name__ == "__main__":
    sys.exit(main())
