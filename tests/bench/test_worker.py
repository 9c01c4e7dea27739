"""One benchmark episode in its own process (`python -m foldbot.bench.worker SPEC OUT REC`):
its record is the result, or the error that ended it with the progress before it, written
whole; a bad call is refused with its usage."""

import dataclasses
import json
import subprocess
import sys

import pytest

from foldbot.bench.suite import load_suite


def run_worker(spec, tmp_path):
    out, rec = tmp_path / "ep", tmp_path / "rec.json"
    proc = subprocess.run(
        [sys.executable, "-m", "foldbot.bench.worker", json.dumps(spec.as_dict()), str(out),
         str(rec)],
        capture_output=True, text=True, timeout=600,
    )  # fmt: skip
    assert proc.returncode == 0, proc.stderr[-3000:]
    assert not list(tmp_path.glob(".rec.json.tmp-*"))  # written through a rename, whole
    return out, json.loads(rec.read_text())


def smoke_spec(**changes):
    spec = next(e for e in load_suite("smoke").episodes if e.perception == "oracle")
    return dataclasses.replace(spec, **changes)


@pytest.mark.slow
def test_an_episode_records_its_result_and_writes_its_folder(tmp_path):
    spec = smoke_spec()
    out, record = run_worker(spec, tmp_path)
    assert record["id"] == spec.id and "error" not in record
    result = record["result"]
    saved = json.loads((out / "result.json").read_text())  # the episode folder, written whole
    assert "out_dir" not in result  # a path on the worker's machine, not part of the record
    assert result["fold_error_mm"] == saved["fold_error_mm"] and result["seed"] == spec.seed
    assert (out / "cloth.npz").is_file()


def test_an_episode_that_ends_in_an_error_records_it_with_its_progress(tmp_path):
    # A towel wider than the camera sees: refused before the arm moves.
    spec = smoke_spec(perception="vision", towel_width=0.9, towel_height=0.9)
    out, record = run_worker(spec, tmp_path)
    assert record["id"] == spec.id and "result" not in record
    assert record["error_type"] == "FoldbotError", record
    assert record["error"].startswith("the cloth extends beyond the camera's")
    assert "settling the cloth" in " ".join(record["log_tail"])
    assert not out.exists()


def test_a_bad_call_is_refused_with_its_usage():
    proc = subprocess.run(
        [sys.executable, "-m", "foldbot.bench.worker", "{}"], capture_output=True, text=True,
        timeout=120,
    )  # fmt: skip
    assert proc.returncode == 2
    assert "usage: python -m foldbot.bench.worker SPEC_JSON OUT_DIR RECORD_JSON" in proc.stderr
