"""Tests for foldbot.simd: numpy, OpenBLAS and OpenCV capped at one SIMD level on x86-64."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

from foldbot.simd import (
    CAP,
    NUMPY_DISABLED_FEATURES,
    OPENBLAS_CORETYPE,
    OPENCV_DISABLED_FEATURES,
    cap_simd_level,
    cpu_flags,
    late_libraries,
    late_warning,
    numpy_avx512_dispatch,
    opencv_avx512_dispatch,
)

CPUINFO = "processor\t: 0\nvendor_id\t: AuthenticAMD\nflags\t\t: fpu sse2 {}\n\nprocessor\t: 1\n"


def cpuinfo(tmp_path: Path, extra: str) -> Path:
    path = tmp_path / "cpuinfo"
    path.write_text(CPUINFO.format(extra))
    return path


def test_cpu_flags_reads_the_first_flags_line() -> None:
    assert cpu_flags(CPUINFO.format("avx2 fma")) == {"fpu", "sse2", "avx2", "fma"}
    assert cpu_flags("processor : 0\n") == frozenset()


def test_caps_an_avx512_cpu_at_avx2(tmp_path: Path) -> None:
    env: dict[str, str] = {}
    avx512 = "avx2 fma avx512f avx512cd avx512bw avx512dq avx512vl"
    got = cap_simd_level(env, cpuinfo(tmp_path, avx512), machine="x86_64")
    assert (
        env
        == got
        == {
            "OPENBLAS_CORETYPE": OPENBLAS_CORETYPE,
            "NPY_DISABLE_CPU_FEATURES": NUMPY_DISABLED_FEATURES,
            "OPENCV_CPU_DISABLE": OPENCV_DISABLED_FEATURES,
        }
    )
    assert OPENBLAS_CORETYPE == "Haswell"
    assert "X86_V4" in NUMPY_DISABLED_FEATURES.split()  # numpy 2.4's AVX-512 group
    assert "AVX512_SKX" in NUMPY_DISABLED_FEATURES.split()  # older numpy's


def test_an_avx2_cpu_leaves_opencv_alone(tmp_path: Path) -> None:
    """OpenCV has nothing above AVX2 to switch off there, and warns at every start if asked to."""
    env: dict[str, str] = {}
    got = cap_simd_level(env, cpuinfo(tmp_path, "avx2 fma avx512f"), machine="x86_64")
    assert (
        env
        == got
        == {
            "OPENBLAS_CORETYPE": OPENBLAS_CORETYPE,
            "NPY_DISABLE_CPU_FEATURES": NUMPY_DISABLED_FEATURES,
        }
    )


def test_opencv_starts_without_a_warning_in_a_capped_process() -> None:
    out = subprocess.run(
        [sys.executable, "-c", "import foldbot, cv2"],
        capture_output=True,
        text=True,
        env={k: v for k, v in os.environ.items() if k not in CAP},
        check=True,
    )
    assert "OPENCV" not in out.stderr, out.stderr


def test_keeps_what_the_user_set(tmp_path: Path) -> None:
    env = {
        "OPENBLAS_CORETYPE": "SkylakeX",
        "NPY_DISABLE_CPU_FEATURES": "",
        "OPENCV_CPU_DISABLE": "",
    }
    got = cap_simd_level(env, cpuinfo(tmp_path, "avx2 fma"), machine="x86_64")
    assert got["OPENBLAS_CORETYPE"] == "SkylakeX"
    assert got["NPY_DISABLE_CPU_FEATURES"] == ""
    assert got["OPENCV_CPU_DISABLE"] == ""


@pytest.mark.parametrize(
    ("extra", "machine"),
    [("sse4_2", "x86_64"), ("avx2", "x86_64"), ("avx2 fma", "aarch64")],
    ids=["no-avx2", "no-fma", "arm"],
)
def test_leaves_the_libraries_to_choose_below_avx2_or_off_x86(
    tmp_path: Path, extra: str, machine: str
) -> None:
    env: dict[str, str] = {}
    assert cap_simd_level(env, cpuinfo(tmp_path, extra), machine=machine) == {}
    assert env == {}


def test_unreadable_cpuinfo_sets_nothing(tmp_path: Path) -> None:
    env: dict[str, str] = {}
    assert cap_simd_level(env, tmp_path / "missing", machine="x86_64") == {}
    assert env == {}


def test_importing_foldbot_first_reaches_the_libraries() -> None:
    """In a fresh process, `import foldbot` before numpy and cv2 (as every foldbot command and
    benchmark worker does) leaves OpenBLAS on its Haswell kernels and numpy and OpenCV without
    AVX-512 dispatch."""
    pytest.importorskip("threadpoolctl")
    code = """
