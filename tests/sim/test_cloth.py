import math

import numpy as np
import pybullet as p
import pytest

from foldbot.errors import ConfigError, SimulationDivergedError
from foldbot.garments.towel import TowelSpec, make_towel
from foldbot.sim.cloth import ClothConfig, DivergenceMonitor, SoftCloth, keep_table_grip, settle
from foldbot.sim.world import SimWorld


def test_cloth_is_a_soft_body_in_mesh_order(world):
    mesh = make_towel(TowelSpec(0.2, 0.2, 8))
    cloth = SoftCloth(
        world.client, mesh, ClothConfig(), world.layout.table_height, (0.45, 0.0), 0.3
    )
    # A real soft body (not a multibody of boxes): PyBullet reports its simulation mesh.
    assert p.getNumJoints(cloth.body_id, physicsClientId=world.client) == 0
    v = cloth.sim_vertices()
    assert v.shape == (64, 3)
    assert np.allclose(v, cloth.spawn_vertices, atol=1e-5)


def test_cloth_settles_flat_without_jitter(cell):
    world, _robot, cloth = cell
    v1 = cloth.sim_vertices()
    heights = v1[:, 2] - world.layout.table_height
    assert heights.min() > 0.0, "cloth must not sink into the table"
    assert heights.max() < 0.006, "settled cloth lies flat on the table"
    assert np.ptp(heights) < 0.002
    extent = np.ptp(v1[:, :2], axis=0)
    assert np.allclose(extent, 0.2, atol=0.004), "no shrinking or stretching when settled"
    world.step(round(0.5 / world.time_step))
    jitter = np.linalg.norm(cloth.sim_vertices() - v1, axis=1).max()
    assert jitter < 5e-4


def test_divergence_is_detected(world):
    mesh = make_towel(TowelSpec(0.2, 0.2, 6))
    cloth = SoftCloth(world.client, mesh, ClothConfig(), world.layout.table_height, (0.45, 0.0))
    world.add_step_hook(DivergenceMonitor(cloth, (0.45, 0.0), radius=1.0, every=1))
    # Throw the cloth far away: the monitor must raise instead of letting it be scored.
    p.resetBasePositionAndOrientation(
        cloth.body_id, [5.0, 0.0, 3.0], [0, 0, 0, 1], physicsClientId=world.client
    )
    with pytest.raises(SimulationDivergedError, match="diverged") as exc:
        world.step(2)
    # Only the bounds broken are named: 5 m out and ~2.25 m up, not under the table.
    assert "from the workspace centre (limit 1.00 m)" in str(exc.value)
    assert "over the table (limit 1.5 m)" in str(exc.value) and "under" not in str(exc.value)


def test_a_vertex_through_the_table_is_named_with_its_depth(world):
    mesh = make_towel(TowelSpec(0.2, 0.2, 6))
    cloth = SoftCloth(world.client, mesh, ClothConfig(), world.layout.table_height, (0.45, 0.0))
    v = cloth.node_positions()
    v[0, 2] = world.layout.table_height - 0.0503  # just past the 50 mm allowed
    cloth.set_node_positions(v)
    with pytest.raises(SimulationDivergedError) as exc:
        cloth.check_finite_and_bounded((0.45, 0.0), 1.0)
    assert str(exc.value) == (
        "cloth simulation diverged: a vertex lies 50.3 mm under the table top (limit 50 mm: it "
        "went through)"
    )


def test_a_cloth_sliding_across_the_table_is_a_divergence(world):
    mesh = make_towel(TowelSpec(0.2, 0.2, 6))
    cloth = SoftCloth(world.client, mesh, ClothConfig(), world.layout.table_height, (0.45, 0.0))
    monitor = DivergenceMonitor(cloth, (0.45, 0.0), radius=1.0)
    world.add_step_hook(monitor)
    settle(world, cloth)
    assert monitor.fastest_slide < 0.05, "a cloth settling flat barely moves across the table"
    pos, orn = p.getBasePositionAndOrientation(cloth.body_id, physicsClientId=world.client)
    # Straight up is not a slide: the lifted cloth falls back without an error.
    p.resetBasePositionAndOrientation(
        cloth.body_id, [pos[0], pos[1], pos[2] + 0.1], orn, physicsClientId=world.client
    )
    world.step(3 * monitor.every)
    # 5 cm sideways between two checks (1/15 s apart) is 0.75 m/s: well inside the bounds, and
    # faster than a cloth nothing holds moves.
    pos, orn = p.getBasePositionAndOrientation(cloth.body_id, physicsClientId=world.client)
    p.resetBasePositionAndOrientation(
        cloth.body_id, [pos[0] + 0.05, pos[1], pos[2]], orn, physicsClientId=world.client
    )
    with pytest.raises(SimulationDivergedError, match=r"slid across the table at 0\.7\d m/s"):
        world.step(monitor.every)


def test_a_held_cloth_moving_fast_is_not_a_slide(world):
    """While anything holds the cloth (SoftCloth.anchor) the slide rule does not apply: a towel
    hung from grippers swings faster than they move. Let go, the same jump is a divergence."""
    mesh = make_towel(TowelSpec(0.2, 0.2, 6))
    cloth = SoftCloth(world.client, mesh, ClothConfig(), world.layout.table_height, (0.45, 0.0))
    monitor = DivergenceMonitor(cloth, (0.45, 0.0), radius=1.0)
    world.add_step_hook(monitor)
    settle(world, cloth)
    corner = mesh.keypoints["corner_00"]
    hand = p.createMultiBody(
        baseMass=0.1,
        basePosition=cloth.sim_vertices()[corner].tolist(),
        physicsClientId=world.client,
    )
    anchor = cloth.anchor(corner, hand)
    assert cloth.held

    def jump() -> None:
        pos, orn = p.getBasePositionAndOrientation(cloth.body_id, physicsClientId=world.client)
        p.resetBasePositionAndOrientation(
            cloth.body_id, [pos[0] + 0.05, pos[1], pos[2]], orn, physicsClientId=world.client
        )
        world.step(monitor.every)

    world.step(monitor.every)
    jump()  # 0.75 m/s while held: no error
    assert monitor.fastest_slide < 0.05
    cloth.release(anchor)
    assert not cloth.held
    world.step(2 * monitor.every)
    with pytest.raises(SimulationDivergedError, match="with nothing holding it"):
        jump()


