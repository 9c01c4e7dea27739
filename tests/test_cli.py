"""foldbot.cli: `kill` stops a command as Ctrl-C does, even when the signal comes while the
interpreter runs a callback of its own, which cannot raise (tests/commands/test_fold_cli.py
stops a whole fold so)."""

from __future__ import annotations

import subprocess
import sys

import pytest

SWALLOWED = """
import os, signal, sys, time
from foldbot.cli import Terminated, sigterm_raises

signum = getattr(signal, sys.argv[1])

class Late:
    def __del__(self):
        # The signal arrives in here, as it may in an at-fork handler while a subprocess
        # starts: what its handler raises, Python prints as "Exception ignored" and goes on.
        os.kill(os.getpid(), signum)
        time.sleep(0.2)

with sigterm_raises():
    try:
        Late()
        for _ in range(100):
            time.sleep(0.01)
        print("not stopped")
    except (Terminated, KeyboardInterrupt) as exc:
        print("stopped by", type(exc).__name__)
"""


@pytest.mark.parametrize(
    ("signame", "raised"), [("SIGTERM", "Terminated"), ("SIGINT", "KeyboardInterrupt")]
)
def test_a_signal_the_interpreter_swallows_is_raised_once_it_can_be(signame, raised):
    proc = subprocess.run(
        [sys.executable, "-c", SWALLOWED, signame], capture_output=True, text=True, timeout=60
    )
    assert proc.returncode == 0, proc.stderr
    assert proc.stdout.strip() == f"stopped by {raised}", proc.stdout + proc.stderr
    assert "Exception ignored" not in proc.stderr


def test_without_the_context_the_handler_before_is_back():
    script = (
        "import signal\nfrom foldbot.cli import sigterm_raises\n"
        "before = signal.getsignal(signal.SIGTERM)\n"
        "with sigterm_raises():\n    inside = signal.getsignal(signal.SIGTERM)\n"
        "print(before is signal.getsignal(signal.SIGTERM), inside is not before)\n"
    )
    proc = subprocess.run(
        [sys.executable, "-c", script], capture_output=True, text=True, timeout=60
    )
    assert proc.stdout.split() == ["True", "True"], proc.stderr
