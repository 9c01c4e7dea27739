"""Conversions between foldbot's types and ROS 1 messages (sensor_msgs, geometry_msgs,
trajectory_msgs, std_msgs), in one place so every node speaks the same conventions:
images rgb8 / 32FC1 metres / mono8 (and, taken in, what RGB-D drivers publish: bgr8, rgba8,
bgra8 colour, 16UC1 millimetre depth), camera_info from K with no distortion, world-frame keypoints
as a PoseArray in CORNER_LABELS order, JSON on std_msgs/String for the control-plane reports."""

from __future__ import annotations

import json
from collections.abc import Sequence

import genpy
import numpy as np
from geometry_msgs.msg import Pose, PoseArray, TransformStamped
from scipy.spatial.transform import Rotation
from sensor_msgs import point_cloud2
from sensor_msgs.msg import CameraInfo, Image, JointState, PointCloud2
from std_msgs.msg import Header, String
from trajectory_msgs.msg import JointTrajectory as JointTrajectoryMsg
from trajectory_msgs.msg import JointTrajectoryPoint

from foldbot.errors import FoldbotError
from foldbot.perception.keypoints import CORNER_LABELS
from foldbot.perception.rectify import rectify, rectify_depth
from foldbot.perception.register import register_depth
from foldbot.perception.state import ClothState
from foldbot.sim.layout import Obstacle
from foldbot.types import CameraIntrinsics

_ENCODINGS = {
    "rgb8": (np.uint8, 3),
    "bgr8": (np.uint8, 3),
    "rgba8": (np.uint8, 4),
    "bgra8": (np.uint8, 4),
    "mono8": (np.uint8, 1),
    "32FC1": (np.float32, 1),
    "16UC1": (np.uint16, 1),
}
COLOR_ENCODINGS = ("rgb8", "bgr8", "rgba8", "bgra8")
"""Colour images the perception node takes (what RGB-D drivers publish); rgb8 from the sim."""
DEPTH_ENCODINGS = ("32FC1", "16UC1")
"""Depth images it takes (REP 118): 32FC1 metres (the sim's), or 16UC1 millimetres (0: no
reading), as RealSense and OpenNI drivers publish them."""


def stamp_of(seconds: float) -> genpy.Time:
    """A ROS time from simulated seconds."""
    return genpy.Time.from_sec(float(seconds))


def header(seconds: float, frame_id: str) -> Header:
    return Header(stamp=stamp_of(seconds), frame_id=frame_id)


def image_msg(array: np.ndarray, encoding: str, seconds: float, frame_id: str) -> Image:
    """sensor_msgs/Image of an H×W(×C) array: rgb8 (uint8 ×3), mono8 (uint8) or 32FC1 (float32)."""
    if encoding not in _ENCODINGS:
        raise FoldbotError(f"unsupported image encoding {encoding!r}; allowed: {list(_ENCODINGS)}")
    dtype, channels = _ENCODINGS[encoding]
    a = np.ascontiguousarray(array, dtype=dtype)
    h, w = a.shape[:2]
    return Image(
        header=header(seconds, frame_id),
        height=h,
        width=w,
        encoding=encoding,
        is_bigendian=0,
        step=w * channels * a.itemsize,
        data=a.tobytes(),
    )


def image_array(msg: Image) -> np.ndarray:
    """The array of a sensor_msgs/Image in one of the encodings above (rows `step` bytes apart,
    padding dropped; either byte order)."""
    if msg.encoding not in _ENCODINGS:
        raise FoldbotError(
            f"unsupported image encoding {msg.encoding!r}; allowed: {list(_ENCODINGS)}"
        )
    dtype, channels = _ENCODINGS[msg.encoding]
    row = msg.width * channels * np.dtype(dtype).itemsize
    data = np.frombuffer(msg.data, dtype=np.uint8)
    if msg.step < row or data.size < msg.height * msg.step:
        raise FoldbotError(
            f"a {msg.width} × {msg.height} {msg.encoding} image needs rows of at least {row} "
            f"bytes and {msg.height} of them; got step {msg.step} and {data.size} bytes"
        )
    rows = data[: msg.height * msg.step].reshape(msg.height, msg.step)[:, :row]
    a = np.ascontiguousarray(rows).view(
        np.dtype(dtype).newbyteorder(">" if msg.is_bigendian else "<")
    )
    shape = (msg.height, msg.width, channels) if channels > 1 else (msg.height, msg.width)
    return a.reshape(shape).astype(dtype)


