import numpy as np
import pytest

from foldbot.errors import ConfigError
from foldbot.sim.grasp import ClothGrasp
from foldbot.sim.robots import gripper_down_quaternion


def _move(world, robot, target, duration=0.8):
    """Joint-space interpolation to the IK solution of a gripper-down target."""
    q0 = robot.joint_positions()
    q1 = robot.solve_ik(np.asarray(target), gripper_down_quaternion(0.0), q_seed=q0)
    n = round(duration / world.time_step)
    for k in range(1, n + 1):
        robot.command_joint_positions(q0 + (q1 - q0) * k / n)
        world.step()
    world.step(20)


def test_grasp_lifts_corner_far_edge_stays_down_and_release(cell):
    world, robot, cloth = cell
    grasp = ClothGrasp(world, robot, cloth)
    table = world.layout.table_height
    corner_id = cloth.mesh.keypoints["corner_00"]
    far_id = cloth.mesh.keypoints["corner_11"]
    corner = cloth.sim_vertices()[corner_id]
    _move(world, robot, corner + [0, 0, 0.06])
    _move(world, robot, corner + [0, 0, 0.004], 0.5)
    result = grasp.close()
    assert result.success, result.reason
    assert corner_id in result.vertex_ids
    # Only vertices inside the jaw volume are attached: all within a jaw's reach of the TCP.
    held = cloth.sim_vertices()[list(result.vertex_ids)]
    assert np.linalg.norm(held[:, :2] - robot.tcp_pose()[0][:2], axis=1).max() < 0.02
    _move(world, robot, corner + [0, 0, 0.12])
    v = cloth.sim_vertices()
    assert v[corner_id, 2] - table > 0.09, "the grasped corner rises with the gripper"
    assert v[far_id, 2] - table < 0.01, "the far corner stays on the table"
    grasp.open()
    world.step(round(0.8 / world.time_step))
    assert not grasp.holding
    assert cloth.sim_vertices()[corner_id, 2] - table < 0.03, "released cloth falls back"
    assert robot.gripper_opening() > 0.07


def test_a_slipped_grasp_drops_the_cloth_and_the_gripper_can_tell(cell):
    """slip() (fault injection) lets the lifted corner fall out of the closed jaws; the hold
    the gripper reports (holds_what_it_grasped) is there while the corner rises with the jaws
    and gone once it has slipped. The jaws' gap, as a real gripper's encoder reads it, is the
    cloth's thickness while they hold it and closes once it has slipped (a cell over ROS sees
    the slip so, on /joint_states)."""
    world, robot, cloth = cell
    grasp = ClothGrasp(world, robot, cloth)
    table = world.layout.table_height
    corner_id = cloth.mesh.keypoints["corner_00"]
    corner = cloth.sim_vertices()[corner_id]
    _move(world, robot, corner + [0, 0, 0.06])
    _move(world, robot, corner + [0, 0, 0.004], 0.5)
    assert not grasp.holds_what_it_grasped()  # nothing grasped yet
    assert np.array_equal(grasp.reported_fingers(), robot.finger_positions())
    held = grasp.close().vertex_ids
    _move(world, robot, corner + [0, 0, 0.12])
    assert grasp.holds_what_it_grasped()
    assert robot.gripper_opening() < 0.003 < cloth.thickness  # the simulated pads pass through
    assert grasp.jaw_gap() == cloth.thickness
    stopped = robot.finger_target(cloth.thickness)
    assert stopped > 0.003 and np.allclose(grasp.reported_fingers(), stopped)
    assert grasp.slip() == held and not grasp.holding and grasp.held == ()
    assert grasp.jaw_gap() == robot.gripper_opening()
    assert np.array_equal(grasp.reported_fingers(), robot.finger_positions())
    assert grasp.reported_fingers().max() < stopped - 0.002  # closed on by over the watch's 2 mm
    world.step(round(0.8 / world.time_step))
    assert not grasp.holds_what_it_grasped()
    assert cloth.sim_vertices()[corner_id, 2] - table < 0.03, "the slipped corner fell"
    assert robot.gripper_opening() < 0.01, "the jaws stay closed, on nothing"


def test_grasp_over_empty_table_fails_and_attaches_nothing(cell):
    world, robot, cloth = cell
    grasp = ClothGrasp(world, robot, cloth)
    lo_x, _, lo_y, _ = world.layout.workspace_bounds
    _move(world, robot, [lo_x + 0.03, lo_y + 0.03, world.layout.table_height + 0.005])
    result = grasp.close()
    assert not result.success
    assert result.vertex_ids == ()
    assert "no cloth" in result.reason
    assert not grasp.holding


@pytest.mark.parametrize("offset", [0.03, 0.05])
def test_grasp_beside_the_edge_catches_nothing(cell, offset):
    world, robot, cloth = cell
    grasp = ClothGrasp(world, robot, cloth)
    corner = cloth.sim_vertices()[cloth.mesh.keypoints["corner_00"]]
    _move(world, robot, corner + [-offset, -offset, 0.004])
    assert not grasp.close().success


def _cell_middle(cloth) -> np.ndarray:
    """The middle of the mesh square at corner_00, where no mesh point lies within the jaws."""
    verts = cloth.sim_vertices()
    corner = verts[cloth.mesh.keypoints["corner_00"]]
    toward = np.sign(verts[:, :2].mean(axis=0) - corner[:2])
    middle = corner.copy()
    middle[:2] += toward * cloth.mesh.edge_length / 2
    return middle


def test_surface_catch_holds_cloth_between_mesh_points(coarse_cell):
    world, robot, cloth = coarse_cell
    table = world.layout.table_height
    middle = _cell_middle(cloth)
    nearest = np.linalg.norm(cloth.sim_vertices() - middle, axis=1).min()
    assert nearest > 0.02, "the jaws must close between mesh points for this test"
    _move(world, robot, middle + [0, 0, 0.06])
    _move(world, robot, middle + [0, 0, 0.004], 0.5)
    points_only = ClothGrasp(world, robot, cloth)
    missed = points_only.close()
    assert not missed.success, "no mesh point lies between the pads"
    points_only.open()
    surface = ClothGrasp(world, robot, cloth, catch="surface")
    result = surface.close()
    assert result.success, result.reason
    assert "holding the cloth between the jaws" in result.reason
    held = cloth.sim_vertices()[list(result.vertex_ids)]
    # Held at the surrounding square's points only, where they lay: nothing farther is attached.
    assert np.linalg.norm(held[:, :2] - middle[:2], axis=1).max() < cloth.mesh.edge_length
    _move(world, robot, middle + [0, 0, 0.12])
    v = cloth.sim_vertices()
    assert v[list(result.vertex_ids), 2].min() - table > 0.09, "the held cloth rises"
    # Held points a mesh edge from the TCP rose with it: the gripper still holds them.
    assert surface.holds_what_it_grasped()
    surface.open()


def test_surface_catch_over_empty_table_holds_nothing(cell):
    world, robot, cloth = cell
    grasp = ClothGrasp(world, robot, cloth, catch="surface")
    corner = cloth.sim_vertices()[cloth.mesh.keypoints["corner_00"]]
    _move(world, robot, corner + [-0.04, -0.04, 0.004])
    result = grasp.close()
    assert not result.success and "no cloth" in result.reason
    assert not grasp.holding


def test_unknown_jaw_catch_is_refused(cell):
    world, robot, cloth = cell
    with pytest.raises(ConfigError, match="unknown jaw catch 'glue'; allowed: vertices, surface"):
        ClothGrasp(world, robot, cloth, catch="glue")
