"""The board on the simulated tool: held where its mount says as the arm moves, seen by the
camera and touching nothing."""

import numpy as np
import pybullet as p
from scipy.spatial.transform import Rotation

from foldbot.calibration.board import Chessboard
from foldbot.calibration.views import BoardMount
from foldbot.control.executor import ArmExecutor, move_joints_together
from foldbot.sim.calibration_board import attach_board
from foldbot.sim.layout import DEFAULT_LAYOUT
from foldbot.sim.robots import make_robot
from foldbot.sim.world import SimWorld


def test_the_board_moves_with_the_tool_and_touches_nothing():
    with SimWorld() as world:
        robot = make_robot("ur5", world.client, DEFAULT_LAYOUT)
        mount = BoardMount()
        board = attach_board(robot, Chessboard(), mount)
        ex = ArmExecutor(world, robot, None)
        q = robot.joint_positions() + np.array([0.3, -0.2, 0.3, 0.2, 0.4, 0.5])
        move_joints_together([(ex, q)])
        world.step(120)
        pos, quat = robot.tcp_pose()
        expected = np.asarray(pos) + Rotation.from_quat(quat).apply(mount.offset_m)
        got, got_quat = p.getBasePositionAndOrientation(board, physicsClientId=world.client)
        assert np.linalg.norm(np.subtract(got, expected)) < 1e-3
        turn = (Rotation.from_quat(quat).inv() * Rotation.from_quat(got_quat)).magnitude()
        assert turn < np.deg2rad(0.2)
        # A block where the board is: nothing touches (the board has no contacts at all).
        p.createMultiBody(
            0.0,
            p.createCollisionShape(
                p.GEOM_BOX, halfExtents=[0.2, 0.2, 0.05], physicsClientId=world.client
            ),
            basePosition=got,
            physicsClientId=world.client,
        )
        world.step(30)
        assert not p.getContactPoints(bodyA=board, physicsClientId=world.client)
