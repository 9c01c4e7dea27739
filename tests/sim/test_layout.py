"""The cell's layout: one arm as it always was, or two side by side."""

import pytest

from foldbot.sim.layout import DEFAULT_LAYOUT


def test_one_arm_layout_is_the_cell_itself():
    assert DEFAULT_LAYOUT.arm_layouts(1) == (DEFAULT_LAYOUT,)


def test_two_arms_stand_apart_on_the_near_edge_left_arm_first():
    left, right = DEFAULT_LAYOUT.arm_layouts(2)
    assert left.robot_base_xyz == pytest.approx((0.0, 0.3, 0.75))
    assert right.robot_base_xyz == pytest.approx((0.0, -0.3, 0.75))
    # Each arm's home is at its own side, not over the workspace centre where both would meet.
    assert left.home_xy == pytest.approx((0.45, 0.3))
    assert right.home_xy == pytest.approx((0.45, -0.3))
    # The table and the cloth's workspace are the cell's.
    assert left.workspace_center_xy == DEFAULT_LAYOUT.workspace_center_xy
    assert left.table_size == DEFAULT_LAYOUT.table_size


@pytest.mark.parametrize("arms", [0, 3])
def test_other_arm_counts_are_refused(arms):
    with pytest.raises(ValueError, match="1 or 2 arms"):
        DEFAULT_LAYOUT.arm_layouts(arms)
