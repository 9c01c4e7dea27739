"""Summary maths on synthetic records: every figure checked against a hand computation."""

import numpy as np
import pytest

from foldbot.bench.suite import suite_from_dict
from foldbot.bench.summary import (
    clustered_success_interval,
    comparisons,
    failure_cause,
    group_stats,
    mean_interval,
    paired_difference,
    replicate_stats,
    success_interval,
    summarise,
    towel_of,
    verdict_stats,
)


def result(success, error_mm, perf, *, sim=10.0, wall=20.0, retries=(0, 0), grasps=(True, True)):
    return {
        "success": success,
        "fold_error_mm": error_mm,
        "normalized_performance": perf,
        "coverage": 0.5,
        "sim_seconds": sim,
        "wall_seconds": wall,
        "actions": [
            {"retries": r, "grasp_success": g} for r, g in zip(retries, grasps, strict=True)
        ],
    }


def test_group_stats_by_hand():
    records = [
        {"id": "a", "result": result(True, 5.0, 0.9, sim=10, wall=20)},
        {"id": "b", "result": result(True, 7.0, 0.85, sim=12, wall=20, retries=(1, 0))},
        {"id": "c", "result": result(False, 30.0, 0.5, sim=14, wall=40, grasps=(True, False))},
        {"id": "d", "result": result(False, 20.0, 0.82, sim=8, wall=10)},
        {"id": "e", "error_type": "SimulationDivergedError", "error": "cloth simulation diverged"},
        {"id": "f", "error_type": "Timeout", "error": "no result", "failed_dir": "f.failed"},
    ]
    s = group_stats(records[:-1])
    assert s["episodes"] == 5 and s["scored"] == 4 and s["successes"] == 2
    assert s["success_rate"] == pytest.approx(2 / 5)  # the diverged episode counts as a failure
    errs = [5.0, 7.0, 30.0, 20.0]
    assert s["fold_error_mm"]["mean"] == pytest.approx(np.mean(errs))
    assert s["fold_error_mm"]["median"] == pytest.approx(13.5)
    assert s["fold_error_mm"]["p95"] == pytest.approx(np.percentile(errs, 95))
    assert s["fold_error_mm"]["max"] == 30.0
    assert s["normalized_performance"]["mean"] == pytest.approx((0.9 + 0.85 + 0.5 + 0.82) / 4)
    assert s["coverage"]["mean"] == pytest.approx(0.5)
    assert s["actions_per_episode"] == 2.0
    assert s["retries_per_episode"] == pytest.approx(0.25)
    assert s["sim_seconds_per_fold"] == pytest.approx(11.0)
    assert s["wall_seconds_per_episode"] == pytest.approx(22.5)
    assert s["sim_speed"] == pytest.approx(44 / 90)
    # Per episode: 0.5, 0.6, 0.35 and 0.8 × real time, every one of them under 1×.
    assert s["episode_speed"]["min"] == pytest.approx(0.35)
    assert s["episode_speed"]["max"] == pytest.approx(0.8)
    assert s["episodes_under_real_time"] == 4
    fast = group_stats([{"id": "g", "result": result(True, 5.0, 0.9, sim=12, wall=10)}])
    assert fast["episodes_under_real_time"] == 0 and fast["episode_speed"]["min"] == 1.2
    assert s["failures"] == {"fold inaccurate": 1, "grasp failed": 1, "diverged": 1}
    assert s["failed_episodes"]["grasp failed"] == ["c"]
    # Where to look at each failure: the scored folder, else what the error left, else its record.
    assert s["failed_evidence"] == {
        "c": "episodes/c",
        "d": "episodes/d",
        "e": "episodes/e.error.json",
    }
    assert group_stats(records)["failed_evidence"]["f"] == "episodes/f.failed"


