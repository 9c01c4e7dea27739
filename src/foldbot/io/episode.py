"""Episode folders (notes/metrics.md contract): result.json, cloth.npz, video.mp4, overlays.

`EpisodeWriter` stages everything in a hidden sibling folder and renames it into place on
`commit()`, so a folder named DIR is either a complete episode or absent, never half-written.
An episode that ends in an error leaves what it had recorded (video up to the error, pictures)
in the sibling `DIR.failed/`, with error.json saying why: evidence, never an episode.
`rescore(DIR)` recomputes every metric from cloth.npz and result.json["fold_lines"] alone.
"""

from __future__ import annotations

import contextlib
import dataclasses
import json
import math
import os
import shutil
import weakref
import zlib
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from types import TracebackType
from typing import Any
from zipfile import BadZipFile

import numpy as np

from foldbot.errors import ConfigError, OutputError
from foldbot.io.video import VideoWriter
from foldbot.metrics import FoldLine, FoldScore, as_fold_lines, score_episode

RESULT_FILE = "result.json"
CLOTH_FILE = "cloth.npz"
VIDEO_FILE = "video.mp4"
ERROR_FILE = "error.json"
FAILED_SUFFIX = ".failed"
CLOTH_KEYS = ("faces", "initial", "final", "thickness")
REQUIRED_RESULT_KEYS: tuple[str, ...] = (
    "success",
    "fold_error_mm",
    "normalized_performance",
    "coverage",
    "fold_lines",
    "garment",
    "recipe",
    "seed",
    "actions",
    "sim_seconds",
    "wall_seconds",
)
"""Keys result.json must contain (notes/metrics.md, episode output contract)."""


def is_episode_dir(path: str | Path) -> bool:
    """True when `path` is a folder holding a committed episode (result.json and cloth.npz)."""
    p = Path(path)
    return p.is_dir() and (p / RESULT_FILE).is_file() and (p / CLOTH_FILE).is_file()


