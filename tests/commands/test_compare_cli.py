"""`foldbot compare`: Markdown or JSON on stdout; a clear one-line error for a folder that is
not a run."""

import json

from foldbot.cli import main


def test_compare_prints_markdown_and_json(tmp_path, capsys, write_run):
    a = write_run(tmp_path / "a", {"towel-half-vision-closed-s0000": ("half", 0, 8.0)})
    b = write_run(tmp_path / "b", {"towel-half-vision-closed-s0000": ("half", 0, 12.0)})
    assert main(["compare", str(a), str(b)]) == 0
    out = capsys.readouterr().out
    assert f"# `{b}` against `{a}`" in out
    assert "| towel-half-vision-closed-s0000 | 8.0 → 12.0 | success → fold inaccurate |" in out
    assert main(["compare", str(a), str(b), "--json"]) == 0
    assert json.loads(capsys.readouterr().out)["overall"]["difference_mm"]["mean"] == 4.0


def test_a_folder_that_is_not_a_run_gets_one_line(tmp_path, capsys):
    assert main(["compare", str(tmp_path), str(tmp_path)]) == 2
    err = capsys.readouterr().err
    assert "foldbot compare: error:" in err and "is not a benchmark run folder" in err
    assert "Traceback" not in err
