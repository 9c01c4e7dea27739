"""Tests for foldbot.io.episode: atomic episode folders, result.json contract, rescoring."""

from __future__ import annotations

import io
import json
from pathlib import Path
from typing import Any

import imageio.v3 as iio
import numpy as np
import pytest

from foldbot.errors import ConfigError, OutputError
from foldbot.io.episode import (
    REQUIRED_RESULT_KEYS,
    EpisodeWriter,
    is_episode_dir,
    is_failed_dir,
    is_unscored_episode_dir,
    load_episode,
    rescore,
)
from foldbot.metrics import fold_goal, score_episode

LINES = [[0.0, 0.0, 0.0, 1.0], [0.0, 0.0, 1.0, 0.0]]
THICKNESS = 0.002


def cloth(n: int = 11, size: float = 0.3) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Faces, flat start and an imperfectly quarter-folded final state of an n×n grid."""
    xs = np.linspace(-size / 2, size / 2, n)
    gx, gy = np.meshgrid(xs, xs)
    initial = np.stack([gx.ravel(), gy.ravel(), np.full(n * n, 0.76)], axis=1)
    faces = np.array(
        [
            tri
            for i in range(n - 1)
            for j in range(n - 1)
            for tri in (
                [i * n + j, i * n + j + 1, (i + 1) * n + j + 1],
                [i * n + j, (i + 1) * n + j + 1, (i + 1) * n + j],
            )
        ],
        dtype=np.int32,
    )
    goal, _ = fold_goal(initial, LINES, THICKNESS)
    final = goal + np.random.default_rng(0).normal(0, 0.004, goal.shape)
    return faces, initial, final


def result_for(faces: np.ndarray, initial: np.ndarray, final: np.ndarray) -> dict[str, Any]:
    """A complete result dict with numpy-typed values, as the pipeline would produce it."""
    score = score_episode(initial, final, faces, LINES, THICKNESS)
    return {
        "success": np.bool_(score.success),
        "fold_error_mm": np.float64(score.fold_error_mm),
        "normalized_performance": score.normalized_performance,
        "coverage": np.float32(score.coverage),
        "fold_lines": np.array(LINES),
        "garment": "towel",
        "recipe": "quarter",
        "seed": np.int64(3),
        "actions": [{"kind": "fold", "grasp": np.zeros(3), "retries": 0}],
        "sim_seconds": 12.5,
        "wall_seconds": 30.0,
    }


def write_episode(out: Path, **kwargs: Any) -> Path:
    """Write a full episode into `out` and return the committed folder."""
    faces, initial, final = cloth()
    with EpisodeWriter(out, fps=5, **kwargs) as w:
        for k in range(3):
            w.add_frame(np.full((48, 64, 3), 40 * k, np.uint8))
        w.write_cloth(faces, initial, final, THICKNESS)
        w.write_result(result_for(faces, initial, final))
        w.write_image("overlay", np.zeros((8, 8, 3), np.uint8))
        return w.commit()


def test_roundtrip_and_rescore_equals_written(tmp_path: Path) -> None:
    out = write_episode(tmp_path / "ep")
    assert out == (tmp_path / "ep").absolute()
    assert sorted(p.name for p in out.iterdir()) == [
        "cloth.npz",
        "overlay.png",
        "result.json",
        "video.mp4",
    ]
    assert [p.name for p in tmp_path.iterdir()] == ["ep"]  # no staging folder left
    with np.load(out / "cloth.npz") as npz:
        assert sorted(npz.files) == ["faces", "final", "initial", "thickness"]
        assert npz["faces"].dtype.kind == "i" and npz["faces"].shape[1] == 3
    result = json.loads((out / "result.json").read_text())
    assert set(REQUIRED_RESULT_KEYS) <= set(result)
    assert result["success"] is True or result["success"] is False
    assert result["seed"] == 3 and result["fold_lines"] == LINES
    score = rescore(out)
    assert score.fold_error_mm == result["fold_error_mm"]
    assert score.normalized_performance == result["normalized_performance"]
    assert score.success == result["success"]
    assert score.coverage == pytest.approx(result["coverage"], rel=1e-6)  # written as float32
    assert 0.0 < score.fold_error_mm < 15.0
    ep = load_episode(out)
    assert ep.thickness == THICKNESS and ep.initial.shape == ep.final.shape == (121, 3)


def test_an_error_leaves_no_episode_and_keeps_what_was_recorded_beside_it(
    tmp_path: Path,
) -> None:
    faces, initial, final = cloth()
    target = tmp_path / "ep"
    with pytest.raises(RuntimeError, match="boom") as raised, EpisodeWriter(target, fps=5) as w:
        for k in range(4):
            w.add_frame(np.full((32, 48, 3), 60 * k, np.uint8))
        w.write_image("flatten", np.zeros((8, 8, 3), np.uint8))
        w.write_cloth(faces, initial, final, THICKNESS)
        w.write_result(result_for(faces, initial, final))
        raise RuntimeError("boom")
    failed = tmp_path / "ep.failed"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["ep.failed"]  # no episode, no staging
    assert w.failed == failed.absolute() and is_failed_dir(failed) and not is_episode_dir(failed)
    assert sorted(p.name for p in failed.iterdir()) == [
        "cloth.npz",
        "error.json",
        "flatten.png",
        "video.mp4",
    ]
    assert json.loads((failed / "error.json").read_text()) == {
        "error_type": "RuntimeError",
        "error": "boom",
    }
    assert len(iio.imread(failed / "video.mp4")) == 4  # closed, every frame
    (note,) = raised.value.__notes__
    assert str(failed.absolute()) in note and "video.mp4" in note


def test_an_errors_facts_are_kept_in_error_json(tmp_path: Path) -> None:
    """What the episode measured before a FoldbotError (its flattening, say) is evidence too."""
    from foldbot.errors import SimulationDivergedError, add_facts

    with pytest.raises(SimulationDivergedError), EpisodeWriter(tmp_path / "ep") as w:
        w.write_image("flatten", np.zeros((8, 8, 3), np.uint8))
        exc = SimulationDivergedError("cloth simulation diverged")
        add_facts(exc, flatten={"actions": np.int64(2), "coverage_start": np.float64(0.5)})
        raise exc
    assert json.loads((tmp_path / "ep.failed" / "error.json").read_text()) == {
        "error_type": "SimulationDivergedError",
        "error": "cloth simulation diverged",
        "facts": {"flatten": {"actions": 2, "coverage_start": 0.5}},
    }


def test_an_error_with_nothing_recorded_leaves_nothing(tmp_path: Path) -> None:
    with pytest.raises(RuntimeError, match="boom"), EpisodeWriter(tmp_path / "ep") as w:
        raise RuntimeError("boom")
    assert w.failed is None and list(tmp_path.iterdir()) == []


def test_an_interrupt_keeps_nothing(tmp_path: Path) -> None:
    with pytest.raises(KeyboardInterrupt), EpisodeWriter(tmp_path / "ep") as w:
        w.add_frame(np.zeros((32, 32, 3), np.uint8))
        raise KeyboardInterrupt
    assert list(tmp_path.iterdir()) == []


def test_failed_folders_are_replaced_by_the_next_try_and_others_left_alone(
    tmp_path: Path,
) -> None:
    def fail(out: Path, message: str) -> None:
        with pytest.raises(RuntimeError), EpisodeWriter(out, overwrite=True) as w:
            w.write_image("flatten", np.zeros((8, 8, 3), np.uint8))
            raise RuntimeError(message)

    fail(tmp_path / "ep", "first")
    fail(tmp_path / "ep", "second")
    assert json.loads((tmp_path / "ep.failed" / "error.json").read_text())["error"] == "second"
    write_episode(tmp_path / "ep")  # the episode that succeeds removes the earlier evidence
    assert sorted(p.name for p in tmp_path.iterdir()) == ["ep"]
    foreign = tmp_path / "other.failed"
    foreign.mkdir()
    (foreign / "notes.txt").write_text("keep me")
    fail(tmp_path / "other", "third")  # not ours to replace: the staged files are dropped
    assert sorted(p.name for p in foreign.iterdir()) == ["notes.txt"]
    assert sorted(p.name for p in tmp_path.iterdir()) == ["ep", "other.failed"]


def test_clean_exit_commits(tmp_path: Path) -> None:
    faces, initial, final = cloth()
    with EpisodeWriter(tmp_path / "ep") as w:
        w.write_cloth(faces, initial, final, THICKNESS)
        w.write_result(result_for(faces, initial, final))
    assert is_episode_dir(tmp_path / "ep")


def test_commit_without_result_fails_and_cleans_up(tmp_path: Path) -> None:
    faces, initial, final = cloth()
    with pytest.raises(OutputError, match=r"result\.json"), EpisodeWriter(tmp_path / "ep") as w:
        w.write_cloth(faces, initial, final, THICKNESS)
    assert list(tmp_path.iterdir()) == []


def test_an_unscored_episode_commits_without_the_cloth_only_when_asked(tmp_path: Path) -> None:
    # A real cell's fold has no ground-truth cloth: result.json with its metrics None.
    faces, initial, final = cloth()
    unscored = {**result_for(faces, initial, final), "scored": False, "success": None}
    with pytest.raises(OutputError, match=r"cloth\.npz"), EpisodeWriter(tmp_path / "ep") as w:
        w.write_result(unscored)
    assert list(tmp_path.iterdir()) == []
    with EpisodeWriter(tmp_path / "ep") as w:
        w.write_result(unscored)
        w.commit(require_cloth=False)
    assert sorted(p.name for p in (tmp_path / "ep").iterdir()) == ["result.json"]
    assert not is_episode_dir(tmp_path / "ep")  # nothing there to rescore
    with pytest.raises(ConfigError, match=r"a fold on a real cell, unscored: it has no cloth"):
        rescore(tmp_path / "ep")


def test_an_unscored_episode_is_replaced_with_overwrite_as_a_scored_one(tmp_path: Path) -> None:
    # `ros-fold --cell real --out DIR --overwrite` a second time: DIR holds the first fold's
    # result.json (scored false) and its pictures, no cloth.npz.
    faces, initial, final = cloth()
    unscored = {**result_for(faces, initial, final), "scored": False, "success": None}
    out = tmp_path / "ep"
    for run in range(2):
        with EpisodeWriter(out, overwrite=run > 0) as w:
            w.write_result({**unscored, "wall_seconds": float(run)})
            w.write_image("overlay_final", np.zeros((8, 8, 3), np.uint8))
            w.commit(require_cloth=False)
    assert is_unscored_episode_dir(out)
    assert json.loads((out / "result.json").read_text())["wall_seconds"] == 1.0
    with pytest.raises(OutputError, match=r"already holds an episode; use --overwrite"):
        EpisodeWriter(out)
    # A result.json that does not say it is unscored, with no cloth, is no episode to replace.
    (tmp_path / "other").mkdir()
    (tmp_path / "other" / "result.json").write_text(json.dumps({"scored": True}))
    assert not is_unscored_episode_dir(tmp_path / "other")
    with pytest.raises(OutputError, match="not a foldbot episode"):
        EpisodeWriter(tmp_path / "other", overwrite=True)


def test_missing_result_keys_named(tmp_path: Path) -> None:
    faces, initial, final = cloth()
    result = result_for(faces, initial, final)
    del result["seed"], result["actions"]
    w = EpisodeWriter(tmp_path / "ep")
    with pytest.raises(OutputError, match="'seed', 'actions'"):
        w.write_result(result)
    assert not (w.staging_dir / "result.json").exists()
    w.abort()
    assert list(tmp_path.iterdir()) == []


def test_target_validation(tmp_path: Path) -> None:
    a_file = tmp_path / "file.txt"
    a_file.write_text("x")
    with pytest.raises(OutputError, match="not a folder"):
        EpisodeWriter(a_file)
    with pytest.raises(OutputError, match="parent folder"):
        EpisodeWriter(a_file / "ep")  # parent is a regular file
    busy = tmp_path / "busy"
    busy.mkdir()
    (busy / "notes.txt").write_text("keep me")
    with pytest.raises(OutputError, match="not a foldbot episode"):
        EpisodeWriter(busy)
    assert (busy / "notes.txt").read_text() == "keep me"
    empty = tmp_path / "empty"
    empty.mkdir()
    assert is_episode_dir(write_episode(empty))


def test_overwrite_only_when_asked(tmp_path: Path) -> None:
    out = write_episode(tmp_path / "ep")
    with pytest.raises(OutputError, match=r"use --overwrite \(overwrite=True\) to replace it"):
        EpisodeWriter(out)
    (out / "stale.png").write_bytes(b"old")
    write_episode(out, overwrite=True)
    assert not (out / "stale.png").exists()
    assert sorted(p.name for p in tmp_path.iterdir()) == ["ep"]


def test_bad_cloth_and_image_args(tmp_path: Path) -> None:
    faces, initial, final = cloth()
    w = EpisodeWriter(tmp_path / "ep")
    with pytest.raises(ConfigError, match="differs"):
        w.write_cloth(faces, initial, final[:-1], THICKNESS)
    with pytest.raises(ConfigError, match="integer"):
        w.write_cloth(faces.astype(float), initial, final, THICKNESS)
    with pytest.raises(ConfigError, match="plain file name"):
        w.write_image("../x.png", np.zeros((4, 4, 3), np.uint8))
    with pytest.raises(ConfigError, match="uint8"):
        w.write_image("x", np.zeros((4, 4, 3), np.float32))
    w.abort()
    assert list(tmp_path.iterdir()) == []


def test_load_rejects_non_episode(tmp_path: Path) -> None:
    with pytest.raises(ConfigError, match="not an episode folder"):
        rescore(tmp_path)


def _cloth_npz(**arrays: Any) -> bytes:
    """A cloth.npz's bytes: the test cloth's arrays, with `arrays` in place of them."""
    faces, initial, final = cloth()
    base = {"faces": faces, "initial": initial, "final": final, "thickness": THICKNESS}
    buf = io.BytesIO()
    np.savez(buf, **{**base, **arrays})
    return buf.getvalue()


_, _INITIAL, _FINAL = cloth()


@pytest.mark.parametrize(
    ("data", "says"),
    [
        (b"", "is not a readable episode file (it is empty)"),
        (b"not a zip at all", "is not a readable episode file (it is not a .npz (zip) archive)"),
        (_cloth_npz()[:500], "is not a readable episode file (a truncated or corrupt archive"),
        (
            _cloth_npz(final=np.array([None] * 3, dtype=object)),
            "array 'final' holds Python objects, which foldbot does not load",
        ),
        (
            _cloth_npz(final=np.array(["a"] * len(_FINAL))),
            "final must be a non-empty V×3 array of numbers (m), got <U1",
        ),
        (
            _cloth_npz(final=np.where(np.arange(len(_FINAL))[:, None] < 2, np.nan, _FINAL)),
            "final has NaN or inf coordinates at 2 of its 121 vertices; every coordinate must be "
            "finite and within ±100 m of the world origin",
        ),
        (
            _cloth_npz(initial=_INITIAL * 1e300),
            "initial has a vertex coordinate of 7.6e+299 m; every coordinate must be finite",
        ),
        (_cloth_npz(thickness=np.float64("nan")), "thickness = nan must be a finite number ≥ 0"),
        (_cloth_npz(thickness=np.array([1.0, 2.0])), "thickness = float64 array of shape (2,)"),
    ],
)
def test_load_names_a_cloth_file_it_cannot_use(tmp_path: Path, data: bytes, says: str) -> None:
    out = write_episode(tmp_path / "ep")
    (out / "cloth.npz").write_bytes(data)
    with pytest.raises(ConfigError) as caught:
        load_episode(out)
    message = str(caught.value)
    assert message.startswith(f"cloth.npz in {out}") and says in message
    assert "array(" not in message and "allow_pickle" not in message


def test_write_cloth_refuses_coordinates_no_cloth_has(tmp_path: Path) -> None:
    faces, initial, final = cloth()
    w = EpisodeWriter(tmp_path / "ep")
    final[5, 2] = np.inf
    with pytest.raises(ConfigError, match="final has NaN or inf coordinates at 1 of its 121"):
        w.write_cloth(faces, initial, final, THICKNESS)
    w.abort()
    assert list(tmp_path.iterdir()) == []
