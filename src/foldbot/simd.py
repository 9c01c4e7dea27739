"""One SIMD level for numpy, OpenBLAS and OpenCV on every x86-64 CPU, so the same seed gives the
same episode on any machine, not only on one: these libraries pick their kernels by CPU (AVX-512
where there is AVX-512), those kernels round sums differently in the last bit, and the cloth's
chaotic dynamics grow that bit into a different fold (the demo towel: 8.4 mm with the AVX-512
kernels, 6.1 mm without).

`import foldbot` caps them at AVX2 with FMA (x86-64-v3): OpenBLAS runs its Haswell kernels, and
numpy's and OpenCV's AVX-512 dispatch is switched off. Each reads its setting once, when it first
loads, so the cap is set before anything imports numpy or cv2; a value the user has set is kept.
A program that imported numpy or cv2 before foldbot keeps their AVX-512 kernels: `import foldbot`
warns, naming them (late_libraries), and result.json records them (`simd_uncapped`)."""

from __future__ import annotations

import os
import platform
import sys
from collections.abc import Mapping, MutableMapping
from pathlib import Path

OPENBLAS_CORETYPE = "Haswell"
"""OpenBLAS's kernel family for AVX2 with FMA, used wherever the CPU can run it."""
NUMPY_DISABLED_FEATURES = (
    "X86_V4 AVX512_ICL AVX512_SPR "  # numpy ≥ 2.4's names
    "AVX512F AVX512CD AVX512_KNL AVX512_KNM AVX512_SKX AVX512_CLX AVX512_CNL"  # numpy < 2.4's
)
"""numpy's AVX-512 dispatch targets (`NPY_DISABLE_CPU_FEATURES`); names a numpy version does not
know, or a CPU does not have, are ignored."""
OPENCV_DISABLED_FEATURES = "AVX512-SKX"
"""OpenCV's AVX-512 dispatch target (`OPENCV_CPU_DISABLE`), its only one in the 4.x, 5.x wheels."""
CAP = {
    "OPENBLAS_CORETYPE": OPENBLAS_CORETYPE,
    "NPY_DISABLE_CPU_FEATURES": NUMPY_DISABLED_FEATURES,
    "OPENCV_CPU_DISABLE": OPENCV_DISABLED_FEATURES,
}
"""The environment variables that cap the three libraries, and their values."""
REQUIRED_CPU_FLAGS = frozenset({"avx2", "fma"})
"""CPU flags (as /proc/cpuinfo spells them) of the level every machine is capped at."""
OPENCV_AVX512_FLAGS = frozenset({"avx512f", "avx512cd", "avx512bw", "avx512dq", "avx512vl"})
"""CPU flags OpenCV's AVX512-SKX dispatch needs: only where all are present is it switched off
(elsewhere OpenCV would not use it, and prints a warning at every start when asked to)."""


def cpu_flags(cpuinfo: str) -> frozenset[str]:
    """The flags of the first processor listed in /proc/cpuinfo's text (empty if none)."""
    for line in cpuinfo.splitlines():
        key, _, value = line.partition(":")
        if key.strip() == "flags":
            return frozenset(value.split())
    return frozenset()


def cap_simd_level(
    environ: MutableMapping[str, str] = os.environ,
    cpuinfo_path: Path = Path("/proc/cpuinfo"),
    machine: str | None = None,
) -> dict[str, str]:
    """Cap numpy, OpenBLAS and OpenCV at AVX2 with FMA where the CPU has both (x86-64 Linux; OpenCV
    only where it has AVX-512 to switch off), keeping any value the user set; return the settings
    in force (empty: the libraries choose)."""
    if (machine or platform.machine()).lower() in ("x86_64", "amd64"):
        try:
            flags = cpu_flags(cpuinfo_path.read_text())
        except OSError:
            flags = frozenset()
        if flags >= REQUIRED_CPU_FLAGS:
            for name, value in CAP.items():
                if name == "OPENCV_CPU_DISABLE" and not flags >= OPENCV_AVX512_FLAGS:
                    continue
                environ.setdefault(name, value)
    return {k: environ[k] for k in CAP if k in environ}


def numpy_avx512_dispatch(dispatch: list[str], features: Mapping[str, bool]) -> list[str]:
    """numpy's AVX-512 dispatch targets in use: those of `dispatch` (numpy's `__cpu_dispatch__`)
    that NUMPY_DISABLED_FEATURES names and `features` (`__cpu_features__`) has switched on."""
    capped = set(NUMPY_DISABLED_FEATURES.split())
    return [f for f in dispatch if f in capped and features.get(f, False)]


def opencv_avx512_dispatch(line: str) -> list[str]:
    """OpenCV's AVX-512 dispatch targets in use, from `cv2.getCPUFeaturesLine()`: a target the
    CPU lacks, or that is switched off, ends in '?'."""
    return [f.lstrip("*") for f in line.split() if "AVX512" in f and not f.endswith("?")]


def late_libraries(
    environ: Mapping[str, str] = os.environ, modules: Mapping[str, object] = sys.modules
) -> list[str]:
    """The libraries the cap in `environ` did not reach: numpy or OpenCV, already loaded before it
    was set (imported before foldbot), still dispatching AVX-512 kernels, e.g. "numpy (X86_V4,
    AVX512_ICL)". Empty where the cap holds, or where none of foldbot's is set (a CPU that needs
    none, or a value the user chose)."""
    late = []
    if "numpy" in modules and environ.get("NPY_DISABLE_CPU_FEATURES") == NUMPY_DISABLED_FEATURES:
        try:
            from numpy._core._multiarray_umath import __cpu_dispatch__, __cpu_features__
        except ImportError:  # numpy < 2
            from numpy.core._multiarray_umath import __cpu_dispatch__, __cpu_features__
        used = numpy_avx512_dispatch(list(__cpu_dispatch__), __cpu_features__)
        if used:
            late.append(f"numpy ({', '.join(used)})")
    cv2 = modules.get("cv2")
    if cv2 is not None and environ.get("OPENCV_CPU_DISABLE") == OPENCV_DISABLED_FEATURES:
        used = opencv_avx512_dispatch(cv2.getCPUFeaturesLine())
        if used:
            late.append(f"OpenCV ({', '.join(used)})")
    return late


def late_warning(late: list[str]) -> str:
    """What `import foldbot` says when late_libraries found some."""
    return (
        f"foldbot was imported after {' and '.join(late)} had loaded: those AVX-512 kernels stay "
        "in use, so the same seed can give a different episode here than in foldbot's commands, "
        "benchmark and CI (README: Determinism). Import foldbot before numpy and cv2."
    )
