"""`foldbot score` and `foldbot export-bag` on a damaged episode or an output they cannot write:
one line naming the file and what is allowed, exit 2, and no bag (or partial bag) left behind."""

import io
import json
from pathlib import Path

import numpy as np
import pytest

from foldbot.cli import main
from foldbot.garments.towel import TowelSpec, make_towel
from foldbot.io.episode import REQUIRED_RESULT_KEYS, EpisodeWriter
from foldbot.metrics import score_episode


def write_episode(folder: Path, **cloth: object) -> Path:
    """A small scored episode (a 4×4 towel left flat), its cloth.npz arrays replaced by `cloth`."""
    mesh = make_towel(TowelSpec(0.3, 0.3, resolution=4, odd_grid=False))
    faces, initial = mesh.faces, mesh.vertices + np.array([0.15, 0.15, 0.76])  # x, y in 0–0.3
    result = dict.fromkeys(REQUIRED_RESULT_KEYS, 0)
    result.update(success=False, fold_lines=[[0.15, 0.0, 0.0, 1.0]], actions=[], garment="towel")
    with EpisodeWriter(folder) as w:
        w.write_cloth(faces, initial, initial, 0.002)
        w.write_result(result)
    if cloth:
        arrays = {"faces": faces, "initial": initial, "final": initial, "thickness": 0.002}
        buf = io.BytesIO()
        np.savez(buf, **{**arrays, **cloth})
        (folder / "cloth.npz").write_bytes(buf.getvalue())
    return folder


def test_score_prints_the_metrics_of_a_sound_episode(tmp_path, capsys):
    ep = write_episode(tmp_path / "ep")
    assert main(["score", str(ep)]) == 0
    printed = json.loads(capsys.readouterr().out)
    with np.load(ep / "cloth.npz") as cloth:
        expected = score_episode(
            cloth["initial"], cloth["final"], cloth["faces"], [[0.15, 0.0, 0.0, 1.0]], 0.002
        )
    assert printed == json.loads(json.dumps(expected.as_dict()))
    # A towel left flat: nothing folded, nothing gained, the table still covered.
    assert printed["success"] is False and printed["normalized_performance"] == pytest.approx(0)
    assert printed["coverage"] == pytest.approx(1.0, abs=0.02) and printed["fold_error_mm"] > 50


@pytest.mark.parametrize(
    ("damage", "says"),
    [
        (b"", "is not a readable episode file (it is empty)"),
        (b"PK\x03\x04 and then nothing", "is not a readable episode file (a truncated or corrupt"),
        (b"plain text", "is not a readable episode file (it is not a .npz (zip) archive)"),
        ({"final": np.full((16, 3), "x")}, "final must be a non-empty V×3 array of numbers"),
        ({"final": np.full((16, 3), np.nan)}, "final has NaN or inf coordinates at 16 of its 16"),
        ({"final": np.full((16, 3), 1e300)}, "final has a vertex coordinate of 1e+300 m"),
        ({"thickness": np.float64(-1.0)}, "thickness = -1 must be a finite number ≥ 0 (m)"),
    ],
)
@pytest.mark.parametrize("command", ["score", "export-bag"])
def test_a_damaged_cloth_npz_gets_one_line_naming_it(tmp_path, capsys, command, damage, says):
    if isinstance(damage, bytes):
        ep = write_episode(tmp_path / "ep")
        (ep / "cloth.npz").write_bytes(damage)
    else:
        ep = write_episode(tmp_path / "ep", **damage)
    bag = tmp_path / "out" / "ep.bag"
    argv = [command, str(ep)] + (["--out", str(bag)] if command == "export-bag" else [])
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert err.startswith(f"foldbot {command}: error: cloth.npz in {ep}") and says in err
    assert "Traceback" not in err and "allow_pickle" not in err and "array(" not in err
    assert not (tmp_path / "out").exists()  # nothing written, not even the bag's folder


def test_export_bag_onto_a_folder_or_under_a_file_is_refused(tmp_path, capsys):
    ep = write_episode(tmp_path / "ep")
    folder = tmp_path / "d.bag"
    folder.mkdir()
    for flags in ([], ["--overwrite"]):
        assert main(["export-bag", str(ep), "--out", str(folder), *flags]) == 2
        err = capsys.readouterr().err
        assert f"foldbot export-bag: error: {folder} is a folder; name a .bag file" in err
    assert list(folder.iterdir()) == []
    (tmp_path / "afile").write_text("keep")
    under = tmp_path / "afile" / "x.bag"
    assert main(["export-bag", str(ep), "--out", str(under)]) == 2
    err = capsys.readouterr().err
    assert f"cannot write the bag {under}: {tmp_path / 'afile'} is not a folder" in err
    assert sorted(p.name for p in tmp_path.iterdir()) == ["afile", "d.bag", "ep"]


def test_export_bag_into_a_folder_it_cannot_write_is_refused(tmp_path, capsys, unwritable_folder):
    ep = write_episode(tmp_path / "ep")
    shut = unwritable_folder
    assert main(["export-bag", str(ep), "--out", str(shut / "x.bag")]) == 2
    err = capsys.readouterr().err
    assert f"cannot write the bag {shut / 'x.bag'} (" in err and "Traceback" not in err
    assert list(shut.iterdir()) == []
