"""`foldbot bench`: run a benchmark suite of fold episodes and summarise them.

    foldbot bench --suite NAME --out DIR [--seeds S] [--workers N] [--ray ADDRESS]
                  [--loop-option NAME=VALUE] [--cloth NAME=VALUE] [--flatten-option NAME=VALUE]
    foldbot bench --recipe R --seeds 0-19 [--perception P] [--size-range LO HI] --out DIR

A suite (suites/NAME.toml, or a path to one) is the grid garment × recipe × perception × loop ×
seed and states what the seed randomises (`--seeds` runs it over other seeds, each drawn as the
suite draws it); the second form is a one-recipe suite built from the
options, on the towel `foldbot fold` folds (odd vertex counts, 17 along the longer side). Each
episode runs in a fresh process and writes its own folder, DIR/episodes/<id>/; finished episodes
are not run again, so an interrupted run resumes. `--ray auto` (a running
cluster), `--ray ADDRESS` or `--ray local` runs the episodes as Ray tasks instead (pip install
'foldbot[ray]'). DIR/summary.json, DIR/summary.md and DIR/errors.png hold the summary: success
rate, fold error, SoftGym normalized performance, coverage, actions and retries, simulated and
wall seconds, simulation speed, failures by cause, per group and overall, the vision/oracle and
closed/open-loop comparisons, and a plain-PyBullet speed reference at Deformable Ravens' settings.
"""

from __future__ import annotations

import argparse
import dataclasses
import os
import shlex
from pathlib import Path

from foldbot.bench.report import write_report
from foldbot.bench.runner import DEFAULT_TIMEOUT_S, MAX_TIMEOUT_S, check_timeout, run_suite
from foldbot.bench.suite import (
    Suite,
    camera_from_items,
    camera_items,
    load_suite,
    parse_seeds,
    suite_from_dict,
)
from foldbot.bench.summary import summarise
from foldbot.cloth_options import cloth_options_from_args
from foldbot.commands.fold import (
    add_camera_pose_option,
    add_cloth_option,
    add_flatten_option,
    add_loop_option,
)
from foldbot.errors import ConfigError
from foldbot.flatten_options import flatten_options_from_args
from foldbot.io.staging import output_path
from foldbot.loop_options import loop_options_from_args
from foldbot.pipeline import PERCEPTION_MODES
from foldbot.planning.recipes import RECIPE_HELP, RECIPES
from foldbot.sim.layout import DEFAULT_LAYOUT

__all__ = ["add_arguments", "parse_seeds", "run", "suite_from_args"]

