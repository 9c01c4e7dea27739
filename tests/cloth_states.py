"""Hand-made perception states for the grasp-point and loop tests: a towel outline and keypoints on
a flat table, and the towel of a half fold whose far-right corner the first carry dragged."""

import numpy as np

from foldbot.perception.state import ClothState

TABLE_Z = 0.75
# Fold line x = 0.45 pointing −y: its left (moving) side is x > 0.45, the far side.
LINE = (0.45, 0.15, 0.0, -0.3)


def state(outline_xy, keypoints, table_z=TABLE_Z):
    outline = np.column_stack([np.asarray(outline_xy, float), np.full(len(outline_xy), 0.76)])
    return ClothState(
        detected=True,
        keypoints={k: (np.asarray(v, float), 0.5) for k, v in keypoints.items()},
        mask=np.zeros((4, 4), bool),
        outline_world=outline,
        table_plane=np.array([0.0, 0.0, 1.0, -table_z]),
    )


def dragged_towel():
    """After the first carry of a half fold: far_left is folded onto near_left; the far_right
    corner was dragged to (0.56, −0.06), the tip of a tent of cloth still on the far side."""
    outline = [
        (0.30, 0.15),  # folded far_left over near_left
        (0.30, -0.15),  # near_right
        (0.45, -0.15),
        (0.56, -0.06),  # the dragged far_right: the tent's tip
        (0.45, 0.05),
    ]
    keypoints = {
        "near_left": (0.30, 0.15, 0.757),
        "near_right": (0.30, -0.15, 0.755),
        # The corner detector fits a quad to the pentagon: its far_right is 3.5 cm off the tip.
        "far_right": (0.535, -0.085, 0.757),
        "far_left": (0.45, 0.05, 0.757),
    }
    return state(outline, keypoints)
