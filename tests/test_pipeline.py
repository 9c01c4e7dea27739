import json

import numpy as np
import pytest
from scipy.spatial import cKDTree

from foldbot.errors import ConfigError
from foldbot.io.episode import REQUIRED_RESULT_KEYS, load_episode, rescore
from foldbot.metrics import fold_goal
from foldbot.pipeline import EpisodeConfig, run_episode


@pytest.fixture(scope="module")
def half_fold_episode(tmp_path_factory):
    """One half fold of the 30 cm, 16×16 towel with the UR5 (the README's headline case)."""
    out = tmp_path_factory.mktemp("episodes") / "half"
    result = run_episode(EpisodeConfig(seed=0, video_fps=2.0), out, log=lambda *_: None)
    return out, result


@pytest.mark.slow
def test_half_fold_meets_target(half_fold_episode):
    _out, result = half_fold_episode
    assert result["normalized_performance"] >= 0.85
    assert result["fold_error_mm"] <= 10.0
    assert result["success"] is True
    assert all(a["grasp_success"] for a in result["actions"])


@pytest.mark.slow
def test_folded_layers_stay_apart_and_above_the_table(half_fold_episode):
    out, result = half_fold_episode
    episode = load_episode(out)
    _goal, layers = fold_goal(episode.initial, result["fold_lines"], episode.thickness)
    final, top = episode.final, layers > 0
    table = EpisodeConfig().sim.layout.table_height
    assert final[:, 2].min() > table - 0.001, "no vertex passes through the table"
    # Each vertex of the folded-over layer lies above the lower-layer vertex beneath it.
    dist, idx = cKDTree(final[~top, :2]).query(final[top, :2])
    beneath = dist < 0.015
    gap = final[top][beneath, 2] - final[~top][idx[beneath], 2]
    assert beneath.sum() > 0.8 * top.sum()
    assert (gap > 0).mean() >= 0.99, f"layers interpenetrate: min gap {gap.min() * 1000:.1f} mm"


@pytest.mark.slow
def test_episode_folder_follows_the_contract(half_fold_episode):
    out, _result = half_fold_episode
    assert {p.name for p in out.iterdir()} >= {"result.json", "cloth.npz", "video.mp4"}
    stored = json.loads((out / "result.json").read_text())
    assert set(REQUIRED_RESULT_KEYS) <= stored.keys()
    assert stored["grasp_points_source"] == "oracle"
    episode = load_episode(out)
    assert episode.faces.shape[1] == 3 and episode.initial.shape == episode.final.shape
    # Every metric can be recomputed from cloth.npz and fold_lines alone.
    again = rescore(out)
    assert again.fold_error_mm == pytest.approx(stored["fold_error_mm"])
    assert again.normalized_performance == pytest.approx(stored["normalized_performance"])
    # The flat start is flat, the final state folded (half the area covered).
    assert np.ptp(episode.initial[:, 2]) < 0.003
    assert 0.4 < stored["coverage"] < 0.6
    for action in stored["actions"]:
        assert {
            "kind",
            "grasp",
            "place",
            "grasp_success",
            "retries",
            "sim_seconds",
        } <= action.keys()


@pytest.mark.parametrize(
    ("kwargs", "needle"),
    [
        ({"garment": "sock"}, "garment"),
        ({"robot": "kuka"}, "robot"),
        ({"recipe": "origami"}, "recipe"),
        ({"perception": "psychic"}, "perception"),
        ({"seed": -1}, "seed"),
    ],
)
def test_bad_episode_config(kwargs, needle):
    with pytest.raises(ConfigError, match=needle):
        EpisodeConfig(**kwargs)
