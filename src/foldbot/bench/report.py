"""Write a run's summary: summary.json, summary.md (Markdown tables) and errors.png (the fold-error
distributions per group), each through a temporary file and a rename: complete or absent."""

from __future__ import annotations

import contextlib
import json
import os
from pathlib import Path
from typing import Any

from foldbot.bench.summary import CAUSES, FIRST_FRAME_OFF_MM
from foldbot.errors import OutputError
from foldbot.flatten_options import shown_flatten_value
from foldbot.io.episode import to_jsonable
from foldbot.loop_options import shown_value


def _atomic_write(path: Path, data: bytes) -> None:
    """Write `path` through a temporary file and a rename (complete or absent); OutputError
    naming it when it cannot be written, with no temporary file left behind."""
    tmp = path.with_name(f".{path.name}.tmp-{os.getpid()}")
    try:
        tmp.write_bytes(data)
        os.replace(tmp, path)
    except OSError as exc:
        raise OutputError(f"cannot write {path}: {exc.strerror or exc}") from None
    finally:
        with contextlib.suppress(OSError):
            tmp.unlink(missing_ok=True)


def save_figure(fig: Any, path: Path) -> None:
    """Write a matplotlib figure as PNG through a temporary file and a rename (complete or
    absent), and close it; OutputError naming `path` when it cannot be written (a folder there,
    a read-only place), with no temporary file left behind."""
    import matplotlib.pyplot as plt

    tmp = path.with_name(f".{path.name}.tmp-{os.getpid()}.png")
    try:
        fig.savefig(tmp)
        if path.is_dir():  # os.replace would say only "Is a directory"
            raise OutputError(f"cannot write {path}: it is a folder; name a .png file")
        os.replace(tmp, path)
    except OSError as exc:
        raise OutputError(f"cannot write {path}: {exc.strerror or exc}") from None
    finally:
        plt.close(fig)
        with contextlib.suppress(OSError):
            tmp.unlink(missing_ok=True)


def _f(v: Any, fmt: str = ".1f", none: str = "–") -> str:
    return none if v is None else format(v, fmt)


def _pct(v: float | None) -> str:
    return "–" if v is None else f"{100 * v:.0f} %"


def _stat(s: dict | None, fmt: str = ".1f", keys: tuple[str, ...] = ("mean", "median", "p95")):
    return "–" if not s else " / ".join(format(s[k], fmt) for k in keys)


def _interval(ci: list[float] | None, fmt: str = ".1f", scale: float = 1.0) -> str:
    """A 95 % interval as 'lo–hi' (scaled: 100 for percentages), or – where there is none."""
    if not ci:
        return "–"
    return f"{format(scale * ci[0], fmt)}–{format(scale * ci[1], fmt)}"


def _tangled(f: dict) -> str:
    """The flattening row's tangled counts: 'a / b of n (c of u)', or '–' where not recorded."""
    if f.get("tangled_end") is None:
        return "–"
    return (
        f"{f['tangled_start']} / {f['tangled_end']} of {f['recorded']} "
        f"({f['unflattened_tangled']} of {f['unflattened']})"
    )


def _perfect(g: dict) -> str:
    """The perfect fold's error and normalized performance, means: '3.5 / 0.872'; – for a
    figure the results predate."""
    mm = (g.get("perfect_fold_error_mm") or {}).get("mean")
    normalized = (g.get("perfect_normalized") or {}).get("mean")
    return f"{_f(mm)} / {_f(normalized, '.3f')}"


def _through_itself(t: dict | None) -> str:
    """Scored folds through themselves: '4 of 39 (3)', or – where not recorded."""
    if not t:
        return "–"
    return f"{t['folds']} of {t['recorded']} ({t['successes']})"


def _rate(g: dict) -> str:
    """A success rate with its 95 % interval: '55 % (34–74)'."""
    ci = g.get("success_ci95")
    return _pct(g["success_rate"]) + ("" if not ci else f" ({_interval(ci, '.0f', 100)})")


