"""The loop's own verdict on a fold from its recorded stages."""

from foldbot.verdict import lowest_stage_iou, perceived_verdict


def stage(iou, verified):
    return {"stage": 0, "mask_iou_vs_predicted": iou, "verified": verified}


def test_a_fold_is_verified_only_when_every_stage_was():
    assert perceived_verdict([stage(0.9, True), stage(0.85, True)]) is True
    assert perceived_verdict([stage(0.9, True), stage(0.6, False)]) is False


def test_no_verdict_where_no_stage_was_checked():
    assert perceived_verdict([]) is None  # a flattening that ended the episode
    assert perceived_verdict([{"stage": 0, "verified": None}]) is None  # the open loop


def test_the_lowest_stage_iou_decides():
    assert lowest_stage_iou([stage(0.9, True), stage(0.6, False)]) == 0.6
    assert lowest_stage_iou([{"stage": 0, "verified": None}]) is None
