"""foldbot: a cloth-folding robot stack — simulated cell, perception, planning and control."""

from foldbot.simd import cap_simd_level

__version__ = "0.1.0"

# Before anything imports numpy: the same numeric kernels on every x86-64 CPU (see foldbot.simd).
cap_simd_level()
