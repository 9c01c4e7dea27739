"""The transforms /tf_static carries, kept as a tree so a node can look up one frame in another
(a real RGB-D camera publishes its colour and depth optical frames under its own link, not under
`world`). Static only: the cell's camera and arm bases do not move."""

from __future__ import annotations

import numpy as np
from sensor_msgs.msg import CameraInfo, Image
from tf2_msgs.msg import TFMessage

from foldbot.ros import convert
from foldbot.types import CameraIntrinsics


class StaticFrames:
    """Every parent → child transform seen on /tf_static (the newest per child)."""

    def __init__(self) -> None:
        self._parent: dict[str, tuple[str, np.ndarray]] = {}

    def add(self, msg: TFMessage) -> None:
        """Take the transforms of one /tf_static message (each child's newest replaces it)."""
        for t in msg.transforms:
            child, parent = t.child_frame_id.lstrip("/"), t.header.frame_id.lstrip("/")
            if child and parent and child != parent:
                self._parent[child] = (parent, convert.matrix_of(t))

    def _to_root(self, frame: str) -> tuple[str, np.ndarray]:
        T = np.eye(4)
        seen = {frame}
        while frame in self._parent:
            parent, T_parent_frame = self._parent[frame]
            T = T_parent_frame @ T
            frame = parent
            if frame in seen:  # a loop: no root to reach
                break
            seen.add(frame)
        return frame, T

    def transform(self, target: str, source: str) -> np.ndarray | None:
        """T_target_source, the 4×4 mapping `source` coordinates into `target`'s, or None where
        the two frames are not joined by the transforms seen."""
        target, source = target.lstrip("/"), source.lstrip("/")
        if target == source:
            return np.eye(4)
        root_t, T_root_target = self._to_root(target)
        root_s, T_root_source = self._to_root(source)
        if root_t != root_s:
            return None
        return np.linalg.inv(T_root_target) @ T_root_source

    def camera_images(
        self, color: Image, depth: Image, info: CameraInfo, depth_info: CameraInfo | None
    ) -> tuple[np.ndarray, np.ndarray | None, CameraIntrinsics]:
        """convert.camera_images with the depth camera placed through these frames: `depth_info`
        where it describes `depth` (its frame), and the transform from that frame to the colour
        one (the perception and task nodes read a frame alike)."""
        depth_info = convert.info_for(depth, depth_info)
        T_color_depth = (
            None
            if depth_info is None
            else self.transform(info.header.frame_id, depth_info.header.frame_id)
        )
        return convert.camera_images(color, depth, info, depth_info, T_color_depth)