import json, os, foldbot, numpy, cv2, threadpoolctl
from numpy._core._multiarray_umath import __cpu_dispatch__, __cpu_features__
print(json.dumps({
    "env": os.environ.get("OPENBLAS_CORETYPE"),
    "blas": [i.get("architecture") for i in threadpoolctl.threadpool_info()
             if i.get("internal_api") == "openblas"],
    "numpy": [f for f in __cpu_dispatch__
              if ("512" in f or f == "X86_V4") and __cpu_features__.get(f)],
    "cv2": cv2.getCPUFeaturesLine(),
}))
"""
    env = {k: v for k, v in os.environ.items() if k not in CAP}
    out = subprocess.run(
        [sys.executable, "-c", code], capture_output=True, text=True, env=env, check=True
    )
    seen = json.loads(out.stdout.strip().splitlines()[-1])
    if seen["env"] is None:
        pytest.skip("not an x86-64 CPU with AVX2 and FMA: the libraries choose their kernels")
    assert seen["env"] == "Haswell"
    assert seen["blas"], "numpy loaded no OpenBLAS"
    assert {a.lower() for a in seen["blas"]} == {"haswell"}
    assert seen["numpy"] == [], f"numpy still dispatches {seen['numpy']}"
    cv2_avx512 = [f for f in seen["cv2"].split() if "AVX512" in f and not f.endswith("?")]
    assert cv2_avx512 == [], f"OpenCV still dispatches {cv2_avx512}"


def test_this_test_process_computes_as_the_commands_do() -> None:
    """tests/conftest.py imports foldbot before any test module imports numpy."""
    if "OPENBLAS_CORETYPE" not in os.environ:
        pytest.skip("not an x86-64 CPU with AVX2 and FMA: the libraries choose their kernels")
    from numpy._core._multiarray_umath import __cpu_features__

    assert not __cpu_features__.get("X86_V4", False)


def test_the_avx512_kernels_in_use_are_read_from_what_the_libraries_report() -> None:
    dispatch = ["X86_V3", "X86_V4", "AVX512_ICL", "AVX512_SPR"]  # numpy 2.4 on x86-64
    on = {"X86_V3": True, "X86_V4": True, "AVX512_ICL": True, "AVX512_SPR": False}
    assert numpy_avx512_dispatch(dispatch, on) == ["X86_V4", "AVX512_ICL"]
    capped = {**on, "X86_V4": False, "AVX512_ICL": False}
    assert numpy_avx512_dispatch(dispatch, capped) == []
    assert opencv_avx512_dispatch("SSE SSE2 *SSE4.1 *AVX2 *AVX512-SKX") == ["AVX512-SKX"]
    assert opencv_avx512_dispatch("SSE SSE2 *SSE4.1 *AVX2 *AVX512-SKX?") == []


class _OpenCV:
    """What late_libraries reads of a loaded cv2: its dispatch line."""

    def __init__(self, line: str) -> None:
        self.line = line

    def getCPUFeaturesLine(self) -> str:  # OpenCV's name
        return self.line


def test_a_library_loaded_before_the_cap_is_named_only_where_the_cap_is_foldbots() -> None:
    uncapped = {"cv2": _OpenCV("SSE *AVX2 *AVX512-SKX")}
    assert late_libraries(dict(CAP), uncapped) == ["OpenCV (AVX512-SKX)"]
    assert late_libraries(dict(CAP), {"cv2": _OpenCV("SSE *AVX2 *AVX512-SKX?")}) == []
    # No cap set (a CPU without AVX2, or off x86), or the user's own value: their choice.
    assert late_libraries({}, uncapped) == []
    assert late_libraries({"OPENCV_CPU_DISABLE": "AVX2"}, uncapped) == []
    message = late_warning(["OpenCV (AVX512-SKX)"])
    assert "after OpenCV (AVX512-SKX) had loaded" in message
    assert message.endswith("Import foldbot before numpy and cv2.")


IMPORT_ORDER = """
import json, sys, warnings
warnings.simplefilter("always")
with warnings.catch_warnings(record=True) as caught:
    for name in sys.argv[1:]:
        __import__(name)
from foldbot.simd import late_libraries
ours = [str(w.message) for w in caught if w.category is RuntimeWarning]
print(json.dumps({"late": late_libraries(), "warnings": ours}))
"""


@pytest.mark.parametrize(
    ("order", "late"), [(["foldbot", "numpy"], False), (["numpy", "foldbot"], True)]
)
def test_numpy_imported_before_foldbot_is_warned_about(order: list[str], late: bool) -> None:
    """numpy loaded first keeps its AVX-512 dispatch on a CPU that has it: `import foldbot` says
    so; imported after foldbot, it is capped and nothing is said."""
    env = {k: v for k, v in os.environ.items() if k not in CAP}
    out = subprocess.run(
        [sys.executable, "-c", IMPORT_ORDER, *order],
        capture_output=True, text=True, env=env, check=True,
    )  # fmt: skip
    seen = json.loads(out.stdout.strip().splitlines()[-1])
    if late and not seen["late"] and "avx512f" not in cpu_flags(Path("/proc/cpuinfo").read_text()):
        pytest.skip("no AVX-512 on this CPU: numpy has no AVX-512 kernels to keep")
    if not late:
        assert seen == {"late": [], "warnings": []}
        return
    assert seen["late"] and seen["late"][0].startswith("numpy (")
    assert len(seen["warnings"]) == 1
    assert seen["warnings"][0] == late_warning(seen["late"])
