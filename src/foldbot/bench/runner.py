"""Run a suite's missing episodes — local processes by default, or a Ray cluster — resumably.

Output folder layout (DIR = --out):

    DIR/suite.json                  the resolved suite; a resumed run must not change an episode
    DIR/episodes/<id>/              one episode folder per run (the output contract)
    DIR/episodes/<id>.error.json    the error that ended an episode that could not be scored
    DIR/episodes/<id>.failed/       what such an episode recorded up to the error (video,
                                    pictures, error.json), named by the record's "failed_dir"

An episode with either file is finished and is not run again (`retry_errors` re-runs the second
kind). Every episode runs in a fresh Python process (`foldbot.bench.worker`): Bullet's soft-body
solver keeps process-global random state, so an episode is deterministic only as the first
simulation in its process. On Ray each task starts that same worker process on its node, in a
temporary folder, and returns the folder's files, which the driver writes into DIR; so a cluster
needs no shared file system, and a Ray run gives the same per-episode results as a local one.
"""

from __future__ import annotations

import json
import os
import shutil
import signal
import subprocess
import sys
import tempfile
import threading
from collections.abc import Callable, Iterable
from concurrent.futures import ThreadPoolExecutor, as_completed
from pathlib import Path
from typing import Any

from tqdm import tqdm

from foldbot.bench.suite import EpisodeSpec, Suite
from foldbot.bench.worker import write_json_atomic
from foldbot.errors import ConfigError, OutputError
from foldbot.io.episode import RESULT_FILE, failed_dir, is_episode_dir, is_failed_dir

EPISODES = "episodes"
SUITE_FILE = "suite.json"
SINGLE_THREAD_ENV = {"OMP_NUM_THREADS": "1", "OPENBLAS_NUM_THREADS": "1", "MKL_NUM_THREADS": "1"}
"""Set in every episode process: no BLAS/OpenMP thread pools beside the episode's one core."""
DEFAULT_TIMEOUT_S = 3600.0
"""An episode still running after this long is stopped and recorded as a timeout."""
MAX_TIMEOUT_S = 7 * 24 * 3600.0
"""Longest allowed episode timeout (a week), far beyond any episode's wall time."""


def check_timeout(timeout: float | None) -> None:
    """ConfigError unless `timeout` (wall seconds per episode; None: no limit) is a finite number
    in (0, MAX_TIMEOUT_S]."""
    if timeout is None:
        return
    if not (isinstance(timeout, int | float) and 0 < timeout <= MAX_TIMEOUT_S):
        raise ConfigError(
            f"--timeout must be a number of seconds in (0, {MAX_TIMEOUT_S:g}] (a week), "
            f"got {timeout!r}"
        )


def _staging_dirs(out: Path, spec: EpisodeSpec) -> list[Path]:
    """The staging folders an episode's writers may leave behind when stopped mid-write: the
    worker's `.<id>.partial-<pid>` (io.episode.EpisodeWriter) and the driver's Ray copies."""
    parent = out / EPISODES
    return [
        *parent.glob(f".{spec.id}.partial-*"),
        *parent.glob(f".{spec.id}.ray-partial"),
        *parent.glob(f".{spec.id}.failed.ray-partial"),
    ]


def _remove_stale_staging(out: Path, spec: EpisodeSpec) -> None:
    """Remove the staging folders an earlier, stopped run of the episode left behind; a
    `.partial-<pid>` whose process still runs on this machine (a run writing it now) is kept."""
    for path in _staging_dirs(out, spec):
        _, _, pid = path.name.rpartition(".partial-")
        if not (pid.isdigit() and _alive(int(pid))):
            shutil.rmtree(path, ignore_errors=True)


def _alive(pid: int) -> bool:
    """Whether a process `pid` (> 0) runs on this machine."""
    if pid <= 0:
        return False
    try:
        os.kill(pid, 0)
    except PermissionError:  # another user's process
        return True
    except (ProcessLookupError, OverflowError):
        return False
    return True


