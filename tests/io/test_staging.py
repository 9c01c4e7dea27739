"""An output folder written whole or not at all: staged beside it, moved into place complete."""

import pytest

from foldbot.errors import OutputError
from foldbot.io.staging import commit_output, prepare_output


def test_a_staged_folder_appears_only_when_committed(tmp_path):
    out = tmp_path / "runs" / "cal"
    stage = prepare_output(out)
    assert stage.parent == out.parent and stage.name.startswith(".cal.tmp-")
    (stage / "a.json").write_text("{}")
    assert not out.exists()
    commit_output(stage, out)
    assert (out / "a.json").read_text() == "{}" and not stage.exists()
    # Into a folder that exists: its other files stay, the staged ones replace theirs.
    (out / "keep.txt").write_text("x")
    stage = prepare_output(out)
    (stage / "a.json").write_text("[]")
    commit_output(stage, out)
    assert (out / "a.json").read_text() == "[]" and (out / "keep.txt").exists()


def test_a_file_in_the_way_is_named(tmp_path):
    (tmp_path / "cal").write_text("")
    with pytest.raises(OutputError, match="exists and is not a folder"):
        prepare_output(tmp_path / "cal")
