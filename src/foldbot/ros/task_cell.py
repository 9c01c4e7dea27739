"""RosCell, the FoldCell a fold runs on over ROS: its eyes are the perception node's outputs, its
planner the planner node, its arm (or arms) the sim node's commands or the arms' drivers' actions.
Kept apart from the task node (task_node.py), which sequences the fold on it and writes the episode.
"""

from __future__ import annotations

import itertools
import json
import threading
import time
from collections import OrderedDict
from typing import Any

import numpy as np
import rospy
from rosgraph_msgs.msg import Clock
from sensor_msgs.msg import CameraInfo, Image, PointCloud2
from std_msgs.msg import Empty, Float64, String
from tf2_msgs.msg import TFMessage
from trajectory_msgs.msg import JointTrajectory as JointTrajectoryMsg

from foldbot import errors
from foldbot.carry import nearest_arm
from foldbot.cell import FoldCell, StepLog, lift_move, park_move
from foldbot.io.episode import EpisodeWriter
from foldbot.loop import corners_of
from foldbot.perception.overlay import draw_overlay
from foldbot.perception.state import ClothState
from foldbot.planning.actions import FoldAction, FoldPlan
from foldbot.planning.garment_recipes import GarmentPlan
from foldbot.planning.spread import SpreadAction, action_as_dict
from foldbot.ros import (
    CAMERA_FRAME,
    TOPICS,
    WORLD_FRAME,
    arm_joint_names,
    arm_prefixes,
    convert,
    driver_actions,
)
from foldbot.ros.frames import StaticFrames
from foldbot.ros.node_args import CELLS, SLIP_FINGER_TRAVEL, TOGETHER_LEAD_S
from foldbot.ros.publish import publish_when_heard, wait_for_listed_subscribers
from foldbot.sim.grasp import slip_reason
from foldbot.sim.layout import CellLayout
from foldbot.types import GraspResult, Observation

REPLY_TIMEOUT_S = 300.0
"""Longest wall time to wait for a node's reply before the fold is abandoned."""
TF_WAIT_S = 30.0
"""How long the task waits for the latched world → camera transform after its first frame."""
FRAME_RETRY_S = 10.0
"""Wall time after which a resting frame whose perception has not arrived is asked for again."""


def _same_corners(a: dict[str, np.ndarray], b: dict[str, np.ndarray]) -> bool:
    return a.keys() == b.keys() and all(np.array_equal(a[k], b[k]) for k in a)


class _Inbox:
    """Messages of one topic as they arrive, and a wait for the next one that matches."""

    def __init__(self) -> None:
        self.items: list[Any] = []
        self.cond = threading.Condition()

    def put(self, item: Any) -> None:
        with self.cond:
            self.items.append(item)
            self.cond.notify_all()

    def take(self, match, what: str, timeout: float | None = None) -> Any:
        """The first message `match` accepts, waited for up to `timeout` s (REPLY_TIMEOUT_S)."""
        timeout = REPLY_TIMEOUT_S if timeout is None else timeout
        deadline = time.monotonic() + timeout
        with self.cond:
            while True:
                for i, item in enumerate(self.items):
                    if match(item):
                        return self.items.pop(i)
                left = deadline - time.monotonic()
                if rospy.is_shutdown():
                    raise errors.FoldbotError(f"shut down while waiting for the {what}")
                if left <= 0:
                    raise errors.FoldbotError(f"no {what} within {timeout:.0f} s")
                self.cond.wait(min(left, 0.5))


def finger_slip_reason(motion: str, travel: float) -> str:
    """The task node's word for a hold lost in `motion` (its name), seen on /joint_states as the
    fingers moving `travel` after the jaws had stalled on the cloth (drivers.ActionArm). The
    watch counts a move either way (a gripper's joints close toward + or −), so says "moved"."""
    return (
        f"the cloth slipped from the jaws in the {motion} (on /joint_states the fingers moved "
        f"by {travel:.4g}, in their joints' units, after they had stalled on it)"
    )