def test_success_interval_is_wilsons():
    # Wilson, z = 1.96: 11 of 20 → 0.342–0.742; it stays inside [0, 1] at 0 % and 100 %.
    lo, hi = success_interval(11, 20)
    assert (lo, hi) == pytest.approx((0.3421, 0.7418), abs=1e-4)
    lo, hi = success_interval(0, 20)
    assert lo == 0.0 and hi == pytest.approx(0.1611, abs=1e-4)
    lo, hi = success_interval(20, 20)
    assert lo == pytest.approx(0.8389, abs=1e-4) and hi == 1.0
    assert success_interval(0, 0) is None
    with pytest.raises(ValueError, match="successes = 3"):
        success_interval(3, 2)


def test_mean_interval_is_students_t():
    # 5, 7, 30, 20: mean 15.5, s = 11.73, t(0.975, 3) = 3.182 → ± 18.67.
    lo, hi = mean_interval([5.0, 7.0, 30.0, 20.0, None, float("nan")])
    assert (lo, hi) == pytest.approx((15.5 - 18.670, 15.5 + 18.670), abs=1e-3)
    assert mean_interval([4.0]) is None and mean_interval([]) is None
    assert mean_interval([3.0, 3.0]) == [3.0, 3.0]


def test_paired_difference_over_towels_scored_both_ways():
    a = [{"result": {"fold_error_mm": e}} for e in (10.0, 20.0, 30.0)] + [{"error": "x"}]
    b = [{"result": {"fold_error_mm": e}} for e in (12.0, 26.0)] + [{"error": "y"}] * 2
    d = paired_difference(a, b, "fold_error_mm")
    assert d["pairs"] == 2 and d["mean"] == pytest.approx(4.0)
    # Differences 2 and 6: s = 2.83, t(0.975, 1) = 12.71 → 4 ± 25.41.
    assert d["mean_ci95"] == pytest.approx([4.0 - 25.412, 4.0 + 25.412], abs=1e-2)
    assert paired_difference(a[3:], b[3:], "fold_error_mm") is None


def test_with_replicates_the_mean_interval_is_over_the_towels():
    # Towel 0 folded three times (5, 7, 9 mm), towel 1 three times (20, 22, 24): the interval is
    # over the two towel means, 7 and 22, not over six episodes.
    errors = {"s0000": (5.0, 7.0, 9.0), "s0001": (20.0, 22.0, 24.0)}
    records = [
        {"id": f"towel-half-vision-closed-{towel}{'' if k == 0 else f'-r{k}'}",
         "result": result(True, e, e / 100)}
        for towel, es in errors.items()
        for k, e in enumerate(es)
    ]  # fmt: skip
    s = group_stats(records)
    assert s["towels"] == 2 and s["episodes"] == 6
    assert s["fold_error_mm"]["mean"] == pytest.approx(14.5)
    assert s["fold_error_mm"]["mean_ci95"] == pytest.approx(mean_interval([7.0, 22.0]))
    # So is every other mean's: the normalized performance's, here a hundredth of the error.
    assert s["normalized_performance"]["mean_ci95"] == pytest.approx(mean_interval([0.07, 0.22]))
    assert towel_of("towel-half-vision-closed-s0001-r2") == "towel-half-vision-closed-s0001"
    assert towel_of("towel-half-vision-closed-crumpled-s0001") == (
        "towel-half-vision-closed-crumpled-s0001"
    )
    # Without replicates the interval is over the episodes, as before.
    plain = group_stats(records[::3])
    assert plain["towels"] == 2
    assert plain["fold_error_mm"]["mean_ci95"] == pytest.approx(mean_interval([5.0, 20.0]))


