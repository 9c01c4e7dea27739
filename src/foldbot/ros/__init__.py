"""ROS 1 wrappers: the cell, perception, planner and task as nodes talking over topics.

Every node is a thin shell around the library modules (sim, perception, planning, loop); the
message conversions live in `convert`. Importing `foldbot.ros.convert` or a node needs rospy and
the ROS message packages (Debian's python3-rospy & co., see scripts/install_ros.sh);
`foldbot.ros.bag_export` needs only the pure-Python `rosbags`.
"""

WORLD_FRAME = "world"
"""The fixed frame of the cell (REP 105 style world frame; z up, x away from the robot)."""
BASE_FRAME = "base_link"
CAMERA_FRAME = "camera_color_optical_frame"
"""The camera's optical frame (REP 103: x right, y down, z forward)."""

TOPICS = {
    "color": "camera/color/image_raw",
    "color_info": "camera/color/camera_info",
    "depth": "camera/depth/image_raw",
    "depth_info": "camera/depth/camera_info",
    "joint_states": "/joint_states",
    "clock": "/clock",
    "tf_static": "/tf_static",
    "trajectory": "arm/joint_trajectory",
    "gripper": "gripper/command",
    "grasp": "gripper/grasp",
    "wait": "sim/wait",
    "cell_result": "sim/result",
    "ground_truth": "ground_truth/cloth",
    "ground_truth_mesh": "ground_truth/mesh",
    "ground_truth_request": "ground_truth/request",
    "keypoints": "cloth/keypoints",
    "mask": "cloth/mask",
    "state": "cloth/state",
    "plan_request": "planner/request",
    "plan_response": "planner/response",
    "episode": "task/result",
}
"""Every topic the nodes use (relative names resolve in the launch namespace)."""