def episode_dir(out: Path, spec: EpisodeSpec) -> Path:
    """Where the episode's folder goes."""
    return out / EPISODES / spec.id


def error_file(out: Path, spec: EpisodeSpec) -> Path:
    """Where the record of an episode that ended in an error goes."""
    return out / EPISODES / f"{spec.id}.error.json"


def load_finished(out: Path, spec: EpisodeSpec, retry_errors: bool = False) -> dict | None:
    """The record of a finished episode (scored, or ended by an error), or None if it must run."""
    ep = episode_dir(out, spec)
    if is_episode_dir(ep):
        return {"id": spec.id, "result": json.loads((ep / RESULT_FILE).read_text())}
    err = error_file(out, spec)
    if err.is_file() and not retry_errors:
        return json.loads(err.read_text())
    return None


_LIVE: set[subprocess.Popen] = set()
"""The episode processes running now (run_episode_process), so a bench stopped by `kill` stops
them too rather than waiting for them (Ctrl-C reaches them by itself, as the terminal's)."""
_LIVE_LOCK = threading.Lock()


def _kill_live_episodes() -> None:
    """Kill every running episode process; each one's thread then removes its staging folder."""
    with _LIVE_LOCK:
        for proc in _LIVE:
            proc.kill()


def run_episode_process(spec: EpisodeSpec, out_dir: Path, timeout: float | None) -> dict:
    """Run one episode in a fresh Python process; return its record (result or error). A
    process stopped at the timeout (or dead without a result) leaves no staging folder."""
    with tempfile.TemporaryDirectory(prefix="foldbot-bench-") as tmp:
        record_path = Path(tmp) / "record.json"
        cmd = [
            sys.executable,
            "-m",
            "foldbot.bench.worker",
            json.dumps(spec.as_dict()),
            str(out_dir),
            str(record_path),
        ]
        # One core per episode, and the same numeric set-up locally and on Ray (which sets
        # OMP_NUM_THREADS=1 in its workers): the episode is the same wherever it runs.
        env = {**os.environ, "PYTHONWARNINGS": "ignore", **SINGLE_THREAD_ENV}
        with subprocess.Popen(
            cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=env
        ) as proc:
            with _LIVE_LOCK:
                _LIVE.add(proc)
            try:
                stderr: str | None = proc.communicate(timeout=timeout)[1]
            except subprocess.TimeoutExpired:
                stderr = None
            finally:
                with _LIVE_LOCK:
                    _LIVE.discard(proc)
                # Stopped at the timeout (or by Ctrl-C), or dead: nothing of it left running,
                # nor the staging folder its episode writer had begun (named by its pid).
                proc.kill()
                proc.wait()
                staging = out_dir.parent / f".{out_dir.name}.partial-{proc.pid}"
                shutil.rmtree(staging, ignore_errors=True)
        if stderr is None:
            return {
                "id": spec.id,
                "error_type": "Timeout",
                "error": f"no result within {timeout:g} s; the episode process was stopped",
            }
        if record_path.is_file():
            return json.loads(record_path.read_text())
        code = proc.returncode
        if code in (-signal.SIGINT, 130):  # Ctrl-C: not a result; the episode runs again later
            raise KeyboardInterrupt
        how = (
            f"signal {signal.Signals(-code).name}"
            if code < 0 and -code in signal.valid_signals()
            else f"exit code {code}"
        )
        tail = stderr.strip().splitlines()[-3:]
        return {
            "id": spec.id,
            "error_type": "Crashed",
            "error": f"the episode process died ({how}) before writing a result: "
            + " | ".join(tail),
        }


