"""Tests of dice_sweep.inputs: a FIFO or a device named as an input is told apart from a file."""

import os

import pytest

from dice_sweep.inputs import not_a_file


def test_a_fifo_and_a_device_are_not_files(tmp_path):
    fifo = tmp_path / "pipe"
    os.mkfifo(fifo)
    assert not_a_file(fifo) == "is a FIFO (named pipe), not a regular file (allowed: a regular file)"
    if os.path.exists("/dev/zero"):
        assert "a character device" in not_a_file("/dev/zero")


@pytest.mark.parametrize("name", ["file.toml", "folder", "missing.csv"])
def test_files_folders_and_missing_paths_are_left_to_the_reader(tmp_path, name):
    (tmp_path / "file.toml").write_text("")
    (tmp_path / "folder").mkdir()
    assert not_a_file(tmp_path / name) is None
