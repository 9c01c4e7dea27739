"""What the driver probes read from the cell, as a bare client of real drivers would: the
camera's topics subscribed (the sim node holds its first frame for a reader), /joint_states
(the newest joints by name, and every message's stamp and joints) and /clock. Imported by the
probe scripts beside it, each run in its own process after rospy.init_node."""

import rospy
from rosgraph_msgs.msg import Clock
from sensor_msgs.msg import CameraInfo, Image, JointState

from foldbot.ros import TOPICS


class CellListener:
    """The cell as the probe hears it (joints, their history, the clock)."""

    def __init__(self) -> None:
        for topic, cls in (("color", Image), ("depth", Image), ("color_info", CameraInfo)):
            rospy.Subscriber(TOPICS[topic], cls, lambda m: None)
        self.joints: dict[str, float] = {}
        self.history: list[tuple[float, dict[str, float]]] = []
        self.clock = 0.0
        rospy.Subscriber("/joint_states", JointState, self._on_joints)
        rospy.Subscriber("/clock", Clock, self._on_clock)

    def _on_joints(self, m: JointState) -> None:
        self.joints.update(zip(m.name, m.position, strict=True))
        self.history.append((m.header.stamp.to_sec(), dict(self.joints)))

    def _on_clock(self, m: Clock) -> None:
        self.clock = m.clock.to_sec()
