import pybullet as p
import pytest

from foldbot.errors import ConfigError
from foldbot.sim.world import SimConfig, SimWorld


def test_world_is_headless_deformable_with_table(world):
    assert p.getConnectionInfo(world.client)["connectionMethod"] == p.DIRECT
    _lo, hi = p.getAABB(world.table_id, physicsClientId=world.client)
    assert hi[2] == pytest.approx(world.layout.table_height, abs=1e-3)
    info = p.getDynamicsInfo(world.table_id, -1, physicsClientId=world.client)
    assert info[1] == pytest.approx(1.0)  # lateral friction
    world.step(10)
    assert world.sim_time == pytest.approx(10 * world.time_step)


@pytest.mark.parametrize(
    ("kwargs", "needle"),
    [
        ({"time_step": 0.0}, "time_step"),
        ({"time_step": 0.5}, "time_step"),
        ({"gravity": -1}, "gravity"),
    ],
)
def test_bad_sim_config(kwargs, needle):
    with pytest.raises(ConfigError, match=needle):
        SimConfig(**kwargs)


def test_close_is_idempotent():
    w = SimWorld()
    w.close()
    assert not p.isConnected(w.client)
    w.close()


def test_gui_without_a_display_is_a_clear_error(monkeypatch):
    monkeypatch.delenv("DISPLAY", raising=False)
    monkeypatch.delenv("WAYLAND_DISPLAY", raising=False)
    with pytest.raises(ConfigError, match="display"):
        SimWorld(SimConfig(gui=True))
