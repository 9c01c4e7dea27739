"""The errors foldbot raises on purpose: each names the bad value and what is allowed."""

from __future__ import annotations

from collections.abc import Callable
from typing import Any


class FoldbotError(Exception):
    """Base class of every error foldbot raises deliberately."""

    facts: dict[str, Any] | None = None
    """What the episode had measured before this error (result.json's entries so far, e.g. its
    "flatten" entry), kept in the benchmark's error record; None where nothing was."""


class ConfigError(FoldbotError, ValueError):
    """A configuration or argument value is out of its allowed range."""


class UnreachableTargetError(FoldbotError):
    """Inverse kinematics found no joint configuration for a target pose within tolerance."""

    segment: str | None = None
    """The motion segment that failed ('approach', 'descend', …), where the planner knows it."""


class ArmsWouldCollideError(FoldbotError):
    """Two arms' planned motions would bring them closer than their clearance."""

    segment: str | None = None
    """The motion segment in which they would meet, where the planner knows it."""


class OperatorStopped(FoldbotError):
    """The operator answered stop (or nothing: input closed) before a motion (foldbot.operator)."""


class SimulationDivergedError(FoldbotError):
    """The physics blew up (NaN or cloth vertices far outside the workspace); never scored."""

    segment: str | None = None
    """The motion segment the arm was running when it happened ('lift', 'lay', …), where known."""


class OutputError(FoldbotError):
    """An output folder cannot be created or written."""


class PerceptionError(FoldbotError, ValueError):
    """Perception cannot give what is asked of it: malformed input (wrong shapes, dtypes, empty
    images, bad intrinsics), or a garment whose keypoints it did not recognise."""


def failed_segment(error: BaseException) -> str | None:
    """The motion segment an infeasible-motion error (or the error it was raised from) names,
    or None: lets a caller tell a failure that a changed parameter cannot fix from one it can."""
    seen: BaseException | None = error
    while seen is not None:
        segment = getattr(seen, "segment", None)
        if segment is not None:
            return str(segment)
        seen = seen.__cause__
    return None


def add_facts(error: BaseException, **facts: Any) -> None:
    """Attach `facts` to a FoldbotError (beside any it carries; an entry already there is kept,
    being the nearer to the error); other exceptions, bugs, are left as they are."""
    if isinstance(error, FoldbotError):
        error.facts = {**facts, **(error.facts or {})}


def require(condition: bool, message: str) -> None:
    """Raise ConfigError with `message` unless `condition` holds."""
    if not condition:
        raise ConfigError(message)


def split_name_value(text: str, what: str, example: str, names: tuple[str, ...]) -> tuple[str, str]:
    """A command line's 'NAME=VALUE' → (name, raw value), both stripped; ConfigError naming `what`
    (e.g. "loop option"), an `example` and the allowed `names` when it is not of that form."""
    name, sep, raw = text.partition("=")
    name, raw = name.strip(), raw.strip()
    if not sep or not name or not raw:
        raise ConfigError(
            f"{what} {text!r} must look like NAME=VALUE, e.g. {example}; names: {', '.join(names)}"
        )
    return name, raw


def options_from_args(
    texts: list[str],
    parse: Callable[[str], tuple[str, Any]],
    flag: str,
    shown: Callable[[Any], str],
) -> dict[str, Any]:
    """Repeated `flag NAME=VALUE` words, each read by `parse` (→ name, checked value), as a
    dict in the order given; naming an option twice is a ConfigError showing both values."""
    options: dict[str, Any] = {}
    for text in texts:
        name, value = parse(text)
        if name in options:
            raise ConfigError(
                f"{flag} {name} is given twice ({shown(options[name])}, {shown(value)})"
            )
        options[name] = value
    return options


def option_word(raw: str, names: tuple[str, ...] = ()) -> bool | int | float | str | None:
    """A command line's VALUE word as a value: true/false, none, one of `names` (as given), an
    integer, or a number; ValueError when it is none of these (the caller names the option)."""
    low = raw.lower()
    if low in ("true", "false"):
        return low == "true"
    if low == "none":
        return None
    if low in names:
        return low
    try:
        return int(raw)
    except ValueError:
        return float(raw)


def reported_error(report: dict, what: str) -> FoldbotError:
    """The error another process reported (JSON: `error`, `error_type`) as the same foldbot error
    type (FoldbotError for any other name), its message prefixed with `what`, with the report's
    `notes` as the exception's notes, its `segment` (failed_segment) and its `facts` (what the
    episode measured before it) as the error's."""
    cls = globals().get(str(report.get("error_type", "")), FoldbotError)
    if not (isinstance(cls, type) and issubclass(cls, FoldbotError)):
        cls = FoldbotError
    error = cls(f"{what}: {report.get('error', 'failed')}")
    if report.get("segment") is not None:  # the motion segment it failed in, where one is named
        error.segment = str(report["segment"])
    for note in report.get("notes") or ():  # e.g. where the episode's video up to it went
        error.add_note(str(note))
    if isinstance(report.get("facts"), dict) and report["facts"]:
        error.facts = dict(report["facts"])
    return error