def _ray_episode(spec_dict: dict, timeout: float | None) -> dict:
    """Ray task body: run the worker process on this node and return its record and files."""
    spec = EpisodeSpec.from_dict(spec_dict)
    with tempfile.TemporaryDirectory(prefix="foldbot-ray-") as tmp:
        ep = Path(tmp) / spec.id
        record = run_episode_process(spec, ep, timeout)
        files = (
            {p.name: p.read_bytes() for p in ep.iterdir() if p.is_file()}
            if is_episode_dir(ep)
            else {}
        )
        failed = failed_dir(ep)
        failed_files = (
            {p.name: p.read_bytes() for p in failed.iterdir() if p.is_file()}
            if is_failed_dir(failed)
            else {}
        )
    return {"record": record, "files": files, "failed_files": failed_files}


def _write_folder(target: Path, files: dict[str, bytes]) -> None:
    """Write files returned by a Ray task into the folder `target` atomically (a staging folder,
    then a rename), replacing what was there."""
    staging = target.with_name(f".{target.name}.ray-partial")
    shutil.rmtree(staging, ignore_errors=True)
    staging.mkdir(parents=True)
    for name, data in files.items():
        (staging / Path(name).name).write_bytes(data)
    if target.exists():
        shutil.rmtree(target)
    os.replace(staging, target)


def _record_done(out: Path, spec: EpisodeSpec, record: dict) -> None:
    """Persist an error record (a scored episode's folder is already in place)."""
    err = error_file(out, spec)
    if "result" in record:
        err.unlink(missing_ok=True)
    else:
        write_json_atomic(err, record)


def connect_ray(address: str) -> Any:
    """Import Ray lazily and connect: 'auto' (a running cluster), an address, or 'local'
    (start a local instance in this process)."""
    try:
        import ray
    except ImportError:
        raise ConfigError(
            "--ray needs the optional Ray dependency; install it with "
            "`pip install -e '.[ray]'` (or `pip install 'ray[default]'`)"
        ) from None
    if not ray.is_initialized():
        kwargs: dict[str, Any] = {"log_to_driver": False, "include_dashboard": False}
        try:
            if address == "local":
                ray.init(**kwargs)
            else:
                ray.init(address=address, **kwargs)
        except (ConnectionError, RuntimeError, ValueError) as exc:
            raise ConfigError(
                f"cannot connect to Ray at {address!r}: {exc}; allowed: 'auto' (a running "
                "cluster, `ray start --head`), 'local', or a cluster address such as "
                "ray://HOST:10001 or HOST:6379"
            ) from None
    return ray


def prepare_output(out: Path, suite: Suite) -> None:
    """Create DIR and check that it holds no other run (its suite.json names another suite
    with other episodes) and that a resumed run does not change any finished episode's spec."""
    described = suite.as_dict()
    previous = out / SUITE_FILE
    if previous.is_file():
        try:
            before = json.loads(previous.read_text())
        except (OSError, ValueError) as exc:
            raise OutputError(
                f"cannot read {previous} ({exc}); use another --out or remove that folder"
            ) from None
        episodes = before.get("episodes", {}) if isinstance(before, dict) else {}
        if not isinstance(episodes, dict):
            episodes = {}
        name = before.get("name") if isinstance(before, dict) else None
        if name != suite.name and set(episodes) != set(described["episodes"]):
            raise ConfigError(
                f"output folder {out} holds another run: its {SUITE_FILE} describes suite "
                f"{name!r} (other episodes), not {suite.name!r}; a folder resumes only its own "
                "run: use another --out, or remove that folder"
            )
        for eid, spec in described["episodes"].items():
            if eid in episodes and episodes[eid] != spec:
                changed = sorted(
                    k for k in spec | episodes[eid] if episodes[eid].get(k) != spec.get(k)
                )
                raise ConfigError(
                    f"{out} holds a run of episode {eid} with different settings "
                    f"({', '.join(changed)}); use another --out or remove that folder"
                )
    try:
        (out / EPISODES).mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise OutputError(f"cannot create output folder {out}: {exc.strerror}") from exc
    if not os.access(out, os.W_OK):
        raise OutputError(f"output folder {out} is not writable")
    write_json_atomic(previous, described)


