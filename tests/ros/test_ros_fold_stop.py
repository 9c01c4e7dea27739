"""`foldbot ros-fold` stopped by `kill` (SIGTERM, as `timeout` and process managers stop
things): roslaunch is stopped as Ctrl-C stops it, so it takes its nodes and roscore down with
it rather than leaving them running; neither the episode folder nor a failure record is
written."""

import signal
import subprocess
import sys
import threading
import time
from pathlib import Path

import pytest
from ros_helpers import free_port, requires_ros

pytestmark = [requires_ros, pytest.mark.slow]


def _running(port: int) -> list[str]:
    """Every process on this ROS master's port: started with it (roscore) or pointed at it by
    ROS_MASTER_URI (roslaunch's nodes)."""
    found = []
    for proc in Path("/proc").iterdir():
        if not proc.name.isdigit():
            continue
        try:
            args = (proc / "cmdline").read_bytes().replace(b"\0", b" ").decode(errors="replace")
            env = (proc / "environ").read_bytes().split(b"\0")
        except OSError:  # gone meanwhile, or not ours to read
            continue
        uri = f"ROS_MASTER_URI=http://localhost:{port}".encode()
        if f"-p {port}" in args or any(v.rstrip(b"/") == uri for v in env):
            found.append(args)
    return found


def test_a_ros_fold_stopped_by_sigterm_takes_its_nodes_down(tmp_path):
    port = free_port()
    out = tmp_path / "ep"
    proc = subprocess.Popen(
        [sys.executable, "-m", "foldbot.cli", "ros-fold", "--resolution", "6", "--video-fps",
         "0", "--camera-rate", "2", "--out", str(out), "--port", str(port)],
        stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True,
    )  # fmt: skip
    # Stopped mid-fold: once the arm is on its way to the first grasp (the task node has staged
    # the first overlay by then; a fold stopped there was left as ep.failed/, its error the
    # shutdown's).
    watchdog = threading.Timer(180, proc.kill)  # a launch that never gets there fails the test
    watchdog.start()
    seen = []
    for line in proc.stdout:
        seen.append(line)
        if "stage 1, action 1/" in line:
            break
    watchdog.cancel()
    assert proc.poll() is None, "".join(seen)[-3000:]
    running = _running(port)
    assert any("sim_node" in a for a in running) and any("task_node" in a for a in running)
    proc.send_signal(signal.SIGTERM)
    log = "".join(seen) + proc.communicate(timeout=120)[0]
    assert proc.returncode == 128 + signal.SIGTERM, log[-3000:]
    assert "terminated (SIGTERM)" in log
    # What the task node had staged is gone: a stopped fold is no failed one (no ep.failed/).
    assert not out.exists() and not (tmp_path / "ep.failed").exists()
    assert not list(tmp_path.glob(".ep.partial-*"))
    deadline = time.monotonic() + 30
    while _running(port):
        assert time.monotonic() < deadline, _running(port)
        time.sleep(0.2)
