"""Per-towel table of a crumpled-start bench run: how each towel's flattening went, where it
diverged, and how its fold scored; the per-seed tables in docs/experiments.md.

Reads DIR/episodes/*/result.json (finished episodes) and DIR/episodes/*.error.json (episodes that
ended in an error: its message names the motion segment a divergence stopped, its log tail the
flattening actions done before; its missed grasps are those among the
tail's 20 lines). One markdown row per episode, by seed:

    .venv/bin/python scripts/flatten_table.py runs/cs2_surface [--compare runs/cs2_comedown]

Coverage figures per action are the perceived ones the robot acted on (before → after each
action; `x` marks an action whose grasps missed; missed grasps count every attempt, retries too); the flattening's verdict uses the ground-truth
coverage after flattening (result.json's flatten.success).
"""

from __future__ import annotations

import argparse
import json
import re
import sys
from pathlib import Path

SEED = re.compile(r"-s(\d{4})(?:\.error\.json)?$")
SEGMENT = re.compile(r"\(in segment ([^,]+), ([\d.]+) s in\)")
ACTION_LINE = re.compile(r"^flatten (\d+): ")


def episode_rows(run: Path) -> dict[int, dict]:
    """{seed: row} for every finished or failed crumpled-start episode under `run`/episodes."""
    episodes = run / "episodes"
    if not episodes.is_dir():
        raise SystemExit(f"{run} holds no episodes/ folder: not a `foldbot bench` output folder")
    rows: dict[int, dict] = {}
    for path in sorted(episodes.iterdir()):
        match = SEED.search(path.name)
        if match is None:
            continue
        seed = int(match.group(1))
        if path.name.endswith(".error.json"):
            rows[seed] = _error_row(json.loads(path.read_text()))
        elif (path / "result.json").is_file():
            rows[seed] = _result_row(json.loads((path / "result.json").read_text()))
    return rows


def _result_row(result: dict) -> dict:
    flat = result.get("flatten") or {}
    actions = flat.get("pulls", [])
    return {
        "outcome": "flattened" if flat.get("success") else "neither",
        "coverage": f"{flat.get('coverage_start', float('nan')):.2f} → "
        f"{flat.get('coverage_end', float('nan')):.2f}",
        "actions": " ".join(_action_cell(a) for a in actions),
        "misses": sum(_missed(attempt) for a in actions for attempt in a.get("attempts", [])),
        "fold": f"{result['fold_error_mm']:.1f} mm" + (" ✓" if result.get("success") else ""),
    }


def _missed(attempt: dict) -> bool:
    """Whether a grasp attempt (one arm's, or a spread's pair) missed."""
    success = attempt.get("grasp_success", True)
    return not all(success if isinstance(success, list) else [success])


def _action_cell(action: dict) -> str:
    missed = "" if action.get("grasp_success", True) else "x"
    return f"{action['coverage_before']:.2f}→{action['coverage_after']:.2f}{missed}"


def _error_row(error: dict) -> dict:
    message = error.get("error", "")
    segment = SEGMENT.search(message)
    tail = error.get("log_tail", [])
    done = [int(m.group(1)) for line in tail if (m := ACTION_LINE.match(line))]
    folding = any(line.startswith("flattened: ") for line in tail)
    flattening = tail[: next((i for i, x in enumerate(tail) if x.startswith("flattened: ")), None)]
    crumpling = "crumpling the towel…" in tail and not any(
        line.startswith("crumpled: ") for line in tail
    )
    if error.get("error_type") == "SimulationDivergedError":
        where = f"in {segment.group(1)}" if segment else "outside a segment"
        stage = "in the fold" if folding else "while crumpling" if crumpling else "while flattening"
        outcome = f"diverged {stage} ({where}) after {max(done, default=0)} actions"
    else:
        outcome = f"{error.get('error_type', 'error')}: {message[:60]}"
    return {
        "outcome": outcome,
        "coverage": "",
        "actions": "",
        "misses": sum(line.startswith("  grasp failed") for line in flattening),
        "fold": "",
    }


def table(rows: dict[int, dict], compare: dict[int, dict] | None = None) -> str:
    """The markdown table of `rows` (and the outcome of the same seed in `compare`)."""
    head = ["seed", "outcome", "coverage (truth)", "perceived per action", "missed grasps", "fold"]
    if compare is not None:
        head.append("compared run")
    lines = ["| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
    for seed in sorted(rows):
        r = rows[seed]
        cells = [str(seed), r["outcome"], r["coverage"], r["actions"], str(r["misses"]), r["fold"]]
        if compare is not None:
            other = compare.get(seed)
            cells.append(other["outcome"] if other else "not run")
        lines.append("| " + " | ".join(cells) + " |")
    outcomes = [r["outcome"] for r in rows.values()]
    diverged = sum(o.startswith("diverged") for o in outcomes)
    lines.append("")
    lines.append(
        f"{len(rows)} episodes: flattened {outcomes.count('flattened')}, diverged {diverged}, "
        f"neither {outcomes.count('neither')}, other errors "
        f"{len(rows) - outcomes.count('flattened') - diverged - outcomes.count('neither')}; "
        f"folds succeeded {sum(r['fold'].endswith('✓') for r in rows.values())}"
    )
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("run", type=Path, help="a `foldbot bench` output folder")
    parser.add_argument("--compare", type=Path, help="another run of the same seeds")
    args = parser.parse_args(argv)
    compare = episode_rows(args.compare) if args.compare else None
    print(table(episode_rows(args.run), compare))
    return 0


if __name__ == "__main__":
    sys.exit(main())