def test_flatten_figures_with_replicates_are_over_the_towels():
    # Two crumpled towels, each flattened three times: towel 0 in 1, 2, 3 actions to coverage
    # 0.90, 0.92, 0.94; towel 1 in 5, 6, 6 to 0.70, 0.80, 0.90 (flattened once). Every mean's
    # interval is over the two towel means, the success interval over the two towels.
    runs = {"s0000": ((1, 0.90), (2, 0.92), (3, 0.94)), "s0001": ((5, 0.70), (6, 0.80), (6, 0.90))}
    records = [
        {"id": f"towel-half-vision-closed-crumpled-{towel}{'' if k == 0 else f'-r{k}'}",
         "result": {**result(False, 20.0, 0.5),
                    "flatten": {"success": cov >= 0.9, "actions": n, "coverage_start": 0.4,
                                "coverage_end": cov}}}
        for towel, rs in runs.items()
        for k, (n, cov) in enumerate(rs)
    ]  # fmt: skip
    f = group_stats(records)["flatten"]
    assert f["episodes"] == 6 and f["successes"] == 4
    assert f["actions"]["mean"] == pytest.approx(23 / 6)
    assert f["actions"]["mean_ci95"] == pytest.approx(mean_interval([2.0, 17 / 3]))
    assert f["coverage_end"]["mean_ci95"] == pytest.approx(mean_interval([0.92, 0.80]))
    assert f["coverage_start"]["mean_ci95"] == pytest.approx([0.4, 0.4])  # no spread at all
    by_towel = [[True] * 3, [False, False, True]]
    assert f["success_ci95"] == pytest.approx(clustered_success_interval(by_towel))
    # Each towel flattened once: over the episodes, as before.
    once = group_stats(records[::3])["flatten"]
    assert once["actions"]["mean_ci95"] == pytest.approx(mean_interval([1.0, 5.0]))
    assert (f["errors"], f["errors_recorded"], f["errors_tangled_start"]) == (0, None, None)


def test_flatten_figures_count_what_episodes_ending_in_errors_kept():
    def crumpled(seed: int) -> str:
        return f"towel-half-vision-closed-crumpled-s{seed:04d}"

    flat = {"success": True, "actions": 1, "coverage_start": 0.4, "coverage_end": 0.95}
    records = [
        {"id": crumpled(0), "result": {**result(True, 5.0, 0.9), "flatten": flat}},
        # Diverged while flattening a cloth the crumple had passed through itself …
        {"id": crumpled(1), "error_type": "SimulationDivergedError", "error": "x",
         "facts": {"flatten": {"success": False, "actions": 3, "self_crossings_start": 12,
                               "ended_in_error": True}}},
        # … in the fold after flattening an untangled one …
        {"id": crumpled(2), "error_type": "SimulationDivergedError", "error": "x",
         "facts": {"flatten": {**flat, "self_crossings_start": 0, "self_crossings_end": 0}}},
        # … and a crumple that failed before any flattening (nothing kept).
        {"id": crumpled(3), "error_type": "FoldbotError", "error": "crumple left the table"},
    ]  # fmt: skip
    f = group_stats(records)["flatten"]
    assert (f["episodes"], f["successes"]) == (4, 1)  # an episode not scored is not counted
    assert (f["errors"], f["errors_recorded"], f["errors_tangled_start"]) == (3, 2, 1)
    assert f["errors_after_flattening"] == 1


def test_clustered_success_interval_counts_what_replicates_are_worth():
    # Each towel folded once: Wilson's interval over the episodes.
    assert clustered_success_interval([[True], [False], [True]]) == success_interval(2, 3)
    # Five towels folded three times, each either always or never succeeding: the replicates
    # add nothing, so the interval is over the five towels (deff held at n / towels = 3).
    always = [[True] * 3] * 3 + [[False] * 3] * 2
    assert clustered_success_interval(always) == pytest.approx(success_interval(3, 5))
    # Four towels each succeeding two times in three: the towels scatter no more than
    # independent episodes would (deff held at 1), so all twelve episodes count.
    mixed = [[True, True, False]] * 4
    assert clustered_success_interval(mixed) == pytest.approx(success_interval(8, 12))
    # In between, the interval lies between the two.
    some = [[True, True, True], [True, True, False], [False, False, False], [True, False, False]]
    lo, hi = clustered_success_interval(some)
    lo_ep, hi_ep = success_interval(6, 12)
    lo_t, hi_t = success_interval(2, 4)  # 50 % over four draws
    assert lo_t < lo < lo_ep and hi_ep < hi < hi_t
    # Nothing succeeded (or everything did): nothing measures the correlation; each towel once.
    assert clustered_success_interval([[False] * 3] * 20) == pytest.approx(success_interval(0, 20))
    assert clustered_success_interval([]) is None