def test_nan_vertices_are_detected(world):
    mesh = make_towel(TowelSpec(0.2, 0.2, 6))
    cloth = SoftCloth(world.client, mesh, ClothConfig(), world.layout.table_height, (0.45, 0.0))
    cloth._raw_vertices = lambda: np.full((36, 3), math.nan)  # what a blown-up solver returns
    with pytest.raises(SimulationDivergedError, match="non-finite"):
        cloth.check_finite_and_bounded((0.45, 0.0), 1.0)


def test_default_thickness_is_two_margins(world):
    mesh = make_towel(TowelSpec(0.3, 0.3, 16))
    cloth = SoftCloth(world.client, mesh, ClothConfig(), world.layout.table_height, (0.45, 0.0))
    assert cloth.margin == pytest.approx(mesh.edge_length / 5)
    assert cloth.thickness == pytest.approx(2 * cloth.margin)
    assert settle(world, cloth) < 2.0


@pytest.mark.parametrize(
    ("kwargs", "needle"),
    [
        ({"mass": 0.0}, "mass"),
        ({"mass": -1.0}, "mass"),
        ({"elastic_stiffness": 0.0}, "elastic_stiffness"),
        ({"friction": -0.1}, "friction"),
        ({"collision_margin": 0.5}, "collision_margin"),
        ({"margin_divisor": 1.0}, "margin_divisor"),
        ({"margin_divisor": float("nan")}, "margin_divisor"),
        ({"thickness": 1.0}, "thickness"),
        ({"layer_friction": 0.0}, "layer_friction"),
        ({"layer_friction": float("inf")}, "layer_friction"),
        ({"layer_friction": 5.0}, "layer_friction"),
    ],
)
def test_bad_cloth_config(kwargs, needle):
    with pytest.raises(ConfigError, match=needle):
        ClothConfig(**kwargs)


def test_a_larger_margin_divisor_makes_a_thinner_cloth(world):
    mesh = make_towel(TowelSpec(0.3, 0.3, 8))
    cloth = SoftCloth(
        world.client, mesh, ClothConfig(margin_divisor=8.0), world.layout.table_height, (0.45, 0.0)
    )
    assert cloth.margin == pytest.approx(mesh.edge_length / 8)
    assert cloth.thickness == pytest.approx(mesh.edge_length / 4)


def test_layer_friction_sets_the_body_coefficient_and_the_table_gain():
    assert ClothConfig().body_friction == 1.0 and ClothConfig().table_friction_gain == 1.0
    assert ClothConfig(friction=0.5).body_friction == 0.5  # unset: cloth–cloth follows friction²
    assert ClothConfig(friction=0.0).table_friction_gain == 1.0  # frictionless cloth, as before
    layers = ClothConfig(layer_friction=0.25)
    assert layers.body_friction == pytest.approx(0.5)
    assert layers.table_friction_gain == pytest.approx(2.0)
    assert ClothConfig(friction=0.8, layer_friction=0.16).table_friction_gain == pytest.approx(2.0)


def _slides_down_a_tilted_table(config: ClothConfig, tan_tilt: float) -> tuple[float, float]:
    """A 12 cm cloth on the table and an 8 cm one on top of it, gravity tilted to tan_tilt along
    +x (the table a slope): how far (m) the lower and the upper cloth slide in 1 s."""
    with SimWorld() as world:
        g, tilt = world.config.gravity, math.atan(tan_tilt)
        # Set before the soft bodies load: the deformable world gives each its gravity then.
        p.setGravity(g * math.sin(tilt), 0, -g * math.cos(tilt), physicsClientId=world.client)
        z = world.layout.table_height
        lower = SoftCloth(world.client, make_towel(TowelSpec(0.12, 0.12, 6)), config, z, (0.45, 0))
        keep_table_grip(world, config)
        upper_mesh = make_towel(TowelSpec(0.08, 0.08, 5))
        upper = SoftCloth(world.client, upper_mesh, config, z + 2.5 * lower.margin, (0.45, 0))
        start = [c.sim_vertices()[:, 0].mean() for c in (lower, upper)]
        world.step(round(1.0 / world.time_step))
        return tuple(
            c.sim_vertices()[:, 0].mean() - x0 for c, x0 in zip((lower, upper), start, strict=True)
        )


def test_layer_friction_lets_layers_slide_while_the_table_still_grips():
    """On a slope of 0.7 (cloth–table friction 1.0): at the defaults neither layer moves; with
    layers at 0.25 the upper slides off the lower, which the table still holds (its friction raised
    2×); lowering the cloth's friction instead (0.5) lets the whole cloth slide off the table."""
    lower, upper = _slides_down_a_tilted_table(ClothConfig(), 0.7)
    assert lower < 0.02 and upper < 0.03
    lower, upper = _slides_down_a_tilted_table(ClothConfig(layer_friction=0.25), 0.7)
    assert lower < 0.02 and upper > 0.1
    lower, upper = _slides_down_a_tilted_table(ClothConfig(friction=0.5), 0.7)
    assert lower > 0.3
