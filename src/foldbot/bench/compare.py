"""Two benchmark runs side by side, episode by episode: what changed between them, and whether
the change is larger than the towels' own scatter.

Episodes are paired by id (garment, recipe, perception, loop, seed), so each pair is the same
towel folded twice: by two versions of the code, or with two settings (`--loop-option`,
`--flatten-option`, a suite edit). Per group and overall: how many pairs came out the same to the last digit, the success
rates with their Wilson intervals, and the fold error's paired difference (second minus first)
with its Student-t interval (both over the towels where a towel was folded several times:
replicates); then every pair that changed. The simulation is deterministic, so a
pair that differs differs because of the change, or a chaotic amplification of it: a quarter
fold's error moved from 43.6 to 152.7 mm when its stack grasp moved by a tenth of a millimetre
(docs/experiments.md), which is why the interval, not the sign of the mean, decides.
"""

from __future__ import annotations

import json
import math
from collections import defaultdict
from pathlib import Path
from typing import Any

from foldbot.bench.report import _f, _interval, _pct, _through_itself, save_figure
from foldbot.bench.runner import EPISODES, SUITE_FILE
from foldbot.bench.summary import (
    by_towel,
    clustered_success_interval,
    difference_interval,
    failure_cause,
    through_itself,
)
from foldbot.errors import ConfigError
from foldbot.io.episode import RESULT_FILE, is_episode_dir

SPEC_AXES = ("garment", "recipe", "perception", "loop")
"""The spec fields a group is made of (an episode's id adds its seed)."""


_JSON_KINDS = {
    list: "array",
    str: "string",
    int: "number",
    float: "number",
    bool: "boolean",
    type(None): "null",
}
"""What JSON calls the values json.loads returns as these types."""


def _read_object(path: Path, what: str) -> dict:
    """The JSON object in `path`; ConfigError naming the file and what it should hold (`what`)
    when it cannot be read, is not JSON, or holds something other than an object."""
    try:
        text = path.read_text(encoding="utf-8")
    except (OSError, UnicodeDecodeError) as exc:
        raise ConfigError(f"cannot read {path}: {getattr(exc, 'strerror', None) or exc}") from None
    if not text.strip():
        raise ConfigError(f"{path} is empty; it must hold {what}")
    try:
        data = json.loads(text)
    except ValueError as exc:
        raise ConfigError(f"{path} is not valid JSON ({exc}); it must hold {what}") from None
    if not isinstance(data, dict):
        kind = _JSON_KINDS.get(type(data), type(data).__name__)
        raise ConfigError(f"{path} holds a JSON {kind}, not an object; it must hold {what}")
    return data


def _check_result(path: Path, result: dict) -> None:
    """ConfigError naming `path` when a result.json value compare reads has the wrong type."""
    v = result.get("fold_error_mm")
    if v is not None and (isinstance(v, bool) or not isinstance(v, int | float)):
        raise ConfigError(f"{path}: fold_error_mm = {v!r} must be a number (mm) or null")
    v = result.get("self_crossings")
    if v is not None and (isinstance(v, bool) or not isinstance(v, int | float)):
        raise ConfigError(f"{path}: self_crossings = {v!r} must be a number or null")
    actions = result.get("actions", [])
    if not isinstance(actions, list) or not all(isinstance(a, dict) for a in actions):
        raise ConfigError(f"{path}: actions = {actions!r} must be a list of objects")


def load_run(run: Path) -> tuple[dict[str, dict], dict[str, dict]]:
    """A run folder's episode specs (suite.json) and the records of its finished episodes (scored:
    {"id", "result"}; ended by an error: the error record), both by episode id. ConfigError
    naming the file when suite.json, a result.json or an error record is malformed."""
    run = Path(run)
    suite_file = run / SUITE_FILE
    if not suite_file.is_file():
        raise ConfigError(
            f"{run} is not a benchmark run folder: it has no {SUITE_FILE} "
            "(a folder written by `foldbot bench --out`)"
        )
    suite = _read_object(suite_file, 'an object with "episodes": {id: spec object}')
    specs = suite.get("episodes", {})
    if not isinstance(specs, dict):
        raise ConfigError(
            f"{suite_file}: episodes = {specs!r} must be an object of episode id → spec object"
        )
    for eid, spec in specs.items():
        if not isinstance(spec, dict):
            raise ConfigError(f"{suite_file}: episode {eid!r} = {spec!r} must be a spec object")
    records: dict[str, dict] = {}
    for eid in specs:
        ep = run / EPISODES / eid
        err = run / EPISODES / f"{eid}.error.json"
        if is_episode_dir(ep):
            result = _read_object(ep / RESULT_FILE, "an episode's result object")
            _check_result(ep / RESULT_FILE, result)
            records[eid] = {"id": eid, "result": result}
        elif err.is_file():
            record = _read_object(err, 'an error record: {"error_type", "error", ...}')
            for key in ("error_type", "error"):
                if not isinstance(record.get(key, ""), str):
                    raise ConfigError(f"{err}: {key} = {record[key]!r} must be a string")
            records[eid] = record
    return specs, records


