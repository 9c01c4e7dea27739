"""Ray scale-out against a local Ray instance: the same per-episode results as a local run."""

import json

import pytest

from foldbot.bench.runner import episode_dir, run_suite
from foldbot.bench.suite import suite_from_dict

ray = pytest.importorskip(
    "ray", reason="Ray is an optional extra (pip install -e '.[ray]'); the Ray runner is untested"
)


def without_wall_time(value):
    """result.json minus the wall-clock fields, which no two runs share."""
    if isinstance(value, dict):
        return {k: without_wall_time(v) for k, v in value.items() if k != "wall_seconds"}
    if isinstance(value, list):
        return [without_wall_time(v) for v in value]
    return value


def test_ray_run_equals_local_run(tmp_path, tiny_suite_data):
    suite = suite_from_dict(tiny_suite_data(perception=["vision"], loop=["closed", "open"]))
    local = run_suite(suite, tmp_path / "local", workers=2, progress=False)
    try:
        remote = run_suite(suite, tmp_path / "ray", ray_address="local", progress=False)
    finally:
        ray.shutdown()
    assert [r["id"] for r in remote] == [r["id"] for r in local]
    for a, b in zip(local, remote, strict=True):
        assert "result" in a and "result" in b
        assert without_wall_time(a["result"]) == without_wall_time(b["result"])
    for spec in suite.episodes:
        folder = episode_dir(tmp_path / "ray", spec)
        names = {p.name for p in folder.iterdir()}
        assert {"result.json", "cloth.npz", "overlay_final.png"} <= names
        stored = json.loads((folder / "result.json").read_text())
        local_stored = json.loads(
            (episode_dir(tmp_path / "local", spec) / "result.json").read_text()
        )
        assert without_wall_time(stored) == without_wall_time(local_stored)
        assert (folder / "cloth.npz").read_bytes() == (
            episode_dir(tmp_path / "local", spec) / "cloth.npz"
        ).read_bytes()


def test_ray_brings_back_what_a_failed_episode_recorded(tmp_path, tiny_suite_data):
    data = tiny_suite_data(perception=["vision"])
    data["towel"].update(width=1.0, height=1.0, resolution=8)  # beyond the camera's view
    data["episode"]["video_fps"] = 5
    suite = suite_from_dict(data)
    try:
        (rec,) = run_suite(suite, tmp_path, ray_address="local", progress=False)
    finally:
        ray.shutdown()
    ep = episode_dir(tmp_path, suite.episodes[0])
    assert "result" not in rec and not ep.exists()
    failed = ep.parent / rec["failed_dir"]
    assert sorted(p.name for p in failed.iterdir()) == ["error.json", "video.mp4"]
    assert json.loads((failed / "error.json").read_text())["error"] == rec["error"]
