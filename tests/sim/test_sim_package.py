"""Importing the simulation package keeps pybullet's start-up banner (on standard error) quiet."""

import subprocess
import sys


def test_pybullet_banner_is_silenced_and_stderr_still_works():
    code = "import sys, foldbot.sim, pybullet; from foldbot.sim import import_pybullet; "
    code += "assert import_pybullet() is pybullet; print('after import', file=sys.stderr)"
    out = subprocess.run(
        [sys.executable, "-c", code], capture_output=True, text=True, timeout=120, check=True
    )
    assert "build time" not in out.stderr + out.stdout
    assert out.stderr.strip() == "after import"
    plain = subprocess.run(
        [sys.executable, "-c", "import pybullet"], capture_output=True, text=True, timeout=120
    )
    assert "build time" in plain.stderr  # the banner this silences


def test_the_command_line_prints_no_banner():
    out = subprocess.run(
        [sys.executable, "-m", "foldbot.cli", "fold", "--help"],
        capture_output=True,
        text=True,
        timeout=120,
        check=True,
    )
    assert "build time" not in out.stdout + out.stderr
    assert out.stdout.startswith("usage")
