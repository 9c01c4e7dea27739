"""`foldbot bench` from the command line: the smoke suite end to end, resume, clear errors."""

import json
import subprocess
import sys

import numpy as np
import pytest

from foldbot.bench.suite import load_suite
from foldbot.cli import build_parser, main
from foldbot.commands.bench import suite_from_args
from foldbot.errors import ConfigError

FIGURES = (
    "success_rate",
    "fold_error_mm",
    "normalized_performance",
    "coverage",
    "actions_per_episode",
    "retries_per_episode",
    "sim_seconds_per_fold",
    "wall_seconds_per_episode",
    "sim_speed",
    "failures",
)


def bench(*args: str) -> subprocess.CompletedProcess:
    return subprocess.run(
        [sys.executable, "-m", "foldbot.cli", "bench", *args],
        capture_output=True,
        text=True,
        timeout=900,
    )


@pytest.fixture(scope="module")
def smoke_run(tmp_path_factory):
    out = tmp_path_factory.mktemp("bench") / "smoke"
    proc = bench("--suite", "smoke", "--out", str(out), "--workers", "2")
    assert proc.returncode == 0, proc.stderr[-2000:]
    return out, proc


def test_smoke_suite_end_to_end(smoke_run):
    out, proc = smoke_run
    assert {"suite.json", "summary.json", "summary.md", "errors.png"} <= {
        p.name for p in out.iterdir()
    }
    summary = json.loads((out / "summary.json").read_text())
    assert summary["complete"] and summary["episodes_finished"] == 4
    for group in [summary["overall"], *summary["groups"]]:
        assert set(FIGURES) <= group.keys()
    assert {(g["perception"], g["loop"]) for g in summary["groups"]} == {
        ("vision", "closed"),
        ("vision", "open"),
        ("oracle", "closed"),
        ("oracle", "open"),
    }
    assert {c["axis"] for c in summary["comparisons"]} == {"perception", "loop"}
    ref = summary["ravens_speed_reference"]
    assert ref["vertices"] == 100 and ref["sim_speed"] > 0
    assert ref["sim_seconds"] == pytest.approx(summary["overall"]["sim_seconds_per_fold"], rel=0.01)
    assert ref["reference_to_foldbot_speed"] == pytest.approx(
        ref["sim_speed"] / summary["overall"]["sim_speed"]
    )
    for e in summary["episodes"]:
        ep = out / "episodes" / e["id"]
        result = json.loads((ep / "result.json").read_text())
        assert (ep / "cloth.npz").is_file()
        assert result["closed_loop"] is ("-closed-" in e["id"])
        assert result["fold_error_mm"] == e["fold_error_mm"]
    assert "smoke: 4 of 4 episodes" in proc.stdout
    assert (out / "errors.png").read_bytes()[:4] == b"\x89PNG"


def test_fold_runs_one_suite_episode_as_bench_did(smoke_run, tmp_path):
    """`foldbot fold --suite smoke --episode ID` gives the episode the bench wrote, value for
    value (each in a fresh process), with a video the suite leaves out."""
    out, _ = smoke_run
    ep = "towel-half-vision-open-s0000"
    proc = subprocess.run(
        [sys.executable, "-m", "foldbot.cli", "fold", "--suite", "smoke", "--episode", ep,
         "--video-fps", "5", "--out", str(tmp_path / "ep")],
        capture_output=True, text=True, timeout=900,
    )  # fmt: skip
    assert proc.returncode == 0, proc.stderr[-2000:]
    mine = json.loads((tmp_path / "ep" / "result.json").read_text())
    bench_s = json.loads((out / "episodes" / ep / "result.json").read_text())
    for key in ("success", "fold_error_mm", "normalized_performance", "coverage", "sim_seconds"):
        assert mine[key] == bench_s[key], key
    wall = "wall_seconds"  # the only figure a video (and the machine's load) changes
    assert [{k: v for k, v in a.items() if k != wall} for a in mine["actions"]] == [
        {k: v for k, v in a.items() if k != wall} for a in bench_s["actions"]
    ]
    assert (tmp_path / "ep" / "video.mp4").is_file()
    assert not (out / "episodes" / ep / "video.mp4").exists()


