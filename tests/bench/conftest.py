"""Tiny suites for the benchmark tests: a 6 × 6-vertex towel folds in a few seconds."""

import pytest


def tiny_suite_dict(**axes) -> dict:
    """A one-episode suite (half fold, oracle, closed loop, seed 0) unless `axes` says otherwise."""
    return {
        "name": "tiny",
        "axes": {
            "garment": ["towel"],
            "recipe": ["half"],
            "perception": ["oracle"],
            "loop": ["closed"],
            "seeds": "0",
            **axes,
        },
        "towel": {"resolution": 6},
        "episode": {"video_fps": 0},
    }


@pytest.fixture
def tiny_suite_data():
    return tiny_suite_dict