_LEGACY = ("recipe", "perception", "seeds", "size_range", "video_fps")


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Options of `foldbot bench`."""
    parser.add_argument(
        "--suite",
        default=None,
        help="suite name (a file in suites/, e.g. smoke, towel_full, towel_compare) or a .toml path",
    )
    parser.add_argument("--out", type=output_path, required=True, help="output folder")
    parser.add_argument(
        "--workers",
        type=int,
        default=max(1, (os.cpu_count() or 1)),
        help="parallel episode processes (default: CPU count)",
    )
    parser.add_argument(
        "--ray",
        default=None,
        metavar="ADDRESS",
        help="run the episodes on Ray: 'auto' (running cluster), 'local', or a cluster address",
    )
    parser.add_argument(
        "--retry-errors",
        action="store_true",
        help="run again the episodes that ended in an error (diverged, unreachable, …)",
    )
    parser.add_argument(
        "--report-only",
        action="store_true",
        help="run nothing: summarise the episodes already finished in DIR (marked incomplete)",
    )
    parser.add_argument(
        "--no-reference", action="store_true", help="skip the Deformable Ravens speed reference"
    )
    parser.add_argument(
        "--timeout",
        type=float,
        default=DEFAULT_TIMEOUT_S,
        help=f"stop an episode after this many wall seconds, at most {MAX_TIMEOUT_S:g} "
        f"(default {DEFAULT_TIMEOUT_S:g})",
    )
    parser.add_argument(
        "--seeds",
        default=None,
        help="seeds to run, e.g. 0-19 or 0,4,7: with --suite, instead of the suite's own (each "
        "drawn as the suite draws it); for a one-recipe suite, default 0-9",
    )
    add_loop_option(parser, "in every episode, over the suite's [loop_options]")
    add_cloth_option(parser, "in every episode, over the suite's [cloth]")
    add_flatten_option(parser, "in every episode, over the suite's [flatten_options]")
    add_camera_pose_option(
        parser,
        "every episode perceives from the camera pose a calibration found, as `foldbot "
        "fold --camera-pose` does (a simulated calibration: the camera where it truly stood, "
        "perception given the pose found); the episodes keep their ids, so `foldbot compare` "
        "pairs them with a run of the exact pose",
    )
    one = parser.add_argument_group("one-recipe suite (instead of --suite)")
    one.add_argument(
        "--recipe",
        default=None,
        choices=RECIPES,
        help="fold recipe (default half): "
        + "; ".join(f"{k}: {v}" for k, v in RECIPE_HELP.items()),
    )
    one.add_argument(
        "--perception",
        default=None,
        choices=PERCEPTION_MODES,
        help="keypoints from the RGB-D image (vision, default) or simulator ground truth (oracle)",
    )
    one.add_argument(
        "--size-range",
        nargs=2,
        type=float,
        metavar=("LO", "HI"),
        default=None,
        help="draw each towel side from [LO, HI] m per seed (default: 0.30 m square)",
    )
    one.add_argument(
        "--video-fps", type=float, default=None, help="video per episode (default 0 = off)"
    )


def suite_from_args(args: argparse.Namespace) -> Suite:
    """The suite named by --suite, or the one-recipe suite the other options describe, with the
    --loop-option, --cloth and --flatten-option settings over its own, seen through the camera
    --camera-pose places."""
    suite = with_options(
        _suite_from_args(args),
        loop_options_from_args(args.loop_option),
        cloth_options_from_args(args.cloth),
        flatten_options_from_args(args.flatten_option),
    )
    path = getattr(args, "camera_calibration", None)
    return suite if path is None else with_camera(suite, path)


def with_camera(suite: Suite, path: Path) -> Suite:
    """The suite's episodes seen through the camera the calibration at `path` places (the file
    read once: a resumed run keeps the pose its episodes were run with). A placed camera does
    not move with a layout, so one placement serves every episode."""
    from foldbot.commands.check_layout import camera_placement

    camera = camera_items(camera_placement(path.resolve(), DEFAULT_LAYOUT))
    camera_from_items(camera)  # a camera the calibration cannot place, refused before any run
    episodes = tuple(dataclasses.replace(e, camera=camera) for e in suite.episodes)
    return dataclasses.replace(suite, episodes=episodes)


def with_options(suite: Suite, loop: dict, cloth: dict, flatten: dict | None = None) -> Suite:
    """The suite with the `loop`, `cloth` and `flatten` options set in every episode, over (and
    beside) the suite's own; every episode's configuration is checked with them (ConfigError
    before any run: e.g. a flatten option in a suite of flat starts)."""
    if not loop and not cloth and not flatten:
        return suite
    episodes = tuple(e.with_options(loop, cloth, flatten or {}) for e in suite.episodes)
    for e in {(e.garment, e.perception): e for e in episodes}.values():
        e.to_config()  # anything EpisodeConfig refuses, refused here before any run
    return dataclasses.replace(suite, episodes=episodes)


def _suite_from_args(args: argparse.Namespace) -> Suite:
    given = [f"--{k.replace('_', '-')}" for k in _LEGACY if getattr(args, k) is not None]
    if args.suite is not None:
        given = [g for g in given if g != "--seeds"]
        if given:
            raise ConfigError(
                f"{', '.join(given)} cannot be combined with --suite; "
                "a suite file states its recipes, perception and ranges (--seeds may replace "
                "its seeds)"
            )
        return load_suite(args.suite, None if args.seeds is None else _seeds(args.seeds))
    recipe = args.recipe or "half"
    perception = args.perception or "vision"
    data: dict = {
        "name": f"{recipe}_{perception}",
        "description": f"{recipe} fold, {perception} perception (built from command-line options)",
        "axes": {
            "garment": ["towel"],
            "recipe": [recipe],
            "perception": [perception],
            "loop": ["closed"],
            "seeds": ",".join(map(str, _seeds("0-9" if args.seeds is None else args.seeds))),
        },
        # The towel `foldbot fold` folds by default: odd vertex counts, 17 along the longer side.
        "towel": {"resolution": 17, "odd_grid": True},
        "episode": {"video_fps": args.video_fps or 0.0},
    }
    if args.size_range is not None:
        data["randomise"] = {"towel_side": list(args.size_range)}
    return suite_from_dict(data)


def _seeds(text: str) -> list[int]:
    """--seeds as seeds (parse_seeds), its ConfigError naming the option."""
    try:
        return parse_seeds(text)
    except ConfigError as exc:
        raise ConfigError(f"--{exc}") from None


def _reference(suite: Suite, summary: dict) -> dict | None:
    """Run the Ravens speed reference for the towel's (mid-range) size and the episodes'
    mean simulated duration, and relate it to foldbot's measured speed."""
    from foldbot.bench.ravens_reference import ravens_speed_reference

    overall = summary["overall"]
    duration, speed = overall["sim_seconds_per_fold"], overall["sim_speed"]
    if not duration or not speed:
        return None
    rnd = suite.randomised
    side = rnd["towel_side_m"]
    w, h = (sum(side) / 2, sum(side) / 2) if side else tuple(rnd["towel_fixed_m"])
    ref = ravens_speed_reference(w, h, min(duration, 120.0))
    ref["foldbot_sim_speed"] = speed
    ref["reference_to_foldbot_speed"] = ref["sim_speed"] / speed if ref["sim_speed"] else None
    ref["foldbot_to_reference_speed"] = speed / ref["sim_speed"] if ref["sim_speed"] else None
    return ref


