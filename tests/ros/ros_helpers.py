"""ROS 1 availability for the tests under tests/ros (they skip, with the reason, without it)."""

import contextlib
import os
import signal
import socket
import subprocess
import sys
import time
from collections.abc import Iterator

import pytest

from foldbot.commands.ros_fold import ros_missing

ROS_MISSING = ros_missing()
requires_ros = pytest.mark.skipif(
    ROS_MISSING is not None, reason=f"ROS 1 not available: {ROS_MISSING}"
)


def free_port() -> int:
    """A free TCP port for a private ROS master (tests never touch a user's roscore)."""
    with socket.socket() as s:
        s.bind(("localhost", 0))
        return s.getsockname()[1]


@contextlib.contextmanager
def private_master() -> Iterator[dict[str, str]]:
    """A private roscore on a free port, up until the block ends; the environment that reaches
    it."""
    import rosgraph

    port = free_port()
    uri = f"http://localhost:{port}"
    env = {**os.environ, "ROS_MASTER_URI": uri, "ROS_HOSTNAME": "localhost"}
    core = subprocess.Popen(
        ["roscore", "-p", str(port)], env=env, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL
    )
    try:
        deadline = time.monotonic() + 60
        while not rosgraph.is_master_online(uri):
            assert time.monotonic() < deadline, f"roscore did not come up on port {port}"
            time.sleep(0.2)
        yield env
    finally:
        core.terminate()
        core.wait(timeout=30)


def wait_for_master(port: int, timeout_s: float = 60.0) -> None:
    """Wait until the ROS master on `port` answers (a cell started in the background)."""
    import rosgraph

    master = rosgraph.Master("/test_wait", master_uri=f"http://localhost:{port}")
    deadline = time.monotonic() + timeout_s
    while not master.is_online():
        assert time.monotonic() < deadline, f"no ROS master on port {port} within {timeout_s} s"
        time.sleep(0.2)


def start_cell(*options: str) -> tuple[subprocess.Popen, int]:
    """`foldbot ros-cell` with `options` on a free port, in its own session; and the port."""
    port = free_port()
    cell = subprocess.Popen(
        [sys.executable, "-m", "foldbot.cli", "ros-cell", *options, "--port", str(port)],
        stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True, start_new_session=True,
    )  # fmt: skip
    return cell, port


def stop_cell(cell: subprocess.Popen) -> str:
    """Interrupt a cell start_cell started, as Ctrl-C does; its output."""
    os.killpg(cell.pid, signal.SIGINT)
    return cell.communicate(timeout=60)[0]


DRIVERS_LAUNCH = """<launch>
  <param name="/use_sim_time" value="true"/>
  <param name="/foldbot/fold_args" value="--out {out} --resolution 5 --video-fps 2 {extra}"/>
  <param name="/foldbot/camera_rate" value="2"/>
  <param name="/foldbot/arm_interface" value="actions"/>
  <param name="/foldbot/real_time_factor" value="2.0"/>
  <node pkg="foldbot_ros" type="sim_node" name="foldbot_sim" output="screen" required="true"/>
</launch>
"""
"""A sim node alone serving its drivers' actions (a 5 × 5 towel, the clock at twice real time)."""


def probe_drivers(tmp_path, probe: str, fold_args: str = "") -> dict:
    """Run the sim node as drivers (DRIVERS_LAUNCH, `fold_args` added) on a private master and
    the probe script `probe` (beside this file) against it; the JSON the probe printed."""
    import json
    import os
    import signal
    import subprocess
    import sys
    from pathlib import Path

    from foldbot.commands.ros_fold import ros_env

    port = free_port()
    launch = tmp_path / "sim.launch"
    launch.write_text(DRIVERS_LAUNCH.format(out=tmp_path / "unused", extra=fold_args))
    env = ros_env(port)
    sim = subprocess.Popen(
        ["roslaunch", "-p", str(port), str(launch)],
        env=env, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True,
        start_new_session=True,
    )  # fmt: skip
    try:
        run = subprocess.run(
            [sys.executable, str(Path(__file__).with_name(probe))],
            env=env, capture_output=True, text=True, timeout=300, check=False,
        )  # fmt: skip
        stdout, stderr = run.stdout, run.stderr
    except subprocess.TimeoutExpired as exc:  # what the probe and the cell said, to see why
        stdout = f"{probe} ran past {exc.timeout} s\n" + _text(exc.stdout)
        stderr = _text(exc.stderr)
    finally:
        os.killpg(sim.pid, signal.SIGINT)
        log = sim.communicate(timeout=60)[0]
    lines = [ln for ln in stdout.splitlines() if ln.startswith("PROBE ")]
    assert lines, stdout[-2000:] + stderr[-3000:] + log[-3000:]
    return json.loads(lines[0][len("PROBE ") :])


def _text(output: bytes | str | None) -> str:
    """A timed-out subprocess's captured output as text (TimeoutExpired holds bytes)."""
    if isinstance(output, bytes):
        return output.decode(errors="replace")
    return output or ""