def _difference(d: dict | None) -> str:
    """A paired difference as '+4.2 (-1.0 to +9.4), 6', or – where no pair was scored both ways."""
    if not d:
        return "–"
    ci = d.get("mean_ci95")
    shown = "no interval" if not ci else f"{ci[0]:+.1f} to {ci[1]:+.1f}"
    return f"{d['mean']:+.1f} ({shown}), {d['pairs']}"


def _speed(g: dict) -> str:
    """The run's simulation speed with its episodes' spread: '1.21× (0.89–1.78; 7 under 1×)'."""
    speed = f"{_f(g.get('sim_speed'), '.2f')}×"
    each = g.get("episode_speed")
    if not each or g.get("episodes_under_real_time") is None:
        return speed
    return (
        f"{speed} ({each['min']:.2f}–{each['max']:.2f}; {g['episodes_under_real_time']} under 1×)"
    )


def _iou_range(s: dict | None) -> str:
    if not s:
        return "–"
    return f"{s['median']:.2f} ({s['min']:.2f}–{s['max']:.2f})"


def _failures(f: dict[str, int]) -> str:
    return ", ".join(f"{c} {n}" for c, n in f.items()) or "none"


def _group_name(g: dict) -> str:
    return f"{g['garment']} {g['recipe']}, {g['perception']}, {g['loop']} loop"