def _fold_error(record: dict) -> float | None:
    v = record.get("result", {}).get("fold_error_mm")
    return float(v) if v is not None and math.isfinite(v) else None


def _outcome(record: dict) -> str:
    """'success', or the failure cause."""
    return failure_cause(record) or "success"


def _same(a: dict, b: dict) -> bool:
    """Whether two records of one episode agree to the last digit in what the episode did: its
    outcome, fold error and normalized performance (wall-clock figures always differ)."""
    keys = ("fold_error_mm", "normalized_performance", "success")
    ra, rb = a.get("result", {}), b.get("result", {})
    return _outcome(a) == _outcome(b) and all(ra.get(k) == rb.get(k) for k in keys)


def _group_figures(pairs: list[tuple[str, dict, dict]]) -> dict[str, Any]:
    n = len(pairs)
    sides = [[p[1] for p in pairs], [p[2] for p in pairs]]
    wins = [sum(_outcome(r) == "success" for r in side) for side in sides]
    both = [(a.get("id", eid), _fold_error(a), _fold_error(b)) for eid, a, b in pairs]
    both = [(eid, ea, eb) for eid, ea, eb in both if ea is not None and eb is not None]
    diffs = [eb - ea for _, ea, eb in both]
    return {
        "pairs": n,
        "same": sum(_same(a, b) for _, a, b in pairs),
        "success_rate": [w / n if n else None for w in wins],
        "success_ci95": [
            clustered_success_interval(by_towel(side, lambda r: _outcome(r) == "success"))
            for side in sides
        ],
        "scored_both": len(both),
        "fold_error_mm_mean": [
            sum(e[k] for e in both) / len(both) if both else None for k in (1, 2)
        ],
        "difference_mm": {
            "mean": sum(diffs) / len(diffs) if diffs else None,
            "mean_ci95": difference_interval([(eid, eb - ea) for eid, ea, eb in both]),
            "closer": sum(d < 0 for d in diffs),
            "further": sum(d > 0 for d in diffs),
        },
        "diverged": [sum(_outcome(r) == "diverged" for r in side) for side in sides],
        "through_itself": [
            through_itself([r["result"] for r in side if "result" in r]) for side in sides
        ],
    }


PAIRINGS = ("id", "seed")
"""How episodes pair: by id (garment, recipe, perception, loop, seed, replicate), or by seed (and
replicate) within garment, perception and loop (two recipes on the same towels: quarter against
quarter_y)."""


def _keyed(run: Path, specs: dict[str, dict], pair_by: str) -> dict[Any, str]:
    """Episode id by pairing key; with pair_by 'seed', one recipe per garment, perception and loop."""
    if pair_by == "id":
        return {eid: eid for eid in specs}
    keyed: dict[Any, str] = {}
    for eid, spec in specs.items():
        key = (
            spec.get("garment"),
            spec.get("perception"),
            spec.get("loop"),
            spec.get("seed"),
            spec.get("replicate", 0),
        )
        if key in keyed:
            raise ConfigError(
                f"--pair-by seed needs one recipe per garment, perception and loop in each run; "
                f"{run} has {keyed[key]} and {eid}"
            )
        keyed[key] = eid
    return keyed


