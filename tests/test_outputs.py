"""Tests of dice_sweep.outputs: an output that cannot be written is one line naming the option,
the path, what is wrong and what is allowed, before any work; files are written whole or not
at all."""

import json
import os

import pytest

from dice_sweep.errors import DiceSweepError
from dice_sweep.outputs import CSV, FOLDER, JSON, NPZ, SWEEP_FILE, check_outputs, replace_atomically, write_json


@pytest.mark.parametrize(
    ("name", "suffixes", "problem"),
    [
        ("out.png", JSON, "wrong file extension (allowed: a file name ending in .json in an existing folder you may write to)"),
        (".json", JSON, "nothing before the extension"),
        ("a_folder", FOLDER, None),
        ("a_folder.json", JSON, "is a folder"),
        ("a_file.json", FOLDER, "is a file (allowed: a folder (created if missing) in an existing folder you may write to)"),
        ("missing/out.json", JSON, "folder {tmp}/missing does not exist"),
        ("a_file.json/out.json", JSON, "{tmp}/a_file.json is a file, not a folder"),
        ("DROPS.CSV.GZ", CSV, None),  # case ignored
        ("part.h5.partial", SWEEP_FILE, None),
        ("maps.npz", NPZ, None),
        ("maps.csv", CSV[:1] + NPZ, None),
    ],
)
def test_each_problem_is_named(tmp_path, name, suffixes, problem):
    (tmp_path / "a_folder").mkdir()
    (tmp_path / "a_folder.json").mkdir()
    (tmp_path / "a_file.json").write_text("{}")
    path = tmp_path / name
    if problem is None:
        check_outputs(("--out", path, suffixes))
        return
    with pytest.raises(DiceSweepError) as error:
        check_outputs(("--out", path, suffixes))
    message = str(error.value)
    assert message.startswith(f"--out: {path}: {problem.format(tmp=tmp_path)}"), message
    assert "\n" not in message


def test_an_option_not_given_is_skipped_and_the_first_bad_one_is_named(tmp_path):
    check_outputs(("--json", None, JSON), ("--png", "", FOLDER))
    with pytest.raises(DiceSweepError, match="^--md: "):
        check_outputs(("--json", tmp_path / "a.json", JSON), ("--md", tmp_path / "a.txt", (".md",)), ("--png", tmp_path / "x.y", JSON))


def test_two_outputs_on_one_path_are_refused(tmp_path):
    os.symlink(tmp_path, tmp_path / "same")
    with pytest.raises(DiceSweepError) as error:
        check_outputs(("--json", tmp_path / "a.json", JSON), ("--report", tmp_path / "same" / "a.json", JSON))
    assert str(error.value) == f"--report: {tmp_path / 'same' / 'a.json'}: also given to --json (allowed: a different path for each output)"


@pytest.mark.skipif(os.geteuid() == 0, reason="root writes to any folder")
def test_a_folder_without_write_permission_is_refused(tmp_path):
    locked = tmp_path / "locked"
    locked.mkdir(mode=0o500)
    with pytest.raises(DiceSweepError, match="cannot be written to"):
        check_outputs(("--json", locked / "a.json", JSON))


def test_a_folder_root_cannot_write_to_is_refused():
    if not os.path.isdir("/proc/self"):
        pytest.skip("no /proc")
    with pytest.raises(DiceSweepError, match="cannot be written"):
        check_outputs(("--json", "/proc/self/a.json", JSON))


def test_replace_atomically_writes_the_whole_file_or_leaves_the_old_one(tmp_path):
    path = tmp_path / "out.json"
    path.write_text("old")

    def half_then_fail(file):
        file.write(b"half")
        raise RuntimeError("killed")

    with pytest.raises(RuntimeError):
        replace_atomically(path, half_then_fail)
    assert path.read_text() == "old" and sorted(p.name for p in tmp_path.iterdir()) == ["out.json"]  # no .partial left
    replace_atomically(path, lambda file: file.write(b"new"))
    assert path.read_text() == "new" and sorted(p.name for p in tmp_path.iterdir()) == ["out.json"]


def test_write_json_writes_indented_json_and_a_newline(tmp_path):
    data = {"a": [1, 2.5], "b": {"c": None}}
    written = write_json(tmp_path / "d.json", data)
    assert written == tmp_path / "d.json"
    text = written.read_text()
    assert text == json.dumps(data, indent=2) + "\n" and json.loads(text) == data
