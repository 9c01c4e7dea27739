"""The loop's own verdict on a fold, from what its camera saw: all a real cell has to go by.

A closed-loop stage is verified when the cloth's perceived mask matches the outline the stage's
plan predicted (IoU ≥ the loop's `verify_iou`); a fold is verified when every stage was. The
benchmark sets this verdict beside metrics.md's success (ground truth) to measure how far a cell
without ground truth can trust it (bench.summary.verdict_stats).
"""

from __future__ import annotations

from collections.abc import Sequence


def perceived_verdict(stages: Sequence[dict]) -> bool | None:
    """True when every stage recorded (result.json's `stages`) was verified, False when one was
    not; None when no stage was checked (the open loop records `verified: null`, a flattening
    that ended the episode records no stage)."""
    checked = [s.get("verified") for s in stages]
    if not checked or any(v is None for v in checked):
        return None
    return all(bool(v) for v in checked)


def lowest_stage_iou(stages: Sequence[dict]) -> float | None:
    """The lowest stage's mask IoU with its predicted outline: the fold is verified when this
    reaches `verify_iou`. None where no stage recorded one."""
    ious = [
        s["mask_iou_vs_predicted"] for s in stages if s.get("mask_iou_vs_predicted") is not None
    ]
    return float(min(ious)) if ious else None


def unscored_outcome(perceived: dict) -> str:
    """One line on a fold no ground truth scores (result.json's `perceived`, a real cell's):
    the flattening's perceived coverage where there was one, each stage's mask IoU with its
    predicted outline, and how the cloth's top view shrank."""
    flat = perceived.get("flatten")
    flattened = (
        ""
        if flat is None
        else f"flattened in {flat['actions']} actions, perceived coverage "
        f"{flat['perceived_coverage_start']:.2f} → {flat['perceived_coverage_end']:.2f}"
        f"{'' if flat['reached_target'] else ' (target NOT reached)'}; "
    )
    ious = ", ".join(f"{v:.2f}" for v in perceived["stage_mask_iou"])
    ratio = perceived["coverage_ratio"]
    area = "" if ratio is None else f", the cloth's top view {ratio:.2f} of its start"
    return (
        f"fold done on a real cell, not scored (no ground truth); perceived: {flattened}"
        f"{'every stage verified' if perceived['verified'] else 'NOT every stage verified'} "
        f"(mask IoU with the predicted outline {ious}){area}"
    )
