"""Perception and planning never reach the simulator: every module of foldbot.perception and
foldbot.planning imports, directly or through what it imports, neither pybullet nor foldbot.sim.
That is what lets the same code run on a real camera, in a ROS node or on a recorded bag."""

import json
import subprocess
import sys

import pytest

# A fresh interpreter: this process has long since loaded the simulator for other tests.
SCRIPT = """
import importlib, json, pkgutil, sys
import foldbot
loaded = {}
for package in sys.argv[1:]:
    for info in pkgutil.iter_modules(importlib.import_module(package).__path__):
        name = f"{package}.{info.name}"
        importlib.import_module(name)
        loaded[name] = sorted(
            m for m in sys.modules
            if m == "pybullet" or m.startswith("pybullet_") or m == "foldbot.sim"
            or m.startswith("foldbot.sim.")
        )
print(json.dumps(loaded))
"""


@pytest.mark.parametrize("package", ["foldbot.perception", "foldbot.planning"])
def test_no_module_reaches_the_simulator(package):
    out = subprocess.run(
        [sys.executable, "-c", SCRIPT, package],
        capture_output=True, text=True, timeout=300, check=True,
    )  # fmt: skip
    loaded = json.loads(out.stdout)
    assert len(loaded) >= 5  # every module was imported, not none
    # A failure shows each module that pulls the simulator in, and what it pulls in.
    reaching = {name: sim for name, sim in loaded.items() if sim}
    assert not reaching


def test_the_check_sees_the_simulator_where_it_is_imported():
    out = subprocess.run(
        [sys.executable, "-c", SCRIPT, "foldbot.sim"],
        capture_output=True, text=True, timeout=300, check=True,
    )  # fmt: skip
    loaded = json.loads(out.stdout)
    assert "pybullet" in loaded["foldbot.sim.world"]