def run(args: argparse.Namespace) -> int:
    """Run the missing episodes, then summarise all of them."""
    out = args.out
    check_timeout(args.timeout)  # before anything is written (--report-only too)
    suite = suite_from_args(args)
    try:
        import matplotlib  # noqa: F401  (checked before any episode runs: errors.png needs it)
    except ImportError:
        raise ConfigError(
            "foldbot bench needs matplotlib for errors.png; install it with "
            "`pip install -e '.[bench]'` (or `pip install matplotlib`)"
        ) from None
    records = run_suite(
        suite,
        out,
        workers=args.workers,
        ray_address=args.ray,
        retry_errors=args.retry_errors,
        timeout=args.timeout,
        run=not args.report_only,
    )
    summary = summarise(suite, records)
    cmd = ["foldbot", "bench"]
    if args.suite is not None:
        cmd += ["--suite", args.suite]
        if args.seeds is not None:
            cmd += ["--seeds", args.seeds]
    else:
        cmd += ["--recipe", suite.axes["recipe"][0], "--perception", suite.axes["perception"][0]]
        cmd += ["--seeds", "0-9" if args.seeds is None else args.seeds]
        if args.size_range is not None:
            cmd += ["--size-range", *map(str, args.size_range)]
    for option in args.loop_option:
        cmd += ["--loop-option", option]
    for option in args.cloth:
        cmd += ["--cloth", option]
    for option in args.flatten_option:
        cmd += ["--flatten-option", option]
    if getattr(args, "camera_calibration", None) is not None:
        cmd += ["--camera-pose", str(args.camera_calibration)]
    summary["command"] = shlex.join([*cmd, "--out", str(out)])
    if suite.ravens_speed and not args.no_reference:
        summary["ravens_speed_reference"] = _reference(suite, summary)
    labels = {
        s.id: f"{s.recipe}\n{s.perception} {s.loop}"
        + (f"\n{s.garment}" if len(suite.axes["garment"]) > 1 else "")
        for s in suite.episodes
    }
    paths = write_report(summary, records, labels, out)
    _print_overview(summary)
    print(f"summary written to {paths['json']}, {paths['md'].name}, {paths['png'].name}")
    return 0


def _print_overview(s: dict) -> None:
    o = s["overall"]
    e, p = o["fold_error_mm"], o["normalized_performance"]
    print(
        f"\n{s['suite']['name']}: {s['episodes_finished']} of {s['episodes_planned']} episodes, "
        f"success {100 * (o['success_rate'] or 0):.0f} %"
    )
    if e:
        print(
            f"  fold error (mm)         mean {e['mean']:.1f}  median {e['median']:.1f}  "
            f"p95 {e['p95']:.1f}"
        )
        perfect = o.get("perfect_fold_error_mm")
        if perfect and perfect["max"] > 0:
            print(
                f"  perfect fold (mm)       mean {perfect['mean']:.1f}  (what a physically "
                "perfect fold, lying flat, scores under the layer rule)"
            )
        ceiling = o.get("perfect_normalized")
        print(
            f"  normalized performance  mean {p['mean']:.3f}  median {p['median']:.3f}"
            + (f"  (a perfect fold: {ceiling['mean']:.3f}; success asks 0.8)" if ceiling else "")
        )
        tangled = o.get("through_itself")
        if tangled and tangled["folds"]:
            print(
                f"  folded through itself   {tangled['folds']} of {tangled['recorded']} scored "
                f"folds ({tangled['successes']} counted successes): a simulated cloth's tangle"
            )
        print(
            f"  per episode             {o['actions_per_episode']:.1f} actions, "
            f"{o['retries_per_episode']:.2f} retries, {o['sim_seconds_per_fold']:.1f} s simulated, "
            f"{o['wall_seconds_per_episode']:.1f} s wall (sim speed {o['sim_speed']:.2f}× real time)"
        )
        each = o.get("episode_speed")
        if each:
            print(
                f"  speed per episode       {each['min']:.2f}–{each['max']:.2f}× real time, "
                f"{o['episodes_under_real_time']} of {o['scored']} under 1×"
            )
    for g in s["groups"]:
        e = g["fold_error_mm"]
        print(
            f"  {g['recipe']:>9} {g['perception']:>6} {g['loop']:>6}: success "
            f"{100 * (g['success_rate'] or 0):3.0f} %, fold error median "
            f"{'–' if not e else format(e['median'], '.1f')} mm, failures {g['failures'] or 'none'}"
        )
    ref = s.get("ravens_speed_reference")
    if ref:
        print(
            f"  speed reference (plain PyBullet, Ravens settings): {ref['sim_speed']:.2f}× real "
            f"time, {ref['reference_to_foldbot_speed']:.1f}× foldbot's"
        )
