"""The sim node: the PyBullet cell (pipeline.build_sim_cell) behind ROS topics.

Publishes the RGB-D camera (camera/color/image_raw rgb8, camera/depth/image_raw 32FC1 metres,
their camera_info), /joint_states, /clock (simulated time), /tf_static (world → base_link and
→ camera_color_optical_frame; a UR's base_link → base), /tf (a UR's base → tool0_controller, the
flange where its controller puts it, as ur_robot_driver streams it), the grasp outcome
(gripper/grasp) and, for scoring only, the cloth's ground truth (ground_truth/cloth). Executes trajectory_msgs/JointTrajectory on
arm/joint_trajectory, "open"/"close" on gripper/command and sim/wait (s), one at a time; after
each it publishes a camera frame of the resting cell and a JSON report on sim/result.

A two-arm cell (`--arms 2`) names each arm's joints and base frame with its prefix (left_,
right_: foldbot.ros.ARM_PREFIXES); one trajectory may move one arm or both on one clock, and a
gripper command names its arm ("close 1").

The simulation advances only while it executes a command (lockstep), so a run over topics is as
reproducible as the in-process one and /clock never runs ahead of the cell.
"""

from __future__ import annotations

import queue
import sys
import time
from typing import Any

import numpy as np
import rospy
from rosgraph_msgs.msg import Clock
from scipy.spatial.transform import Rotation
from sensor_msgs.msg import CameraInfo, Image, JointState, PointCloud2
from std_msgs.msg import Empty, Float64, String
from tf2_msgs.msg import TFMessage
from trajectory_msgs.msg import JointTrajectory as JointTrajectoryMsg

from foldbot.control.trajectory import commands_at_steps
from foldbot.errors import FoldbotError
from foldbot.pipeline import build_sim_cell, crumple_start
from foldbot.ros import (
    BASE_FRAME,
    CAMERA_FRAME,
    TOPICS,
    UR_BASE_FRAME,
    UR_TOOL_FRAME,
    WORLD_FRAME,
    arm_joint_names,
    arm_prefixes,
    convert,
)
from foldbot.ros.node_args import (
    ARM_INTERFACE_PARAM,
    ARM_INTERFACES,
    CALIBRATION_BOARD_PARAM,
    CALIBRATION_BOARD_PATTERN_PARAM,
    CAMERA_RATE_PARAM,
    FOLD_ARGS_PARAM,
    PUBLISH_CAMERA_POSE_PARAM,
    REAL_TIME_FACTOR_PARAM,
    parse_fold_args,
)
from foldbot.ros.publish import wait_for_listed_subscribers
from foldbot.sim.cloth import settle
from foldbot.sim.grasp import SlipFault
from foldbot.sim.rest import RestWatch
from foldbot.sim.robots import UR5
from foldbot.sim.robots.kinematics import DH_BASE_IN_BASE_LINK
from foldbot.sim.world import SimWorld

SUBSCRIBER_WAIT_S = 60.0
"""Longest wall time the first camera frame waits for a subscriber (the perception node)."""
PACE_SLACK_S = 0.05
"""How far (wall s) a cell running at a real-time factor may fall behind its wall clock and still
catch up; beyond it, its clock goes on from there (a step's jitter is made up, a stall is not)."""


def trajectory_arms(joint_names: list[str], arm_joints: list[list[str]]) -> list[int]:
    """The arms a trajectory moves, from its joint names: one arm's joints (`arm_joints[arm]`,
    in order), or several arms' one after the other in arm order; anything else is refused."""
    arms, k = [], 0
    for arm, names in enumerate(arm_joints):
        if joint_names[k : k + len(names)] == names:
            arms.append(arm)
            k += len(names)
    if not arms or k != len(joint_names):
        allowed = " or ".join(str(n) for n in arm_joints)
        raise FoldbotError(
            f"trajectory joint_names {joint_names} must be an arm's joints ({allowed}), "
            "or several arms' one after the other"
        )
    return arms


