"""The plain-PyBullet speed reference at Deformable Ravens' settings."""

import pytest

from foldbot.bench.ravens_reference import RAVENS_HZ, ravens_speed_reference, write_grid_obj
from foldbot.errors import ConfigError


def test_grid_obj(tmp_path):
    path = tmp_path / "c.obj"
    write_grid_obj(path, 0.3, 0.2, 10)
    lines = path.read_text().splitlines()
    verts = [tuple(map(float, ln.split()[1:])) for ln in lines if ln.startswith("v ")]
    faces = [ln for ln in lines if ln.startswith("f ")]
    assert len(verts) == 100 and len(faces) == 2 * 9 * 9
    xs, ys = [v[0] for v in verts], [v[1] for v in verts]
    assert max(xs) - min(xs) == pytest.approx(0.3) and max(ys) - min(ys) == pytest.approx(0.2)


def test_reference_simulates_the_requested_time():
    ref = ravens_speed_reference(0.3, 0.3, sim_seconds=1.0)
    assert ref["vertices"] == 100 and ref["time_step_s"] == pytest.approx(1 / RAVENS_HZ)
    assert ref["sim_seconds"] == pytest.approx(1.0)
    assert ref["finite"] and ref["sim_speed"] > 0 and ref["wall_seconds"] > 0
    assert ref["settings"]["springElasticStiffness"] == 40 and ref["settings"]["mass"] == 0.5
    assert ref["settings"]["collisionMargin"] == pytest.approx(0.3 / 9 / 5)


@pytest.mark.parametrize(
    ("args", "needle"), [((2.0, 0.3, 1.0), "sides"), ((0.3, 0.3, 0), "duration")]
)
def test_reference_bad_input(args, needle):
    with pytest.raises(ConfigError, match=needle):
        ravens_speed_reference(*args)
