"""`python -m foldbot.envs.evaluate`: a baseline policy over seeds, its table and JSON."""

import json

import numpy as np

from foldbot.envs.evaluate import main, read_episode, summary, table
from foldbot.envs.towel_fold import TowelFoldConfig, fold_episode_config
from foldbot.metrics import fold_error_limit_mm
from foldbot.pipeline import seeded_towel


def test_a_policy_over_seeds_writes_its_rows(tmp_path, capsys):
    out = tmp_path / "random.json"
    assert main(["--policy", "random", "--seeds", "0", "--resolution", "5", "--out", str(out)]) == 0
    result = json.loads(out.read_text())
    assert result["policy"] == "random" and result["episodes"] == 1
    (row,) = result["rows"]
    assert row["seed"] == 0 and row["suite_seed"] == 0
    # Random picks rarely find cloth: the episode runs its 6 steps unless it is flattened.
    assert row["steps"] == len(row["coverage"]) and 1 <= row["steps"] <= 6
    assert row["success"] == (row["coverage"][-1] >= 0.9)
    printed = capsys.readouterr().out
    assert "| seed | start |" in printed and "random: flattened" in printed


def test_the_summary_counts_flattened_towels_with_their_interval():
    rows = [
        {
            "seed": 0,
            "suite_seed": 0,
            "coverage_start": 0.5,
            "coverage": [0.7, 0.95],
            "grasps_held": 2,
            "steps": 2,
            "diverged": None,
            "success": True,
        },
        {
            "seed": 1,
            "suite_seed": 9,
            "coverage_start": 0.4,
            "coverage": [0.5],
            "grasps_held": 0,
            "steps": 2,
            "diverged": "cloth simulation diverged",
            "success": False,
        },
    ]
    s = summary(rows)
    assert s["flattened"] == 1 and s["episodes"] == 2 and s["diverged"] == 1
    lo, hi = s["interval_95"]
    assert lo < 0.5 < hi
    text = table(rows)
    assert "| 0 | 0.50 | 0.70 → 0.95 | 2 of 2 | yes |" in text
    assert "| 1 (ran 9) | 0.40 | 0.50 → diverged | 0 of 2 | no |" in text


def test_bad_arguments_are_refused(capsys):
    assert main(["--seeds", "0", "--suite", "towel_crumpled_two_arms"]) == 2
    assert "has 2 arms" in capsys.readouterr().err
    assert main(["--seeds", "0", "--workers", "0"]) == 2
    assert "--workers must be ≥ 1, got 0" in capsys.readouterr().err


def test_recorded_episodes_hold_their_transitions_and_are_not_run_again(tmp_path, capsys):
    args = ["--policy", "pulls", "--seeds", "0", "--resolution", "5", "--record", str(tmp_path)]
    assert main(args) == 0
    (path,) = tmp_path.glob("*.npz")
    assert path.name == "towel_flatten-s0000.npz"
    assert not list(tmp_path.glob(".*"))  # nothing half-written left beside it
    ep = read_episode(path)
    t = len(ep["action"])
    assert 1 <= t <= 6
    assert ep["rgb"].shape == (t + 1, 120, 160, 3) and ep["rgb"].dtype == np.uint8
    assert ep["depth"].shape == (t + 1, 120, 160) and ep["coverage"].shape == (t + 1,)
    assert ep["action"].shape == (t, 4) and np.all(np.abs(ep["action"]) <= 1.0)
    np.testing.assert_allclose(ep["reward"], np.diff(ep["coverage"]), atol=1e-6)
    assert ep["terminated"][-1] or ep["truncated"][-1]
    assert not (ep["terminated"][:-1] | ep["truncated"][:-1]).any()
    assert int(ep["seed"]) == 0 and str(ep["policy"]) == "pulls"
    assert str(ep["suite"]) == "towel_crumpled" and str(ep["env"]) == "flatten"
    assert not bool(ep["stopped"])
    capsys.readouterr()
    stamp = path.stat().st_mtime_ns
    assert main(args) == 0
    assert "1 seeds already recorded" in capsys.readouterr().out
    assert path.stat().st_mtime_ns == stamp


def test_the_recipe_policy_on_towelfold_records_its_fold_errors(tmp_path, capsys):
    out = tmp_path / "fold.json"
    args = ["--env", "fold", "--seeds", "1", "--resolution", "5", "--out", str(out)]
    assert main([*args, "--record", str(tmp_path / "rec")]) == 0
    result = json.loads(out.read_text())
    assert result["policy"] == "recipe" and result["recipe"] == "half"
    assert result["episodes"] == 1 and "folded" in result and "flattened" not in result
    (row,) = result["rows"]
    assert row["steps"] == 2 == len(row["fold_error_mm"])
    assert row["fold_error_mm"][-1] < 0.4 * row["fold_error_mm_start"]
    printed = capsys.readouterr().out
    assert "| seed | start | fold error (mm) after each step |" in printed
    # A fold counted folded kept within the success rule's fold error bound (metrics.success).
    towel = seeded_towel(fold_episode_config(TowelFoldConfig(resolution=5), 1))
    limit = fold_error_limit_mm(towel.width * towel.height)
    assert not row["success"] or row["fold_error_mm"][-1] <= limit
    # The count printed is the record's: towels whose fold met the success rule.
    assert result["folded"] == sum(r["success"] for r in result["rows"]) == int(row["success"])
    assert f"recipe: folded {result['folded']} of {result['episodes']} (" in printed
    ep = read_episode(tmp_path / "rec" / "towel_fold-s0001.npz")
    assert ep["fold_error_mm"].shape == ep["coverage"].shape == (3,)
    np.testing.assert_allclose(ep["reward"], -np.diff(ep["fold_error_mm"]) / 1000, atol=1e-6)
    assert str(ep["env"]) == "fold" and str(ep["suite"]) == "towel_loop"


def test_a_recipe_is_towelfolds_alone(capsys):
    assert main(["--seeds", "0", "--recipe", "quarter"]) == 2
    err = capsys.readouterr().err
    assert "--recipe is TowelFold's (--env fold or fold_pair), not --env flatten's" in err
    assert main(["--env", "fold", "--policy", "pulls", "--seeds", "0"]) == 2
    assert "policy 'pulls' drives flatten, not --env fold" in capsys.readouterr().err


def test_the_recipe_policy_drives_towelfoldpair_and_its_pairs_are_recorded(tmp_path, capsys):
    args = ["--env", "fold_pair", "--seeds", "1", "--resolution", "5", "--record", str(tmp_path)]
    assert main(args) == 0
    assert "recipe: folded" in capsys.readouterr().out
    ep = read_episode(tmp_path / "towel_fold_pair-s0001.npz")
    assert ep["action"].shape == (1, 8)  # both corners of the half fold in one step
    assert str(ep["suite"]) == "towel_two_arms"