def run_suite(
    suite: Suite,
    out: Path,
    workers: int = 1,
    ray_address: str | None = None,
    retry_errors: bool = False,
    timeout: float | None = DEFAULT_TIMEOUT_S,
    progress: bool = True,
    on_record: Callable[[dict], None] | None = None,
    run: bool = True,
) -> list[dict]:
    """Run every unfinished episode of `suite` into `out`; return all records in suite order.

    A record is {"id", "result": result.json} for a scored episode, or {"id", "error_type",
    "error"} for one that ended in an error (divergence, unreachable target, no cloth …).
    With run=False nothing runs: the records of the finished episodes only.
    """
    if workers < 1:
        raise ConfigError(f"--workers must be ≥ 1, got {workers}")
    check_timeout(timeout)
    ray = connect_ray(ray_address) if run and ray_address is not None else None
    prepare_output(out, suite)
    records: dict[str, dict] = {}
    todo: list[EpisodeSpec] = []
    for spec in suite.episodes:
        done = load_finished(out, spec, retry_errors)
        if done is None:
            if run:
                _remove_stale_staging(out, spec)  # an earlier run stopped mid-write
                todo.append(spec)
        else:
            records[spec.id] = done
    # Seed-major order: a run stopped part-way has the same seeds for every grid cell.
    order = {s.id: i for i, s in enumerate(suite.episodes)}
    todo.sort(key=lambda s: (s.seed, order[s.id]))
    bar = tqdm(
        total=len(suite.episodes),
        initial=len(records),
        desc=f"{suite.name}",
        unit="ep",
        disable=not progress,
        dynamic_ncols=True,
    )
    failed = sum("result" not in r or not r["result"].get("success") for r in records.values())

    def finish(spec: EpisodeSpec, record: dict) -> None:
        nonlocal failed
        _record_done(out, spec, record)
        records[spec.id] = record
        failed += "result" not in record or not record["result"].get("success")
        bar.update(1)
        bar.set_postfix(ok=len(records) - failed, failed=failed)
        if on_record is not None:
            on_record(record)

    try:
        if todo and ray is not None:
            _run_ray(ray, todo, out, timeout, finish)
        elif todo:
            with ThreadPoolExecutor(max_workers=workers) as pool:
                futures = {
                    pool.submit(run_episode_process, spec, episode_dir(out, spec), timeout): spec
                    for spec in todo
                }
                try:
                    for fut in as_completed(futures):
                        finish(futures[fut], fut.result())
                except BaseException:  # stopped (foldbot.cli.Terminated) or failed: no waiting
                    pool.shutdown(wait=False, cancel_futures=True)
                    _kill_live_episodes()
                    raise
    finally:
        bar.close()
    return [records[s.id] for s in suite.episodes if s.id in records]


def _run_ray(
    ray: Any,
    todo: Iterable[EpisodeSpec],
    out: Path,
    timeout: float | None,
    finish: Callable[[EpisodeSpec, dict], None],
) -> None:
    """Submit every episode as a Ray task (1 CPU each) and collect them as they finish."""
    task = ray.remote(num_cpus=1, max_retries=0)(_ray_episode)
    pending = {task.remote(spec.as_dict(), timeout): spec for spec in todo}
    while pending:
        ready, _ = ray.wait(list(pending), num_returns=1)
        for ref in ready:
            spec = pending.pop(ref)
            try:
                reply = ray.get(ref)
            except Exception as exc:  # the task itself failed (node lost, worker killed)
                reply = {
                    "record": {
                        "id": spec.id,
                        "error_type": "Crashed",
                        "error": f"Ray task failed: {type(exc).__name__}: {exc}",
                    },
                    "files": {},
                }
            if reply["files"]:
                _write_folder(episode_dir(out, spec), reply["files"])
                stale = failed_dir(episode_dir(out, spec))
                if is_failed_dir(stale):
                    shutil.rmtree(stale, ignore_errors=True)
            if reply.get("failed_files"):
                _write_folder(failed_dir(episode_dir(out, spec)), reply["failed_files"])
            finish(spec, reply["record"])
