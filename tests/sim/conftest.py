"""Shared fixtures for simulator tests: a small world with the UR5 and a small towel."""

import pytest

from foldbot.garments.towel import TowelSpec, make_towel
from foldbot.sim.cloth import ClothConfig, DivergenceMonitor, SoftCloth, settle
from foldbot.sim.robots import make_robot
from foldbot.sim.world import SimWorld


@pytest.fixture
def world():
    w = SimWorld()
    yield w
    w.close()


def make_cell(world, resolution: int = 10):
    """World + UR5 + a settled 0.2 m towel, `resolution` vertices a side, at the workspace centre."""
    lay = world.layout
    robot = make_robot("ur5", world.client, lay)
    mesh = make_towel(TowelSpec(0.2, 0.2, resolution))
    cloth = SoftCloth(world.client, mesh, ClothConfig(), lay.table_height, lay.workspace_center_xy)
    world.add_step_hook(DivergenceMonitor(cloth, lay.workspace_center_xy, radius=1.0))
    settle(world, cloth)
    return world, robot, cloth


@pytest.fixture
def cell(world):
    """World + UR5 + a settled 0.2 m, 10×10 towel at the workspace centre."""
    return make_cell(world)


@pytest.fixture
def coarse_cell(world):
    """World + UR5 + a settled 0.2 m towel meshed 6×6 (4 cm squares, as coarse as the jaws)."""
    return make_cell(world, resolution=6)