def gripper_command(text: str, arms: int) -> tuple[str, int]:
    """("open" | "close", arm) from a gripper command: "close" (arm 0), or "close 1" for arm 1."""
    words = text.split()
    ok = 1 <= len(words) <= 2 and words[0] in ("open", "close")
    if ok and len(words) == 2:
        ok = words[1].isdigit() and int(words[1]) < arms
    if not ok:
        raise FoldbotError(
            f"unknown gripper command {text!r}; allowed: open, close, or either followed by an "
            f"arm in 0–{arms - 1}"
        )
    return words[0], int(words[1]) if len(words) == 2 else 0


def ur_tool_in_base(robot: UR5) -> np.ndarray:
    """4 × 4 pose of the simulated UR's flange in its controller's base frame (UR_BASE_FRAME):
    what ur_robot_driver publishes as base → tool0_controller."""
    pos, quat = robot.flange_pose()
    T_world_flange = np.eye(4)
    T_world_flange[:3, :3] = Rotation.from_quat(quat).as_matrix()
    T_world_flange[:3, 3] = pos
    T_world_base = np.eye(4)  # arms are mounted unrotated (sim.robots.base)
    T_world_base[:3, 3] = robot.layout.robot_base_xyz
    return np.linalg.inv(T_world_base @ DH_BASE_IN_BASE_LINK) @ T_world_flange