def test_smoke_suite_resumes_without_rerunning(smoke_run):
    out, _ = smoke_run
    stamps = {p: p.stat().st_mtime_ns for p in out.glob("episodes/*/result.json")}
    proc = bench("--suite", "smoke", "--out", str(out), "--no-reference")
    assert proc.returncode == 0, proc.stderr[-2000:]
    assert {p: p.stat().st_mtime_ns for p in out.glob("episodes/*/result.json")} == stamps
    assert "ravens_speed_reference" not in json.loads((out / "summary.json").read_text())


def test_unknown_suite_lists_the_available_ones(tmp_path, capsys):
    out = tmp_path / "b"
    assert main(["bench", "--suite", "nope", "--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert "nope" in err and "smoke" in err and "towel_full" in err and "Traceback" not in err
    assert not out.exists()


def test_suite_and_one_recipe_options_do_not_mix(tmp_path, capsys):
    assert (
        main(["bench", "--suite", "smoke", "--recipe", "half", "--out", str(tmp_path / "b")]) == 2
    )
    assert "--recipe cannot be combined with --suite" in capsys.readouterr().err


def test_seeds_run_a_suite_over_other_seeds(tmp_path):
    """`--suite NAME --seeds S`: the suite's episodes for those seeds, and the summary's command
    says so."""
    args = build_parser().parse_args(
        ["bench", "--suite", "towel_loop", "--seeds", "25,40", "--out", "x"]
    )
    suite = suite_from_args(args)
    assert list(suite.episodes) == [
        e for e in load_suite("towel_full").episodes if e.seed in (25, 40)
    ]
    out = tmp_path / "r"
    assert (
        main(["bench", "--suite", "smoke", "--seeds", "5", "--out", str(out), "--report-only"]) == 0
    )
    summary = json.loads((out / "summary.json").read_text())
    assert summary["command"].endswith(f"--suite smoke --seeds 5 --out {out}")
    assert summary["episodes_planned"] == 4


def test_one_recipe_options_build_a_suite():
    args = build_parser().parse_args(
        ["bench", "--recipe", "diagonal", "--seeds", "0-19", "--size-range", "0.25", "0.45"]
        + ["--perception", "oracle", "--out", "x"]
    )
    suite = suite_from_args(args)
    assert len(suite.episodes) == 20
    e = suite.episodes[0]
    assert (e.recipe, e.perception, e.loop, e.towel_side_range) == (
        "diagonal",
        "oracle",
        "closed",
        (0.25, 0.45),
    )
    assert e.video_fps == 0.0
    # The towel `foldbot fold` folds by default (17 × 17 vertices for a square one).
    assert (e.towel_resolution, e.towel_odd_grid) == (17, True)
    assert e.to_config().towel.grid_shape[0] == 17


def test_help_mentions_suites(capsys):
    with pytest.raises(SystemExit):
        main(["bench", "--help"])
    out = capsys.readouterr().out
    assert "--suite" in out and "--ray" in out


def test_loop_options_go_over_the_suites_own(tmp_path):
    suite_file = tmp_path / "tiny.toml"
    suite_file.write_text(
        'name = "tiny"\n[axes]\nseeds = "0-1"\n[loop_options]\nrelay_corners = false\n'
        "finish_actions = 2\n"
    )
    args = build_parser().parse_args(
        ["bench", "--suite", str(suite_file), "--out", "x"]
        + ["--loop-option", "finish_actions=0", "--loop-option", "pair_descent=none"]
    )
    suite = suite_from_args(args)
    expected = {"finish_actions": 0, "relay_corners": False, "pair_descent": None}
    assert [e.to_config().loop_options for e in suite.episodes] == [expected, expected]
    assert suite.loop_options == expected


def test_cloth_options_go_over_the_suites_own(tmp_path):
    suite_file = tmp_path / "tiny.toml"
    suite_file.write_text(
        'name = "tiny"\n[axes]\nseeds = "0-1"\n[cloth]\nfriction = 2.0\nmass = 0.2\n'
    )
    args = build_parser().parse_args(
        ["bench", "--suite", str(suite_file), "--out", "x", "--cloth", "mass=0.3"]
    )
    suite = suite_from_args(args)
    assert [(e.to_config().cloth.mass, e.to_config().cloth.friction) for e in suite.episodes] == [
        (0.3, 2.0),
        (0.3, 2.0),
    ]
    assert suite.cloth_options == {"mass": 0.3, "friction": 2.0}


def test_a_bad_loop_option_is_refused_before_anything_runs(tmp_path, capsys):
    out = tmp_path / "b"
    code = main(
        ["bench", "--suite", "smoke", "--loop-option", "stack_edge_carry=1", "--out", str(out)]
    )
    assert code == 2
    err = capsys.readouterr().err
    assert "stack_edge_carry = 1 must be true or false" in err and "Traceback" not in err
    assert not out.exists()


def test_the_summary_command_repeats_the_options_set(tmp_path):
    """summary.md's command reruns the run: the loop and cloth options it set are in it."""
    out = tmp_path / "r"
    options = ["--loop-option", "relay_corners=false", "--cloth", "friction=0.5"]
    assert main(["bench", "--suite", "smoke", "--out", str(out), "--report-only", *options]) == 0
    command = json.loads((out / "summary.json").read_text())["command"]
    assert command.endswith(
        "--loop-option relay_corners=false --cloth friction=0.5 --out " + str(out)
    )


def test_flatten_options_go_over_the_suites_own(tmp_path):
    suite_file = tmp_path / "tiny.toml"
    suite_file.write_text(
        'name = "tiny"\n[axes]\nseeds = "0-1"\n[episode]\nstart = "crumpled"\n'
        "[flatten_options]\nfinish_coverage = 0.97\nmin_pull = 0.03\n"
    )
    args = build_parser().parse_args(
        ["bench", "--suite", str(suite_file), "--out", "x"]
        + ["--flatten-option", "finish_coverage=none"]
    )
    suite = suite_from_args(args)
    expected = {"finish_coverage": None, "min_pull": 0.03}
    assert [e.to_config().flatten_options for e in suite.episodes] == [expected, expected]
    assert suite.flatten_options == expected
    # Set on a suite of flat starts, the option would be read by no episode: refused.
    flat = tmp_path / "flat.toml"
    flat.write_text('name = "flat"\n[axes]\nseeds = "0-1"\n')
    args = build_parser().parse_args(
        ["bench", "--suite", str(flat), "--out", "x", "--flatten-option", "min_pull=0.03"]
    )
    with pytest.raises(ConfigError, match=r"flatten options \(min_pull\) act on crumpled starts"):
        suite_from_args(args)


def test_a_calibration_sees_every_episode_and_a_resume_keeps_its_pose(tmp_path):
    """`bench --camera-pose`: every episode perceives from the calibration's pose, the camera
    standing where it truly stood; the ids are the suite's own (compare pairs them with a run of
    the exact pose); the pose is read once and kept in suite.json, and summary.md's command
    repeats the option."""
    from calibration_files import write_calibration

    from foldbot.bench.suite import EpisodeSpec

    cal = tmp_path / "calibration.json"
    true, found = write_calibration(cal)
    args = build_parser().parse_args(["bench", "--suite", "smoke", "--out", "x"])
    plain = suite_from_args(args)
    args = build_parser().parse_args(
        ["bench", "--suite", "smoke", "--out", "x", "--camera-pose", str(cal)]
    )
    suite = suite_from_args(args)
    assert [e.id for e in suite.episodes] == [e.id for e in plain.episodes]
    for e in suite.episodes:
        camera = e.to_config().camera
        np.testing.assert_allclose(camera.T_world_camera, true)
        np.testing.assert_allclose(camera.reported_T_world_camera, found)
        assert camera.reported_pose_source.startswith(str(cal))
        again = EpisodeSpec.from_dict(json.loads(json.dumps(e.as_dict())))
        assert again == e and again.to_config() == e.to_config()
    assert "camera" not in plain.episodes[0].as_dict()  # earlier runs resume unchanged
    out = tmp_path / "r"
    assert main(["bench", "--suite", "smoke", "--out", str(out), "--report-only",
                 "--camera-pose", str(cal)]) == 0  # fmt: skip
    command = json.loads((out / "summary.json").read_text())["command"]
    assert command.endswith(f"--camera-pose {cal} --out {out}")


@pytest.mark.parametrize("bad", ["nan", "inf", "-1", "0", "1e9"])
@pytest.mark.parametrize("report_only", [False, True])
def test_a_bad_timeout_is_refused_before_anything_is_written(tmp_path, capsys, bad, report_only):
    out = tmp_path / "b"
    args = ["bench", "--suite", "smoke", "--out", str(out), "--timeout", bad]
    assert main(args + ["--report-only"] * report_only) == 2
    err = capsys.readouterr().err
    assert "--timeout must be a number of seconds in (0, 604800]" in err
    assert f"got {float(bad)!r}" in err and "Traceback" not in err
    assert not out.exists()


@pytest.mark.parametrize(
    ("seeds", "needle"),
    [
        ("", "--seeds must look like '0-9' or '0,3,5', got ''"),
        ("0-99999999999", "--seeds must name at most 10000 seeds, each in [0, 2147483647]"),
    ],
)
@pytest.mark.parametrize("suite", [[], ["--suite", "smoke"]])
def test_bad_seeds_are_refused_before_anything_is_written(tmp_path, capsys, seeds, needle, suite):
    """An empty --seeds was taken for the one-recipe suite's default, 0-9; a huge range ran out
    of memory expanding it."""
    out = tmp_path / "b"
    assert main(["bench", *suite, "--seeds", seeds, "--report-only", "--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert needle in err and "Traceback" not in err
    assert not out.exists()


@pytest.mark.parametrize("empty", ["", " "])
def test_an_empty_out_is_refused(tmp_path, monkeypatch, capsys, empty):
    """`--out ''` was the current folder: the run's files went among whatever was there."""
    monkeypatch.chdir(tmp_path)
    with pytest.raises(SystemExit) as exc:  # argparse's error
        main(["bench", "--suite", "smoke", "--report-only", "--out", empty])
    assert exc.value.code == 2
    err = capsys.readouterr().err
    assert f"argument --out: must name a folder or file, got {empty!r}" in err
    assert list(tmp_path.iterdir()) == []


def test_a_folder_holding_another_run_is_refused(tmp_path, capsys):
    """A run folder is not taken over by another suite's run; the same run still resumes,
    reports and retries its errors (over other seeds too)."""
    out = tmp_path / "r"
    assert main(["bench", "--suite", "smoke", "--report-only", "--out", str(out)]) == 0
    kept = {p.name: p.read_bytes() for p in out.iterdir() if p.is_file()}
    capsys.readouterr()
    args = ["bench", "--recipe", "quarter", "--seeds", "0", "--report-only", "--out", str(out)]
    assert main(args) == 2
    err = capsys.readouterr().err
    assert f"output folder {out} holds another run: its suite.json describes suite 'smoke'" in err
    assert "not 'quarter_vision'" in err and "use another --out" in err
    assert "Traceback" not in err
    assert {p.name: p.read_bytes() for p in out.iterdir() if p.is_file()} == kept
    for again in (["--report-only"], ["--report-only", "--retry-errors", "--seeds", "0-2"]):
        assert main(["bench", "--suite", "smoke", "--out", str(out), *again]) == 0


def test_a_bench_stopped_by_sigterm_stops_its_episodes_and_leaves_none_half_written(tmp_path):
    """`kill` stops a bench at once, as Ctrl-C does: the running episode's process is killed
    rather than waited for, its staging folder removed, no record written (it runs again on
    the next bench); exit 143."""
    import os
    import signal
    import time

    suite_file = tmp_path / "one.toml"
    suite_file.write_text(
        'name = "one"\n[axes]\nrecipe = ["half"]\nperception = ["oracle"]\nseeds = "0"\n'
        "[towel]\nresolution = 17\n[episode]\nvideo_fps = 0\n[reference]\nravens_speed = false\n"
    )
    out = tmp_path / "run"
    proc = subprocess.Popen(
        [sys.executable, "-m", "foldbot.cli", "bench", "--suite", str(suite_file), "--out",
         str(out), "--workers", "1", "--no-reference"],
        stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
    )  # fmt: skip
    deadline = time.monotonic() + 120
    staged: list = []
    while not staged and time.monotonic() < deadline:
        assert proc.poll() is None, proc.communicate()
        staged = (
            list((out / "episodes").glob(".*.partial-*")) if (out / "episodes").is_dir() else []
        )
        time.sleep(0.05)
    assert staged, "the episode never staged its folder"
    worker = int(staged[0].name.rsplit("-", 1)[1])
    started = time.monotonic()
    proc.send_signal(signal.SIGTERM)
    _, err = proc.communicate(timeout=120)
    assert proc.returncode == 128 + signal.SIGTERM, err[-2000:]
    # Not waited for: the episode alone takes ~40 s here (a hang guard, not a speed target).
    assert time.monotonic() - started < 30
    assert "terminated (SIGTERM)" in err
    assert list((out / "episodes").iterdir()) == []
    for _ in range(100):  # the worker is gone (killed, then reaped by bench or by init)
        try:
            os.kill(worker, 0)
        except ProcessLookupError:
            break
        time.sleep(0.1)
    else:
        raise AssertionError(f"the episode process {worker} still runs")
