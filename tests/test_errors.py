"""Errors reported by another process (a ROS node) come back as the same foldbot error type."""

import pytest

from foldbot import errors


@pytest.mark.parametrize(
    ("name", "cls"),
    [
        ("PerceptionError", errors.PerceptionError),
        ("SimulationDivergedError", errors.SimulationDivergedError),
        ("KeyError", errors.FoldbotError),  # not a foldbot error: the base type
        ("reported_error", errors.FoldbotError),  # not a class at all
        ("", errors.FoldbotError),
    ],
)
def test_reported_error_keeps_its_type_and_says_where(name, cls):
    exc = errors.reported_error({"error": "no cloth", "error_type": name}, "over ROS")
    assert type(exc) is cls and str(exc) == "over ROS: no cloth"
    assert not hasattr(exc, "__notes__")  # a report without notes adds none


def test_reported_error_keeps_the_reports_notes():
    report = {"error": "diverged", "error_type": "SimulationDivergedError", "notes": ["see x"]}
    exc = errors.reported_error(report, "over ROS")
    assert exc.__notes__ == ["see x"]


def test_reported_error_keeps_the_reports_facts():
    """A task node's failure carries how far the episode got (over ROS as in process)."""
    report = {"error": "diverged", "error_type": "SimulationDivergedError"}
    assert errors.reported_error(report, "over ROS").facts is None
    facts = {"flatten": {"actions": 3, "ended_in_error": True}}
    exc = errors.reported_error({**report, "facts": facts}, "over ROS")
    assert isinstance(exc, errors.SimulationDivergedError) and exc.facts == facts


def test_reported_error_keeps_the_segment_it_failed_in():
    # The planner node names the motion segment an infeasible pair failed in; the task node's
    # flattening reads it (failed_segment) to skip hang margins that cannot help.
    report = {"error": "no IK", "error_type": "UnreachableTargetError", "segment": "approach"}
    exc = errors.reported_error(report, "planning together")
    assert type(exc) is errors.UnreachableTargetError
    assert errors.failed_segment(exc) == "approach"
    unnamed = errors.reported_error({**report, "segment": None}, "planning together")
    assert errors.failed_segment(unnamed) is None


def test_failed_segment_is_found_through_the_errors_raised_from():
    inner = errors.UnreachableTargetError("segment 'approach': no IK")
    inner.segment = "approach"
    try:
        try:
            raise inner
        except errors.UnreachableTargetError as exc:
            raise errors.UnreachableTargetError(f"actions infeasible: {exc}") from exc
    except errors.UnreachableTargetError as outer:
        assert errors.failed_segment(outer) == "approach"
    assert errors.failed_segment(errors.UnreachableTargetError("no segment named")) is None
    assert errors.failed_segment(ValueError("other")) is None


def test_facts_attach_to_a_foldbot_error_and_the_nearer_entry_is_kept():
    exc = errors.SimulationDivergedError("diverged")
    assert exc.facts is None
    errors.add_facts(exc, flatten={"actions": 2})
    errors.add_facts(exc, flatten={"actions": 5}, crumple={"crossings": 3})
    # The entry attached first, nearer the error, wins; a new entry is added beside it.
    assert exc.facts == {"flatten": {"actions": 2}, "crumple": {"crossings": 3}}
    assert errors.FoldbotError("other").facts is None  # not shared between errors


def test_facts_leave_other_exceptions_alone():
    exc = KeyError("a bug")
    errors.add_facts(exc, flatten={"actions": 2})
    assert not hasattr(exc, "facts")


def test_an_option_word_reads_as_its_value():
    words = ("true", "FALSE", "none", "top", "3", "0.25", "1e-3")
    assert [errors.option_word(w, ("all", "top")) for w in words] == [
        True, False, None, "top", 3, 0.25, 0.001,
    ]  # fmt: skip
    with pytest.raises(ValueError):  # a name is a value only where the option allows it
        errors.option_word("top")
    with pytest.raises(ValueError):
        errors.option_word("3 cm")
