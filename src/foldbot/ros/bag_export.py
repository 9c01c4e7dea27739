"""Export an episode folder to a ROS 1 bag with the pure-Python `rosbags` library (no ROS needed).

Topics (stamps in simulated seconds from the episode's start):
- /camera/color/image_raw (sensor_msgs/Image, rgb8): the frames of video.mp4 at its frame rate;
- /camera/color/camera_info and /tf_static (world → camera_color_optical_frame), when result.json
  records the camera (episodes written since the ROS integration);
- /ground_truth/cloth_initial, /ground_truth/cloth_final (sensor_msgs/PointCloud2, world): the
  cloth's vertices from cloth.npz, for scoring and display;
- /fold/grasp_points, /fold/place_points (geometry_msgs/PoseArray, world): per action;
- /task/result (std_msgs/String): result.json.
The message definitions are ROS 1 Noetic's, so `rosbag play` and `rosbag info` read the bag.
"""

from __future__ import annotations

import json
import os
import tempfile
from pathlib import Path

import imageio.v3 as iio
import numpy as np
from rosbags.rosbag1 import Writer
from rosbags.typesys import Stores, get_types_from_msg, get_typestore

from foldbot.errors import OutputError
from foldbot.io.episode import load_episode

_TF_MESSAGE = "geometry_msgs/TransformStamped[] transforms\n"


def _typestore():
    store = get_typestore(Stores.ROS1_NOETIC)
    if "tf2_msgs/msg/TFMessage" not in store.types:
        store.register(get_types_from_msg(_TF_MESSAGE, "tf2_msgs/msg/TFMessage"))
    return store


def _check_writable(bag_path: Path) -> None:
    """OutputError unless `bag_path`'s folder is (or can be made) a folder that takes a new file:
    checked by writing one, the one sure test (read-only mounts, permissions, root)."""
    parent = bag_path.parent
    if parent.exists() and not parent.is_dir():
        raise OutputError(
            f"cannot write the bag {bag_path}: {parent} is not a folder; name a .bag file in a "
            "writable folder"
        )
    try:
        parent.mkdir(parents=True, exist_ok=True)
        with tempfile.NamedTemporaryFile(dir=parent, prefix=f".{bag_path.name}.probe-"):
            pass
    except OSError as exc:
        raise OutputError(
            f"cannot write the bag {bag_path} ({exc.strerror or exc}); name a .bag file in a "
            "writable folder"
        ) from None


