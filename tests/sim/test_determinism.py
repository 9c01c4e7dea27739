"""Same inputs, same physics: a settle + grasp + lift run twice gives identical cloth states."""

import numpy as np

from foldbot.garments.towel import TowelSpec, make_towel
from foldbot.sim.cloth import ClothConfig, SoftCloth, settle
from foldbot.sim.grasp import ClothGrasp
from foldbot.sim.robots import gripper_down_quaternion, make_robot
from foldbot.sim.world import SimWorld


def _run_once() -> np.ndarray:
    with SimWorld() as world:
        lay = world.layout
        robot = make_robot("ur5", world.client, lay)
        mesh = make_towel(TowelSpec(0.2, 0.2, 8))
        cloth = SoftCloth(world.client, mesh, ClothConfig(), lay.table_height, (0.47, 0.02), 0.4)
        settle(world, cloth, max_time=0.6)
        grasp = ClothGrasp(world, robot, cloth)
        corner = cloth.sim_vertices()[mesh.keypoints["corner_00"]]
        for target in (corner + [0, 0, 0.004], corner + [0, 0, 0.1]):
            q0 = robot.joint_positions()
            q1 = robot.solve_ik(target, gripper_down_quaternion(), q_seed=q0)
            for k in range(1, 121):
                robot.command_joint_positions(q0 + (q1 - q0) * k / 120)
                world.step()
            if not grasp.holding:
                assert grasp.close().success
        return cloth.sim_vertices()


def test_same_inputs_give_the_same_cloth_state():
    a = _run_once()
    b = _run_once()
    assert np.array_equal(a, b)
