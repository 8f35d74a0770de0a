"""Tests of dice_sweep.outputs: an output that cannot be written is one line naming the option,
the path, what is wrong and what is allowed, before any work; files are written whole or not
at all."""

import errno
import json
import os

import pytest

from dice_sweep.errors import DiceSweepError
from dice_sweep.outputs import (CSV, FOLDER, HDF5_SPARE, JSON, NPZ, SWEEP_FILE, check_outputs, check_space, replace_atomically, write_json,
                                make_folder, together, written)


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


# ---- every write under a temporary name, renamed when complete (issue 32) ------------------------


def full_disk(file):
    """A writer that meets a full disk half-way (the fault `written` must clean up after)."""
    file.write(b"half")
    raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))


def test_a_full_disk_is_one_line_naming_the_file_and_leaves_nothing(tmp_path):
    path = tmp_path / "report.md"
    with pytest.raises(DiceSweepError) as error:
        replace_atomically(path, full_disk)
    assert str(error.value) == f"{path}: cannot be written: No space left on device (errno 28); nothing was written to it"
    assert list(tmp_path.iterdir()) == []
    path.write_text("old")
    with pytest.raises(DiceSweepError):
        replace_atomically(path, full_disk)
    assert [p.name for p in tmp_path.iterdir()] == ["report.md"] and path.read_text() == "old"


@pytest.mark.parametrize("name", ["fig.png", "drops.csv.gz", "maps.npz", "sweep.h5"])
def test_the_temporary_sits_beside_the_output_and_ends_like_it(tmp_path, name):
    """Writers that go by the extension (matplotlib, Pillow, numpy) write the right format."""
    with written(tmp_path / name) as temporary:
        assert temporary.parent == tmp_path and temporary.name.endswith(".partial" + name[name.index("."):])
        assert temporary.name != name
        temporary.write_bytes(b"data")
    assert [p.name for p in tmp_path.iterdir()] == [name] and (tmp_path / name).read_bytes() == b"data"
    mode = (tmp_path / name).stat().st_mode & 0o777
    assert mode == 0o666 & ~current_umask()  # not mkstemp's 0600


def current_umask():
    mask = os.umask(0o022)
    os.umask(mask)
    return mask


def test_without_replace_an_existing_output_is_kept(tmp_path):
    path = tmp_path / "sweep.h5"
    path.write_bytes(b"precious")
    with pytest.raises(DiceSweepError, match="sweep.h5: cannot be written: File exists"):
        with written(path, replace=False) as temporary:
            temporary.write_bytes(b"new")
    assert path.read_bytes() == b"precious" and [p.name for p in tmp_path.iterdir()] == ["sweep.h5"]


def test_a_bug_inside_the_block_is_not_hidden_and_leaves_nothing(tmp_path):
    with pytest.raises(ZeroDivisionError):
        with written(tmp_path / "a.json") as temporary:
            temporary.write_bytes(b"{")
            1 / 0
    assert list(tmp_path.iterdir()) == []


def test_check_space_refuses_what_the_disk_cannot_hold(tmp_path, monkeypatch):
    import dice_sweep.outputs as outputs

    check_space(tmp_path / "a.h5", 10)  # this disk has room
    monkeypatch.setattr(outputs, "free_bytes", lambda folder: HDF5_SPARE + 9)
    with pytest.raises(DiceSweepError, match=rf"a.h5: no space left on the device: {HDF5_SPARE + 9} bytes free, "
                                             rf"{HDF5_SPARE + 10} needed .*; resume later"):
        check_space(tmp_path / "a.h5", 10, "; resume later")
    check_space(tmp_path / "a.h5", 9)


def test_together_renames_every_file_at_the_end_or_none(tmp_path):
    with together():
        replace_atomically(tmp_path / "a.json", lambda file: file.write(b"{}"))
        assert not (tmp_path / "a.json").exists()  # held back until the command succeeds
        make_folder(tmp_path / "png" / "deep")
        write_json(tmp_path / "png" / "deep" / "b.json", [1])
    assert (tmp_path / "a.json").read_text() == "{}" and json.loads((tmp_path / "png" / "deep" / "b.json").read_text()) == [1]
    failed = tmp_path / "failed"
    failed.mkdir()
    with pytest.raises(DiceSweepError, match="c.md: cannot be written: No space left on device"):
        with together():
            write_json(failed / "report.json", {"complete": True})
            make_folder(failed / "pictures")
            replace_atomically(failed / "c.md", full_disk)
    assert list(failed.iterdir()) == []  # no lone report that looks complete, no empty picture folder
