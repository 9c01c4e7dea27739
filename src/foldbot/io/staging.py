"""An output folder written whole or not at all: results staged in a hidden folder beside it
and moved into place once complete (a run that fails leaves no folder that looks finished)."""

from __future__ import annotations

import argparse
import os
import shutil
import tempfile
from pathlib import Path

from foldbot.errors import OutputError


def output_path(text: str) -> Path:
    """An `--out` value as argparse reads it: a path, never the empty string (which Path would
    take for the current folder, writing a run's files among whatever is there)."""
    if not text.strip():
        raise argparse.ArgumentTypeError(f"must name a folder or file, got {text!r}")
    return Path(text)


def prepare_output(out: Path) -> Path:
    """Check `out` can be written; return a fresh staging folder beside it (OutputError if not)."""
    out = Path(out)
    if out.exists() and not out.is_dir():
        raise OutputError(f"--out {out} exists and is not a folder")
    parent = out.parent if str(out.parent) else Path(".")
    try:
        parent.mkdir(parents=True, exist_ok=True)
        stage = Path(tempfile.mkdtemp(prefix=f".{out.name}.tmp-", dir=parent))
    except OSError as exc:
        raise OutputError(f"cannot write to --out {out}: {exc.strerror or exc}") from None
    if out.exists() and not os.access(out, os.W_OK | os.X_OK):
        shutil.rmtree(stage, ignore_errors=True)
        raise OutputError(f"cannot write to --out {out}: permission denied")
    return stage


def commit_output(stage: Path, out: Path) -> None:
    """Move the staged results into `out` (atomic rename when `out` does not exist yet)."""
    if not out.exists():
        os.replace(stage, out)
        return
    for item in stage.iterdir():
        dest = out / item.name
        if dest.is_dir() and not dest.is_symlink():
            shutil.rmtree(dest)
        os.replace(item, dest)
    stage.rmdir()
