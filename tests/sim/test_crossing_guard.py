"""The crossing guard puts a mesh point that went through its own cloth back on its side, and
leaves alone a cloth that did not (nor a point that went round the cloth's border)."""

import numpy as np
import pytest

from foldbot import metrics
from foldbot.garments.towel import TowelSpec, make_towel
from foldbot.sim.cloth import ClothConfig, SoftCloth, settle
from foldbot.sim.crossing_guard import CrossingGuard, barycentric


def _folded_towel(world):
    """A 0.2 m, 10×10 towel placed folded in half by hand: the far half (rows 5–9) mirrored over
    the near half (rows 0–4) one cloth thickness up. Returns (cloth, guard, the node positions,
    the node index of mesh vertex (row, col))."""
    lay = world.layout
    mesh = make_towel(TowelSpec(0.2, 0.2, 10))
    cloth = SoftCloth(world.client, mesh, ClothConfig(), lay.table_height, lay.workspace_center_xy)
    guard = CrossingGuard(cloth)  # from the flat start
    assert guard.check() == 0
    flat = cloth.sim_vertices()
    rows = flat[:, 1].reshape(10, 10)[:, 0]
    line = 0.5 * (rows[4] + rows[5])
    folded = flat.copy()
    top = flat[:, 1] > line
    folded[top, 1] = 2 * line - flat[top, 1]
    folded[top, 2] += cloth.thickness
    x = cloth.node_positions()
    x[cloth._order] = folded
    cloth.set_node_positions(x)
    assert metrics.self_crossings(cloth.sim_vertices(), mesh.faces) == 0
    assert guard.check() == 0  # learns which side of the lower layer the upper layer lies on

    def node(row: int, col: int) -> int:
        return int(cloth._order[row * 10 + col])

    return cloth, guard, x, node


def test_a_flat_towel_at_rest_is_left_alone(world):
    lay = world.layout
    mesh = make_towel(TowelSpec(0.2, 0.2, 10))
    cloth = SoftCloth(world.client, mesh, ClothConfig(), lay.table_height, lay.workspace_center_xy)
    guard = CrossingGuard(cloth)
    world.add_step_hook(guard)
    settle(world, cloth)
    world.step(round(0.3 / world.time_step))
    assert guard.restored == 0


def test_a_point_pushed_through_the_layer_beneath_is_put_back(world):
    cloth, guard, x, node = _folded_towel(world)
    mesh = cloth.mesh
    k = node(7, 4)  # over the middle of the lower layer, one thickness up
    below = x.copy()
    below[k, 2] = cloth.table_height - 0.002  # through the lower layer, under it
    cloth.set_node_positions(below)
    assert metrics.self_crossings(cloth.sim_vertices(), mesh.faces) > 0
    # The point, and the lower layer's point that the faces round it now dip over, go back.
    restored = guard.check()
    assert restored >= 1 and guard.restored == restored
    after = cloth.node_positions()
    assert metrics.self_crossings(cloth.sim_vertices(), mesh.faces) == 0
    lower = cloth.sim_vertices()[:50, 2].max()
    assert after[k, 2] > lower, "back over the layer it went through"
    assert after[k, 2] - lower == pytest.approx(cloth.margin, abs=0.002)
    moved = np.linalg.norm(after - below, axis=1)
    assert np.count_nonzero(moved) == restored
    assert np.delete(moved, k).max() < 2 * cloth.margin
    assert np.allclose(after[k, :2], below[k, :2], atol=0.002), "moved along the face's normal"


def test_a_point_gone_round_the_border_keeps_its_new_side(world):
    cloth, guard, x, node = _folded_towel(world)
    k = node(9, 0)  # the upper layer's corner, over the lower layer's corner (row 0, col 0)
    out = x.copy()
    out[k, 0] -= 0.05  # 5 cm past the cloth's side border, out of every face's reach
    cloth.set_node_positions(out)
    assert guard.check() == 0
    under = out.copy()
    under[k, 2] = cloth.table_height - 0.002
    cloth.set_node_positions(under)
    assert guard.check() == 0  # under the plane, but beside the cloth: nothing went through
    back = under.copy()
    back[k, 0] += 0.05  # round the border, under the lower layer's corner
    cloth.set_node_positions(back)
    assert guard.check() == 0, "came round the border: not put back"
    assert guard.restored == 0


def test_bad_every_is_refused(world):
    lay = world.layout
    cloth = SoftCloth(
        world.client,
        make_towel(TowelSpec(0.2, 0.2, 6)),
        ClothConfig(),
        lay.table_height,
        lay.workspace_center_xy,
    )
    with pytest.raises(ValueError, match="every must be ≥ 1 physics step, got 0"):
        CrossingGuard(cloth, every=0)


def test_barycentric_coordinates():
    a, b, c = np.zeros((1, 3)), np.array([[1.0, 0, 0]]), np.array([[0.0, 1, 0]])
    q = np.array([[0.25, 0.25, 0.7]])  # off the plane: the coordinates of its foot
    assert np.allclose(barycentric(q, a, b, c), [[0.5, 0.25, 0.25]])
    assert (barycentric(np.array([[-0.5, 0.2, 0.0]]), a, b, c)[0] < 0).any()