class RosCell(FoldCell):
    """The cell as seen over topics: the perception, planner and sim nodes."""

    def stop_video(self) -> None:
        """Let no more camera frames into the video (they arrive on rospy's threads)."""
        with self._lock:
            self.video = None

    def __init__(
        self,
        layout: CellLayout,
        video: EpisodeWriter | None,
        arms: int = 1,
        arm_interface: str = "topics",
        joint_names: tuple[str, ...] = (),
        cell: str = "sim",
        finger_names: tuple[str, ...] = (),
        finger_travel: float = SLIP_FINGER_TRAVEL,
        gripper_lead: float | None = None,
        together_lead: float = TOGETHER_LEAD_S,
        gripper_effort: float = 0.0,
    ) -> None:
        """`arm_interface` "actions" drives the arm through its drivers' actions
        (foldbot.ros.drivers.ActionArm, one per arm: `joint_names` are an arm's, prefixed
        per arm as over topics) and reads where it left the cell from /joint_states and the
        camera stream, where the gripper's `finger_names` (prefixed likewise) show a slip by
        moving over `finger_travel` (their units) after the jaws stalled on cloth, and whose
        gripper goals carry `gripper_effort` (N; 0: no limit);
        "topics" through the sim node's commands and reports. `cell` "real" (actions only)
        neither publishes nor subscribes to anything of the sim node's own (its reports,
        commands, clock, ground truth): the cell is whatever serves the drivers' actions and the
        camera."""
        if cell not in CELLS:
            raise errors.ConfigError(f"cell must be one of {', '.join(CELLS)}, got {cell!r}")
        if cell == "real" and arm_interface != "actions":
            raise errors.ConfigError(
                f"a real cell is driven through its drivers' actions, got arm interface "
                f"{arm_interface!r}"
            )
        self.cell = cell
        self.table_height = layout.table_height
        self.video = video
        self.bases_y = tuple(lay.robot_base_xyz[1] for lay in layout.arm_layouts(arms))
        """Each arm's base along y, arm 0 first (arm_for picks the arm on a point's side)."""
        self.active = 0
        self._ids = itertools.count(1)
        self._clock = 0.0
        self.fastest_slide = 0.0
        """The sim node's divergence monitor's fastest cloth slide (m/s), from its last report."""
        self.guard_restored: int | None = None
        """The sim node's crossing guard's count of mesh points put back (None: no guard)."""
        self.fault_slipped = False
        """Whether the sim node's injected slip (EpisodeConfig.fault_slip) has happened."""
        self.rest_qs = [np.zeros(0)] * arms
        """Every arm's joints where the last command left it (the sim node's report)."""
        self._lock = threading.Lock()
        self.results, self.plans = _Inbox(), _Inbox()
        self.states: OrderedDict[float, str] = OrderedDict()
        self.masks: OrderedDict[float, np.ndarray] = OrderedDict()
        self.frames: OrderedDict[float, Image] = OrderedDict()
        self._infos: OrderedDict[float, CameraInfo] = OrderedDict()
        self.depths: OrderedDict[float, Image] = OrderedDict()
        self.perceived = threading.Condition()
        self.T_world_camera: np.ndarray | None = None
        self.static_frames = StaticFrames()
        self.depth_info: CameraInfo | None = None
        """The depth camera's newest camera_info (a depth image not registered to the colour
        camera is registered onto it, as the perception node does)."""
        self.latest_state: ClothState | None = None
        self.latest_obs: Observation | None = None
        self._latest_frame_id = ""
        self.overlay: dict = {}
        self.pub_plan_overlay = rospy.Publisher(
            TOPICS["plan_overlay"], Image, queue_size=1, latch=True
        )
        """What the task plans next (show), drawn over the frame it was planned from."""
        self._planned: list[dict] = []
        """The last planned action's steps (the actions interface sends those up to a gripper
        event as one goal)."""
        self._ran: dict[int, float] = {}
        """Steps (by id) already moved through in a chain: their tracking error (m)."""
        self._gripped: dict[int, tuple[bool, str]] = {}
        """Steps (by id) whose gripper event went with their chain: (held, the driver's text)."""
        self._lost: dict[int, GraspResult] = {}
        """Steps (by id) of a chain in which the jaws were seen to lose their hold."""
        self.gripper_lead = gripper_lead
        """With the actions interface: how long (s) before a chain's end its gripper goal is
        sent (None: after the motion's result, a round trip later)."""
        self.together_lead = together_lead
        """With the actions interface: how far ahead of the cell's clock (s) a motion several
        arms make together is stamped to start."""
        self.rest_stamp: float | None = 0.0
        """The stamp of the frame the cell rests in (None: a streaming cell's next frame after
        _frame_after; the lockstep sim node's, asked for by a zero-second wait)."""
        self._frame_after = 0.0
        self.truth = _Inbox()
        self.mesh = _Inbox()
        self.pub_plan = rospy.Publisher(TOPICS["plan_request"], String, queue_size=5)
        rospy.Subscriber(TOPICS["tf_static"], TFMessage, self._on_tf)
        rospy.Subscriber(
            TOPICS["plan_response"], String, lambda m: self.plans.put(json.loads(m.data))
        )
        if cell == "sim":  # the sim node's own commands, reports, clock and ground truth
            self.pub_traj = rospy.Publisher(TOPICS["trajectory"], JointTrajectoryMsg, queue_size=5)
            self.pub_gripper = rospy.Publisher(TOPICS["gripper"], String, queue_size=5)
            self.pub_wait = rospy.Publisher(TOPICS["wait"], Float64, queue_size=5)
            self.pub_truth = rospy.Publisher(TOPICS["ground_truth_request"], Empty, queue_size=5)
            rospy.Subscriber(TOPICS["clock"], Clock, self._on_clock)
            rospy.Subscriber(
                TOPICS["cell_result"], String, lambda m: self.results.put(json.loads(m.data))
            )
            rospy.Subscriber(TOPICS["ground_truth"], PointCloud2, self.truth.put)
            rospy.Subscriber(
                TOPICS["ground_truth_mesh"], String, lambda m: self.mesh.put(json.loads(m.data))
            )
        self._start = 0.0
        """The cell's time (s) when a real cell's fold began (sim_time counts from it)."""
        rospy.Subscriber(TOPICS["state"], String, self._on_state, queue_size=200)
        rospy.Subscriber(TOPICS["mask"], Image, self._on_mask, queue_size=200, buff_size=2**24)
        self._color_sub = rospy.Subscriber(
            TOPICS["color"], Image, self._on_color, queue_size=200, buff_size=2**26
        )
        rospy.Subscriber(TOPICS["color_info"], CameraInfo, self._on_info, queue_size=200)
        rospy.Subscriber(TOPICS["depth_info"], CameraInfo, self._on_depth_info, queue_size=5)
        rospy.Subscriber(
            TOPICS["depth"],
            Image,
            lambda m: self._remember(self.depths, m.header.stamp.to_sec(), m, keep=16),
            queue_size=200,
            buff_size=2**26,
        )
        self.drivers: list = []
        """With the actions interface, each arm's drivers (foldbot.ros.drivers.ActionArm), arm 0
        first."""
        if arm_interface == "actions":
            from foldbot.ros.drivers import ActionArm

            self.drivers = [
                ActionArm(
                    names,
                    self.raise_reported_error,
                    actions,
                    fingers,
                    finger_travel,
                    gripper_effort,
                )
                for names, actions, fingers in zip(
                    arm_joint_names(joint_names, arms),
                    driver_actions(arms),
                    arm_joint_names(finger_names, arms),
                    strict=True,
                )
            ]

    # ------------------------------------------------------------------ subscriptions
    def _on_clock(self, msg: Clock) -> None:
        self._clock = max(self._clock, msg.clock.to_sec())

    def _now(self) -> float:
        """The cell's time now (s): the sim node's /clock, or on a real cell ROS time (the wall
        clock, or /clock where /use_sim_time is set), as its drivers stamp /joint_states."""
        return self._clock if self.cell == "sim" else rospy.get_time()

    def _on_depth_info(self, msg: CameraInfo) -> None:
        self.depth_info = msg

    def _on_tf(self, msg: TFMessage) -> None:
        self.static_frames.add(msg)
        T = self.static_frames.transform(WORLD_FRAME, CAMERA_FRAME)  # directly or via the camera's
        if T is not None:  # own frames, as in the perception node
            self.T_world_camera = T

    def _remember(self, store: OrderedDict, stamp: float, value: Any, keep: int = 64) -> None:
        with self.perceived:
            store[round(stamp, 6)] = value
            while len(store) > keep:
                store.popitem(last=False)
            self.perceived.notify_all()

    def _on_state(self, msg: String) -> None:
        stamp = json.loads(msg.data)["stamp"]
        self._remember(self.states, stamp, msg.data)

    def _on_mask(self, msg: Image) -> None:
        self._remember(self.masks, msg.header.stamp.to_sec(), convert.image_array(msg))

    def _on_info(self, msg: CameraInfo) -> None:
        self._remember(self._infos, msg.header.stamp.to_sec(), msg)

    def _on_color(self, msg: Image) -> None:
        stamp = msg.header.stamp.to_sec()
        self._remember(self.frames, stamp, msg, keep=16)
        if self.video is None:
            return
        # The video: every camera frame, with the newest perceived state and planned points.
        info = self._infos.get(round(stamp, 6))
        if info is None:
            frame = convert.color_array(msg)
        else:  # rectified as perception sees it, so the overlays land where they belong
            frame, _, intrinsics = convert.camera_images(msg, None, info)
        state = self.latest_state
        if (
            state is not None
            and state.detected
            and info is not None
            and self.T_world_camera is not None
        ):
            obs = Observation(
                frame,
                np.ones(frame.shape[:2], np.float32),  # drawing needs no depth
                intrinsics,
                self.T_world_camera,
            )
            frame = draw_overlay(obs, state, **self.overlay)
        with self._lock:
            if self.video is not None:  # stop_video may have run since the check above
                self.video.add_frame(frame)

    # ------------------------------------------------------------------ requests
    def _command(self, pub: rospy.Publisher, msg: Any, what: str) -> dict:
        publish_when_heard(pub, msg, REPLY_TIMEOUT_S)
        reply = self.results.take(lambda r: True, f"reply from the sim node to {what}")
        if not reply.get("ok"):
            raise errors.reported_error(reply, what)
        self._at_rest(reply)
        return reply

    def raise_reported_error(self) -> None:
        """Raise the error the sim node reported, if it has (e.g. the cloth diverged while the
        arm's driver had a goal): with the actions interface no other reply would come."""
        with self.results.cond:
            failed = [r for r in self.results.items if not r.get("ok")]
        if failed:
            raise errors.reported_error(failed[0], "the cell")

    def check_cell(self) -> None:
        """Raise when the cell has reported an error or, on a real cell, its drivers or its
        camera went away (a cell that died: nothing waited for from it would come)."""
        self.raise_reported_error()
        for driver in self.drivers:
            driver.check_servers()
        if self.frames and self._color_sub.get_num_connections() == 0:
            raise errors.FoldbotError(
                f"the camera went away: nothing publishes {TOPICS['color']} any more"
            )

    def _settle(self, ended: float = 0.0) -> None:
        """Where the arm's driver left the cell: the arm's joints from a /joint_states stamped
        after the command ended (`ended`, s, or the clock now); the camera frame to observe is
        the first after it, taken when `observe` asks (a real cell's camera streams; nothing
        waits for a frame between motions)."""
        since = max(self._now(), ended)
        self.rest_qs = [d.joints_after(since, REPLY_TIMEOUT_S) for d in self.drivers]
        self._frame_after = since
        self.rest_stamp = None

    def _first_frame_after(self, since: float) -> float:
        """The stamp of the first camera frame at or after `since` (s), waited for."""
        deadline = time.monotonic() + REPLY_TIMEOUT_S
        with self.perceived:
            while True:
                later = [stamp for stamp in self.frames if stamp >= round(since, 6)]
                if later:
                    return min(later)
                self.check_cell()
                if time.monotonic() > deadline or rospy.is_shutdown():
                    raise errors.FoldbotError(
                        f"no camera frame after t = {since:.3f} s within {REPLY_TIMEOUT_S:.0f} s"
                    )
                self.perceived.wait(0.2)

    def _at_rest(self, reply: dict) -> None:
        """Where a sim node's report left the cell: its frame, every arm's joints, its clock."""
        stamp = reply["frame_stamp"]  # None: no frame rendered (observe asks for one)
        self.rest_stamp = None if stamp is None else float(stamp)
        self.rest_qs = [np.array(q, dtype=float) for q in reply.get("qs", [reply["q"]])]
        if len(self.rest_qs) != self.arms:
            raise errors.FoldbotError(
                f"the sim node reports {len(self.rest_qs)} arms, this fold has {self.arms}"
            )
        self._clock = float(reply["sim_time"])
        self.fastest_slide = float(reply.get("cloth_fastest_slide_mps", 0.0))
        self.guard_restored = reply.get("crossing_guard_restored")
        self.fault_slipped = bool(reply.get("fault_slipped", False))

    def _plan(self, kind: str, **payload: Any) -> dict:
        rid = next(self._ids)
        request = String(data=json.dumps({"id": rid, "kind": kind, **payload}))
        publish_when_heard(self.pub_plan, request, REPLY_TIMEOUT_S)
        try:
            reply = self.plans.take(
                lambda r: r.get("id") == rid, f"{kind} plan from the planner node"
            )
        except errors.FoldbotError:
            # A cell that diverged meanwhile (running on by itself between goals) takes every
            # node down with it: its report is why no plan came.
            self.raise_reported_error()
            raise
        if not reply.get("ok"):
            raise errors.reported_error(reply, f"planning {kind}")
        return reply

    def joint_positions(self, arm: int | None = None) -> np.ndarray:
        """An arm's joints (the active arm's by default) where the last command left it (the
        sim node's report: exact, where /joint_states may lag the last step)."""
        return self.rest_qs[self.active if arm is None else arm].copy()

    def _qs(self) -> list[list[float]]:
        return [q.tolist() for q in self.rest_qs]

    def _gripper(self, command: str, arm: int) -> dict:
        """Open or close `arm`'s gripper (the sim node's gripper/command: "close", "close 1"; or
        the gripper driver's GripperCommand, where a grasp holds when the jaws stall)."""
        if self.drivers:
            held, text = self.drivers[arm].grip(
                command == "close", f"gripper {command}" + (f" {arm}" if self.arms > 1 else ""),
                REPLY_TIMEOUT_S,
            )  # fmt: skip
            self._settle()
            if command != "close":
                return {}
            return {"grasp": {"success": held, "vertex_ids": [], "reason": text}}
        text = command if self.arms == 1 else f"{command} {arm}"
        return self._command(self.pub_gripper, String(data=text), f"gripper {text}")

    # ------------------------------------------------------------------ FoldCell
    @property
    def sim_time(self) -> float:
        """The cell's clock (s): the simulated one, or on a real cell the time since the fold
        began."""
        return self._clock if self.cell == "sim" else rospy.get_time() - self._start

    @property
    def arms(self) -> int:
        return len(self.rest_qs)

    @property
    def active_arm(self) -> int:
        return self.active

    def use_arm(self, arm: int) -> None:
        if not (0 <= arm < self.arms):
            raise ValueError(f"arm must be in [0, {self.arms - 1}], got {arm!r}")
        self.active = arm

    def arm_for(self, point: np.ndarray) -> int:
        return nearest_arm(point, self.bases_y)

    def camera_transform(self, timeout_s: float = TF_WAIT_S) -> np.ndarray:
        """The world → camera transform. /tf_static is latched, but its connection may come up
        after the first frame's (seen once in CI), so it is waited for rather than missed."""
        deadline = time.monotonic() + timeout_s
        while self.T_world_camera is None:
            if time.monotonic() > deadline or rospy.is_shutdown():
                raise errors.FoldbotError(
                    f"no world → camera transform on /tf_static within {timeout_s:g} s: a "
                    "cell's camera needs its pose (find it with `foldbot ros-calibrate`, then "
                    "publish its camera_pose.launch or give ros-fold --camera-pose "
                    "CALIBRATION.json)"
                )
            time.sleep(0.05)
        return self.T_world_camera

    def wait_ready(self) -> dict:
        reply = self.results.take(
            lambda r: r.get("command") == "ready", "ready report from the sim node"
        )
        if not reply.get("ok"):
            raise errors.reported_error(reply, "preparing the cloth")
        self._at_rest(reply)
        for driver in self.drivers:
            driver.wait_for_servers()
        self._wait_for_listeners()
        return reply

    def _wait_for_listeners(self) -> None:
        """Before the first command: every node subscribed to the task's topics by now (the sim
        node, a recorder) connected, so a bag holds the fold's first request and command."""
        pubs = [self.pub_plan]
        if self.cell == "sim":
            pubs += [self.pub_traj, self.pub_gripper, self.pub_wait, self.pub_truth]
        wait_for_listed_subscribers(pubs, "starting the fold")

    def wait_for_real_cell(self, open_grippers: bool = True) -> None:
        """A real cell (no ready report): wait for every arm's drivers' action servers and the
        first /joint_states, open the grippers (unless `open_grippers` is False: a dry run
        moves nothing) and take the arms' joints from there; the first frame to observe is the
        first the camera streams after."""
        for driver in self.drivers:
            driver.wait_for_servers()
        self._wait_for_listeners()
        while rospy.get_time() <= 0.0:  # /use_sim_time set: no /clock received yet
            if rospy.is_shutdown():
                raise errors.FoldbotError("shut down before the cell's clock started")
            time.sleep(0.02)
        self._start = rospy.get_time()
        if not open_grippers:
            self._settle()  # the arms' joints and the first frame from now, nothing moved
        for arm in range(len(self.drivers) if open_grippers else 0):
            self._gripper("open", arm)

    def _have_frame(self, key: float) -> bool:
        return (
            key in self.states
            and key in self.masks
            and key in self.frames
            and key in self._infos
            and key in self.depths
        )

    def _perceived_frame(self, key: float) -> float | None:
        """The frame to observe: the resting one, or with a streaming cell (the actions
        interface) the first perceived since, should perception have passed over it."""
        if self._have_frame(key):
            return key
        if self.drivers:
            later = [k for k in self.states if k > key and self._have_frame(k)]
            if later:
                return min(later)
        return None

    def observe(self) -> tuple[ClothState, Observation]:
        if self.rest_stamp is None and not self.drivers:
            self.wait(0.0)  # the lockstep sim node renders the resting frame when asked
        if self.rest_stamp is None:  # the actions interface: the first frame since the rest
            self.rest_stamp = self._first_frame_after(self._frame_after)
        key = round(self.rest_stamp, 6)
        deadline = time.monotonic() + REPLY_TIMEOUT_S
        ask_again = time.monotonic() + FRAME_RETRY_S
        while True:
            with self.perceived:
                while self._perceived_frame(key) is None and time.monotonic() < ask_again:
                    if time.monotonic() > deadline or rospy.is_shutdown():
                        raise errors.FoldbotError(
                            f"no perception result for the frame at t = {self.rest_stamp:.3f} s"
                        )
                    self.perceived.wait(0.2)
                found = self._perceived_frame(key)
                if found is not None:
                    if found != key:  # a later frame of the streaming cell
                        key = found
                        self.rest_stamp = found
                    break
            # The frame or its perception was lost (the topics are latched, so a late subscriber
            # gets the newest; a lost message is rarer): the resting cell publishes it again at
            # the same stamp (a zero-second wait); a cell that streams (the actions interface)
            # gives the next frame.
            rospy.logwarn(
                "no perception of the frame at t = %.3f s within %.0f s; asking for another",
                self.rest_stamp,
                FRAME_RETRY_S,
            )
            self.wait(0.0)
            if self.rest_stamp is None:
                self.rest_stamp = self._first_frame_after(self._frame_after)
            key = round(self.rest_stamp, 6)
            ask_again = time.monotonic() + FRAME_RETRY_S
        with self.perceived:
            state = convert.state_from(self.states[key], self.masks[key])
            color, info, depth = self.frames[key], self._infos[key], self.depths[key]
        if (
            convert.info_for(depth, self.depth_info) is None
            and depth.header.frame_id != info.header.frame_id
        ):
            raise errors.FoldbotError(
                f"the depth images are in {depth.header.frame_id!r}, the colour images in "
                f"{info.header.frame_id!r}, and no camera_info for the depth camera came on "
                f"{TOPICS['depth_info']}: cannot register the depth onto the colour image"
            )
        rgb, z, intrinsics = self.static_frames.camera_images(color, depth, info, self.depth_info)
        obs = Observation(
            rgb=rgb,
            depth=z,
            intrinsics=intrinsics,
            T_world_camera=self.camera_transform(),
            stamp=self.rest_stamp,
        )
        self.latest_state, self.latest_obs = state, obs
        self._latest_frame_id = color.header.frame_id
        return state, obs

    def plan_stage(
        self,
        recipe: str,
        stage: int,
        corners: dict[str, np.ndarray],
        place_lift: float,
        crease_room: float = 0.0,
    ) -> tuple[FoldPlan, np.ndarray]:
        seen = self.latest_state
        if seen is not None and _same_corners(corners, corners_of(seen)):
            # Perceived corners: the planner takes them from cloth/keypoints itself.
            source = {"keypoints_stamp": seen.stamp}
        else:  # e.g. the open loop's predicted corners of a later stage
            source = {"corners": {k: [float(x) for x in v] for k, v in corners.items()}}
        reply = self._plan(
            "stage",
            recipe=recipe,
            stage=stage,
            place_lift=place_lift,
            crease_room=crease_room,
            **source,
        )
        plan = FoldPlan(
            recipe=recipe,
            fold_lines=tuple(tuple(line) for line in reply["fold_lines"]),
            actions=tuple(FoldAction.from_dict(a) for a in reply["actions"]),
        )
        return plan, np.array(reply["predicted_outline"], dtype=float)

    def plan_garment(
        self, recipe: str, keypoints: dict[str, np.ndarray], place_lift: float, thickness: float
    ) -> GarmentPlan:
        reply = self._plan(
            "garment",
            recipe=recipe,
            keypoints={k: [float(x) for x in v] for k, v in keypoints.items()},
            place_lift=place_lift,
            thickness=thickness,
        )
        return GarmentPlan.from_dict(reply["plan"])

    def plan_action(self, action: FoldAction) -> list[dict]:
        # A two-arm cell, as SimCell: the active arm first, else the other (the planner node
        # checks each against the other arm where it stands).
        steps = self.plan_on_an_able_arm(
            lambda arm: self._plan("action", action=action.as_dict(), arm=arm, qs=self._qs())[
                "steps"
            ]
        )
        self._planned, self._ran, self._gripped, self._lost = steps, {}, {}, {}  # in chains
        return steps

    def step_seconds(self, step: dict) -> float:
        # The planner node's timing of the step from its own first waypoint, dwell included.
        return float(self._time_step(step, np.array(step["path"][0], dtype=float))["times"][-1])

    def plan_together(
        self, actions: list[tuple[int, FoldAction | SpreadAction]]
    ) -> list[list[dict]]:
        # Pick-and-places, or a spread's two parts (each names its kind).
        pairs = [{"arm": arm, "action": action_as_dict(action)} for arm, action in actions]
        return self._plan("together", pairs=pairs, qs=self._qs())["steps"]

    def run_together(self, steps: list[tuple[int, dict]]) -> list[StepLog]:
        # Every arm's step timed from where it really is, as one trajectory on one clock (an arm
        # that finishes first holds still), then each arm's gripper event in turn.
        order = sorted(range(len(steps)), key=lambda i: steps[i][0])
        timed = []
        for i in order:
            arm, step = steps[i]
            path = np.array(step["path"], dtype=float)
            path[0] = self.joint_positions(arm)
            timed.append(
                {
                    "arm": arm,
                    "path": path.tolist(),
                    "points": step["points"],
                    "speed": step["speed"],
                    "dwell": step.get("dwell", 0.0),
                }
            )
        traj = self._plan("time_together", name=steps[0][1]["name"], steps=timed)["trajectory"]
        reply = self._follow(traj)
        errs = dict(zip(reply["arms"], reply["tracking_errors"], strict=True))
        lost = self._lost_holds(reply, steps[0][1]["name"])
        grips = [(arm, step["gripper"]) for arm, step in steps if step["gripper"]]
        if self.drivers and len(grips) > 1:
            held = self._grip_together(grips)
        else:
            held = {arm: self._gripper(command, arm).get("grasp") for arm, command in grips}
        logs = []
        for arm, step in steps:
            g = held.get(arm) if step["gripper"] == "close" else None
            grasp = None
            if g is not None:
                grasp = GraspResult(bool(g["success"]), tuple(g["vertex_ids"]), g["reason"])
            elif arm in lost and step["gripper"] != "open":
                grasp = lost[arm]
            logs.append(StepLog(step["name"], float(errs[arm]), grasp))
        return logs

    @staticmethod
    def _lost_holds(reply: dict, motion: str) -> dict[int, GraspResult]:
        """The grasps the sim node reports lost in a motion's reply (its gripper no longer holds
        what it grasped), by arm: failed GraspResults, which the loops treat as the in-process
        cell's slips (carry.execute_action)."""
        return {
            int(s["arm"]): GraspResult(
                False, (), s.get("reason") or slip_reason(motion, int(s["vertices_held"]))
            )
            for s in reply.get("slipped", ())
        }

    def _grip_together(self, grips: list[tuple[int, str]]) -> dict[int, dict | None]:
        """Several arms' gripper events through their drivers at once, as a bimanual cell's
        grippers act (each goal sent, then each outcome waited for); a close's grasp by arm."""
        for arm, command in grips:
            self.drivers[arm].send_grip(command == "close")
        held: dict[int, dict | None] = {}
        try:
            for arm, command in grips:
                what = f"gripper {command} {arm}"
                ok, text = self.drivers[arm].grip_result(what, REPLY_TIMEOUT_S)
                held[arm] = {"success": ok, "vertex_ids": [], "reason": text}
        except errors.FoldbotError:
            for arm, _command in grips:  # no jaws left acting (a done goal ignores it)
                self.drivers[arm].gripper.cancel_goal()
            raise
        self._settle()
        return held

    def _follow(self, traj: dict) -> dict:
        if self.drivers:
            return self._follow_through_drivers(traj)
        msg = convert.trajectory_msg(
            traj["joint_names"],
            np.array(traj["times"]),
            np.array(traj["positions"]),
            np.array(traj["velocities"]),
            self.sim_time,
            "",
        )
        return self._command(self.pub_traj, msg, f"trajectory '{traj['name']}'")

    def _driver_columns(self, joint_names: list[str]) -> list[tuple[int, list[int]]]:
        """The arms a trajectory moves, each with its joints' columns in its driver's order."""
        moved = []
        for arm, driver in enumerate(self.drivers):
            cols = [joint_names.index(n) for n in driver.arm_joints if n in joint_names]
            if cols and len(cols) != len(driver.arm_joints):
                raise errors.FoldbotError(
                    f"a trajectory moves some of arm {arm}'s joints, not all: {joint_names}"
                )
            if cols:
                moved.append((arm, cols))
        if sum(len(cols) for _, cols in moved) != len(joint_names) or not moved:
            raise errors.FoldbotError(f"a trajectory names joints no arm has: {joint_names}")
        return moved

    def _follow_through_drivers(self, traj: dict) -> dict:
        """A trajectory of one arm, or of several on one clock, through the arms' drivers: one
        arm's goal starts on arrival; several arms' goals, one to each arm's driver, start
        together at a stamp `together_lead` ahead of the cell's clock, as drivers take a goal's
        header stamp for its start. Each arm's TCP tracking error from its driver's feedback."""
        names = list(traj["joint_names"])
        moved = self._driver_columns(names)
        if len(moved) == 1:
            arm = moved[0][0]
            _times, errs, _, lost = self._follow_through_driver(traj, arm=arm)
            err = float(errs.max(initial=0.0))
            return {
                "max_tracking_error": err,
                "arms": [arm],
                "tracking_errors": [err],
                "slipped": self._slips({arm: lost}, traj["name"]),
            }
        times = np.array(traj["times"])
        pos, vel = np.array(traj["positions"]), np.array(traj["velocities"])
        what = f"trajectory '{traj['name']}'"
        start = self._now() + self.together_lead
        for arm, _cols in moved:
            self.drivers[arm].watch_hold(self._now(), REPLY_TIMEOUT_S)
        sent = [
            (arm, self.drivers[arm].send(
                [names[c] for c in cols], times, pos[:, cols], vel[:, cols], start))
            for arm, cols in moved
        ]  # fmt: skip
        try:
            feedback = [
                (arm, self.drivers[arm].finish(following, what, REPLY_TIMEOUT_S))
                for arm, following in sent
            ]
        except errors.FoldbotError:
            for arm, _following in sent:  # the other arm stops too (a done goal ignores it)
                self.drivers[arm].trajectory.cancel_goal()
            raise
        lost = {arm: self.drivers[arm].take_lost() for arm, _cols in moved}
        tracking = [self._tracking(arm, desired, actual) for arm, (_t, desired, actual) in feedback]
        self._settle(start + float(times[-1]))
        errs = [float(e.max(initial=0.0)) for e in tracking]
        return {
            "max_tracking_error": max(errs),
            "arms": [arm for arm, _ in moved],
            "tracking_errors": errs,
            "slipped": self._slips(lost, traj["name"]),
        }

    @staticmethod
    def _slips(lost: dict[int, tuple[float, float] | None], motion: str) -> list[dict]:
        """The holds the drivers' arms lost in a motion (ActionArm.take_lost), as the sim
        node's motion reply words them (its "slipped"), each with the task node's reason."""
        return [
            {"arm": arm, "vertices_held": 0, "reason": finger_slip_reason(motion, seen[1])}
            for arm, seen in lost.items()
            if seen is not None
        ]

    def _tracking(self, arm: int, desired: np.ndarray, actual: np.ndarray) -> np.ndarray:
        """TCP tracking error (m) per feedback sample, on the planner node's kinematic model."""
        if not len(desired):
            return np.zeros(0)
        reply = self._plan("tracking", arm=arm, desired=desired.tolist(), actual=actual.tolist())
        return np.array(reply["errors"])

    def _follow_through_driver(
        self, traj: dict, then_grip: bool | None = None, arm: int | None = None
    ) -> tuple[np.ndarray, np.ndarray, tuple[bool, str] | None, tuple[float, float] | None]:
        """One FollowJointTrajectory goal to `arm`'s driver (the active arm's by default); the
        driver's feedback as (time from the start, TCP tracking error on the planner node's
        kinematic model) per sample, with `then_grip` (True: close, False: open) the gripper's
        outcome, its goal sent `gripper_lead` s before the motion's end (None: after the
        motion's result), and, where the jaws held cloth and let it go before that goal, (when
        from the start, how far the fingers closed on) (ActionArm.take_lost)."""
        arm = self.active if arm is None else arm
        driver = self.drivers[arm]
        sent = self._now()
        driver.watch_hold(sent, REPLY_TIMEOUT_S)
        # It ends no sooner than its duration after it was sent (the clock reaching this node
        # may lag the driver's result by a step or two: the arm is all but still then).
        ended = self._now() + float(traj["times"][-1])
        ahead = then_grip is not None and self.gripper_lead is not None
        times, desired, actual, gripped = driver.follow(
            traj["joint_names"],
            np.array(traj["times"]),
            np.array(traj["positions"]),
            np.array(traj["velocities"]),
            f"trajectory '{traj['name']}'",
            REPLY_TIMEOUT_S,
            then_grip if ahead else None,
            self.gripper_lead or 0.0,
        )
        lost = driver.take_lost()
        errs = self._tracking(arm, desired, actual)
        self._settle(ended)
        return times, errs, gripped, None if lost is None else (lost[0] - sent, lost[1])

    def _time_step(self, step: dict, start: np.ndarray) -> dict:
        """A planned step's trajectory from joints `start` (the planner node's ruckig)."""
        path = np.array(step["path"], dtype=float)
        path[0] = start
        return self._plan(
            "time",
            name=step["name"],
            arm=self.active,
            path=path.tolist(),
            points=step["points"],
            speed=step["speed"],
            dwell=step.get("dwell", 0.0),
        )["trajectory"]

    def _run_chain(self, step: dict) -> None:
        """The actions interface: `step` and the planned steps after it up to the next gripper
        event, as one goal (the arm comes to rest between them as in the lockstep cell, but
        never waits on a round trip with the cloth hanging). Each later step is timed from
        where the one before is commanded to end; each step's tracking is kept for its log."""
        planned = self._planned
        i = next((k for k, s in enumerate(planned) if s is step), None)
        chain = [step]
        if i is not None:
            while chain[-1]["gripper"] is None and i + 1 < len(planned):
                i += 1
                chain.append(planned[i])
        trajs = [self._time_step(chain[0], self.joint_positions())]
        for nxt in chain[1:]:
            trajs.append(self._time_step(nxt, np.array(trajs[-1]["positions"][-1])))
        times, pos, vel, ends = [0.0], [trajs[0]["positions"][0]], [trajs[0]["velocities"][0]], []
        for traj in trajs:  # each one's first sample is the one before's last
            t0 = times[-1]
            times += [t0 + t for t in traj["times"][1:]]
            pos += traj["positions"][1:]
            vel += traj["velocities"][1:]
            ends.append(times[-1])
        event = chain[-1]["gripper"]
        fb_times, errs, gripped, lost = self._follow_through_driver(
            {
                "name": " + ".join(t["name"] for t in trajs),
                "joint_names": trajs[0]["joint_names"],
                "times": times,
                "positions": pos,
                "velocities": vel,
            },
            None if event is None else event == "close",
        )
        if gripped is not None:  # the chain's gripper event, done as the arm arrived
            self._gripped[id(chain[-1])] = gripped
        start = 0.0
        for s, end in zip(chain, ends, strict=True):
            mine = errs[(fb_times > start - 1e-9) & (fb_times <= end + 1e-9)]
            self._ran[id(s)] = float(mine.max(initial=0.0))
            if lost is not None and (lost[0] <= end or s is chain[-1]):
                # The hold was lost in this step (seen on /joint_states): the later steps of
                # the chain moved empty jaws; the loop lets go and lifts from where they ended.
                reason = finger_slip_reason(s["name"], lost[1])
                self._lost[id(s)] = GraspResult(False, (), reason)
                lost = None
            start = end

    def run_step(self, step: dict) -> StepLog:
        if self.drivers:
            if id(step) not in self._ran:
                self._run_chain(step)
            err = self._ran.pop(id(step))
            if (lost := self._lost.pop(id(step), None)) is not None and step["gripper"] != "open":
                return StepLog(step["name"], err, lost)
        else:
            # Time the planned joint path from where the arm really is (it may be off by the
            # tracking error), then follow it and apply the step's gripper event.
            reply = self._follow(self._time_step(step, self.joint_positions()))
            err = float(reply["max_tracking_error"])
            if step["gripper"] != "open" and self.active in (
                lost := self._lost_holds(reply, step["name"])
            ):
                return StepLog(step["name"], err, lost[self.active])
        grasp = None
        if id(step) in self._gripped:  # sent ahead of the motion's end (the actions interface)
            held, text = self._gripped.pop(id(step))
            if step["gripper"] == "close":
                grasp = GraspResult(held, (), text)
        elif step["gripper"] == "close":
            g = self._gripper("close", self.active)["grasp"]
            grasp = GraspResult(bool(g["success"]), tuple(g["vertex_ids"]), g["reason"])
        elif step["gripper"] == "open":
            self._gripper("open", self.active)
        return StepLog(step["name"], err, grasp)

    def set_finger_travel(self, travel: float) -> None:
        """How far a watched finger may move before a hold counts as lost, every arm's (the
        drivers' ActionArm.slip_travel)."""
        for driver in self.drivers:
            driver.slip_travel = travel

    def release_and_lift(self) -> None:
        if self.gate is not None:  # the lift as it would move now (the jaws leave the arm still)
            up = self._plan("lift", arm=self.active, qs=self._qs())["steps"]
            height = float(up[-1]["points"][-1][2] - up[0]["points"][0][2])
            seconds = sum(self.step_seconds(step) for step in up)
            self.confirm_move(lift_move(self.active, height, seconds))
        self._gripper("open", self.active)
        # Straight up by the episode's retreat height (the planner node's MotionConfig).
        for step in self._plan("lift", arm=self.active, qs=self._qs())["steps"]:
            self.run_step(step)

    def park(self) -> None:
        traj = self._plan("park", qs=self._qs())["trajectory"]
        if traj is not None:
            names = traj["joint_names"]
            moving = tuple(
                arm
                for arm, prefix in enumerate(arm_prefixes(self.arms))
                if any(n.startswith(prefix) for n in names)
            )
            self.confirm_move(park_move(moving, float(traj["times"][-1])))
            self._follow(traj)

    def wait(self, seconds: float) -> None:
        if self.drivers:  # a real cell rests by itself: wait on its clock
            until = self._now() + seconds
            deadline = time.monotonic() + REPLY_TIMEOUT_S
            while self._now() < until:
                self.check_cell()
                if time.monotonic() > deadline or rospy.is_shutdown():
                    raise errors.FoldbotError(f"the cell's clock did not reach {until:.3f} s")
                time.sleep(0.005)
            self._settle()
            return
        self._command(self.pub_wait, Float64(data=float(seconds)), "wait")

    def show(self, state: ClothState | None = None, **overlay: Any) -> None:
        # The video's marks from now on, and on task/plan_overlay (latched) the newest frame
        # with them: what is about to move, for RViz and for an operator answering --confirm.
        self.overlay = overlay
        obs, seen = self.latest_obs, state if state is not None else self.latest_state
        if obs is None or seen is None:
            return
        image = draw_overlay(obs, seen, **overlay)
        self.pub_plan_overlay.publish(
            convert.image_msg(image, "rgb8", obs.stamp, self._latest_frame_id)
        )

    def ground_truth(self) -> np.ndarray:
        """The cloth's vertices now (for scoring only)."""
        self.truth.items.clear()
        self._command(self.pub_truth, Empty(), "ground-truth request")
        return convert.cloud_array(
            self.truth.take(lambda m: True, "ground truth from the sim node")
        )
