"""Tests for foldbot.io.video: padding, validation and read-back through imageio."""

from __future__ import annotations

from pathlib import Path

import imageio.v2 as iio
import numpy as np
import pytest

from foldbot.errors import ConfigError, OutputError
from foldbot.io.video import VideoWriter, pad_to_macro_block


def frames(n: int, h: int = 60, w: int = 100) -> list[np.ndarray]:
    """`n` frames of a flat colour that changes per frame."""
    return [np.full((h, w, 3), (20 * i % 256, 128, 255 - 20 * i % 256), np.uint8) for i in range(n)]


def test_video_reads_back_with_frame_count_and_padding(tmp_path: Path) -> None:
    path = tmp_path / "v.mp4"
    with VideoWriter(path, fps=10) as video:
        for f in frames(12):
            video.add(f)
    assert video.frame_count == 12
    reader = iio.get_reader(path, format="FFMPEG")
    try:
        assert reader.count_frames() == 12
        first = reader.get_data(0)
        meta = reader.get_meta_data()
    finally:
        reader.close()
    assert first.shape == (64, 112, 3)  # padded to multiples of 16, not resized
    assert meta["fps"] == pytest.approx(10)
    np.testing.assert_allclose(first[:60, :100].mean(axis=(0, 1)), [0, 128, 255], atol=6)
    assert first[62:, 104:].max() < 20  # the padding is black


def test_pad_keeps_aligned_frames() -> None:
    f = np.zeros((32, 48, 3), np.uint8)
    assert pad_to_macro_block(f) is f
    assert pad_to_macro_block(np.zeros((33, 47, 3), np.uint8)).shape == (48, 48, 3)


@pytest.mark.parametrize(
    "bad",
    [
        np.zeros((16, 16, 3), np.float32),
        np.zeros((16, 16), np.uint8),
        np.zeros((16, 16, 4), np.uint8),
    ],
)
def test_rejects_bad_frames(tmp_path: Path, bad: np.ndarray) -> None:
    video = VideoWriter(tmp_path / "bad.mp4")
    with pytest.raises(ConfigError, match="H×W×3 uint8"):
        video.add(bad)
    video.close()
    assert not (tmp_path / "bad.mp4").exists()


def test_rejects_size_change(tmp_path: Path) -> None:
    with VideoWriter(tmp_path / "s.mp4") as video:
        video.add(frames(1)[0])
        with pytest.raises(ConfigError, match="differs from the first frame"):
            video.add(frames(1, h=64, w=64)[0])


def test_bad_path_and_fps(tmp_path: Path) -> None:
    with pytest.raises(ConfigError, match=r"\.mp4"):
        VideoWriter(tmp_path / "v.avi")
    with pytest.raises(ConfigError, match="fps"):
        VideoWriter(tmp_path / "v.mp4", fps=0)
    with pytest.raises(OutputError, match="does not exist"):
        VideoWriter(tmp_path / "missing" / "v.mp4")