def compare_runs(first: Path, second: Path, pair_by: str = "id") -> dict[str, Any]:
    """The comparison of two run folders (see the module docstring) as a dict; episodes paired
    by `pair_by` (PAIRINGS)."""
    if pair_by not in PAIRINGS:
        raise ConfigError(f"pair_by = {pair_by!r} is unknown; allowed: {', '.join(PAIRINGS)}")
    specs_a, rec_a = load_run(first)
    specs_b, rec_b = load_run(second)
    keyed_a, keyed_b = _keyed(first, specs_a, pair_by), _keyed(second, specs_b, pair_by)
    common = [
        (keyed_a[k], keyed_b[k])
        for k in keyed_a
        if k in keyed_b and keyed_a[k] in rec_a and keyed_b[k] in rec_b
    ]
    if not common:
        raise ConfigError(
            f"{first} and {second} share no finished episode (episodes pair by {pair_by}, e.g. "
            "towel-half-vision-closed-s0003); compare runs of the same suite's towels"
        )
    differing_settings = sorted(
        {
            key
            for ia, ib in common
            for key in set(specs_a[ia]) | set(specs_b[ib])
            if specs_a[ia].get(key) != specs_b[ib].get(key)
        }
    )
    groups: dict[tuple, list[tuple[str, dict, dict]]] = defaultdict(list)
    for ia, ib in common:
        key = tuple(
            specs_a[ia].get(k)
            if specs_a[ia].get(k) == specs_b[ib].get(k)
            else f"{specs_a[ia].get(k)} / {specs_b[ib].get(k)}"
            for k in SPEC_AXES
        )
        groups[key].append((ia if ia == ib else f"{ia} / {ib}", rec_a[ia], rec_b[ib]))
    every = [p for key in groups for p in groups[key]]
    pairs = [
        {
            "id": eid,
            "group": " ".join(str(v) for v in key),
            "fold_error_mm": [_fold_error(a), _fold_error(b)],
            "outcome": [_outcome(a), _outcome(b)],
            "same": _same(a, b),
        }
        for key, group in groups.items()
        for eid, a, b in group
    ]
    paired_a, paired_b = {ia for ia, _ in common}, {ib for _, ib in common}
    return {
        "runs": [str(first), str(second)],
        "pair_by": pair_by,
        "only_in_one": sorted((set(rec_a) - paired_a) | (set(rec_b) - paired_b)),
        "differing_settings": differing_settings,
        "overall": _group_figures(every),
        "groups": [
            {**dict(zip(SPEC_AXES, key, strict=True)), **_group_figures(pairs)}
            for key, pairs in groups.items()
        ],
        "changed": [
            {k: p[k] for k in ("id", "fold_error_mm", "outcome")} for p in pairs if not p["same"]
        ],
        "pairs": pairs,
    }


def _rate(rate: float | None, ci: list[float] | None) -> str:
    """A success rate with its interval, as the bench summary writes it: '55 % (34–74)'."""
    return _pct(rate) + ("" if rate is None or not ci else f" ({_interval(ci, '.0f', 100)})")


def _difference(d: dict) -> str:
    if d["mean"] is None:
        return "–"
    ci = d["mean_ci95"]
    shown = f"{d['mean']:+.1f}"
    return shown + ("" if not ci else f" ({ci[0]:+.1f} to {ci[1]:+.1f})")