def test_with_replicates_the_success_interval_is_over_the_towels():
    ids = [f"towel-half-vision-closed-s000{t}{'' if k == 0 else f'-r{k}'}" for t in range(4)
           for k in range(3)]  # fmt: skip
    records = [{"id": i, "result": result("s0000" in i or "s0001" in i, 5.0, 0.9)}
               for i in ids]  # fmt: skip
    s = group_stats(records)
    assert s["successes"] == 6 and s["episodes"] == 12 and s["towels"] == 4
    assert s["success_ci95"] == pytest.approx(success_interval(2, 4))


def test_with_replicates_the_paired_difference_is_over_the_towels():
    # Towel 0's three pairs differ by 1, 2, 3 mm; towel 1's by 10, 11, 12: the interval is over
    # the two towels' mean differences (2 and 11), the mean over the six pairs.
    ids = [f"towel-half-vision-closed-s000{t}{'' if k == 0 else f'-r{k}'}" for t in range(2)
           for k in range(3)]  # fmt: skip
    a = [{"id": i, "result": {"fold_error_mm": 10.0}} for i in ids]
    b = [{"id": i, "result": {"fold_error_mm": 10.0 + d}} for i, d in
         zip(ids, (1.0, 2.0, 3.0, 10.0, 11.0, 12.0), strict=True)]  # fmt: skip
    d = paired_difference(a, b, "fold_error_mm")
    assert d["pairs"] == 6 and d["mean"] == pytest.approx(6.5)
    assert d["mean_ci95"] == pytest.approx(mean_interval([2.0, 11.0]))


def test_replicate_stats_compare_the_spread_within_a_towel_with_that_between_towels():
    # Towel 0: 5, 7, 9 mm, all successes; towel 1: 20, 22 and a divergence, never; towel 2:
    # 8 and 12 mm, one success. Within: pooled over (3 − 1) + (2 − 1) + (2 − 1) = 4 degrees of
    # freedom, (8 + 2 + 8) / 4 = 4.5 → SD 2.121; the towels' means 7, 21, 10: SD 7.371.
    def rid(t, k):
        return f"towel-half-vision-closed-s000{t}{'' if k == 0 else f'-r{k}'}"

    records = [{"id": rid(0, k), "result": result(True, e, 0.9)} for k, e in enumerate((5, 7, 9))]
    records += [{"id": rid(1, k), "result": result(False, e, 0.9)} for k, e in enumerate((20, 22))]
    records += [{"id": rid(1, 2), "error_type": "SimulationDivergedError", "error": "diverged"}]
    records += [{"id": rid(2, 0), "result": result(True, 8.0, 0.9)}]
    records += [{"id": rid(2, 1), "result": result(False, 12.0, 0.9)}]
    r = replicate_stats(records)
    assert (r["towels"], r["folds_per_towel"]) == (3, 3)
    assert (r["towels_always_succeeding"], r["towels_never_succeeding"]) == (1, 1)
    assert r["fold_error_mm_sd_within_towel"] == pytest.approx(4.5**0.5)
    assert r["fold_error_mm_sd_of_towel_means"] == pytest.approx(np.std([7, 21, 10], ddof=1))
    assert group_stats(records)["replicates"] == r
    # Every towel folded once: nothing to say.
    assert replicate_stats(records[::3]) is None
    assert group_stats(records[::3])["replicates"] is None


def test_group_stats_gives_the_intervals():
    records = [{"id": str(i), "result": result(i < 3, 10.0 + i, 0.9)} for i in range(5)]
    s = group_stats(records)
    assert s["success_ci95"] == success_interval(3, 5)
    assert s["fold_error_mm"]["mean_ci95"] == mean_interval([10.0, 11.0, 12.0, 13.0, 14.0])


