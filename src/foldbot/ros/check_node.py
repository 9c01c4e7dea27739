"""The bring-up check node: `foldbot ros-check`'s run on a running cell. It asks the cell for
everything `foldbot ros-fold --cell real` will need, all of it rather than the first thing
missing, and says what it found: each arm's driver actions, /joint_states with every joint
within its limits, the camera's colour, depth and camera_info (with a calibration's pose, its
image size, K and distortion as the calibration was solved with), world → base_link and
world → the camera on /tf_static (or a calibration's pose), a UR arm's own controller's flange
where foldbot's model of the arm puts it (base → tool0_controller on /tf), the table where the
layout puts it
as the camera's depth sees it, the layout's obstacles the camera sees where the file puts them,
and every workspace point reached by an arm and inside the image (foldbot.layout_check). Moves nothing. Writes ros_check.json and ros_check.png (the camera's
image, the workspace drawn where the camera's pose puts it) into the staging folder it is given.
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import threading
import time
from collections.abc import Sequence
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any

import actionlib
import cv2
import imageio.v3 as iio
import numpy as np
import rospy
from sensor_msgs.msg import CameraInfo, Image, JointState
from tf2_msgs.msg import TFMessage

from foldbot.control.executor import ArmExecutor
from foldbot.errors import ConfigError, FoldbotError
from foldbot.garments import GARMENTS
from foldbot.layout_check import (
    OBSTACLE_SEEN_FRACTION,
    CameraPlacement,
    ObstacleSighting,
    check_layout,
    obstacles_in_depth,
)
from foldbot.loop import cut_by_image_edge
from foldbot.perception.fallback import vision_estimator
from foldbot.perception.overlay import draw_overlay
from foldbot.perception.state import ClothState
from foldbot.ros import (
    BASE_FRAME,
    TOPICS,
    UR_BASE_FRAME,
    UR_TOOL_FRAME,
    WORLD_FRAME,
    arm_joint_names,
    arm_prefixes,
    convert,
    driver_actions,
)
from foldbot.ros.control_msgs import msg as control_msgs
from foldbot.ros.frames import StaticFrames
from foldbot.sim.layout import DEFAULT_LAYOUT, CellLayout, load_layout
from foldbot.sim.robots import ROBOT_NAMES, make_robot, robot_class
from foldbot.sim.robots.kinematics import UR_DH, pose_offset, ur5_fk
from foldbot.sim.world import SimConfig, SimWorld
from foldbot.types import Observation

WAIT_S = 30.0
"""How long (wall s) the check waits for what the cell should serve (its action servers, together;
then its joint states; then its camera's topics): a loaded cell can be slow to connect."""
BASE_TOLERANCE_M = 0.01
"""How far world → base_link may lie from the layout's robot_base_xyz (m)."""
TABLE_TOLERANCE_M = 0.01
"""How far the table the depth shows may lie from the layout's table_height (m)."""
TILT_TOLERANCE_DEG = 2.0
"""How far from level the table the depth shows may be tilted (a camera pose turned wrong)."""
MODEL_TOLERANCE_M = 0.01
"""How far foldbot's model of a UR arm may put its flange from where the arm's controller says
it is (base → tool0_controller), at the joints the arm reports (m): a factory-calibrated arm
lies a few mm from its nominal lengths; another model (a UR5e's lengths for a UR5's) centimetres."""
MODEL_TOLERANCE_DEG = 1.0
"""The same, for the flange's orientation (degrees)."""
TOOL_WAIT_S = 3.0
"""How long (wall s) the check waits for base → tool0_controller on /tf after the joints came:
ur_robot_driver streams it at the controller's rate."""


@dataclass(frozen=True)
class Check:
    """One line of the check: what was asked, whether the cell answered right, and what it said."""

    name: str
    ok: bool
    detail: str


class _Inbox:
    """The newest message of each topic the check listens to."""

    def __init__(self) -> None:
        self.lock = threading.Lock()
        self.latest: dict[str, Any] = {}
        self.frames = StaticFrames()
        topics = {
            "color": (TOPICS["color"], Image),
            "color_info": (TOPICS["color_info"], CameraInfo),
            "depth": (TOPICS["depth"], Image),
            "depth_info": (TOPICS["depth_info"], CameraInfo),
            "joint_states": (TOPICS["joint_states"], JointState),
        }
        for key, (topic, kind) in topics.items():
            rospy.Subscriber(
                topic,
                kind,
                self._keep(key),
                queue_size=2,
                buff_size=2**24 if kind is Image else 65536,
            )
        rospy.Subscriber(TOPICS["tf_static"], TFMessage, self._on_tf, queue_size=10)
        self.tools: dict[str, tuple[str, np.ndarray]] = {}
        """The newest transform /tf gave each UR_TOOL_FRAME (prefixed): its parent and pose."""
        rospy.Subscriber(TOPICS["tf"], TFMessage, self._on_moving_tf, queue_size=50)

    def _keep(self, key: str):
        def keep(msg) -> None:
            with self.lock:
                self.latest[key] = msg

        return keep

    def _on_tf(self, msg: TFMessage) -> None:
        with self.lock:
            self.frames.add(msg)

    def _on_moving_tf(self, msg: TFMessage) -> None:
        for t in msg.transforms:
            child = t.child_frame_id.lstrip("/")
            if child.endswith(UR_TOOL_FRAME):
                with self.lock:
                    self.tools[child] = (t.header.frame_id.lstrip("/"), convert.matrix_of(t))

    def wait_tools(self, children: Sequence[str], timeout_s: float) -> dict[str, tuple]:
        """The newest transform of each of `children` (UR_TOOL_FRAME, prefixed) within
        `timeout_s`, those that came."""
        deadline = time.monotonic() + timeout_s
        while time.monotonic() < deadline and not rospy.is_shutdown():
            with self.lock:
                if all(c in self.tools for c in children):
                    break
            time.sleep(0.02)
        with self.lock:
            return {c: self.tools[c] for c in children if c in self.tools}

    def wait(self, keys: tuple[str, ...], timeout_s: float) -> dict[str, Any]:
        """The newest of each of `keys` that came within `timeout_s` (those that did not: absent)."""
        deadline = time.monotonic() + timeout_s
        while time.monotonic() < deadline and not rospy.is_shutdown():
            with self.lock:
                if all(k in self.latest for k in keys):
                    break
            time.sleep(0.02)
        with self.lock:
            return {k: self.latest[k] for k in keys if k in self.latest}


def check_drivers(arms: int) -> list[Check]:
    """Each arm's FollowJointTrajectory and GripperCommand action servers answer (all asked at
    once, within one WAIT_S: a busy cell can take seconds to connect an action's topics)."""
    kinds = (control_msgs.FollowJointTrajectoryAction, control_msgs.GripperCommandAction)
    clients = {
        name: actionlib.SimpleActionClient(name, kind)
        for names in driver_actions(arms)
        for name, kind in zip(names, kinds, strict=True)
    }
    ready = dict.fromkeys(clients, False)
    deadline = time.monotonic() + WAIT_S
    while not all(ready.values()) and time.monotonic() < deadline and not rospy.is_shutdown():
        for name, client in clients.items():
            if not ready[name]:
                ready[name] = client.wait_for_server(rospy.Duration(0.05))
    return [
        Check(
            f"action {rospy.resolve_name(name)}",
            ok,
            "its server answers" if ok else f"no action server within {WAIT_S:g} s",
        )
        for name, ok in ready.items()
    ]


def check_joints(inbox: _Inbox, robot: str, arms: int) -> Check:
    """/joint_states names every arm joint, each finite and within the robot's limits."""
    msg = inbox.wait(("joint_states",), WAIT_S).get("joint_states")
    topic = rospy.resolve_name(TOPICS["joint_states"])
    if msg is None:
        return Check(f"joints on {topic}", False, f"no message within {WAIT_S:g} s")
    cls = robot_class(robot)
    position = dict(zip(msg.name, msg.position, strict=False))
    problems = []
    for names in arm_joint_names(cls.ARM_JOINT_NAMES, arms):
        for j, name in enumerate(names):
            if name not in position:
                problems.append(f"{name} missing")
                continue
            q = position[name]
            lo, hi = cls.LOWER_LIMITS[j], cls.UPPER_LIMITS[j]
            if not (np.isfinite(q) and lo - 1e-6 <= q <= hi + 1e-6):
                problems.append(f"{name} = {q:.4g} rad outside [{lo:.4g}, {hi:.4g}]")
    count = sum(len(n) for n in arm_joint_names(cls.ARM_JOINT_NAMES, arms))
    if problems:
        return Check(f"joints on {topic}", False, "; ".join(problems))
    return Check(
        f"joints on {topic}", True, f"all {count} arm joints of the {robot}, within limits"
    )


def arm_model_offsets(
    q: np.ndarray, T_base_tool: np.ndarray, robot: str
) -> dict[str, tuple[float, float]]:
    """For `robot` and every other UR model: how far its kinematics at joints `q` put the flange
    from `T_base_tool` (the arm's controller's), as (m, rad), `robot` first."""
    models = [robot, *(m for m in ROBOT_NAMES if m in UR_DH and m != robot)]
    return {m: pose_offset(ur5_fk(q, m), T_base_tool) for m in models}


def model_words(robot: str, offsets: dict[str, tuple[float, float]]) -> tuple[bool, str]:
    """Whether `robot`'s offset is within MODEL_TOLERANCE_M/DEG, and the words that say so
    (naming the UR model that would be, where `robot` is not)."""
    dist, angle = offsets[robot]
    ok = dist <= MODEL_TOLERANCE_M and np.degrees(angle) <= MODEL_TOLERANCE_DEG
    words = (
        f"the {robot}'s kinematics put the flange {dist * 1000:.1f} mm and "
        f"{np.degrees(angle):.2f}° from where the arm's controller says it is"
    )
    if ok:
        return True, words
    words += f" (at most {MODEL_TOLERANCE_M * 1000:g} mm and {MODEL_TOLERANCE_DEG:g}°)"
    better = [
        m
        for m, (d, a) in offsets.items()
        if m != robot and d <= MODEL_TOLERANCE_M and np.degrees(a) <= MODEL_TOLERANCE_DEG
    ]
    if better:
        d, a = offsets[better[0]]
        words += (
            f"; the {better[0]}'s put it {d * 1000:.1f} mm and {np.degrees(a):.2f}° off: "
            f"the arm is a {better[0]} (--robot {better[0]})"
        )
    else:
        words += ": is --robot the arm's model? (or its calibration far from its nominal lengths)"
    return False, words


def check_arm_model(inbox: _Inbox, robot: str, arms: int) -> Check | None:
    """A UR arm's flange where its own controller puts it (base → tool0_controller on /tf,
    ur_robot_driver's) against where foldbot's model of the arm puts it at the joints the arm
    reports, every arm: planned on another arm's lengths (a UR5's for a UR5e), every waypoint
    would be centimetres off. None for an arm that is not a UR (nothing to compare with)."""
    if robot not in UR_DH:
        return None
    cls = robot_class(robot)
    prefixes = arm_prefixes(arms)
    tools = inbox.wait_tools([p + UR_TOOL_FRAME for p in prefixes], TOOL_WAIT_S)
    msg = inbox.wait(("joint_states",), WAIT_S).get("joint_states")  # the newest, with /tf's
    position = {} if msg is None else dict(zip(msg.name, msg.position, strict=False))
    arm_names = ("arm",) if arms == 1 else ("left arm", "right arm")
    lines, ok = [], True
    for name, prefix, joints in zip(
        arm_names, prefixes, arm_joint_names(cls.ARM_JOINT_NAMES, arms), strict=True
    ):
        tool = prefix + UR_TOOL_FRAME
        if tool not in tools:
            ok = False
            lines.append(
                f"{name}: no {prefix}{UR_BASE_FRAME} → {tool} on /tf within {TOOL_WAIT_S:g} s "
                "(ur_robot_driver publishes the arm's own forward kinematics there; without it "
                "the arm is not checked against foldbot's model of it)"
            )
            continue
        if not all(j in position for j in joints):
            ok = False
            lines.append(f"{name}: its joints are not on /joint_states")
            continue
        _parent, T = tools[tool]
        q = np.array([position[j] for j in joints])
        fits, words = model_words(robot, arm_model_offsets(q, T, robot))
        ok = ok and fits
        lines.append(words if arms == 1 else f"{name}: {words}")
    return Check("the arm as modelled", ok, "; ".join(lines))


def check_obstacles(inbox: _Inbox, layout: CellLayout, robot: str, arms: int) -> Check:
    """No arm rests in one of the layout's obstacles (its home), nor stands in one now (the
    joints on /joint_states): either would say the layout's obstacles are not where the cell's
    fixtures are, or the arm is where no motion may start. On twins in a world of their own."""
    msg = inbox.wait(("joint_states",), WAIT_S).get("joint_states")
    position = {} if msg is None else dict(zip(msg.name, msg.position, strict=False))
    cls = robot_class(robot)
    world = SimWorld(SimConfig(layout=layout))
    problems = []
    try:
        arm_names = ("arm",) if arms == 1 else ("left arm", "right arm")
        for a, (arm_layout, names) in enumerate(
            zip(layout.arm_layouts(arms), arm_joint_names(cls.ARM_JOINT_NAMES, arms), strict=True)
        ):
            model = make_robot(robot, world.client, arm_layout)
            postures = {"home": np.asarray(model.home_q, dtype=float)}
            if all(n in position for n in names):
                postures["current (/joint_states)"] = np.array([position[n] for n in names])
            try:
                ArmExecutor(world, model, None).check_postures(postures)  # type: ignore[arg-type]
            except ConfigError as exc:
                problems.append(f"{arm_names[a]}: {exc}")
    finally:
        world.close()
    names = ", ".join(repr(o.name) for o in layout.obstacles)
    return Check(
        "the layout's obstacles",
        not problems,
        "; ".join(problems)
        or f"{names}: no arm rests or stands in one (every motion keeps 2 cm from them)",
    )


def _pose_check(
    name: str, T: np.ndarray | None, expected_xyz, tolerance: float, hint: str
) -> Check:
    if T is None:
        return Check(name, False, f"not on /tf_static; {hint}")
    off = float(np.linalg.norm(T[:3, 3] - np.asarray(expected_xyz)))
    xyz = ", ".join(f"{v:.3f}" for v in T[:3, 3])
    if off > tolerance:
        return Check(
            name,
            False,
            f"at ({xyz}) m, {1000 * off:.0f} mm from the layout's "
            f"({', '.join(f'{v:g}' for v in expected_xyz)}): is the layout file the cell's?",
        )
    return Check(name, True, f"at ({xyz}) m, as the layout says")


def check_table(
    depth: np.ndarray, K: np.ndarray, T_world_camera: np.ndarray, layout: CellLayout
) -> Check:
    """The table top the depth shows over the workspace lies at the layout's height and level:
    the camera's pose and the layout agree (a pose turned or moved wrong tilts or lifts it)."""
    h, w = depth.shape
    v, u = np.mgrid[0:h, 0:w]
    z = depth.ravel()
    ok = np.isfinite(z) & (z > 0)
    rays = np.linalg.inv(K) @ np.stack([u.ravel()[ok], v.ravel()[ok], np.ones(ok.sum())])
    points = (T_world_camera[:3, :3] @ (rays * z[ok]) + T_world_camera[:3, 3:4]).T
    x0, x1, y0, y1 = layout.workspace_bounds
    inside = (
        (points[:, 0] >= x0) & (points[:, 0] <= x1) & (points[:, 1] >= y0) & (points[:, 1] <= y1)
    )
    points = points[inside]
    name = "the table in depth"
    if len(points) < 100:
        return Check(name, False, "under 100 depth pixels over the workspace: is it in view?")
    # The table is the lowest large surface: fit a plane to the lowest half of the points (a
    # cloth or an arm over the table lies above it).
    low = points[points[:, 2] <= np.median(points[:, 2])]
    A = np.column_stack([low[:, 0], low[:, 1], np.ones(len(low))])
    (a, b, c), *_ = np.linalg.lstsq(A, low[:, 2], rcond=None)
    cx, cy = layout.workspace_center_xy
    height = float(a * cx + b * cy + c)
    tilt = float(np.degrees(np.arctan(np.hypot(a, b))))
    off = height - layout.table_height
    detail = (
        f"at {height:.4f} m over the workspace centre ({1000 * off:+.1f} mm from the layout's "
        f"{layout.table_height:g}), tilted {tilt:.2f}°"
    )
    good = abs(off) <= TABLE_TOLERANCE_M and tilt <= TILT_TOLERANCE_DEG
    if not good:
        detail += (
            f" (allowed ±{1000 * TABLE_TOLERANCE_M:.0f} mm, {TILT_TOLERANCE_DEG:g}°): the camera's "
            "pose or the layout's table_height is off"
        )
    return Check(name, good, detail)


CLOTH_NAMES = {"towel": "the towel", "tshirt": "the T-shirt", "pants": "the pants"}
"""How a check line names the cloth --garment says the fold will find."""


INTRINSICS_TOLERANCE_PX = 0.5
"""How far the camera's fx, fy, cx, cy may lie from those a calibration was solved with (px)."""
DISTORTION_TOLERANCE = 1e-3
"""How far each of its distortion coefficients may lie from the calibration's."""


@dataclass(frozen=True)
class CalibratedCamera:
    """The camera a calibration was solved with: K (3 × 3), image size (px) and, where the file
    records it, the distortion coefficients."""

    K: np.ndarray
    width: int
    height: int
    distortion: np.ndarray | None


def check_intrinsics(info: CameraInfo, calibrated: CalibratedCamera) -> Check:
    """The running camera is the one the calibration was solved with: its camera_info's image
    size, K (within INTRINSICS_TOLERANCE_PX) and distortion (within DISTORTION_TOLERANCE, the
    shorter list padded with zeros). Another resolution, lens or driver mode since then leaves
    the calibration's pose unproven."""
    name = "the camera as calibrated"
    K = np.asarray(info.K, dtype=float).reshape(3, 3)
    now = f"{info.width} × {info.height} px, fx {K[0, 0]:.1f} px"
    then = f"{calibrated.width} × {calibrated.height} px, fx {calibrated.K[0, 0]:.1f} px"
    fix = (
        ": calibrate again (`foldbot ros-calibrate`) or run the camera as it was then "
        "(resolution, driver mode, lens)"
    )
    if (info.width, info.height) != (calibrated.width, calibrated.height):
        return Check(name, False, f"its camera_info is {now}, the calibration's {then}{fix}")
    idx = ((0, 0), (1, 1), (0, 2), (1, 2))
    off = max(abs(K[i] - calibrated.K[i]) for i in idx)
    if off > INTRINSICS_TOLERANCE_PX:
        names = ("fx", "fy", "cx", "cy")
        words = ", ".join(f"{n} {K[i]:.1f}" for n, i in zip(names, idx, strict=True))
        cal = ", ".join(f"{n} {calibrated.K[i]:.1f}" for n, i in zip(names, idx, strict=True))
        return Check(
            name,
            False,
            f"its camera_info's K ({words} px) lies {off:.1f} px from the calibration's "
            f"({cal} px){fix}",
        )
    detail = f"{now} as the calibration was solved with"
    if calibrated.distortion is None:
        return Check(name, True, detail + " (the calibration records no distortion)")
    d_now = np.asarray(info.D, dtype=float).ravel()
    d_cal = calibrated.distortion
    n = max(d_now.size, d_cal.size)
    diff = np.abs(np.pad(d_now, (0, n - d_now.size)) - np.pad(d_cal, (0, n - d_cal.size)))
    if n and float(diff.max()) > DISTORTION_TOLERANCE:
        return Check(
            name,
            False,
            f"its camera_info's distortion {np.round(d_now, 4).tolist()} is not the "
            f"calibration's {np.round(d_cal, 4).tolist()} (coefficient {int(diff.argmax())} "
            f"{float(diff.max()):.4f} apart){fix}",
        )
    return Check(name, True, detail + ", its distortion too")


def check_obstacles_seen(sightings: Sequence[ObstacleSighting]) -> Check:
    """Each of the layout's obstacles the camera sees is where the file puts it
    (layout_check.obstacles_in_depth's `sightings`): of the pixels whose line of sight meets its
    box, most see it there rather than past it (a box drawn where nothing stands, or a fixture
    moved since). Out of view, it is named as not checked."""
    name = "the obstacles in view"
    wrong = [s for s in sightings if not s.where_the_layout_says]
    words = []
    for s in sightings:
        if not s.in_view:
            words.append(f"{s.name!r} out of view (not checked)")
        else:
            where = "where the layout puts it" if s.where_the_layout_says else "NOT there"
            words.append(
                f"{s.name!r} {where}: seen on {100 * s.seen_fraction:.0f} % of the "
                f"{s.seen + s.past} pixels that look at it"
            )
    detail = "; ".join(words)
    if wrong:
        names = ", ".join(repr(s.name) for s in wrong)
        detail += (
            f" — the camera sees past {names} (under {100 * OBSTACLE_SEEN_FRACTION:.0f} % on "
            "it): is the layout file this cell's, the fixture where the file says, the camera's "
            "pose right?"
        )
    return Check(name, not wrong, detail)


def camera_as_calibrated(calibrated: CalibratedCamera | None) -> Check | None:
    """check_intrinsics on the camera_info the running camera publishes within WAIT_S (a failed
    check where none comes); None where the calibration records no intrinsics to compare."""
    if calibrated is None:
        return None
    got = _Inbox().wait(("color_info",), WAIT_S)
    if "color_info" not in got:
        return Check(
            "the camera as calibrated",
            False,
            f"nothing on {rospy.resolve_name(TOPICS['color_info'])} within {WAIT_S:g} s",
        )
    return check_intrinsics(got["color_info"], calibrated)


def check_cloth(obs: Observation, layout: CellLayout, garment: str) -> tuple[Check, ClothState]:
    """What perception makes of the camera's frame, as the fold's first look will: the cloth
    found, whole in the image (a cloth cut by the image's edge hides its corners), and every
    keypoint over the layout's workspace (where the arm is checked to reach)."""
    name = CLOTH_NAMES[garment]
    state = vision_estimator(garment, layout.obstacles).estimate(obs)
    if not state.detected:
        return Check(name, False, f"not found ({state.reason}): lay it flat on the table"), state
    if cut_by_image_edge(state):
        detail = "found, but cut by the image's edge: its corners cannot all be seen"
        return Check(name, False, detail), state
    x0, x1, y0, y1 = layout.workspace_bounds
    out = [
        label
        for label, (xyz, _conf) in state.keypoints.items()
        if not (x0 <= xyz[0] <= x1 and y0 <= xyz[1] <= y1)
    ]
    seen = f"found, {len(state.keypoints)} keypoints, {state.coverage_m2:.3f} m² seen from above"
    if out:
        detail = (
            f"{seen}; outside the workspace x {x0:.2f}–{x1:.2f}, y {y0:.2f}–{y1:.2f} m: "
            + ", ".join(out)
            + " (move it, or the layout's workspace)"
        )
        return Check(name, False, detail), state
    return Check(name, True, seen + ", every one over the workspace"), state


BOX_EDGES = tuple((a, b) for a in range(8) for b in range(a + 1, 8) if bin(a ^ b).count("1") == 1)
"""The 12 edges of a box by its corners' indices (sim.layout.Obstacle.corners: bit 2 along its
x, bit 1 along y, bit 0 along z)."""


def check_picture(
    rgb: np.ndarray,
    camera: CameraPlacement,
    layout: CellLayout,
    seen: np.ndarray,
    xs,
    ys,
    sightings: Sequence[ObstacleSighting] = (),
) -> np.ndarray:
    """The camera's image with the workspace's outline (white) and its grid points (green:
    inside the image) drawn where the camera's pose puts them on the table, and each obstacle in
    view as a box (blue: seen where the layout puts it, red: the camera sees past it)."""
    img = np.ascontiguousarray(rgb[..., :3].copy())
    verdict = {s.name: s.where_the_layout_says for s in sightings if s.in_view}
    for obstacle in layout.obstacles:
        if obstacle.name not in verdict:
            continue
        uv, depth = camera.project(obstacle.corners())
        if not (depth > 0).all():
            continue
        colour = (0, 130, 200) if verdict[obstacle.name] else (230, 25, 75)
        for a, b in BOX_EDGES:
            pa, pb = np.round(uv[a]).astype(int), np.round(uv[b]).astype(int)
            cv2.line(img, tuple(pa), tuple(pb), colour, 2, cv2.LINE_AA)
    x0, x1, y0, y1 = layout.workspace_bounds
    z = layout.table_height
    edge = np.array([(x0, y0, z), (x1, y0, z), (x1, y1, z), (x0, y1, z)])
    uv, depth = camera.project(edge)
    if (depth > 0).all():
        cv2.polylines(img, [np.round(uv).astype(np.int32)], True, (255, 255, 255), 2, cv2.LINE_AA)
    gx, gy = np.meshgrid(xs, ys)
    pts = np.stack([gx.ravel(), gy.ravel(), np.full(gx.size, z)], axis=1)
    uv, depth = camera.project(pts)
    for (u, v), d, ok in zip(uv, depth, seen.ravel(), strict=True):
        if d > 0 and np.isfinite(u) and np.isfinite(v) and ok:
            cv2.circle(img, (round(u), round(v)), 3, (60, 180, 75), -1, cv2.LINE_AA)
    return img


def run_checks(
    robot: str,
    arms: int,
    layout: CellLayout,
    camera_pose: np.ndarray | None,
    garment: str | None = "towel",
    calibrated: CalibratedCamera | None = None,
) -> tuple[list[Check], np.ndarray | None, dict[str, Any]]:
    """Every check on the cell the master serves (the cloth `garment` as perception sees it;
    None: not looked for; the camera compared with the one a calibration was solved with, where
    `calibrated` gives it): the lines, the picture (None without a camera frame and pose) and
    what the record keeps besides."""
    inbox = _Inbox()
    checks = check_drivers(arms)
    checks.append(check_joints(inbox, robot, arms))
    model = check_arm_model(inbox, robot, arms)
    if model is not None:
        checks.append(model)
    if layout.obstacles:
        checks.append(check_obstacles(inbox, layout, robot, arms))
    got = inbox.wait(("color", "color_info", "depth"), WAIT_S)
    depth_info = inbox.wait(("depth_info",), 0.5).get("depth_info")
    missing = [TOPICS[k] for k in ("color", "color_info", "depth") if k not in got]
    extra: dict[str, Any] = {}
    rgb = depth = intr = None
    if missing:
        checks.append(
            Check(
                "camera",
                False,
                f"nothing on {', '.join(map(rospy.resolve_name, missing))} within {WAIT_S:g} s",
            )
        )
    else:
        try:
            with inbox.lock:
                rgb, depth, intr = inbox.frames.camera_images(
                    got["color"], got["depth"], got["color_info"], depth_info
                )
            checks.append(
                Check(
                    "camera",
                    True,
                    f"colour {got['color'].encoding} and depth {got['depth'].encoding}, "
                    f"{intr.width} × {intr.height} px, fx {intr.fx:.1f} px",
                )
            )
        except FoldbotError as exc:
            checks.append(Check("camera", False, str(exc)))
        if calibrated is not None:
            checks.append(check_intrinsics(got["color_info"], calibrated))
    # The frames: world → each base_link, world → the camera.
    time.sleep(0.2)  # /tf_static is latched: it has come with the first messages
    with inbox.lock:
        frames = inbox.frames
        for prefix, arm_layout in zip(arm_prefixes(arms), layout.arm_layouts(arms), strict=True):
            T = frames.transform(WORLD_FRAME, prefix + BASE_FRAME)
            checks.append(
                _pose_check(
                    f"{WORLD_FRAME} → {prefix}{BASE_FRAME}",
                    T,
                    arm_layout.robot_base_xyz,
                    BASE_TOLERANCE_M,
                    "the arm's driver or the cell's launch file publishes it",
                )
            )
        cam_frame = got["color_info"].header.frame_id if "color_info" in got else None
        T_cam = None
        if camera_pose is not None:
            T_cam = camera_pose
            checks.append(Check("camera pose", True, "the calibration's (--camera-pose)"))
        elif cam_frame is not None:
            T_cam = frames.transform(WORLD_FRAME, cam_frame)
            checks.append(
                Check(
                    f"{WORLD_FRAME} → {cam_frame}",
                    T_cam is not None,
                    "on /tf_static"
                    if T_cam is not None
                    else "not on /tf_static: calibrate the camera (`foldbot ros-calibrate`) and "
                    "publish its pose, or give it here (--camera-pose CALIBRATION.json)",
                )
            )
    picture = None
    sightings: list[ObstacleSighting] = []
    if depth is not None and intr is not None and T_cam is not None:
        checks.append(check_table(depth, intr.K, T_cam, layout))
        if layout.obstacles:
            sightings = obstacles_in_depth(depth, intr.K, T_cam, layout.obstacles)
            checks.append(check_obstacles_seen(sightings))
    if intr is not None and T_cam is not None:
        placement = CameraPlacement(T_cam, intr.K, intr.width, intr.height, "the cell's camera")
        found = check_layout(layout, placement, robot=robot, arms=arms)
        unreached = found.points - int(found.covered.sum())
        checks.append(
            Check(
                "the arm's reach",
                unreached == 0,
                f"{int(found.covered.sum())} of {found.points} workspace points grasped and "
                "placed gripper down"
                + ("" if unreached == 0 else " (`foldbot check-layout` names the rest)"),
            )
        )
        seen = int(found.in_view.sum())
        hidden = sum(found.hidden.values())
        checks.append(
            Check(
                "the workspace in view",
                seen == found.points,
                f"{seen} of {found.points} workspace points inside the image"
                + (f" and not behind an obstacle ({hidden} behind one)" if hidden else "")
                + ", "
                + found.resolution_words("its centre"),
            )
        )
        extra["T_world_camera"] = T_cam.tolist()
        extra["K"] = intr.K.tolist()
        if rgb is not None:
            base = rgb
            if depth is not None and garment is not None:
                obs = Observation(rgb[..., :3], depth, intr, T_cam)
                cloth, state = check_cloth(obs, layout, garment)
                checks.append(cloth)
                if state.detected:  # its outline and keypoints, as the fold's overlays draw them
                    base = draw_overlay(obs, state)
                extra["keypoints"] = {
                    label: np.asarray(xyz, dtype=float).tolist()
                    for label, (xyz, _conf) in state.keypoints.items()
                }
            picture = check_picture(
                base, placement, layout, found.in_view, found.xs, found.ys, sightings
            )
    return checks, picture, extra


def main(argv: list[str] | None = None) -> int:
    from foldbot.calibration.capture import calibration_camera, calibration_distortion

    parser = argparse.ArgumentParser(prog="foldbot_check")
    parser.add_argument("--stage", type=Path, default=None)
    parser.add_argument(
        "--camera-only",
        action="store_true",
        help="only whether the camera is the one --camera-pose's calibration was solved with "
        "(ros-fold --cell real asks it before it launches); prints the check, writes nothing",
    )
    parser.add_argument("--robot", default="ur5")
    parser.add_argument("--arms", type=int, default=1)
    parser.add_argument("--layout", type=Path, default=None)
    parser.add_argument("--camera-pose", type=Path, default=None)
    parser.add_argument("--garment", choices=(*GARMENTS, "none"), default="towel")
    args = parser.parse_args(rospy.myargv(argv if argv is not None else sys.argv)[1:])
    if args.camera_only and args.camera_pose is None:
        parser.error("--camera-only needs --camera-pose")
    if not args.camera_only and args.stage is None:
        parser.error("--stage is required")
    rospy.init_node("foldbot_check", anonymous=True, disable_signals=True)
    try:
        layout = DEFAULT_LAYOUT if args.layout is None else load_layout(args.layout)
        pose = calibrated = None
        if args.camera_pose is not None:
            pose, lens = calibration_camera(args.camera_pose)
            if lens is not None:  # the intrinsics it was solved with: the camera should match
                dist = calibration_distortion(args.camera_pose)
                calibrated = CalibratedCamera(*lens, distortion=dist)
        if args.camera_only:
            check = camera_as_calibrated(calibrated)
            if check is not None:
                print(f"{'ok  ' if check.ok else 'FAIL'} {check.name}: {check.detail}", flush=True)
            return 0 if check is None or check.ok else 1
        garment = None if args.garment == "none" else args.garment
        checks, picture, extra = run_checks(
            args.robot, args.arms, layout, pose, garment, calibrated
        )
        record = {
            "ok": all(c.ok for c in checks),
            "master": os.environ.get("ROS_MASTER_URI", ""),
            "robot": args.robot,
            "arms": args.arms,
            "layout": layout.changes(),
            "garment": garment,
            "checks": [asdict(c) for c in checks],
            **extra,
        }
        (args.stage / "ros_check.json").write_text(json.dumps(record, indent=2) + "\n")
        if picture is not None:
            iio.imwrite(args.stage / "ros_check.png", picture)
        for c in checks:
            print(f"{'ok  ' if c.ok else 'FAIL'} {c.name}: {c.detail}", flush=True)
    except FoldbotError as exc:
        print(f"{type(exc).__name__}: {exc}", file=sys.stderr, flush=True)
        return 2
    finally:
        rospy.signal_shutdown("check done")
    return 0 if record["ok"] else 1


if __name__ == "__main__":
    sys.exit(main())
