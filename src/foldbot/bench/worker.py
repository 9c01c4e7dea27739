"""Run ONE benchmark episode in this (fresh) process: `python -m foldbot.bench.worker SPEC OUT REC`.

Bullet's soft-body solver keeps process-global random state that its API cannot reset, so an
episode is reproducible only as the first simulation in its process. The runner therefore starts
this module once per episode, locally and on Ray nodes alike. SPEC is a JSON EpisodeSpec, OUT the
episode folder to write (atomically, by the pipeline's EpisodeWriter) and REC where the record
(the result, or the error that ended the episode) is written as JSON.
"""

from __future__ import annotations

import json
import os
import sys
import traceback
from pathlib import Path

from foldbot.bench.suite import EpisodeSpec
from foldbot.errors import FoldbotError
from foldbot.io.episode import failed_dir, is_failed_dir, to_jsonable


def write_json_atomic(path: Path, data: object) -> None:
    """Write JSON to `path` through a temporary sibling and a rename: complete or absent."""
    tmp = path.with_name(f".{path.name}.tmp-{os.getpid()}")
    tmp.write_text(json.dumps(data, indent=2, allow_nan=False))
    os.replace(tmp, path)


LOG_TAIL = 20
"""Progress lines of an episode that ended in an error kept in its record: they say in which
phase (settling, crumpling, which flattening pull, which stage and action) it ended."""


def run_spec(spec: EpisodeSpec, out: Path) -> dict:
    """Run the episode; a deliberate foldbot error becomes an error record, not an exception."""
    from foldbot.pipeline import run_episode

    lines: list[str] = []
    try:
        result = run_episode(
            spec.to_config(),
            out,
            overwrite=True,
            log=lambda *a: lines.append(" ".join(map(str, a))),
        )
    except FoldbotError as exc:
        record = {
            "id": spec.id,
            "error_type": type(exc).__name__,
            "error": str(exc),
            "log_tail": lines[-LOG_TAIL:],
        }
        if exc.facts:  # what the episode had measured before the error (its flattening …)
            record["facts"] = to_jsonable(exc.facts)
        if is_failed_dir(failed_dir(out)):  # the video and pictures up to the error
            record["failed_dir"] = failed_dir(out).name
        return record
    result.pop("out_dir", None)
    return {"id": spec.id, "result": result}


def main(argv: list[str]) -> int:
    """Entry point of the per-episode process."""
    if len(argv) != 3:
        print(
            "usage: python -m foldbot.bench.worker SPEC_JSON OUT_DIR RECORD_JSON", file=sys.stderr
        )
        return 2
    spec = EpisodeSpec.from_dict(json.loads(argv[0]))
    record_path = Path(argv[2])
    try:
        record = run_spec(spec, Path(argv[1]))
    except Exception as exc:  # a bug, not a deliberate error: keep the traceback for the report
        record = {
            "id": spec.id,
            "error_type": type(exc).__name__,
            "error": f"{exc}\n{traceback.format_exc(limit=5)}",
        }
    write_json_atomic(record_path, record)
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
