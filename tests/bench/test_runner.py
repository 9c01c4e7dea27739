"""The runner on real (tiny) episodes: resume, error records, changed settings, open loop."""

import json
import sys

import pytest

from foldbot.bench.runner import episode_dir, error_file, run_suite
from foldbot.bench.suite import suite_from_dict
from foldbot.bench.summary import failure_cause
from foldbot.errors import ConfigError
from foldbot.io.episode import is_episode_dir


def test_resume_skips_finished_episodes(tmp_path, tiny_suite_data):
    suite = suite_from_dict(tiny_suite_data())
    ran: list[str] = []
    (first,) = run_suite(suite, tmp_path, progress=False, on_record=lambda r: ran.append(r["id"]))
    assert ran == ["towel-half-oracle-closed-s0000"]
    ep = episode_dir(tmp_path, suite.episodes[0])
    assert is_episode_dir(ep)
    stamp = (ep / "result.json").stat().st_mtime_ns
    # A second suite that adds a seed: only the new episode runs.
    grown = suite_from_dict(tiny_suite_data(seeds="0-1"))
    ran.clear()
    records = run_suite(grown, tmp_path, progress=False, on_record=lambda r: ran.append(r["id"]))
    assert ran == ["towel-half-oracle-closed-s0001"]
    assert (ep / "result.json").stat().st_mtime_ns == stamp
    assert records[0] == first
    assert [r["id"] for r in records] == [e.id for e in grown.episodes]


def test_an_episode_ending_in_an_error_is_recorded_and_not_rerun(tmp_path, tiny_suite_data):
    data = tiny_suite_data(perception=["vision"])
    data["towel"].update(width=1.0, height=1.0, resolution=8)  # beyond the camera's view
    data["episode"]["video_fps"] = 5
    suite = suite_from_dict(data)
    (rec,) = run_suite(suite, tmp_path, progress=False)
    assert "result" not in rec
    assert failure_cause(rec) == "cloth out of view", rec["error"]
    assert rec["log_tail"] and rec["log_tail"][0].startswith("settling the cloth")  # the phase
    err = error_file(tmp_path, suite.episodes[0])
    assert json.loads(err.read_text()) == rec
    ep = episode_dir(tmp_path, suite.episodes[0])
    assert not ep.exists()
    # What the camera filmed up to the error lies beside it, named by the record.
    assert rec["failed_dir"] == f"{ep.name}.failed"
    assert sorted(p.name for p in (ep.parent / rec["failed_dir"]).iterdir()) == [
        "error.json",
        "video.mp4",
    ]
    ran: list[str] = []
    run_suite(suite, tmp_path, progress=False, on_record=lambda r: ran.append(r["id"]))
    assert ran == []
    run_suite(suite, tmp_path, progress=False, retry_errors=True, on_record=ran.append)
    assert len(ran) == 1


def test_changed_settings_for_a_finished_episode_are_refused(tmp_path, tiny_suite_data):
    run_suite(suite_from_dict(tiny_suite_data()), tmp_path, progress=False, run=False)
    changed = tiny_suite_data()
    changed["randomise"] = {"yaw_deg": 30}
    with pytest.raises(ConfigError, match="yaw_deg"):
        run_suite(suite_from_dict(changed), tmp_path, progress=False, run=False)


def test_a_setting_the_new_run_leaves_out_is_named(tmp_path, tiny_suite_data):
    # The finished episode set a loop option; the new run leaves it at its default, so its spec
    # has no such key: the error still names what changed.
    data = tiny_suite_data()
    data["loop_options"] = {"relay_corners": False}
    run_suite(suite_from_dict(data), tmp_path, progress=False, run=False)
    with pytest.raises(ConfigError, match=r"different settings \(loop_options\)"):
        run_suite(suite_from_dict(tiny_suite_data()), tmp_path, progress=False, run=False)


def test_bad_worker_count(tmp_path, tiny_suite_data):
    with pytest.raises(ConfigError, match="--workers"):
        run_suite(suite_from_dict(tiny_suite_data()), tmp_path, workers=0)


def test_open_loop_runs_without_reobserving(tmp_path, tiny_suite_data):
    """Open loop on a two-stage recipe: the second stage is planned from the first observation."""
    suite = suite_from_dict(tiny_suite_data(recipe=["quarter"], loop=["open"]))
    (rec,) = run_suite(suite, tmp_path, progress=False)
    r = rec["result"]
    assert r["closed_loop"] is False and r["recipe"] == "quarter"
    assert len(r["fold_lines"]) == 2 and len(r["actions"]) == 4
    assert all(a["retries"] == 0 and a["attempts"] == [] for a in r["actions"])
    assert all(stage["verified"] is None for stage in r["stages"])
    assert 0.0 <= r["coverage"] <= 1.0 and r["fold_error_mm"] > 0


def test_ray_missing_is_a_clear_error_before_anything_is_written(
    tmp_path, monkeypatch, tiny_suite_data
):
    monkeypatch.setitem(sys.modules, "ray", None)  # as if the optional extra were not installed
    out = tmp_path / "b"
    with pytest.raises(ConfigError, match=r"pip install -e '\.\[ray\]'"):
        run_suite(suite_from_dict(tiny_suite_data()), out, ray_address="auto")
    assert not out.exists()
