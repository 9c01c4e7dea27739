"""Loaded by pytest before any test module: `import foldbot` caps numpy's, OpenBLAS's and OpenCV's
SIMD level before they load (foldbot.simd), so in-process tests compute as the commands do."""

import foldbot  # noqa: F401