def export_episode(episode_dir: str | Path, bag_path: str | Path, overwrite: bool = False) -> dict:
    """Write `bag_path` from `episode_dir`; returns {topic: message count}."""
    episode_dir, bag_path = Path(episode_dir), Path(bag_path)
    if bag_path.suffix != ".bag":
        raise OutputError(f"the bag file must end in .bag, got {str(bag_path)!r}")
    if bag_path.is_dir():
        raise OutputError(f"{bag_path} is a folder; name a .bag file to write")
    if bag_path.exists() and not overwrite:
        raise OutputError(f"{bag_path} already exists; pass --overwrite to replace it")
    # Validates the folder: a clear error naming the file when result.json or cloth.npz is
    # malformed, or the cloth's coordinates are not finite positions (the check `score` makes).
    episode = load_episode(episode_dir)
    result = episode.result
    ts = _typestore()
    T = ts.types
    counts: dict[str, int] = {}

    def time_of(seconds: float):
        sec = int(np.floor(seconds))
        return T["builtin_interfaces/msg/Time"](sec=sec, nanosec=round((seconds - sec) * 1e9))

    def header(seconds: float, frame: str):
        return T["std_msgs/msg/Header"](seq=0, stamp=time_of(seconds), frame_id=frame)

    def cloud(points: np.ndarray, seconds: float):
        pts = np.asarray(points, dtype=np.float32).reshape(-1, 3)
        field = T["sensor_msgs/msg/PointField"]
        fields = [field(name=n, offset=4 * i, datatype=7, count=1) for i, n in enumerate("xyz")]
        return T["sensor_msgs/msg/PointCloud2"](
            header=header(seconds, "world"),
            height=1,
            width=len(pts),
            fields=fields,
            is_bigendian=False,
            point_step=12,
            row_step=12 * len(pts),
            data=np.frombuffer(pts.tobytes(), dtype=np.uint8),
            is_dense=True,
        )

    def pose_array(points: list, seconds: float):
        poses = []
        for p in points:
            pos = T["geometry_msgs/msg/Point"](x=float(p[0]), y=float(p[1]), z=float(p[2]))
            quat = T["geometry_msgs/msg/Quaternion"](x=0.0, y=0.0, z=0.0, w=1.0)
            poses.append(T["geometry_msgs/msg/Pose"](position=pos, orientation=quat))
        return T["geometry_msgs/msg/PoseArray"](header=header(seconds, "world"), poses=poses)

    _check_writable(bag_path)
    tmp = bag_path.with_name(f".{bag_path.name}.partial-{os.getpid()}")
    tmp.unlink(missing_ok=True)
    end = float(result.get("sim_seconds", 0.0))
    try:
        with Writer(tmp) as writer:
            conns: dict[str, object] = {}

            def write(topic: str, msgtype: str, msg, seconds: float, latching: int = 0) -> None:
                if topic not in conns:
                    conns[topic] = writer.add_connection(
                        topic, msgtype, typestore=ts, latching=latching
                    )
                data = ts.serialize_ros1(msg, msgtype)
                writer.write(conns[topic], round(seconds * 1e9), data)
                counts[topic] = counts.get(topic, 0) + 1

            cam = result.get("camera")
            if cam is not None:
                from scipy.spatial.transform import Rotation

                Tc = np.asarray(cam["T_world_camera"], dtype=float)
                q = Rotation.from_matrix(Tc[:3, :3]).as_quat()
                tf = T["geometry_msgs/msg/TransformStamped"](
                    header=header(0.0, "world"),
                    child_frame_id="camera_color_optical_frame",
                    transform=T["geometry_msgs/msg/Transform"](
                        translation=T["geometry_msgs/msg/Vector3"](*(float(v) for v in Tc[:3, 3])),
                        rotation=T["geometry_msgs/msg/Quaternion"](*(float(v) for v in q)),
                    ),
                )
                write(
                    "/tf_static",
                    "tf2_msgs/msg/TFMessage",
                    T["tf2_msgs/msg/TFMessage"](transforms=[tf]),
                    0.0,
                    latching=1,
                )
            write(
                "/ground_truth/cloth_initial",
                "sensor_msgs/msg/PointCloud2",
                cloud(episode.initial, 0.0),
                0.0,
            )
            video = episode_dir / "video.mp4"
            if video.is_file():
                fps = float(iio.immeta(video, plugin="FFMPEG").get("fps", 10.0) or 10.0)
                for i, frame in enumerate(iio.imiter(video, plugin="FFMPEG")):
                    t = i / fps
                    rgb = np.ascontiguousarray(frame[..., :3], dtype=np.uint8)
                    h, w = rgb.shape[:2]
                    img = T["sensor_msgs/msg/Image"](
                        header=header(t, "camera_color_optical_frame"),
                        height=h,
                        width=w,
                        encoding="rgb8",
                        is_bigendian=0,
                        step=3 * w,
                        data=rgb.reshape(-1),
                    )
                    write("/camera/color/image_raw", "sensor_msgs/msg/Image", img, t)
                    if cam is not None and (w, h) == (cam["width"], cam["height"]):
                        K = np.asarray(cam["K"], dtype=float)
                        P = np.zeros((3, 4))
                        P[:, :3] = K
                        info = T["sensor_msgs/msg/CameraInfo"](
                            header=header(t, "camera_color_optical_frame"),
                            height=h,
                            width=w,
                            distortion_model="plumb_bob",
                            D=np.zeros(5),
                            K=K.ravel(),
                            R=np.eye(3).ravel(),
                            P=P.ravel(),
                            binning_x=0,
                            binning_y=0,
                            roi=T["sensor_msgs/msg/RegionOfInterest"](
                                x_offset=0, y_offset=0, height=0, width=0, do_rectify=False
                            ),
                        )
                        write("/camera/color/camera_info", "sensor_msgs/msg/CameraInfo", info, t)
                    end = max(end, t)
            actions = result.get("actions", [])
            write(
                "/fold/grasp_points",
                "geometry_msgs/msg/PoseArray",
                pose_array([a["grasp"] for a in actions], end),
                end,
            )
            write(
                "/fold/place_points",
                "geometry_msgs/msg/PoseArray",
                pose_array([a["place"] for a in actions], end),
                end,
            )
            write(
                "/ground_truth/cloth_final",
                "sensor_msgs/msg/PointCloud2",
                cloud(episode.final, end),
                end,
            )
            write(
                "/task/result",
                "std_msgs/msg/String",
                T["std_msgs/msg/String"](data=json.dumps(result)),
                end,
            )
        try:
            os.replace(tmp, bag_path)
        except OSError as exc:
            raise OutputError(f"cannot write the bag {bag_path}: {exc.strerror or exc}") from None
    finally:
        tmp.unlink(missing_ok=True)
    return counts
