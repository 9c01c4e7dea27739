"""The transforms /tf_static carries, kept as a tree so a node can look up one frame in another
(a real RGB-D camera publishes its colour and depth optical frames under its own link, not under
`world`). Static only: the cell's camera and arm bases do not move."""

from __future__ import annotations

import numpy as np
from tf2_msgs.msg import TFMessage

from foldbot.ros.convert import matrix_of


class StaticFrames:
    """Every parent → child transform seen on /tf_static (the newest per child)."""

    def __init__(self) -> None:
        self._parent: dict[str, tuple[str, np.ndarray]] = {}

    def add(self, msg: TFMessage) -> None:
        """Take the transforms of one /tf_static message (each child's newest replaces it)."""
        for t in msg.transforms:
            child, parent = t.child_frame_id.lstrip("/"), t.header.frame_id.lstrip("/")
            if child and parent and child != parent:
                self._parent[child] = (parent, matrix_of(t))

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