def markdown(summary: dict) -> str:
    """The summary as Markdown: overall and per-group tables, comparisons, failures, speed."""
    s = summary["suite"]
    lines = [f"# Benchmark `{s['name']}`", ""]
    if s.get("description"):
        lines += [s["description"], ""]
    done, planned = summary["episodes_finished"], summary["episodes_planned"]
    state = "complete" if summary["complete"] else "INCOMPLETE"
    lines += [
        f"Episodes: {done} of {planned} ({state}). Randomised per seed: {s['randomised']['text']}.",
        "",
    ]
    if s.get("robot"):
        lines += [f"Arm: {s['robot']} (`[episode] robot`; the default is the ur5).", ""]
    options = s.get("loop_options")
    if options:
        shown = ", ".join(f"{k} = {shown_value(v)}" for k, v in options.items())
        lines += [f"Loop options set: {shown} (the others at LoopConfig's defaults).", ""]
    cloth = s.get("cloth_options")
    if cloth:
        shown = ", ".join(f"{k} = {v:g}" for k, v in cloth.items())
        lines += [f"Cloth set: {shown} (the others at ClothConfig's defaults).", ""]
    flatten = s.get("flatten_options")
    if flatten:
        shown = ", ".join(f"{k} = {shown_flatten_value(v)}" for k, v in flatten.items())
        lines += [
            f"Flattening set: {shown} (the others at FlattenConfig's and SpreadConfig's defaults).",
            "",
        ]
    if summary.get("command"):
        lines += ["```bash", summary["command"], "```", ""]
    header = (
        "| group | episodes | success (95 % CI) | fold error mm: mean / median / p95 "
        "| fold error mm: mean's 95 % CI | perfect fold: mm / normalized, mean | normalized perf.: mean / median / p95 "
        "| folded through itself (successes) | coverage: mean | actions / retries per episode "
        "| sim s per fold | wall s per episode | sim speed (per episode; under real time) "
        "| failures by cause |"
    )
    lines += [header, "|" + "---|" * 14]
    rows = [("**all**", summary["overall"])] + [(_group_name(g), g) for g in summary["groups"]]
    for name, g in rows:
        lines.append(
            f"| {name} | {g['episodes']} | {_rate(g)} "
            f"| {_stat(g['fold_error_mm'])} | {_interval((g['fold_error_mm'] or {}).get('mean_ci95'))} "
            f"| {_perfect(g)} "
            f"| {_stat(g['normalized_performance'], '.3f')} "
            f"| {_through_itself(g.get('through_itself'))} "
            f"| {_f((g['coverage'] or {}).get('mean'), '.2f')} "
            f"| {_f(g['actions_per_episode'])} / {_f(g['retries_per_episode'], '.2f')} "
            f"| {_f(g['sim_seconds_per_fold'])} | {_f(g['wall_seconds_per_episode'])} "
            f"| {_speed(g)} | {_failures(g['failures'])} |"
        )
    lines += [
        "",
        "*perfect fold*: the fold error a physically perfect fold scores (every vertex on its goal "
        "in the table plane, lying flat on the cloth beneath it) under metrics.md's layer rule, "
        "which lifts a fold above every earlier layer even where none lies beneath "
        "(`foldbot.metrics.perfect_fold_error_mm`); and the normalized performance of a fold "
        "that lands every vertex on its goal, the most the mesh and the simulated cloth's "
        "thickness allow (SoftGym pairs a vertex with the nearest where the mesh has no mirror "
        "partner; `foldbot.metrics.perfect_normalized`). Success asks 0.8.",
        "",
        "*folded through itself*: the scored folds whose cloth ended with mesh edges through its "
        "own triangles (`foldbot.metrics.self_crossings`, ground truth), which no real cloth "
        "can do; in brackets, how many of them metrics.md's rule counts as successes all the "
        "same. — where the results predate the count.",
        "",
        "*95 % CI*: the success rate's Wilson score interval, and the Student-t interval of the "
        "mean fold error over the scored episodes: where a mean over many more towels may lie. "
        "Where a towel was folded more than once (replicates), every mean's interval is over "
        "the towels' means and the success rate's is Wilson's at the effective number of "
        "episodes (`foldbot.bench.summary.clustered_success_interval`): replicates of one towel "
        "are not independent draws.",
    ]
    if summary["comparisons"]:
        lines += [
            "",
            "## Comparisons (paired episodes: same garment, recipe, seed and other axis)",
            "",
            "| compared | recipe | other axis | paired episodes | success | fold error mm: median "
            "| fold error mm, second minus first: mean (95 % CI), pairs scored both ways "
            "| normalized perf.: mean | retries per episode |",
            "|---|---|---|---|---|---|---|---|---|",
        ]
        for c in summary["comparisons"]:
            other = "loop" if c["axis"] == "perception" else "perception"
            pair = f"{c['a']} / {c['b']}"

            def two(v: list, fmt: str = ".1f") -> str:
                return " / ".join(_f(x, fmt) for x in v)

            lines.append(
                f"| {pair} | {c['recipe']} | {other} {c[other]} | {c['paired_episodes']} "
                f"| {' / '.join(_pct(x) for x in c['success_rate'])} "
                f"| {two(c['fold_error_mm_median'])} | {_difference(c.get('fold_error_mm_paired_difference'))} "
                f"| {two(c['normalized_performance_mean'], '.3f')} "
                f"| {two(c['retries_per_episode'], '.2f')} |"
            )
    flat_rows = [(n, g["flatten"]) for n, g in rows if g.get("flatten")]
    if flat_rows:
        lines += [
            "",
            "## Flattening (crumpled starts; success = coverage ≥ 0.9 within the action budget)",
            "",
            "| group | episodes | flattened (95 % CI) | actions: mean / median / p95 "
            "| coverage before: mean | coverage after: mean / median / p95 "
            "| coverage after: mean's 95 % CI | cloth passed through itself: crumpled / "
            "flattened (unflattened) |",
            "|---|---|---|---|---|---|---|---|",
        ]
        for name, f in flat_rows:
            end = f["coverage_end"] or {}
            lines.append(
                f"| {name} | {f['episodes']} | {_rate(f)} "
                f"| {_stat(f['actions'])} | {_f((f['coverage_start'] or {}).get('mean'), '.2f')} "
                f"| {_stat(f['coverage_end'], '.2f')} | {_interval(end.get('mean_ci95'), '.2f')} "
                f"| {_tangled(f)} |"
            )
        lines += [
            "",
            "*cloth passed through itself*: of the finished flattenings, how many cloths had mesh "
            "edges through their own triangles (`foldbot.metrics.self_crossings`, ground truth) "
            "once crumpled, and once flattened; in brackets, how many of the towels left "
            "unflattened had. A real cloth cannot pass through itself; a simulated one that has "
            "is tangled, and no flattening lays it flat.",
        ]
        for name, f in flat_rows:
            if not f.get("errors_recorded"):
                continue
            lines += [
                "",
                f"{name}: of the {f['errors']} episodes that ended in an error, "
                f"{f['errors_tangled_start']} of the {f['errors_recorded']} whose record kept "
                "the crumple had passed through themselves once crumpled"
                + (
                    f"; {f['errors_after_flattening']} had been flattened before the error, "
                    "in the fold"
                    if f["errors_after_flattening"]
                    else ""
                )
                + ".",
            ]
    seen_rows = [(n, g["first_frame_keypoints"]) for n, g in rows if g.get("first_frame_keypoints")]
    if seen_rows:
        lines += [
            "",
            "## Perception in the first frame (the keypoints the fold was planned from)",
            "",
            "| group | episodes | keypoint error mm: median / p95 / max "
            f"| episodes with a keypoint off by > {FIRST_FRAME_OFF_MM:.0f} mm "
            "| worst keypoint: mean / max mm |",
            "|---|---|---|---|---|",
        ]
        for name, f in seen_rows:
            w = f["worst"]
            lines.append(
                f"| {name} | {f['episodes']} | {_stat(f['error_mm'], keys=('median', 'p95', 'max'))} "
                f"| {f['episodes_off']} | {w['name']}: {_f(w['mean_mm'])} / {_f(w['max_mm'])} |"
            )
        lines += [
            "",
            "Measured against the simulator's keypoints of the flat start (ground truth, for "
            "the benchmark only), in the cell's own frame with the arm where it waits: what "
            "`eval-perception`'s scenes do not show.",
        ]
    verdict_rows = [(n, g["verdict"]) for n, g in rows if g.get("verdict")]
    if verdict_rows:
        lines += [
            "",
            "## The loop's own verdict against ground truth",
            "",
            "| group | folds judged | verified: succeeded / failed "
            "| not verified: succeeded / failed | agrees with success "
            "| lowest stage IoU, median (min–max): successes / failures |",
            "|---|---|---|---|---|---|",
        ]
        for name, v in verdict_rows:
            lines.append(
                f"| {name} | {v['judged']} | {v['verified_succeeded']} / {v['verified_failed']} "
                f"| {v['unverified_succeeded']} / {v['unverified_failed']} "
                f"| {_pct(v['agreement'])} "
                f"| {_iou_range(v['lowest_iou_successes'])} / "
                f"{_iou_range(v['lowest_iou_failures'])} |"
            )
        lines += [
            "",
            "A closed-loop fold is *verified* when every stage's perceived mask matched the "
            "outline its plan predicted (IoU ≥ the loop's `verify_iou`, 0.8): the only verdict a "
            "cell without ground truth has (`foldbot ros-fold --cell real` records it as "
            "`perceived`). Success is metrics.md's, from the simulator's vertices. A verified "
            "failure is one a real cell would report as done.",
        ]
    rep_rows = [(n, g["replicates"]) for n, g in rows if g.get("replicates")]
    if rep_rows:
        lines += [
            "",
            "## Replicates (each towel folded several times, laid 0.1 mm apart)",
            "",
            "| group | towels × folds | towels succeeding every time / some times / never "
            "| fold error SD mm: within a towel / of the towels' means |",
            "|---|---|---|---|",
        ]
        for name, r in rep_rows:
            some = r["towels"] - r["towels_always_succeeding"] - r["towels_never_succeeding"]
            lines.append(
                f"| {name} | {r['towels']} × {r['folds_per_towel']} "
                f"| {r['towels_always_succeeding']} / {some} / {r['towels_never_succeeding']} "
                f"| {_f(r['fold_error_mm_sd_within_towel'])} / "
                f"{_f(r['fold_error_mm_sd_of_towel_means'])} |"
            )
        lines += [
            "",
            "A spread within a towel as large as between towels says the fold's outcome is "
            "chaotic: one fold of a towel tells little of what that towel folds to, and a change "
            "needs replicates (or many more towels) before a difference can be seen.",
        ]
    failed = summary["overall"]["failed_episodes"]
    if failed:
        evidence = summary["overall"].get("failed_evidence", {})

        def link(i: str) -> str:
            return f"[{i}]({evidence[i]})" if i in evidence else i

        lines += ["", "## Failures by cause", "", "| cause | episodes | ids |", "|---|---|---|"]
        for cause, ids in failed.items():
            shown = ", ".join(link(i) for i in ids)
            lines.append(f"| {cause} | {len(ids)} | {shown} |")
        lines += [
            "",
            "Causes: " + ", ".join(CAUSES) + ". Each id links to the episode's folder, or for "
            "one that ended in an error to what it recorded up to it (`<id>.failed/`: video, "
            "pictures) or its error record.",
        ]
    ref = summary.get("ravens_speed_reference")
    if ref:
        lines += [
            "",
            "## Speed reference",
            "",
            f"{ref['what']}, {ref['cloth_m'][0]:.2f} × {ref['cloth_m'][1]:.2f} m, "
            f"{ref['sim_seconds']:.1f} s simulated: {_f(ref['sim_speed'], '.2f')}× real time. "
            f"foldbot in this run: {_f(summary['overall']['sim_speed'], '.2f')}× real time. "
            f"Ratio reference / foldbot: {_f(ref.get('reference_to_foldbot_speed'), '.2f')}.",
        ]
    lines += ["", "## The field's reference figures (shared/notes/metrics.md)", ""]
    lines += ["| system | case | figure |", "|---|---|---|"]
    lines += [
        f"| {r['system']} | {r['case']} | {r['figure']} |" for r in summary["reference_figures"]
    ]
    return "\n".join(lines) + "\n"


