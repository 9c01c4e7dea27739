"""The executor's planning checks (foldbot.control.executor): every waypoint keeps the arm clear of
the table, on a real UR5 in a PyBullet world."""

import numpy as np
import pytest

from foldbot.control.executor import ArmExecutor
from foldbot.errors import UnreachableTargetError
from foldbot.planning.motion import Segment, line_path
from foldbot.sim.robots import make_robot
from foldbot.sim.world import SimWorld


@pytest.fixture
def executor():
    with SimWorld() as world:
        robot = make_robot("ur5", world.client, world.layout)
        yield ArmExecutor(world, robot, grasp=None)


def test_a_path_that_would_push_the_wrist_into_the_table_is_refused(executor):
    world, robot = executor.world, executor.robot
    start = robot.tcp_pose()[0]
    # IK reaches a TCP 10 cm under the table top; the palm would be inside the table.
    below = np.array([start[0], start[1], world.layout.table_height - 0.10])
    q0 = robot.joint_positions()
    with pytest.raises(UnreachableTargetError, match=r"segment 'dive'.*would touch the table"):
        executor.plan([Segment("dive", line_path(start, below), 0.25)])
    assert np.array_equal(robot.joint_positions(), q0) and world.steps == 0


def test_a_grasp_at_the_cloth_on_the_table_is_allowed(executor):
    # The fingers close on cloth lying on the table: only they come down to it.
    world, robot = executor.world, executor.robot
    start = robot.tcp_pose()[0]
    grasp = np.array([start[0], start[1], world.layout.table_height + 0.004])
    (planned,) = executor.plan([Segment("descend", line_path(start, grasp), 0.25)])
    assert len(planned.joint_path) > 2


def test_a_twin_without_a_table_is_not_checked():
    with SimWorld() as world, SimWorld() as model_world:
        robot = make_robot("ur5", world.client, world.layout)
        twin = make_robot("ur5", model_world.client, model_world.layout)
        assert ArmExecutor(world, robot, grasp=None, model=twin).model_table_id is None
        checked = ArmExecutor(world, robot, None, model=twin, model_table_id=model_world.table_id)
        assert checked.model_table_id == model_world.table_id