class SimNode:
    """Owns the simulated cell; every PyBullet call happens on the main thread."""

    def __init__(
        self,
        fold_args: str,
        camera_rate: float,
        arm_interface: str = "topics",
        real_time_factor: float = 1.0,
        calibration_board: int | None = None,
        publish_camera_pose: bool = True,
        calibration_board_pattern: str = "chessboard",
    ) -> None:
        _args, self.cfg = parse_fold_args(fold_args)
        if arm_interface not in ARM_INTERFACES:
            raise FoldbotError(
                f"arm interface must be one of {', '.join(ARM_INTERFACES)}, got {arm_interface!r}"
            )
        if not (np.isfinite(real_time_factor) and real_time_factor > 0):
            raise FoldbotError(f"real_time_factor must be > 0, got {real_time_factor!r}")
        if not (np.isfinite(camera_rate) and camera_rate >= 0):
            raise FoldbotError(f"camera_rate must be ≥ 0 frames per s, got {camera_rate!r}")
        if camera_rate == 0 and arm_interface == "actions":
            raise FoldbotError("the actions interface needs a camera stream: camera_rate > 0")
        self.slip_fault = SlipFault(self.cfg.fault_slip)
        """The injected slip, if any (EpisodeConfig.fault_slip): on the first carry, as in
        process. The topics interface reports it with the motion's reply; through the drivers'
        actions only /joint_states tells it (the jaws close on, as a real gripper's do)."""
        self.arm_interface = arm_interface
        self.real_time_factor = real_time_factor
        self._pace_origin: tuple[float, float] | None = None
        """(simulated s, wall s) where real-time pacing started (the actions interface only)."""
        self.world = SimWorld(self.cfg.sim)
        self.parts = build_sim_cell(self.cfg, self.world)
        self.executors = (self.parts.executor, *self.parts.more_executors)
        """One per arm, arm 0 first; each has its kinematic twin (`model`, in a world of its own:
        FK there gives the commanded TCP without touching the simulated arm) and its grasp."""
        self.robot = self.parts.robot
        if calibration_board is not None:  # that arm holds the board (`ros-calibrate`)
            from foldbot.calibration.board import CharucoBoard, Chessboard
            from foldbot.calibration.views import BoardMount
            from foldbot.sim.calibration_board import attach_board

            if not 0 <= calibration_board < len(self.executors):
                raise FoldbotError(
                    f"calibration_board must name an arm, 0 to {len(self.executors) - 1}, got "
                    f"{calibration_board}"
                )
            boards = {"chessboard": Chessboard, "charuco": CharucoBoard}
            if calibration_board_pattern not in boards:
                raise FoldbotError(
                    f"calibration_board_pattern must be one of {', '.join(boards)}, got "
                    f"{calibration_board_pattern!r}"
                )
            board = boards[calibration_board_pattern]()
            attach_board(self.executors[calibration_board].robot, board, BoardMount())
        self.publish_camera_pose = publish_camera_pose
        """Whether world → the camera goes on /tf_static (False: a cell not yet calibrated)."""
        self.first_frame_topics = (
            ("color", "color_info")
            if calibration_board is not None
            else ("color", "depth", "color_info")
        )
        """What the first camera frame waits to have a subscriber on: the perception node takes
        all three; a calibration, the colour image and its camera_info only."""
        arms = len(self.executors)
        self.prefixes = arm_prefixes(arms)
        self.arm_joints = arm_joint_names(self.robot.ARM_JOINT_NAMES, arms)
        self.finger_joints = arm_joint_names(self.robot.FINGER_JOINT_NAMES, arms)
        self.camera_period = 1.0 / camera_rate if camera_rate > 0 else float("inf")
        """Between the camera's streamed frames (s); inf: none streamed, a lockstep cell's
        frames only after its waits (the resting frames a fold looks at)."""
        self.commands: queue.Queue = queue.Queue()
        self._next_clock = 0.0
        self._next_joints = 0.0
        self._next_frame = 0.0 if camera_rate > 0 else float("inf")
        latch = {"queue_size": 1, "latch": True}
        # The camera's topics are latched too: a subscriber that connects after a frame (the
        # task node, launched with the perception node, often connected a moment after the
        # resting frame went out) gets the newest at once instead of waiting for a re-send.
        frames = {"queue_size": 50, "latch": True}
        self.pub = {
            "clock": rospy.Publisher(TOPICS["clock"], Clock, queue_size=10),
            "joints": rospy.Publisher(TOPICS["joint_states"], JointState, queue_size=10),
            "tf": rospy.Publisher(TOPICS["tf_static"], TFMessage, **latch),
            "tool_tf": rospy.Publisher(TOPICS["tf"], TFMessage, queue_size=10),
            "color": rospy.Publisher(TOPICS["color"], Image, **frames),
            "color_info": rospy.Publisher(TOPICS["color_info"], CameraInfo, **frames),
            "depth": rospy.Publisher(TOPICS["depth"], Image, **frames),
            "depth_info": rospy.Publisher(TOPICS["depth_info"], CameraInfo, **frames),
            "grasp": rospy.Publisher(TOPICS["grasp"], String, queue_size=10),
            # Reports can leave back to back (a reply, then a divergence's): each is queued.
            "result": rospy.Publisher(TOPICS["cell_result"], String, queue_size=10, latch=True),
            "truth": rospy.Publisher(TOPICS["ground_truth"], PointCloud2, **latch),
            "mesh": rospy.Publisher(TOPICS["ground_truth_mesh"], String, **latch),
        }
        commands = [(TOPICS["ground_truth_request"], "ground_truth", Empty)]
        if arm_interface == "topics":
            commands += [
                (TOPICS["trajectory"], "trajectory", JointTrajectoryMsg),
                (TOPICS["gripper"], "gripper", String),
                (TOPICS["wait"], "wait", Float64),
            ]
        for topic, kind, cls in commands:
            rospy.Subscriber(topic, cls, lambda msg, k=kind: self.commands.put((k, msg)))
        self.world.add_step_hook(self._on_step, on_idle=True)  # the clock, joints, camera
        self.rest = RestWatch(
            self.parts.cloth.sim_vertices,
            [ex.robot.joint_velocities for ex in self.executors],
            self.world.time_step,
        )
        """Whether the cell, left to itself between goals (the actions interface), is still:
        then its clock runs on without the physics (sim.rest)."""
        self.drivers = None
        if arm_interface == "actions":
            from foldbot.ros.drivers import SimDrivers

            self.drivers = SimDrivers(self)

    # ------------------------------------------------------------------ publishing
    def _on_step(self, world: SimWorld) -> None:
        t = world.sim_time
        if self._pace_origin is not None:
            self._pace(t)
        if t + 1e-9 >= self._next_clock:
            self._next_clock = t + 0.01
            self.pub["clock"].publish(Clock(clock=convert.stamp_of(t)))
        if t + 1e-9 >= self._next_joints:
            self._next_joints = t + 0.02
            self._publish_joints()
        if t + 1e-9 >= self._next_frame:
            self._next_frame = t + self.camera_period
            self.publish_frame()

    def _pace(self, t: float) -> None:
        """Hold the simulated clock to the wall clock (× real_time_factor), as a real cell's is;
        a step that takes longer than real time only falls behind: once more than PACE_SLACK_S
        behind, the clock goes on from where it is rather than racing to catch up (a real
        cell's never runs fast; on a loaded machine it did, 2.4 × for a factor of 2)."""
        sim0, wall0 = self._pace_origin
        now = time.monotonic()
        ahead = (t - sim0) / self.real_time_factor - (now - wall0)
        if ahead > 0:
            time.sleep(ahead)
        elif ahead < -PACE_SLACK_S:
            self._pace_origin = (t, now)

    def _publish_joints(self) -> None:
        names: list[str] = []
        q: list[np.ndarray] = []
        v: list[np.ndarray] = []
        for ex, arm_names, finger_names in zip(
            self.executors, self.arm_joints, self.finger_joints, strict=True
        ):
            r = ex.robot
            names += [*arm_names, *finger_names]
            q += [r.joint_positions(), ex.grasp.reported_fingers()]  # stopped on held cloth
            v += [r.joint_velocities(), np.zeros(len(finger_names))]
        self.pub["joints"].publish(
            convert.joint_state_msg(
                names, np.concatenate(q), np.concatenate(v), self.world.sim_time
            )
        )
        t = self.world.sim_time
        tools = [
            convert.transform_msg(
                ur_tool_in_base(ex.robot), prefix + UR_BASE_FRAME, prefix + UR_TOOL_FRAME, t
            )
            for ex, prefix in zip(self.executors, self.prefixes, strict=True)
            if isinstance(ex.robot, UR5)
        ]
        if tools:  # where the arm's controller says its flange is, as ur_robot_driver's
            self.pub["tool_tf"].publish(TFMessage(transforms=tools))

    def publish_frame(self) -> float:
        """Render and publish one RGB-D frame; returns its stamp (simulated s)."""
        t = self.world.sim_time
        obs = self.parts.camera.observe(self.robot.joint_positions(), stamp=t)
        info = convert.camera_info_msg(obs.intrinsics, t, CAMERA_FRAME)
        self.pub["color_info"].publish(info)
        self.pub["depth_info"].publish(info)
        self.pub["depth"].publish(convert.image_msg(obs.depth, "32FC1", t, CAMERA_FRAME))
        self.pub["color"].publish(convert.image_msg(obs.rgb, "rgb8", t, CAMERA_FRAME))
        return t

    def publish_static(self) -> None:
        tfs = []
        for ex, prefix in zip(self.executors, self.prefixes, strict=True):
            base = np.eye(4)  # arms are mounted unrotated (sim.robots.base)
            base[:3, 3] = ex.robot.layout.robot_base_xyz
            tfs.append(convert.transform_msg(base, WORLD_FRAME, prefix + BASE_FRAME, 0.0))
            if isinstance(ex.robot, UR5):  # base_link → the controller's base, as its URDF has
                tfs.append(
                    convert.transform_msg(
                        DH_BASE_IN_BASE_LINK, prefix + BASE_FRAME, prefix + UR_BASE_FRAME, 0.0
                    )
                )
        if self.publish_camera_pose:
            tfs.append(
                convert.transform_msg(
                    self.parts.camera.reported_T_world_camera, WORLD_FRAME, CAMERA_FRAME, 0.0
                )
            )
        self.pub["tf"].publish(TFMessage(transforms=tfs))

    def wait_for_camera_subscribers(self, timeout_s: float = SUBSCRIBER_WAIT_S) -> None:
        """Hold the first frame until something subscribes to the camera's images and info (the
        perception node): a latched frame reaches a late subscriber, but the perception node should
        estimate the resting frame itself, not only the newest one when it connects."""
        deadline = time.monotonic() + timeout_s
        while not rospy.is_shutdown():
            missing = [
                TOPICS[t] for t in self.first_frame_topics if self.pub[t].get_num_connections() == 0
            ]
            if not missing:
                return
            if time.monotonic() > deadline:
                rospy.logwarn(
                    "no subscriber on %s after %.0f s; publishing anyway", missing, timeout_s
                )
                return
            time.sleep(0.05)

    def publish_ground_truth(self) -> None:
        """Ground truth for scoring only (the task node's metrics), never for perception."""
        t = self.world.sim_time
        self.pub["truth"].publish(
            convert.cloud_msg(self.parts.oracle.cloth_vertices(), t, WORLD_FRAME)
        )

    def report(self, payload: dict) -> None:
        payload.setdefault("sim_time", self.world.sim_time)
        qs = [ex.robot.joint_positions().tolist() for ex in self.executors]
        payload.setdefault("q", qs[0])
        payload.setdefault("qs", qs)
        # The divergence monitor's fastest slide so far: result.json records it, as in process.
        payload.setdefault("cloth_fastest_slide_mps", self.parts.monitor.fastest_slide)
        if self.parts.guard is not None:  # the crossing guard's count, likewise
            payload.setdefault("crossing_guard_restored", self.parts.guard.restored)
        if self.slip_fault.fraction > 0:  # whether the injected slip happened (result.json)
            payload.setdefault("fault_slipped", self.slip_fault.slipped)
        self.pub["result"].publish(convert.string_msg(payload))

    # ------------------------------------------------------------------ commands
    def execute_trajectory(
        self, msg: JointTrajectoryMsg, on_check=None, times_pos_vel=None, splined: bool = False
    ) -> dict:
        """Play a trajectory at the physics step; `on_check(k, t, q_cmd, q)` (the actions
        interface's feedback and path tolerances) is called at the tracking checks and may raise
        to stop the arm where it is. Points not at the physics step are interpolated onto it:
        `splined` (the driver, points with velocities) on cubic Hermite spans, else linearly."""
        arms = trajectory_arms(list(msg.joint_names), self.arm_joints)
        times, pos, vel = times_pos_vel or convert.trajectory_arrays(msg)
        dt = self.world.time_step
        q_cmd, v_cmd = commands_at_steps(times, pos, vel, dt, splined)
        n = len(q_cmd)
        # Each moved arm's columns; arms not named hold their last command.
        dof = self.robot.dof
        moved = [(self.executors[arm], slice(i * dof, (i + 1) * dof)) for i, arm in enumerate(arms)]
        # Commanded TCP for tracking, computed at rest before the arms move.
        check = set(range(7, n, 8)) | ({n - 1} if n else set())
        tcp_ref = {
            (i, k): ex.model.fk_tcp(q_cmd[k, cols])[0]
            for i, (ex, cols) in enumerate(moved)
            for k in check
        }
        max_err = [0.0] * len(moved)
        held = [ex.grasp.held for ex, _cols in moved]
        hook = self.slip_hook(moved, q_cmd)
        try:
            for k in range(n):
                for ex, cols in moved:
                    ex.robot.command_joint_positions(q_cmd[k, cols], v_cmd[k, cols])
                self.world.step()
                if k in check:
                    for i, (ex, _cols) in enumerate(moved):
                        err = float(np.linalg.norm(ex.robot.tcp_pose()[0] - tcp_ref[i, k]))
                        max_err[i] = max(max_err[i], err)
                    if on_check is not None:
                        q_now = np.concatenate([ex.robot.joint_positions() for ex, _c in moved])
                        on_check(k, (k + 1) * dt, q_cmd[k], q_now)
        finally:
            if hook is not None:
                self.world.remove_step_hook(hook)
        # A gripper that held cloth as the motion began and no longer holds what it grasped
        # (no command opened it: that is a gripper command) reports the lost hold, as the
        # in-process cell does (SimCell._run_checked): each such arm and how much it held.
        slipped = []
        for (ex, _cols), arm, h in zip(moved, arms, held, strict=True):
            lost = ex.grasp.lost_hold(h, "motion")
            if lost is None:
                continue
            slipped.append({"arm": arm, "vertices_held": len(h)})
            # On gripper/grasp too, as a gripper's object detection reports a dropped object
            # (a recording holds it beside the grasps).
            self.pub["grasp"].publish(
                convert.string_msg(
                    {"success": False, "vertex_ids": [], "reason": lost, "arm": arm,
                     "lost_hold": True}
                )
            )  # fmt: skip
        return {
            "duration": float(times[-1]),
            "max_tracking_error": max(max_err),
            "arms": arms,
            "tracking_errors": max_err,
            "slipped": slipped,
        }

    def slip_hook(self, moved: list, q_cmd: np.ndarray):
        """The injected slip (EpisodeConfig.fault_slip), on the first motion of an arm that
        holds cloth (a carry: the gripper closes at the end of the descent before it), from the
        motion's commanded start toward its end; added as a step hook, None when none is due."""
        carrying = [(ex, cols) for ex, cols in moved if ex.grasp.holding]
        if self.slip_fault.fraction <= 0.0 or not carrying or not len(q_cmd):
            return None
        ex, cols = carrying[0]
        start, end = (ex.model.fk_tcp(q_cmd[k, cols])[0] for k in (0, -1))
        hook = self.slip_fault.hook(ex.grasp, start, end)
        if hook is not None:
            self.world.add_step_hook(hook)
        return hook

    def execute(self, kind: str, msg) -> dict:
        if kind == "trajectory":
            return self.execute_trajectory(msg)
        if kind == "gripper":
            command, arm = gripper_command(msg.data, len(self.executors))
            grasp = self.executors[arm].grasp
            if command == "close":
                g = grasp.close()
                outcome = {
                    "success": g.success,
                    "vertex_ids": list(g.vertex_ids),
                    "reason": g.reason,
                    "arm": arm,
                }
                self.pub["grasp"].publish(convert.string_msg(outcome))
                return {"grasp": outcome}
            grasp.open()
            return {}
        if kind == "wait":
            if not (np.isfinite(msg.data) and 0.0 <= msg.data <= 60.0):
                raise FoldbotError(f"sim/wait must be in [0, 60] s, got {msg.data!r}")
            self.world.step(round(msg.data / self.world.time_step))
            return {}
        if kind == "ground_truth":
            self.publish_ground_truth()
            return {}
        raise FoldbotError(f"unknown command {kind!r}")

    def prepare_cloth(self) -> None:
        """Settle the cloth; for a crumpled start, crumple it as `foldbot fold` does (the same
        seeded draw after the same settling: the same crumpled cloth as in process)."""
        rospy.loginfo("settling the cloth (%d vertices)", self.parts.mesh.vertices.shape[0])
        settle(self.world, self.parts.cloth)
        if self.cfg.start == "crumpled":
            rospy.loginfo("crumpling the towel")
            crumple_start(self.cfg, self.world, self.parts.cloth)

    def spin(self) -> None:
        mesh = self.parts.mesh
        self.publish_static()
        self.pub["mesh"].publish(
            convert.string_msg(
                {
                    "faces": np.asarray(mesh.faces).tolist(),
                    "thickness": self.parts.cloth.thickness,
                    "flat_area": mesh.area,
                }
            )
        )
        try:
            self.prepare_cloth()
        except FoldbotError as exc:
            # A crumple that diverged or left the workspace: the task node raises it.
            self.report({"command": "ready", "ok": False, "error": str(exc),
                         "error_type": type(exc).__name__})  # fmt: skip
            rospy.signal_shutdown("the cloth could not be prepared")
            return
        self.publish_ground_truth()
        self.wait_for_camera_subscribers()
        # Every node subscribed by now (the task node, a recorder) connected first, so the
        # ready report and the first frame reach them all, and a bag holds the run from its start.
        wait_for_listed_subscribers(list(self.pub.values()), "publishing the ready report")
        self.report({"command": "ready", "ok": True, "frame_stamp": self.publish_frame()})
        if self.drivers is not None:
            self.drivers.start()
            self._pace_origin = (self.world.sim_time, time.monotonic())
        while not rospy.is_shutdown():
            try:
                kind, msg = (
                    self.commands.get(timeout=0.1)
                    if self.drivers is None
                    else self.commands.get_nowait()
                )
            except queue.Empty:
                if self.drivers is None:
                    continue
                # The drivers' goals under way, else the cell left to itself: one step.
                if not (self.drivers.step() if self.drivers.busy else self._run_on()):
                    return
                continue
            if self.drivers is not None and kind != "ground_truth":
                self.rest.wake()
                if not self.drivers.accept(kind, msg):
                    return
                continue
            try:
                out = self.execute(kind, msg)
            except FoldbotError as exc:
                # Divergence or a bad command: report it (the task node raises it) and stop.
                self.fail(kind, exc)
                continue
            # A frame where the task node may look: after a wait, the cell at rest (a zero-second
            # wait is how it asks for one). After the other commands none: the task node looks
            # after few of them, and each frame is a render here and an estimate in the
            # perception node (a two-arm half fold published 13 frames after its commands and
            # looked at the 3 after its waits).
            stamp = self.publish_frame() if kind == "wait" else None
            self.report({"command": kind, "ok": True, **out, "frame_stamp": stamp})

    def _run_on(self) -> bool:
        """One step of the cell left to itself (the actions interface): the cloth settles, the
        camera streams; once the cell is still (sim.rest.RestWatch), the clock runs on without
        the physics until the next goal. A divergence is reported and ends the node (False)."""
        try:
            if self.rest.resting:
                self.world.idle()
            else:
                self.world.step()
                if self.rest.stepped():
                    rospy.logdebug("the cell is at rest at t = %.3f s", self.world.sim_time)
        except FoldbotError as exc:
            self.fail("run", exc)
            return False
        return True

    def fail(self, kind: str, exc: FoldbotError) -> None:
        """Report an error on sim/result (the task node raises it) and, for a divergence, stop;
        logged here too (a real cell's task node never reads sim/result)."""
        rospy.logerr("%s at t = %.3f s: %s", kind, self.world.sim_time, exc)
        self.report(
            {"command": kind, "ok": False, "error": str(exc), "error_type": type(exc).__name__}
        )
        if type(exc).__name__ == "SimulationDivergedError":
            rospy.signal_shutdown("the simulation diverged")


