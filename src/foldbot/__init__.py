"""foldbot: a cloth-folding robot stack — simulated cell, perception, planning and control."""

import warnings

from foldbot.simd import cap_simd_level, late_libraries, late_warning

__version__ = "0.1.0"

# Before anything imports numpy: the same numeric kernels on every x86-64 CPU (see foldbot.simd).
cap_simd_level()
if late := late_libraries():
    warnings.warn(late_warning(late), RuntimeWarning, stacklevel=2)