def markdown(comparison: dict) -> str:
    """The comparison as Markdown: a table per group and overall, then the changed pairs."""
    first, second = comparison["runs"]
    lines = [f"# `{second}` against `{first}`", ""]
    if comparison.get("pair_by") == "seed":
        lines += ["Episodes paired by seed within garment, perception and loop.", ""]
    if comparison["differing_settings"]:
        lines += [
            "Episode settings that differ between the runs: "
            + ", ".join(f"`{k}`" for k in comparison["differing_settings"])
            + ".",
            "",
        ]
    if comparison["only_in_one"]:
        lines += [f"Finished in one run only (left out): {len(comparison['only_in_one'])}.", ""]
    lines += [
        "| group | pairs | the same | success: first / second (95 % CI) "
        "| fold error mm, mean over pairs scored both ways: first / second "
        "| second minus first: mean (95 % CI) | closer / further | diverged: first / second "
        "| folded through itself: first / second |",
        "|---|---|---|---|---|---|---|---|---|",
    ]
    rows = [("**all**", comparison["overall"])] + [
        (" ".join(str(g[k]) for k in SPEC_AXES), g) for g in comparison["groups"]
    ]
    for name, g in rows:
        rates = " / ".join(
            _rate(r, ci) for r, ci in zip(g["success_rate"], g["success_ci95"], strict=True)
        )
        means = " / ".join(_f(v) for v in g["fold_error_mm_mean"])
        d = g["difference_mm"]
        lines.append(
            f"| {name} | {g['pairs']} | {g['same']} | {rates} | {means} ({g['scored_both']}) "
            f"| {_difference(d)} | {d['closer']} / {d['further']} "
            f"| {g['diverged'][0]} / {g['diverged'][1]} "
            f"| {' / '.join(_through_itself(t) for t in g['through_itself'])} |"
        )
    lines += [
        "",
        "*the same*: pairs whose records agree to the last digit. An interval clear of 0 is a "
        "difference these towels show; one across 0 is not. *folded through itself*: scored "
        "folds whose cloth ended with mesh edges through its own triangles (result.json's "
        "`self_crossings`, ground truth), of those that recorded it, with the successes among them in "
        "brackets; – where none did.",
    ]
    if comparison["changed"]:
        lines += ["", "## Pairs that changed", "", "| episode | fold error mm | outcome |"]
        lines += ["|---|---|---|"]
        for c in comparison["changed"]:
            (ea, eb), (oa, ob) = c["fold_error_mm"], c["outcome"]
            lines.append(f"| {c['id']} | {_f(ea)} → {_f(eb)} | {oa} → {ob} |")
    return "\n".join(lines) + "\n"


def plot_pairs(comparison: dict, path: Path) -> None:
    """Each pair's fold error, second run against first, one colour per group, log scales, the
    line of no change dashed; a pair that one run did not score (diverged, or an error) sits on
    that run's 'not scored' edge. Written atomically as PNG."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    pairs = comparison["pairs"]
    scored = [v for p in pairs for v in p["fold_error_mm"] if v is not None and v > 0]
    lo = min(scored, default=1.0) / 1.3
    hi = max(scored, default=10.0) * 1.3
    edge = hi * 1.6  # where a pair not scored by one run is drawn
    fig, ax = plt.subplots(figsize=(5.5, 5.5), dpi=100)
    for i, group in enumerate(dict.fromkeys(p["group"] for p in pairs)):
        mine = [p for p in pairs if p["group"] == group]
        xy = [[edge if v is None else max(v, lo) for v in p["fold_error_mm"]] for p in mine]
        x, y = [v[0] for v in xy], [v[1] for v in xy]
        ax.scatter(x, y, s=18, alpha=0.75, color=f"C{i % 10}", label=f"{group} ({len(mine)})")
    ax.plot([lo, hi], [lo, hi], ls="--", lw=1, color="gray")
    ax.set_xscale("log")
    ax.set_yscale("log")
    ax.minorticks_off()
    ticks = [v for v in (1, 2, 5, 10, 20, 50, 100, 200, 500, 1000, 2000) if lo <= v <= hi]
    labels = [f"{v:g}" for v in ticks] + ["not\nscored"]
    ax.set_xticks([*ticks, edge], labels, fontsize=8)
    ax.set_yticks([*ticks, edge], labels, fontsize=8)
    ax.set_xlim(lo, edge * 1.3)
    ax.set_ylim(lo, edge * 1.3)
    ax.axvline(hi * 1.25, lw=0.5, color="lightgray")
    ax.axhline(hi * 1.25, lw=0.5, color="lightgray")
    first, second = comparison["runs"]
    ax.set_xlabel(f"fold error (mm), first: {first}", fontsize=8)
    ax.set_ylabel(f"fold error (mm), second: {second}", fontsize=8)
    d = comparison["overall"]["difference_mm"]
    ci = d["mean_ci95"]
    shown = "–" if d["mean"] is None else f"{d['mean']:+.1f} mm"
    shown += "" if not ci else f" (95 % CI {ci[0]:+.1f} to {ci[1]:+.1f})"
    ax.set_title(
        f"{len(pairs)} pairs: second minus first {shown}\n"
        f"{d['closer']} closer, {d['further']} further (below the dashed line: closer)",
        fontsize=9,
    )
    ax.legend(fontsize=7, loc="lower right")
    fig.tight_layout()
    save_figure(fig, path)