def test_group_stats_perfect_fold_error_over_records_that_have_it():
    old = result(False, 30.0, 0.5)  # written before result.json had perfect_fold_error_mm
    records = [
        {"id": "a", "result": {**result(False, 40.0, 0.5), "perfect_fold_error_mm": 20.0}},
        {"id": "b", "result": {**result(False, 50.0, 0.5), "perfect_fold_error_mm": 22.0}},
        {"id": "c", "result": old},
    ]
    perfect = group_stats(records)["perfect_fold_error_mm"]
    assert perfect["mean"] == pytest.approx(21.0) and perfect["max"] == 22.0
    assert group_stats([{"id": "c", "result": old}])["perfect_fold_error_mm"] is None


def test_group_stats_count_the_folds_through_themselves_over_records_that_have_it():
    records = [
        {"id": "a", "result": {**result(True, 10.0, 0.9), "self_crossings": 12}},
        {"id": "b", "result": {**result(False, 40.0, 0.7), "self_crossings": 3}},
        {"id": "c", "result": {**result(True, 10.0, 0.9), "self_crossings": 0}},
        {"id": "d", "result": result(True, 10.0, 0.9)},  # written before result.json had it
        {"id": "e", "error_type": "SimulationDivergedError", "error": "diverged"},
    ]
    stats = group_stats(records)
    assert stats["through_itself"] == {"recorded": 3, "folds": 2, "successes": 1}
    assert group_stats(records[3:])["through_itself"] is None


def test_first_frame_keypoint_errors_are_pooled_with_the_worst_keypoint_named():
    def seen(**errors):
        return {**result(False, 40.0, 0.5), "first_frame_keypoint_error_mm": errors}

    records = [
        {"id": "a", "result": seen(left_waist=38.0, right_waist=1.0, crotch=2.0)},
        {"id": "b", "result": seen(left_waist=2.0, right_waist=1.0, crotch=4.0)},
        {"id": "c", "result": {**result(False, 40.0, 0.5), "first_frame_keypoint_error_mm": None}},
        {"id": "d", "error": "diverged", "error_type": "SimulationDivergedError"},
    ]
    first = group_stats(records)["first_frame_keypoints"]
    assert first["episodes"] == 2 and first["episodes_off"] == 1  # a: 38 mm > 10 mm
    assert first["error_mm"]["median"] == pytest.approx(2.0) and first["error_mm"]["max"] == 38.0
    assert first["worst"] == {"name": "left_waist", "mean_mm": 20.0, "max_mm": 38.0}
    # Crumpled starts and results written before the figure have none.
    assert group_stats(records[2:])["first_frame_keypoints"] is None


def test_empty_and_all_failed_groups():
    assert group_stats([])["success_rate"] is None
    s = group_stats([{"id": "x", "error_type": "Crashed", "error": "died"}])
    assert s["success_rate"] == 0 and s["fold_error_mm"] is None and s["sim_speed"] is None
    assert s["failures"] == {"crashed": 1}


@pytest.mark.parametrize(
    ("record", "cause"),
    [
        ({"result": result(True, 5, 0.9)}, None),
        ({"result": result(False, 40, 0.5)}, "fold inaccurate"),
        ({"result": result(False, 40, 0.5, grasps=(False, True))}, "grasp failed"),
        ({"error_type": "SimulationDivergedError", "error": "x"}, "diverged"),
        ({"error_type": "UnreachableTargetError", "error": "x"}, "unreachable"),
        (
            {"error_type": "FoldbotError", "error": "no cloth found before fold stage 1"},
            "no cloth found",
        ),
        (
            {"error_type": "FoldbotError", "error": "the cloth extends beyond the camera's view"},
            "cloth out of view",
        ),
        ({"error_type": "ConfigError", "error": "degenerate corner quad: …"}, "planning failed"),
        ({"error_type": "PerceptionError", "error": "x"}, "perception failed"),
        ({"error_type": "Timeout", "error": "x"}, "timeout"),
        ({"error_type": "Crashed", "error": "x"}, "crashed"),
        ({"error_type": "OutputError", "error": "x"}, "other error (OutputError)"),
    ],
)
def test_failure_causes(record, cause):
    assert failure_cause({"id": "x", **record}) == cause