def camera_images(
    color: Image,
    depth: Image | None,
    info: CameraInfo,
    depth_info: CameraInfo | None = None,
    T_color_depth: np.ndarray | None = None,
) -> tuple[np.ndarray, np.ndarray | None, CameraIntrinsics]:
    """A camera frame as perception takes it: RGB, depth in metres (None: none given) and the
    colour camera's K, rectified when camera_info carries lens distortion (perception.rectify).
    A depth image whose own camera_info (`depth_info`) differs from the colour camera's (frame,
    size, K or distortion) is rectified with it and registered onto the colour camera
    (perception.register), T_color_depth mapping its frame into the colour one (identity where
    both name one frame); the simulated camera's come through as they are."""
    rgb = color_array(color)
    z = None if depth is None else depth_array(depth)
    intr = intrinsics_of(info)
    if z is None or depth_info is None or same_camera(info, depth_info):
        rgb, z = rectify(rgb, z, intr.K, list(info.D), info.distortion_model)
        return rgb, z, intr
    if T_color_depth is None:
        if depth_info.header.frame_id != info.header.frame_id:
            raise FoldbotError(
                f"the depth camera's frame {depth_info.header.frame_id!r} is not the colour "
                f"camera's {info.header.frame_id!r}, and no transform between them is known "
                "(publish both on /tf_static, or register the depth in the driver)"
            )
        T_color_depth = np.eye(4)
    if z.shape != (depth_info.height, depth_info.width):
        raise FoldbotError(
            f"depth image is {z.shape[1]} × {z.shape[0]} px, its camera_info says "
            f"{depth_info.width} × {depth_info.height}"
        )
    d_intr = intrinsics_of(depth_info)
    z = rectify_depth(z, d_intr.K, list(depth_info.D), depth_info.distortion_model)
    z = register_depth(z, d_intr.K, intr.K, T_color_depth, (intr.width, intr.height))
    rgb, _ = rectify(rgb, None, intr.K, list(info.D), info.distortion_model)
    return rgb, z, intr


def info_for(image: Image, info: CameraInfo | None) -> CameraInfo | None:
    """`info` where it describes `image` (the same frame), else None: a depth image already
    registered to the colour camera (a driver's aligned depth, in the colour frame) is not
    registered again by a camera_info of the raw depth sensor's."""
    if info is None or info.header.frame_id != image.header.frame_id:
        return None
    return info


def same_camera(a: CameraInfo, b: CameraInfo) -> bool:
    """Whether two camera_infos describe one camera's images (frame, size, K, distortion): a
    depth image that shares its colour image's needs no registering."""
    return (
        a.header.frame_id == b.header.frame_id
        and (a.width, a.height) == (b.width, b.height)
        and np.allclose(a.K, b.K, rtol=0, atol=1e-9)
        and np.array_equal(
            np.trim_zeros(np.asarray(a.D, dtype=float), "b"),
            np.trim_zeros(np.asarray(b.D, dtype=float), "b"),
        )
    )


def color_array(msg: Image) -> np.ndarray:
    """H×W×3 uint8 RGB of a colour image in any of COLOR_ENCODINGS."""
    if msg.encoding not in COLOR_ENCODINGS:
        raise FoldbotError(
            f"unsupported colour image encoding {msg.encoding!r}; allowed: "
            f"{', '.join(COLOR_ENCODINGS)}"
        )
    a = image_array(msg)[..., :3]
    return np.ascontiguousarray(a[..., ::-1] if msg.encoding.startswith("bgr") else a)


