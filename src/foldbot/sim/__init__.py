"""The simulated cell: PyBullet world, table, robots, soft-body cloth, RGB-D camera, ground-truth oracle.

Importing this package imports pybullet with the banner its C extension prints to standard error
("pybullet build time: …") silenced, so command output, logs and progress bars stay clean.
"""

from __future__ import annotations

import importlib
import os
import sys
from types import ModuleType


def import_pybullet() -> ModuleType:
    """pybullet, imported (the first time) with file descriptor 2 pointed at the null device: the
    banner is written by C code, which Python-level redirection does not catch. An import error
    is still raised as usual."""
    if "pybullet" in sys.modules:
        return sys.modules["pybullet"]
    try:
        sys.stderr.flush()
        saved = os.dup(2)
    except (OSError, ValueError):  # no usable standard error: import as is
        return importlib.import_module("pybullet")
    try:
        null = os.open(os.devnull, os.O_WRONLY)
        os.dup2(null, 2)
        os.close(null)
        return importlib.import_module("pybullet")
    finally:
        os.dup2(saved, 2)
        os.close(saved)


import_pybullet()
