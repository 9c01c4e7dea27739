"""Loaded by pytest before any test module: `import foldbot` caps numpy's, OpenBLAS's and OpenCV's
SIMD level before they load (foldbot.simd), so in-process tests compute as the commands do."""

import json
import re
import subprocess

import pytest

import foldbot  # noqa: F401


@pytest.fixture
def no_launch(monkeypatch):
    """Refuse to start any process (roslaunch, roscore, a node) for the test's length: a check
    that a bad option is refused fails at once, instead of running a cell for ever, should the
    option become valid."""

    def refuse(cmd, *args, **kwargs):
        raise AssertionError(f"the command launched {cmd!r}: the options were accepted")

    monkeypatch.setattr(subprocess, "Popen", refuse)


@pytest.fixture
def unwritable_folder(tmp_path):
    """An empty folder this user cannot write in (mode 555); the test is skipped where the
    user writes there all the same (root, some file systems): nothing to test then."""
    shut = tmp_path / "shut"
    shut.mkdir()
    shut.chmod(0o555)
    try:
        try:
            (shut / "probe").write_bytes(b"")
        except OSError:
            pass
        else:
            pytest.skip("this user can write in a read-only folder")
        yield shut
    finally:
        shut.chmod(0o755)


def _spec(recipe, seed, **extra):
    return {
        "garment": "towel",
        "recipe": recipe,
        "perception": "vision",
        "loop": "closed",
        "seed": seed,
        **extra,
    }


@pytest.fixture
def write_run():
    """Write a benchmark run folder (tests of `foldbot compare`): see _write_run."""
    return _write_run


def _write_run(folder, episodes, **spec_extra):
    """A run folder as `foldbot bench` leaves it: suite.json, and per episode either a scored
    folder (result.json and cloth.npz) or an error record. episodes: id → (recipe, seed, record)
    with record a fold error in mm (success below 10 mm), or an error type."""
    (folder / "episodes").mkdir(parents=True)
    specs = {}
    for eid, (recipe, seed, record) in episodes.items():
        specs[eid] = _spec(recipe, seed, **spec_extra)
        replicate = re.search(r"-r(\d+)$", eid)
        if replicate:  # as EpisodeSpec.as_dict: the field only where it is not 0
            specs[eid]["replicate"] = int(replicate.group(1))
        if isinstance(record, str):
            (folder / "episodes" / f"{eid}.error.json").write_text(
                json.dumps({"id": eid, "error_type": record, "error": "cloth simulation diverged"})
            )
        elif record is not None:
            ep = folder / "episodes" / eid
            ep.mkdir()
            result = {
                "success": record < 10,
                "fold_error_mm": record,
                "normalized_performance": 0.9,
                "wall_seconds": 20.0 + seed,  # differs between runs; not part of "the same"
                "actions": [{"grasp_success": True}],
            }
            (ep / "result.json").write_text(json.dumps(result))
            (ep / "cloth.npz").write_bytes(b"")
    (folder / "suite.json").write_text(json.dumps({"name": "t", "episodes": specs}))
    return folder
