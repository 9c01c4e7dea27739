"""The runner on real (tiny) episodes: resume, error records, changed settings, open loop,
another run's folder, what a stopped episode staged, bad timeouts."""

import json
import os
import signal
import sys
import threading
import time

import pytest

from foldbot.bench.runner import MAX_TIMEOUT_S, episode_dir, error_file, run_suite
from foldbot.bench.suite import suite_from_dict
from foldbot.bench.summary import failure_cause
from foldbot.errors import ConfigError, OutputError
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


def _watch_staging(out, found: list, kill: bool = False):
    """A thread that notes the first staging folder an episode's worker makes under `out`
    (and, with kill, kills that worker, its pid named by the folder)."""

    def watch():
        deadline = time.monotonic() + 60
        while time.monotonic() < deadline and not found:
            partial = list((out / "episodes").glob(".*.partial-*"))
            if partial:
                found.append(partial[0])
                if kill:
                    os.kill(int(partial[0].name.rpartition("-")[2]), signal.SIGKILL)
            time.sleep(0.01)

    thread = threading.Thread(target=watch, daemon=True)
    thread.start()
    return thread


def test_an_episode_stopped_at_the_timeout_leaves_no_staging_folder(tmp_path, tiny_suite_data):
    """The worker is killed mid-write: its `.<id>.partial-<pid>` folder goes with it."""
    data = tiny_suite_data(recipe=["quarter"])
    data["towel"]["resolution"] = 20  # an episode far longer than the timeout
    suite = suite_from_dict(data)
    found: list = []
    thread = _watch_staging(tmp_path, found)
    (rec,) = run_suite(suite, tmp_path, progress=False, timeout=6)
    thread.join()
    assert rec["error_type"] == "Timeout", rec
    assert found, "the worker never began its episode folder within the timeout"
    assert sorted(p.name for p in (tmp_path / "episodes").iterdir()) == [
        f"{suite.episodes[0].id}.error.json"
    ]


def test_a_killed_episode_leaves_no_staging_folder(tmp_path, tiny_suite_data):
    suite = suite_from_dict(tiny_suite_data())
    found: list = []
    thread = _watch_staging(tmp_path, found, kill=True)
    (rec,) = run_suite(suite, tmp_path, progress=False)
    thread.join()
    assert found and rec["error_type"] == "Crashed" and "SIGKILL" in rec["error"], rec
    assert not list((tmp_path / "episodes").glob(".*"))


def test_a_rerun_removes_what_a_stopped_run_staged(tmp_path, tiny_suite_data):
    """Staging folders an earlier run left (its process gone) are removed before the episode
    runs again; one whose process still runs (a run writing it now) is kept."""
    suite = suite_from_dict(tiny_suite_data())
    eid = suite.episodes[0].id
    episodes = tmp_path / "episodes"
    stale = [episodes / f".{eid}.partial-{2**22 + 1}", episodes / f".{eid}.ray-partial"]
    alive = episodes / f".{eid}.partial-{os.getpid()}"
    for folder in [*stale, alive]:
        folder.mkdir(parents=True)
        (folder / "video.mp4").write_bytes(b"half")
    (rec,) = run_suite(suite, tmp_path, progress=False)
    assert "result" in rec
    assert not any(p.exists() for p in stale) and alive.is_dir()


def test_a_bad_timeout_is_refused_before_anything_is_written(tmp_path, tiny_suite_data):
    suite = suite_from_dict(tiny_suite_data())
    for bad in (float("nan"), float("inf"), 0.0, -1.0, MAX_TIMEOUT_S * 2):
        for run in (True, False):
            with pytest.raises(ConfigError, match=rf"--timeout must be .* got {bad!r}"):
                run_suite(suite, tmp_path / "b", timeout=bad, run=run, progress=False)
    assert not (tmp_path / "b").exists()


def test_a_folder_holding_another_run_is_refused(tmp_path, tiny_suite_data):
    """Another suite's run is neither replaced nor mixed with; the same run resumes (with other
    seeds too), and a suite of the very same episodes under another name may report them."""
    run_suite(suite_from_dict(tiny_suite_data()), tmp_path, progress=False, run=False)
    before = (tmp_path / "suite.json").read_bytes()
    other = suite_from_dict({**tiny_suite_data(recipe=["quarter"]), "name": "other"})
    with pytest.raises(ConfigError) as exc:
        run_suite(other, tmp_path, progress=False, run=False)
    assert str(exc.value).startswith(f"output folder {tmp_path} holds another run")
    assert "'tiny'" in str(exc.value) and "'other'" in str(exc.value)
    assert (tmp_path / "suite.json").read_bytes() == before
    for resumed in (tiny_suite_data(), tiny_suite_data(seeds="0-2")):
        run_suite(suite_from_dict(resumed), tmp_path, progress=False, run=False, retry_errors=True)
    renamed = {**tiny_suite_data(seeds="0-2"), "name": "tiny_copy"}
    run_suite(suite_from_dict(renamed), tmp_path, progress=False, run=False)
    assert json.loads((tmp_path / "suite.json").read_text())["name"] == "tiny_copy"


def test_an_unreadable_suite_json_is_a_clear_error(tmp_path, tiny_suite_data):
    (tmp_path / "suite.json").write_text("{not json")
    with pytest.raises(OutputError, match=r"cannot read .*suite.json"):
        run_suite(suite_from_dict(tiny_suite_data()), tmp_path, progress=False, run=False)
    assert not (tmp_path / "episodes").exists()
