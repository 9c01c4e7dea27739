"""ROS 1 wrappers: the cell, perception, planner and task as nodes talking over topics.

Every node is a thin shell around the library modules (sim, perception, planning, loop); the
message conversions live in `convert`. Importing `foldbot.ros.convert` or a node needs rospy and
the ROS message packages (Debian's python3-rospy & co., see scripts/install_ros.sh);
`foldbot.ros.bag_export` needs only the pure-Python `rosbags`.
"""

WORLD_FRAME = "world"
"""The fixed frame of the cell (REP 105 style world frame; z up, x away from the robot)."""
BASE_FRAME = "base_link"
"""The arm's base frame; in a two-arm cell each arm's carries its prefix (ARM_PREFIXES)."""
CAMERA_FRAME = "camera_color_optical_frame"
"""The camera's optical frame (REP 103: x right, y down, z forward)."""
UR_BASE_FRAME = "base"
"""A UR arm's controller base (ur_description's `base`: base_link turned by π about z), prefixed
as BASE_FRAME is."""
UR_TOOL_FRAME = "tool0_controller"
"""The tool flange where a UR arm's own controller puts it, from its joints and its factory
calibration: ur_robot_driver publishes base → tool0_controller on /tf (and so does the sim
node), which ros-check holds foldbot's model of the arm against."""

TOPICS = {
    "color": "camera/color/image_raw",
    "color_info": "camera/color/camera_info",
    "depth": "camera/depth/image_raw",
    "depth_info": "camera/depth/camera_info",
    "joint_states": "/joint_states",
    "clock": "/clock",
    "tf_static": "/tf_static",
    "tf": "/tf",
    "trajectory": "arm/joint_trajectory",
    "gripper": "gripper/command",  # "open" / "close", or "open 1" / "close 1" for arm 1
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
    "plan_overlay": "task/plan_overlay",
    # The actions interface (`--arm-interface actions`): ur_robot_driver's trajectory controller
    # and ros_control's gripper action controller, by their usual names.
    "trajectory_action": "scaled_pos_joint_traj_controller/follow_joint_trajectory",
    "gripper_action": "gripper_controller/gripper_cmd",
}
"""Every topic the nodes use (relative names resolve in the launch namespace)."""

SYNC_SLOP_S = 0.015
"""How far apart (s) a frame's colour image, depth image and camera_info may be stamped and still
be read as one frame (the perception node's private parameter ~sync_slop): a real RGB-D camera's colour and
depth sensors, synchronised, stamp their frames a few milliseconds apart, under half a frame at
30 frames a second."""


ARM_PREFIXES = {1: ("",), 2: ("left_", "right_")}
"""Name prefixes of each arm's joints and base frame, arm 0 first: one arm keeps the URDF's names;
two arms side by side are left (arm 0, +y) and right, as ROS names a bimanual cell's arms."""


def arm_prefixes(arms: int) -> tuple[str, ...]:
    """The joint-name prefixes of a cell with `arms` arms (ARM_PREFIXES)."""
    if arms not in ARM_PREFIXES:
        raise ValueError(f"a cell has 1 or 2 arms, got {arms!r}")
    return ARM_PREFIXES[arms]


def arm_joint_names(joint_names: tuple[str, ...], arms: int) -> list[list[str]]:
    """Each arm's joint names as they go over topics: the robot's names with the arm's prefix."""
    return [[prefix + name for name in joint_names] for prefix in arm_prefixes(arms)]


def driver_namespaces(arms: int) -> tuple[str, ...]:
    """Each arm's drivers' namespace, arm 0 first: none for one arm (its drivers' own names);
    each of two arms' drivers under its arm's name (left/, right/), as a bimanual cell launches
    one ur_robot_driver and one gripper driver per arm."""
    return tuple(f"{prefix.rstrip('_')}/" if prefix else "" for prefix in arm_prefixes(arms))


def driver_actions(arms: int) -> list[tuple[str, str]]:
    """Each arm's (FollowJointTrajectory, GripperCommand) action names, arm 0 first."""
    return [
        (ns + TOPICS["trajectory_action"], ns + TOPICS["gripper_action"])
        for ns in driver_namespaces(arms)
    ]