def depth_array(msg: Image) -> np.ndarray:
    """H×W float32 depth in metres of a depth image in either of DEPTH_ENCODINGS; a 16UC1
    image's 0 (no reading) becomes NaN."""
    if msg.encoding not in DEPTH_ENCODINGS:
        raise FoldbotError(
            f"unsupported depth image encoding {msg.encoding!r}; allowed: "
            f"{', '.join(DEPTH_ENCODINGS)} (REP 118: metres, or millimetres)"
        )
    a = image_array(msg)
    if msg.encoding == "32FC1":
        return a
    out = a.astype(np.float32) * np.float32(0.001)
    out[a == 0] = np.nan
    return out


def camera_info_msg(intr: CameraIntrinsics, seconds: float, frame_id: str) -> CameraInfo:
    """sensor_msgs/CameraInfo of an ideal pinhole camera (plumb_bob, zero distortion)."""
    k = np.asarray(intr.K, dtype=float)
    p = np.zeros((3, 4))
    p[:, :3] = k
    return CameraInfo(
        header=header(seconds, frame_id),
        height=intr.height,
        width=intr.width,
        distortion_model="plumb_bob",
        D=[0.0] * 5,
        K=k.ravel().tolist(),
        R=np.eye(3).ravel().tolist(),
        P=p.ravel().tolist(),
    )


def intrinsics_of(msg: CameraInfo) -> CameraIntrinsics:
    return CameraIntrinsics(
        K=np.array(msg.K, dtype=float).reshape(3, 3), width=msg.width, height=msg.height
    )


def transform_msg(T: np.ndarray, parent: str, child: str, seconds: float) -> TransformStamped:
    """geometry_msgs/TransformStamped of the 4×4 pose of `child` in `parent`."""
    t = TransformStamped(header=header(seconds, parent), child_frame_id=child)
    t.transform.translation.x, t.transform.translation.y, t.transform.translation.z = (
        float(v) for v in T[:3, 3]
    )
    q = Rotation.from_matrix(T[:3, :3]).as_quat()
    r = t.transform.rotation
    r.x, r.y, r.z, r.w = (float(v) for v in q)
    return t


def matrix_of(t: TransformStamped) -> np.ndarray:
    tr, r = t.transform.translation, t.transform.rotation
    T = np.eye(4)
    T[:3, :3] = Rotation.from_quat([r.x, r.y, r.z, r.w]).as_matrix()
    T[:3, 3] = [tr.x, tr.y, tr.z]
    return T


def state_json(state: ClothState, fixtures: Sequence[Obstacle] = ()) -> str:
    """ClothState without its mask (which travels as an image) as JSON; with the cell's
    `fixtures` the estimator masked, where it had any (so a replay masks them alike)."""
    named = {"fixtures": [f.as_dict() for f in fixtures]} if fixtures else {}
    return json.dumps(
        {
            "stamp": state.stamp,
            "detected": state.detected,
            "reason": state.reason,
            "keypoints": {
                k: [*(float(v) for v in xyz), float(c)] for k, (xyz, c) in state.keypoints.items()
            },
            "coverage_m2": state.coverage_m2,
            "flatness": state.flatness,
            "outline_world": np.asarray(state.outline_world).tolist(),
            "table_plane": np.asarray(state.table_plane).tolist(),
            **named,
        }
    )


def keypoints_msg(state: ClothState, seconds: float, frame_id: str) -> PoseArray:
    """The perceived corners as a PoseArray in CORNER_LABELS order (empty when not detected)."""
    msg = PoseArray(header=header(seconds, frame_id))
    for label in CORNER_LABELS:
        if label in state.keypoints:
            pose = Pose()
            pose.position.x, pose.position.y, pose.position.z = (
                float(v) for v in state.keypoints[label][0]
            )
            pose.orientation.w = 1.0
            msg.poses.append(pose)
    return msg


