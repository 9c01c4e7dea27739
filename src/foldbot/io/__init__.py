"""Episode folders (result.json, cloth.npz, video.mp4, overlays) and video writing."""

from foldbot.io.episode import (
    REQUIRED_RESULT_KEYS,
    Episode,
    EpisodeWriter,
    is_episode_dir,
    is_unscored_episode_dir,
    load_episode,
    rescore,
)
from foldbot.io.video import VideoWriter

__all__ = [
    "REQUIRED_RESULT_KEYS",
    "Episode",
    "EpisodeWriter",
    "VideoWriter",
    "is_episode_dir",
    "is_unscored_episode_dir",
    "load_episode",
    "rescore",
]