def test_comparisons_pair_each_replicate_with_its_own(tiny_suite_data):
    suite = suite_from_dict(
        tiny_suite_data(perception=["vision", "oracle"], seeds="0", replicates=2)
    )
    errors = {("vision", 0): 10.0, ("vision", 1): 30.0, ("oracle", 0): 11.0, ("oracle", 1): 33.0}
    records = [
        {"id": e.id, "result": result(True, errors[(e.perception, e.replicate)], 0.9)}
        for e in suite.episodes
    ]
    (row,) = [c for c in comparisons(suite, records) if c["recipe"] == "half"]
    assert row["paired_episodes"] == 2
    # Oracle minus vision, replicate by replicate: +1 and +3 (not crossed: +23 and −19).
    assert row["fold_error_mm_paired_difference"]["mean"] == pytest.approx(2.0)


def test_groups_and_paired_comparisons(tiny_suite_data):
    suite = suite_from_dict(
        tiny_suite_data(perception=["vision", "oracle"], loop=["closed", "open"], seeds="0-1")
    )
    errors = {"vision-closed": 8.0, "oracle-closed": 6.0, "vision-open": 30.0, "oracle-open": 28.0}
    records = []
    for e in suite.episodes:
        err = errors[f"{e.perception}-{e.loop}"] + e.seed
        if e.id == "towel-half-oracle-open-s0001":
            continue  # unfinished: its vision partner must drop out of the pairing too
        records.append({"id": e.id, "result": result(err < 15, err, 0.9 if err < 15 else 0.5)})
    s = summarise(suite, records)
    assert not s["complete"] and s["episodes_finished"] == 7 and s["episodes_planned"] == 8
    assert [(g["perception"], g["loop"], g["episodes"]) for g in s["groups"]] == [
        ("vision", "closed", 2),
        ("vision", "open", 2),
        ("oracle", "closed", 2),
        ("oracle", "open", 1),
    ]
    rows = {(c["axis"], c.get("loop"), c.get("perception")): c for c in comparisons(suite, records)}
    vo_closed = rows[("perception", "closed", None)]
    assert vo_closed["paired_episodes"] == 2
    assert vo_closed["fold_error_mm_median"] == [pytest.approx(8.5), pytest.approx(6.5)]
    vo_open = rows[("perception", "open", None)]
    assert vo_open["paired_episodes"] == 1  # seed 1 has no oracle-open episode
    assert vo_open["fold_error_mm_mean"] == [30.0, 28.0]
    co_vision = rows[("loop", None, "vision")]
    assert co_vision["success_rate"] == [1.0, 0.0]
    assert s["overall"]["episodes"] == 7


def test_the_loops_verdict_is_set_against_success():
    def judged(success, *ious):
        stages = [{"mask_iou_vs_predicted": v, "verified": v >= 0.8} for v in ious]
        return {"success": success, "stages": stages}

    results = [
        judged(True, 0.95, 0.9),  # verified, succeeded
        judged(True, 0.9, 0.7),  # not verified (its second stage), succeeded
        judged(False, 0.85),  # verified, failed: a real cell would call it done
        judged(False, 0.5),  # not verified, failed
        judged(False, 0.4),
        {"success": False, "stages": [{"verified": None}]},  # open loop: not judged
        {"success": True, "stages": []},  # no stage: not judged
    ]
    v = verdict_stats(results)
    assert v["judged"] == 5
    assert (v["verified_succeeded"], v["verified_failed"]) == (1, 1)
    assert (v["unverified_succeeded"], v["unverified_failed"]) == (1, 2)
    assert v["agreement"] == pytest.approx(3 / 5)
    assert v["lowest_iou_successes"]["min"] == pytest.approx(0.7)
    assert v["lowest_iou_failures"]["median"] == pytest.approx(0.5)
    assert verdict_stats(results[-2:]) is None