def node_param(name: str, default: Any = None) -> Any:
    """The sim node's setting `name` (a /foldbot/… parameter): its private one (~fold_args, …)
    where set, else the global one. A running cell (cell.launch) sets its own privately: a fold
    launched on the same master sets the global ones for its nodes, and a cell whose sim node read
    them (a fold started while the cell was still coming up) became the fold's, lockstep cell."""
    private = "~" + name.rsplit("/", 1)[-1]
    if rospy.has_param(private):
        return rospy.get_param(private)
    return rospy.get_param(name) if default is None else rospy.get_param(name, default)


def main(argv: list[str] | None = None) -> int:
    rospy.init_node("foldbot_sim", argv=argv if argv is not None else sys.argv)
    node = SimNode(
        node_param(FOLD_ARGS_PARAM),
        float(node_param(CAMERA_RATE_PARAM, 10.0)),
        node_param(ARM_INTERFACE_PARAM, "topics"),
        float(node_param(REAL_TIME_FACTOR_PARAM, 1.0)),
        board_arm if (board_arm := int(node_param(CALIBRATION_BOARD_PARAM, -1))) >= 0 else None,
        bool(node_param(PUBLISH_CAMERA_POSE_PARAM, True)),
        str(node_param(CALIBRATION_BOARD_PATTERN_PARAM, "chessboard")),
    )
    try:
        node.spin()
    finally:
        node.world.close()
        node.parts.model_world.close()
    return 0
