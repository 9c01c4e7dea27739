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


def test_plot_draws_every_pair_and_refuses_what_it_cannot_write(tmp_path, capsys, write_run):
    episodes = {
        "towel-half-vision-closed-s0000": ("half", 0, 8.0),
        "towel-half-vision-closed-s0001": ("half", 1, "SimulationDivergedError"),
    }
    a = write_run(tmp_path / "a", episodes)
    b = write_run(tmp_path / "b", {**episodes, "towel-half-vision-closed-s0001": ("half", 1, 30.0)})
    picture = tmp_path / "pairs.png"
    assert main(["compare", str(a), str(b), "--plot", str(picture)]) == 0
    assert f"Pairs drawn in {picture}" in capsys.readouterr().out
    assert picture.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["a", "b", "pairs.png"]  # no temp file
    assert main(["compare", str(a), str(b), "--json"]) == 0
    pairs = json.loads(capsys.readouterr().out)["pairs"]
    assert [(p["fold_error_mm"], p["outcome"], p["same"]) for p in pairs] == [
        ([8.0, 8.0], ["success", "success"], True),
        ([None, 30.0], ["diverged", "fold inaccurate"], False),
    ]
    for bad, says in ((tmp_path / "pairs.jpg", "name a .png file"),
                      (tmp_path / "no" / "pairs.png", "does not exist")):  # fmt: skip
        assert main(["compare", str(a), str(b), "--plot", str(bad)]) == 2
        err = capsys.readouterr().err
        assert str(bad) in err and says in err and "Traceback" not in err
        assert not bad.exists()


def test_a_corrupt_result_json_gets_one_line_naming_it(tmp_path, capsys, write_run):
    eid = "towel-half-vision-closed-s0000"
    a = write_run(tmp_path / "a", {eid: ("half", 0, 8.0)})
    b = write_run(tmp_path / "b", {eid: ("half", 0, 12.0)})
    bad = b / "episodes" / eid / "result.json"
    bad.write_text("[]")
    assert main(["compare", str(a), str(b)]) == 2
    err = capsys.readouterr().err
    assert f"foldbot compare: error: {bad} holds a JSON array, not an object" in err
    assert "Traceback" not in err


def test_plot_onto_a_folder_is_refused_first(tmp_path, capsys, write_run):
    episodes = {"towel-half-vision-closed-s0000": ("half", 0, 8.0)}
    a, b = write_run(tmp_path / "a", episodes), write_run(tmp_path / "b", episodes)
    folder = tmp_path / "dir.png"
    folder.mkdir()
    assert main(["compare", str(a), str(b), "--plot", str(folder)]) == 2
    captured = capsys.readouterr()
    assert captured.out == ""  # refused before anything is compared or printed
    assert f"--plot {folder} is a folder; name a .png file to write" in captured.err
    assert sorted(p.name for p in tmp_path.iterdir()) == ["a", "b", "dir.png"]
    assert list(folder.iterdir()) == []


def test_plot_into_a_folder_it_cannot_write_is_refused_first(
    tmp_path, capsys, write_run, unwritable_folder
):
    episodes = {"towel-half-vision-closed-s0000": ("half", 0, 8.0)}
    a, b = write_run(tmp_path / "a", episodes), write_run(tmp_path / "b", episodes)
    shut = unwritable_folder
    assert main(["compare", str(a), str(b), "--plot", str(shut / "p.png")]) == 2
    err = capsys.readouterr().err
    assert f"--plot {shut / 'p.png'}: cannot write in its folder {shut}" in err
    assert "Traceback" not in err and list(shut.iterdir()) == []