def is_unscored_episode_dir(path: str | Path) -> bool:
    """True when `path` is a folder holding a committed unscored episode: a fold on a real cell,
    its result.json saying "scored": false and no cloth.npz (no ground truth to score from)."""
    p = Path(path)
    result_file = p / RESULT_FILE
    if not p.is_dir() or not result_file.is_file() or (p / CLOTH_FILE).exists():
        return False
    try:
        result = json.loads(result_file.read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return False
    return isinstance(result, dict) and result.get("scored") is False


def failed_dir(out_dir: str | Path) -> Path:
    """Where an episode that ended in an error leaves what it had recorded: `DIR.failed`."""
    p = Path(out_dir).expanduser().absolute()
    return p.with_name(p.name + FAILED_SUFFIX)


def is_failed_dir(path: str | Path) -> bool:
    """True when `path` is a folder an EpisodeWriter left after an error (error.json, no
    result.json): safe to replace."""
    p = Path(path)
    return p.is_dir() and (p / ERROR_FILE).is_file() and not (p / RESULT_FILE).exists()


def to_jsonable(value: Any) -> Any:
    """Convert numpy scalars/arrays, paths, dataclasses and FoldLines to plain JSON values.

    Non-finite floats become None (JSON has no NaN/inf).
    """
    if isinstance(value, FoldLine):
        return value.as_list()
    if dataclasses.is_dataclass(value) and not isinstance(value, type):
        return to_jsonable(dataclasses.asdict(value))
    if isinstance(value, Mapping):
        return {str(k): to_jsonable(v) for k, v in value.items()}
    if isinstance(value, np.ndarray):
        return to_jsonable(value.tolist())
    if isinstance(value, list | tuple | set | frozenset):
        return [to_jsonable(v) for v in value]
    if isinstance(value, bool | np.bool_):
        return bool(value)
    if isinstance(value, int | np.integer):
        return int(value)
    if isinstance(value, float | np.floating):
        f = float(value)
        return f if math.isfinite(f) else None
    if isinstance(value, Path):
        return str(value)
    if value is None or isinstance(value, str):
        return value
    raise ConfigError(f"result value {value!r} of type {type(value).__name__} is not JSON-able")


CLOTH_LIMIT_M = 100.0
"""How far from the world origin (m, along each axis) a cloth vertex may lie: a cell's cloth is
within a few metres of it, and a vertex much further out is a diverged simulation or a corrupt
file, whose extent no raster could score."""


def _positions(name: str, value: Any) -> np.ndarray:
    """A V×3 float array of finite vertex positions (m) within CLOTH_LIMIT_M of the origin."""
    try:
        arr = np.asarray(value)
        ok = arr.dtype.kind in "iuf"  # integers or floats; not bool, complex, text or objects
    except (TypeError, ValueError):  # ragged nested lists
        arr, ok = np.asarray(None), False
    if not ok or arr.ndim != 2 or arr.shape[1] != 3 or arr.shape[0] == 0:
        raise ConfigError(
            f"{name} must be a non-empty V×3 array of numbers (m), got {arr.dtype} {arr.shape}"
        )
    arr = arr.astype(np.float64)
    allowed = (
        f"every coordinate must be finite and within ±{CLOTH_LIMIT_M:g} m of the world origin "
        "(did the simulation diverge?)"
    )
    bad = ~np.isfinite(arr).all(axis=1)
    if bad.any():
        raise ConfigError(
            f"{name} has NaN or inf coordinates at {int(bad.sum())} of its {len(arr)} "
            f"vertices; {allowed}"
        )
    far = float(np.abs(arr).max())
    if far > CLOTH_LIMIT_M:
        raise ConfigError(f"{name} has a vertex coordinate of {far:.3g} m; {allowed}")
    return arr


def _thickness(value: Any) -> float:
    """The cloth thickness (m) as a float: one finite number ≥ 0."""
    arr = np.asarray(value)
    if arr.shape != () or arr.dtype.kind not in "iuf":
        shown = f"{arr.dtype} array of shape {arr.shape}" if arr.shape else repr(value)
        raise ConfigError(f"thickness = {shown} must be one finite number ≥ 0 (m)")
    t = float(arr)
    if not math.isfinite(t) or t < 0:
        raise ConfigError(f"thickness = {t:g} must be a finite number ≥ 0 (m)")
    return t


def _validate_cloth(
    faces: Any, initial: Any, final: Any, thickness: Any
) -> tuple[np.ndarray, np.ndarray, np.ndarray, float]:
    """Check the cloth arrays against the cloth.npz contract and return them normalised."""
    init = _positions("initial", initial)
    fin = _positions("final", final)
    if init.shape != fin.shape:
        raise ConfigError(f"final shape {fin.shape} differs from initial shape {init.shape}")
    tri = np.asarray(faces)
    if (
        tri.ndim != 2
        or tri.shape[1] != 3
        or tri.shape[0] == 0
        or not np.issubdtype(tri.dtype, np.integer)
    ):
        raise ConfigError(
            f"faces must be a non-empty F×3 integer array, got {tri.dtype} {tri.shape}"
        )
    tri = tri.astype(np.int64)
    if tri.size and (tri.min() < 0 or tri.max() >= init.shape[0]):
        raise ConfigError(
            f"faces index range [{tri.min()}, {tri.max()}] is outside [0, {init.shape[0] - 1}]"
        )
    return tri, init, fin, _thickness(thickness)


def _close_videos(videos: list[VideoWriter]) -> None:
    """Close every open video (ending its ffmpeg process), whatever state an error left it in."""
    for video in videos:
        with contextlib.suppress(Exception):
            video.close()


def _discard_staging(staging_dir: Path, videos: list[VideoWriter]) -> None:
    """Close any open video and delete the staging folder."""
    _close_videos(videos)
    shutil.rmtree(staging_dir, ignore_errors=True)


class EpisodeWriter:
    """Write one episode folder atomically: stage in `.DIR.partial-<pid>`, rename on commit.

    Use as a context manager: a clean exit commits if `commit()` was not called. An exception
    inside the `with` leaves DIR untouched; whatever was staged (the video up to the error,
    pictures) moves to `DIR.failed/` with error.json (the error's type and message), and the
    exception gets a note naming that folder; with nothing staged, nothing is left. DIR may be a
    new path, an empty folder, or (with overwrite=True) a previous episode folder.
    """

    def __init__(self, out_dir: str | Path, *, overwrite: bool = False, fps: float = 30.0) -> None:
        """Validate the target and create the staging folder now, so bad paths fail early."""
        self.out_dir = Path(out_dir).expanduser().absolute()
        self.overwrite = bool(overwrite)
        self.fps = fps
        self._check_target()
        parent = self.out_dir.parent
        try:
            parent.mkdir(parents=True, exist_ok=True)
        except OSError as exc:
            raise OutputError(
                f"cannot create the parent folder of episode output {str(self.out_dir)!r}: "
                f"{exc}; allowed: a path whose parent is (or can be made) a writable folder"
            ) from exc
        if not os.access(parent, os.W_OK | os.X_OK):
            raise OutputError(
                f"episode output parent folder {str(parent)!r} is not writable; "
                "allowed: a path inside a writable folder"
            )
        self.staging_dir = parent / f".{self.out_dir.name}.partial-{os.getpid()}"
        if self.staging_dir.exists():
            shutil.rmtree(self.staging_dir, ignore_errors=True)
        try:
            self.staging_dir.mkdir()
        except OSError as exc:
            raise OutputError(
                f"cannot create staging folder {str(self.staging_dir)!r} for episode output "
                f"{str(self.out_dir)!r}: {exc}"
            ) from exc
        self._videos: list[VideoWriter] = []  # shared with the finalizer, which must close it
        self._cleanup = weakref.finalize(self, _discard_staging, self.staging_dir, self._videos)
        self._committed: Path | None = None
        self._aborted = False
        self.failed: Path | None = None
        """`DIR.failed` once an error left the staged files there (see keep_failed)."""

    def _check_target(self) -> None:
        """Raise OutputError unless DIR may be written (new, empty, or episode + overwrite)."""
        d = self.out_dir
        allowed = (
            "allowed: a new path, an empty folder, or a previous episode folder with "
            "--overwrite (overwrite=True)"
        )
        if d.exists() and not d.is_dir():
            raise OutputError(f"episode output {str(d)!r} exists and is not a folder; {allowed}")
        if d.is_dir():
            try:
                empty = not any(d.iterdir())
            except OSError as exc:
                raise OutputError(f"cannot read episode output folder {str(d)!r}: {exc}") from exc
            if empty:
                return
            if not (is_episode_dir(d) or is_unscored_episode_dir(d)):  # a real cell's too
                raise OutputError(
                    f"episode output {str(d)!r} is a non-empty folder that is not a foldbot "
                    f"episode; {allowed}"
                )
            if not self.overwrite:
                raise OutputError(
                    f"episode output {str(d)!r} already holds an episode; use --overwrite "
                    f"(overwrite=True) to replace it ({allowed})"
                )

    def _require_open(self) -> None:
        """Raise OutputError once the writer has been committed or aborted."""
        if self._committed is not None or self._aborted:
            state = "committed" if self._committed is not None else "aborted"
            raise OutputError(f"episode writer for {str(self.out_dir)!r} is already {state}")

    def add_frame(self, rgb: np.ndarray) -> None:
        """Append one camera frame (H×W×3 uint8) to video.mp4."""
        self._require_open()
        if not self._videos:
            self._videos.append(VideoWriter(self.staging_dir / VIDEO_FILE, fps=self.fps))
        self._videos[0].add(rgb)

    @property
    def frame_count(self) -> int:
        """Frames written to video.mp4 so far."""
        return self._videos[0].frame_count if self._videos else 0

    def write_cloth(
        self, faces: np.ndarray, initial: np.ndarray, final: np.ndarray, thickness: float
    ) -> Path:
        """Write cloth.npz: faces (F×3 int), initial/final (V×3 m, world), thickness (m)."""
        self._require_open()
        tri, init, fin, t = _validate_cloth(faces, initial, final, thickness)
        path = self.staging_dir / CLOTH_FILE
        try:
            with path.open("wb") as fh:
                np.savez_compressed(fh, faces=tri, initial=init, final=fin, thickness=np.float64(t))
        except OSError as exc:
            raise OutputError(f"cannot write {str(path)!r}: {exc}") from exc
        return path

    def write_result(self, result: Mapping[str, Any]) -> Path:
        """Write result.json (pretty); every key of REQUIRED_RESULT_KEYS must be present."""
        self._require_open()
        if not isinstance(result, Mapping):
            raise ConfigError(f"result must be a dict, got {type(result).__name__}")
        missing = [k for k in REQUIRED_RESULT_KEYS if k not in result]
        if missing:
            raise OutputError(
                f"result.json for {str(self.out_dir)!r} is missing required keys {missing}; "
                f"required: {list(REQUIRED_RESULT_KEYS)}"
            )
        data = to_jsonable(dict(result))
        data["fold_lines"] = [line.as_list() for line in as_fold_lines(result["fold_lines"])]
        path = self.staging_dir / RESULT_FILE
        try:
            path.write_text(json.dumps(data, indent=2, allow_nan=False) + "\n", encoding="utf-8")
        except OSError as exc:
            raise OutputError(f"cannot write {str(path)!r}: {exc}") from exc
        return path

    def write_image(self, name: str, rgb: np.ndarray) -> Path:
        """Write an extra RGB PNG (e.g. a debug overlay) named `name` (.png added if missing)."""
        self._require_open()
        if not isinstance(name, str) or not name or Path(name).name != name or name[0] == ".":
            raise ConfigError(f"image name {name!r} must be a plain file name (no folders)")
        if Path(name).suffix == "":
            name = f"{name}.png"
        if Path(name).suffix.lower() != ".png":
            raise ConfigError(f"image name {name!r} must end in .png")
        if (
            not isinstance(rgb, np.ndarray)
            or rgb.dtype != np.uint8
            or rgb.ndim != 3
            or rgb.shape[2] != 3
        ):
            shape = getattr(rgb, "shape", None)
            dtype = getattr(rgb, "dtype", type(rgb).__name__)
            raise ConfigError(f"image {name!r} must be H×W×3 uint8 RGB, got {dtype} {shape}")
        import imageio.v3 as iio

        path = self.staging_dir / name
        try:
            iio.imwrite(path, rgb)
        except OSError as exc:
            raise OutputError(f"cannot write {str(path)!r}: {exc}") from exc
        return path

    def commit(self, require_cloth: bool = True) -> Path:
        """Close the video, check result.json and cloth.npz exist, and rename into DIR.
        `require_cloth` False: an unscored episode (a real cell's: no ground-truth cloth)."""
        self._require_open()
        for video in self._videos:
            video.close()
        needed = (RESULT_FILE, CLOTH_FILE) if require_cloth else (RESULT_FILE,)
        missing = [f for f in needed if not (self.staging_dir / f).is_file()]
        if missing:
            raise OutputError(
                f"episode {str(self.out_dir)!r} cannot be committed: {missing} not written "
                "(call write_result and write_cloth first)"
            )
        self._check_target()  # the target may have changed since __init__
        old: Path | None = None
        try:
            if self.out_dir.is_dir() and any(self.out_dir.iterdir()):
                old = self.out_dir.parent / f".{self.out_dir.name}.old-{os.getpid()}"
                if old.exists():
                    shutil.rmtree(old)
                os.replace(self.out_dir, old)
            os.replace(self.staging_dir, self.out_dir)  # replaces an empty DIR atomically
        except OSError as exc:
            if old is not None and old.exists() and not self.out_dir.exists():
                os.replace(old, self.out_dir)
            raise OutputError(
                f"cannot move episode into place at {str(self.out_dir)!r}: {exc}"
            ) from exc
        if old is not None:
            shutil.rmtree(old, ignore_errors=True)
        stale = failed_dir(self.out_dir)
        if is_failed_dir(stale):  # an earlier try's evidence; this episode replaces it
            shutil.rmtree(stale, ignore_errors=True)
        self._cleanup.detach()
        self._committed = self.out_dir
        return self.out_dir

    def abort(self) -> None:
        """Drop everything staged; DIR is left as it was (idempotent)."""
        if self._committed is not None or self._aborted:
            return
        self._aborted = True
        self._cleanup()

    def keep_failed(self, error: BaseException) -> Path | None:
        """Move what was staged to `DIR.failed/` with error.json naming `error`, instead of
        dropping it; DIR is untouched. Returns the folder, or None when nothing was staged or
        `DIR.failed` is something else (then it is left alone and the staged files dropped)."""
        if self._committed is not None or self._aborted:
            return self.failed
        self._aborted = True
        _close_videos(self._videos)  # a video cut short by the error is still kept
        target = failed_dir(self.out_dir)
        try:
            staged = any(self.staging_dir.iterdir())
        except OSError:
            staged = False
        if not staged or (target.exists() and not is_failed_dir(target)):
            self._cleanup()
            return None
        report: dict[str, Any] = {"error_type": type(error).__name__, "error": str(error)}
        if getattr(error, "facts", None):  # what the episode measured before it (FoldbotError)
            report["facts"] = to_jsonable(error.facts)
        try:
            (self.staging_dir / RESULT_FILE).unlink(missing_ok=True)  # not an episode
            (self.staging_dir / ERROR_FILE).write_text(json.dumps(report, indent=2) + "\n")
            if target.exists():
                shutil.rmtree(target)
            os.replace(self.staging_dir, target)
        except OSError:
            self._cleanup()
            return None
        self._cleanup.detach()
        self.failed = target
        return target

    def __enter__(self) -> EpisodeWriter:
        return self

    def __exit__(
        self,
        exc_type: type[BaseException] | None,
        exc: BaseException | None,
        tb: TracebackType | None,
    ) -> None:
        if exc_type is not None:
            if isinstance(exc, Exception):
                kept = self.keep_failed(exc)
                if kept is not None:
                    files = ", ".join(sorted(p.name for p in kept.iterdir()))
                    exc.add_note(f"what the episode recorded up to the error: {kept} ({files})")
            self.abort()
            return
        if self._committed is None and not self._aborted:
            try:
                self.commit()
            except BaseException:
                self.abort()
                raise


@dataclass(frozen=True)
class Episode:
    """A committed episode folder read back: result.json and the cloth.npz arrays."""

    path: Path
    result: dict[str, Any]
    faces: np.ndarray  # F×3 int
    initial: np.ndarray  # V×3, m
    final: np.ndarray  # V×3, m
    thickness: float  # m

    @property
    def fold_lines(self) -> tuple[FoldLine, ...]:
        """The fold lines of result.json, in folding order."""
        return as_fold_lines(self.result["fold_lines"])


_NPZ_ERRORS = (OSError, EOFError, ValueError, KeyError, NotImplementedError, BadZipFile, zlib.error)
"""What numpy and zipfile raise on a file that is not a whole .npz archive."""


def _unreadable(path: Path, reason: str) -> ConfigError:
    """The error for a cloth.npz foldbot cannot read: names the file, the reason, what it must be."""
    return ConfigError(
        f"{path.name} in {path.parent} is not a readable episode file ({reason}); it must be "
        f"a NumPy .npz archive of the arrays {', '.join(CLOTH_KEYS)}, as `foldbot fold` writes it"
    )


def _read_cloth(path: Path) -> dict[str, np.ndarray]:
    """The CLOTH_KEYS arrays of cloth.npz at `path` (ConfigError naming the file and the array
    when it is empty, not a .npz archive, truncated or corrupt, or lacks one)."""
    try:
        with path.open("rb") as fh:
            magic = fh.read(4)
    except OSError as exc:
        raise _unreadable(path, exc.strerror or str(exc)) from None
    if not magic:
        raise _unreadable(path, "it is empty")
    if magic != b"PK\x03\x04":  # every .npz is a zip archive
        raise _unreadable(path, "it is not a .npz (zip) archive")
    arrays: dict[str, np.ndarray] = {}
    key = None
    try:
        with np.load(path, allow_pickle=False) as npz:
            missing = [k for k in CLOTH_KEYS if k not in npz.files]
            if missing:
                raise _unreadable(path, f"it lacks the arrays {missing}")
            for key in CLOTH_KEYS:
                arrays[key] = npz[key]
    except _NPZ_ERRORS as exc:
        if isinstance(exc, ConfigError):
            raise
        if key is None:
            reason = f"a truncated or corrupt archive: {exc}"
        elif isinstance(exc, ValueError) and "allow_pickle" in str(exc):
            reason = f"array {key!r} holds Python objects, which foldbot does not load"
        else:
            reason = f"array {key!r} is truncated or corrupt: {exc}"
        raise _unreadable(path, reason) from None
    return arrays


def load_episode(path: str | Path) -> Episode:
    """Read result.json and cloth.npz of an episode folder (ConfigError if malformed)."""
    d = Path(path)
    if is_unscored_episode_dir(d):
        raise ConfigError(
            f"{str(d)!r} holds a fold on a real cell, unscored: it has no {CLOTH_FILE} (no "
            "ground-truth cloth); its result.json says what the camera saw (a real cell's run is "
            "kept as a bag with ros-fold --record)"
        )
    if not is_episode_dir(d):
        raise ConfigError(
            f"{str(d)!r} is not an episode folder; it must contain {RESULT_FILE} and {CLOTH_FILE}"
        )
    try:
        result = json.loads((d / RESULT_FILE).read_text(encoding="utf-8"))
    except (OSError, ValueError) as exc:
        raise ConfigError(f"cannot read {str(d / RESULT_FILE)!r}: {exc}") from exc
    if not isinstance(result, dict):
        raise ConfigError(f"{str(d / RESULT_FILE)!r} must hold a JSON object")
    arrays = _read_cloth(d / CLOTH_FILE)
    try:
        faces, initial, final, thickness = _validate_cloth(
            arrays["faces"], arrays["initial"], arrays["final"], arrays["thickness"]
        )
    except ConfigError as exc:
        raise ConfigError(f"{CLOTH_FILE} in {d}: {exc}") from None
    return Episode(d, result, faces, initial, final, thickness)


def rescore(path: str | Path) -> FoldScore:
    """Recompute every metric of an episode from cloth.npz and result.json["fold_lines"] alone."""
    ep = load_episode(path)
    if "fold_lines" not in ep.result:
        raise ConfigError(f"{str(Path(path) / RESULT_FILE)!r} has no 'fold_lines'")
    return score_episode(ep.initial, ep.final, ep.faces, ep.fold_lines, ep.thickness)