def corners_of_pose_array(msg: PoseArray) -> dict[str, np.ndarray]:
    """Corner positions by label from a `keypoints_msg` PoseArray (all four corners needed)."""
    if len(msg.poses) != len(CORNER_LABELS):
        raise FoldbotError(
            f"keypoints PoseArray must hold the {len(CORNER_LABELS)} corners "
            f"{', '.join(CORNER_LABELS)} in that order, got {len(msg.poses)} poses"
        )
    return {
        label: np.array([p.position.x, p.position.y, p.position.z])
        for label, p in zip(CORNER_LABELS, msg.poses, strict=True)
    }


def state_from(json_text: str, mask: np.ndarray) -> ClothState:
    """Rebuild a ClothState from `state_json` and its mask image (nonzero = cloth)."""
    d = json.loads(json_text)
    return ClothState(
        detected=bool(d["detected"]),
        reason=d["reason"],
        keypoints={k: (np.array(v[:3]), float(v[3])) for k, v in d["keypoints"].items()},
        mask=np.asarray(mask) > 0,
        coverage_m2=float(d["coverage_m2"]),
        flatness=float(d["flatness"]),
        outline_world=np.array(d["outline_world"], dtype=float).reshape(-1, 3),
        table_plane=np.array(d["table_plane"], dtype=float),
        stamp=float(d["stamp"]),
    )


def trajectory_msg(
    joint_names: list[str] | tuple[str, ...],
    times: np.ndarray,
    positions: np.ndarray,
    velocities: np.ndarray,
    seconds: float,
    frame_id: str,
) -> JointTrajectoryMsg:
    """trajectory_msgs/JointTrajectory from sampled times (s), positions (rad), velocities."""
    msg = JointTrajectoryMsg(header=header(seconds, frame_id), joint_names=list(joint_names))
    for t, q, v in zip(times, positions, velocities, strict=True):
        msg.points.append(
            JointTrajectoryPoint(
                positions=[float(x) for x in q],
                velocities=[float(x) for x in v],
                time_from_start=genpy.Duration.from_sec(float(t)),
            )
        )
    return msg


def trajectory_arrays(msg: JointTrajectoryMsg) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(times, positions, velocities) of a JointTrajectory; missing velocities are zeros."""
    if not msg.points:
        raise FoldbotError("joint trajectory has no points")
    n = len(msg.joint_names)
    bad = [i for i, p in enumerate(msg.points) if len(p.positions) != n]
    if bad:
        raise FoldbotError(
            f"joint trajectory points must have {n} positions each (one per joint name); "
            f"point {bad[0]} has {len(msg.points[bad[0]].positions)}"
        )
    times = np.array([p.time_from_start.to_sec() for p in msg.points])
    pos = np.array([p.positions for p in msg.points], dtype=float)
    vel = np.array(
        [p.velocities if len(p.velocities) == n else [0.0] * n for p in msg.points], dtype=float
    )
    if np.any(np.diff(times) < 0):
        raise FoldbotError("joint trajectory time_from_start must not decrease")
    return times, pos, vel


def joint_state_msg(
    names: list[str], q: np.ndarray, v: np.ndarray, seconds: float, frame_id: str = ""
) -> JointState:
    return JointState(
        header=header(seconds, frame_id),
        name=list(names),
        position=[float(x) for x in q],
        velocity=[float(x) for x in v],
    )


def cloud_msg(points: np.ndarray, seconds: float, frame_id: str) -> PointCloud2:
    """An xyz float32 PointCloud2 of N×3 points (m)."""
    return point_cloud2.create_cloud_xyz32(header(seconds, frame_id), np.asarray(points).tolist())


def cloud_array(msg: PointCloud2) -> np.ndarray:
    return np.array(
        list(point_cloud2.read_points(msg, field_names=("x", "y", "z"), skip_nans=False)),
        dtype=float,
    ).reshape(-1, 3)


def string_msg(payload: dict) -> String:
    return String(data=json.dumps(payload))
