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
