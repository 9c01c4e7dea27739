"""MP4 video writer (imageio + imageio-ffmpeg, libx264, yuv420p) for episode camera views.

Frames whose width or height is not a multiple of 16 are padded with black on the right and
bottom (never resized), so every pixel the camera produced lands unchanged in the video.
"""

from __future__ import annotations

import contextlib
import math
from pathlib import Path
from types import TracebackType
from typing import Any

import numpy as np

from foldbot.errors import ConfigError, OutputError

MACRO_BLOCK = 16
"""Frame sizes are padded up to a multiple of this (H.264 macro block)."""


def pad_to_macro_block(frame: np.ndarray, block: int = MACRO_BLOCK) -> np.ndarray:
    """Pad an H×W×3 frame with black on the right/bottom to multiples of `block` (no resize)."""
    h, w = frame.shape[:2]
    ph, pw = (-h) % block, (-w) % block
    if ph == 0 and pw == 0:
        return frame
    return np.pad(frame, ((0, ph), (0, pw), (0, 0)), mode="constant")


class VideoWriter:
    """Stream RGB uint8 frames of a fixed size into an H.264 MP4 file at `fps` frames/s."""

    def __init__(self, path: str | Path, fps: float = 30.0, quality: float = 7.0) -> None:
        """Check the arguments; the ffmpeg process starts with the first frame (size known)."""
        self.path = Path(path)
        if self.path.suffix.lower() != ".mp4":
            raise ConfigError(f"video path {str(self.path)!r} must end in .mp4")
        try:
            fps_value = float(fps)
        except (TypeError, ValueError):
            raise ConfigError(f"fps = {fps!r} must be a finite number > 0") from None
        if not math.isfinite(fps_value) or fps_value <= 0:
            raise ConfigError(f"fps = {fps!r} must be a finite number > 0")
        if not 0.0 <= float(quality) <= 10.0:
            raise ConfigError(f"quality = {quality!r} must be in [0, 10] (imageio scale)")
        if not self.path.parent.is_dir():
            raise OutputError(
                f"cannot write video {str(self.path)!r}: folder {str(self.path.parent)!r} "
                "does not exist"
            )
        self.fps = fps_value
        self.quality = float(quality)
        self.frame_size: tuple[int, int] | None = None  # (H, W) of the frames as given
        self.frame_count = 0
        self._writer: Any = None
        self._closed = False

    def _check(self, frame: Any) -> np.ndarray:
        """Validate one frame: an H×W×3 uint8 array of the video's size."""
        if not isinstance(frame, np.ndarray) or frame.dtype != np.uint8:
            dtype = getattr(frame, "dtype", type(frame).__name__)
            raise ConfigError(f"video frame must be an H×W×3 uint8 numpy array, got {dtype}")
        if frame.ndim != 3 or frame.shape[2] != 3 or frame.shape[0] == 0 or frame.shape[1] == 0:
            raise ConfigError(f"video frame must be H×W×3 uint8 (RGB), got shape {frame.shape}")
        size = (int(frame.shape[0]), int(frame.shape[1]))
        if self.frame_size is not None and size != self.frame_size:
            raise ConfigError(
                f"video frame size {size[0]}×{size[1]} (H×W) differs from the first frame's "
                f"{self.frame_size[0]}×{self.frame_size[1]}; all frames must have one size"
            )
        return frame

    def add(self, frame: np.ndarray) -> None:
        """Append one RGB frame (H×W×3 uint8); the size is fixed by the first frame."""
        if self._closed:
            raise OutputError(f"video {str(self.path)!r} is already closed")
        frame = self._check(frame)
        if self._writer is None:
            import imageio.v2 as iio  # deferred: only video users pay for the ffmpeg plugin

            try:
                self._writer = iio.get_writer(
                    str(self.path),
                    format="FFMPEG",
                    mode="I",
                    fps=self.fps,
                    codec="libx264",
                    pixelformat="yuv420p",
                    quality=self.quality,
                    macro_block_size=1,  # we pad ourselves; imageio would resize instead
                    ffmpeg_log_level="error",
                )
            except OSError as exc:
                raise OutputError(f"cannot open video {str(self.path)!r}: {exc}") from exc
            self.frame_size = (int(frame.shape[0]), int(frame.shape[1]))
        try:
            self._writer.append_data(np.ascontiguousarray(pad_to_macro_block(frame)))
        except (OSError, BrokenPipeError) as exc:
            raise OutputError(f"cannot write video {str(self.path)!r}: {exc}") from exc
        self.frame_count += 1

    def close(self) -> None:
        """Finish the file (idempotent); a writer that got no frame leaves no file."""
        if self._closed:
            return
        self._closed = True
        if self._writer is not None:
            try:
                self._writer.close()
            except OSError as exc:
                raise OutputError(f"cannot finish video {str(self.path)!r}: {exc}") from exc

    def __enter__(self) -> VideoWriter:
        return self

    def __exit__(
        self,
        exc_type: type[BaseException] | None,
        exc: BaseException | None,
        tb: TracebackType | None,
    ) -> None:
        if exc_type is None:
            self.close()
        else:
            with contextlib.suppress(Exception):  # keep the original exception
                self.close()