def plot_errors(summary: dict, records_by_group: dict[str, list[float]], path: Path) -> None:
    """Box plots (with every episode as a dot) of fold error per group, log scale, with the
    FabricFlowNet one- and multi-step figures as dashed lines; written atomically as PNG."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    import numpy as np
    from matplotlib.ticker import FuncFormatter

    names = [n for n, v in records_by_group.items() if v]
    fig, ax = plt.subplots(figsize=(max(6.0, 1.1 * len(names) + 2), 4.5), dpi=100)
    if names:
        data = [records_by_group[n] for n in names]
        ax.boxplot(data, showfliers=False, widths=0.5)
        rng = np.random.default_rng(0)
        for i, d in enumerate(data, start=1):
            ax.scatter(i + rng.uniform(-0.15, 0.15, len(d)), d, s=10, alpha=0.6, color="tab:blue")
        ax.set_xticks(range(1, len(names) + 1), names, rotation=30, ha="right", fontsize=8)
        ax.set_yscale("log")
        ax.yaxis.set_major_formatter(FuncFormatter(lambda v, _pos: f"{v:g}"))
        ax.yaxis.set_minor_formatter(FuncFormatter(lambda v, _pos: ""))
    for y, label in ((4.26, "FabricFlowNet one-step 4.26 mm"), (23.74, "multi-step 23.74 mm")):
        ax.axhline(y, ls="--", lw=1, color="gray")
        ax.text(0.55, y * 1.05, label, fontsize=7, color="gray")
    ax.set_ylabel("fold error (mm, mean particle distance to goal)")
    s = summary["suite"]
    ax.set_title(
        f"{s['name']}: fold error per group ({summary['episodes_finished']} episodes)", fontsize=10
    )
    fig.tight_layout()
    save_figure(fig, path)


def write_report(summary: dict, records: list[dict], groups_of: dict[str, str], out: Path) -> dict:
    """Write summary.json, summary.md and errors.png into `out`; return their paths."""
    errors: dict[str, list[float]] = {}
    for name in dict.fromkeys(groups_of.values()):
        errors[name] = []
    for rec in records:
        r = rec.get("result")
        if r is not None and r.get("fold_error_mm") is not None and rec["id"] in groups_of:
            errors[groups_of[rec["id"]]].append(float(r["fold_error_mm"]))
    paths = {"json": out / "summary.json", "md": out / "summary.md", "png": out / "errors.png"}
    plot_errors(summary, errors, paths["png"])
    _atomic_write(paths["md"], markdown(summary).encode())
    text = json.dumps(to_jsonable(summary), indent=2, allow_nan=False)
    _atomic_write(paths["json"], text.encode())
    return paths
