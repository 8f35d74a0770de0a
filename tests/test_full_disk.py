"""Issue 32, item 1: a full disk gives one line naming the file and the cause, exit 2, never a
segfault or a half-written output. On a real, small tmpfs where this process may mount one
(root; skipped otherwise), each command run as its own process so that a crash shows as its
exit code; tests/test_outputs.py and tests/test_storage.py inject the same fault in-process."""

import os
import subprocess
import sys

import h5py
import numpy as np
import pytest

from tests.helpers import CONFIGS

DEMO = str(CONFIGS / "demo.toml")
SQUARE = str(CONFIGS / "square_drops.toml")
TABLE1 = str(CONFIGS / "table1.toml")
SMALL = ["--set", "grid.x.num=16", "--set", "grid.y.num=16"]
ENV = dict(os.environ, DICE_SWEEP_COMPILE_NOTE="0")


def cli(*args):
    return subprocess.run([sys.executable, "-m", "dice_sweep", *map(str, args)], capture_output=True, text=True, env=ENV, timeout=600)


@pytest.fixture
def disk(tmp_path):
    """A 2 MB tmpfs of its own, unmounted after the test."""
    if os.geteuid() != 0:
        pytest.skip("mounting a tmpfs needs root")
    mount = tmp_path / "disk"
    mount.mkdir()
    result = subprocess.run(["mount", "-t", "tmpfs", "-o", "size=2m", "tmpfs", str(mount)], capture_output=True, text=True)
    if result.returncode != 0:
        pytest.skip(f"cannot mount a tmpfs here: {result.stderr.strip()}")
    yield mount
    subprocess.run(["umount", "-l", str(mount)], check=False)


def fill(disk, leave):
    """Fill ``disk`` until about ``leave`` bytes are free (in pages of 4 KiB)."""
    free = os.statvfs(disk).f_bavail * os.statvfs(disk).f_frsize
    with open(disk / "ballast", "wb") as ballast:
        ballast.write(b"\0" * max(free - leave, 0))
    return disk / "ballast"


@pytest.fixture(scope="module")
def inputs(tmp_path_factory):
    folder = tmp_path_factory.mktemp("full_disk_inputs")
    for name, shard in (("whole", "0/1"), ("part0", "0/2"), ("part1", "1/2")):
        assert cli("sweep", DEMO, "-o", folder / f"{name}.h5", *SMALL, "--shard", shard, "--quiet").returncode == 0
    assert cli("simulate-drops", SQUARE, "-o", folder / "drops.csv", "--tracks", 8, "--seed", 1).returncode == 0
    return folder


COMMANDS = {  # name -> (arguments with {in} for the inputs' folder and {out} for the disk, the output named)
    "sweep": (["sweep", DEMO, "-o", "{out}/s.h5", *SMALL, "--quiet"], "s.h5"),
    "merge": (["merge", "{in}/part0.h5", "{in}/part1.h5", "-o", "{out}/m.h5"], "m.h5"),
    "plot": (["plot", "{in}/whole.h5", "-o", "{out}/p.png"], "p.png"),
    "roll --gif": (["roll", TABLE1, "--gif", "{out}/r.gif"], "r.gif"),
    "roll --png": (["roll", TABLE1, "--png", "{out}/r.png"], "r.png"),
    "simulate-drops": (["simulate-drops", SQUARE, "-o", "{out}/d.csv", "--tracks", "8"], "d.csv"),
    "calibrate": (["calibrate", "{in}/drops.csv", "--config", SQUARE, "--json", "{out}/c.json", "--png", "{out}/c.png"], "c."),
    "measure": (["measure", "{in}/whole.h5", "--json", "{out}/m.json"], "m.json"),
    "control": (["control", "{in}/whole.h5", "--sigma", "y0=0.01", "-o", "{out}/c.npz", "--json", "{out}/c.json"], "c."),
}


@pytest.mark.parametrize("command", sorted(COMMANDS))
def test_a_full_disk_is_one_line_and_leaves_nothing(disk, inputs, command):
    args, named = COMMANDS[command]
    fill(disk, 0)
    result = cli(*(arg.format(**{"in": inputs, "out": disk}) for arg in args))
    assert result.returncode == 2, (result.returncode, result.stderr[-2000:])  # 139 was a segfault
    lines = result.stderr.splitlines()
    assert len(lines) == 1 and "Traceback" not in result.stderr, result.stderr[-2000:]
    assert lines[0].startswith(f"error: {disk}/{named}") and "No space left on device (errno 28)" in lines[0], lines[0]
    assert sorted(path.name for path in disk.iterdir()) == ["ballast"]  # no output, no temporary


def test_a_disk_that_fills_mid_sweep_stops_cleanly_and_the_sweep_resumes(disk, tmp_path):
    """Room for the empty file and about one tile of four: the sweep stops before the write
    HDF5 could not finish, exit 2, the file kept and not complete; with room again, --resume
    finishes it to the maps of a sweep that never stopped."""
    from dice_sweep.outputs import HDF5_SPARE
    from dice_sweep.storage import read_sweep

    path = disk / "s.h5"
    ballast = fill(disk, HDF5_SPARE + 48_000)  # the empty file is 18 kB, a tile about 20 kB
    result = cli("sweep", DEMO, "-o", path, "--quiet", "--workers", 1)
    assert result.returncode == 2, (result.returncode, result.stderr[-2000:])
    assert result.stderr.startswith(f"error: {path}: no space left on the device") and result.stderr.count("\n") == 1, result.stderr
    assert "the tiles written before it are kept, and the file is not marked complete" in result.stderr
    with h5py.File(path, "r") as h5:
        done = h5["done_tiles"][...]
        assert h5.attrs["complete"] == 0 and 0 < done.sum() < done.size, done
    ballast.unlink()
    assert cli("sweep", DEMO, "-o", path, "--quiet", "--resume").returncode == 0
    assert cli("sweep", DEMO, "-o", tmp_path / "ref.h5", "--quiet").returncode == 0
    resumed, reference = read_sweep(path), read_sweep(tmp_path / "ref.h5")
    assert resumed.complete
    for name, values in reference.maps.items():
        np.testing.assert_array_equal(resumed.maps[name], values, err_msg=name)


def test_a_disk_full_at_the_last_picture_leaves_no_report_without_it(disk, inputs):
    """Room for measure's JSON but not its pictures: neither the JSON (which would look like a
    finished run) nor the picture folder the command made is left."""
    fill(disk, 16_384)
    result = cli("measure", inputs / "whole.h5", "--json", disk / "m.json", "--png", disk / "pictures")
    assert result.returncode == 2 and result.stderr.count("\n") == 1, result.stderr
    assert result.stderr.startswith(f"error: {disk}/pictures/") and "No space left on device" in result.stderr, result.stderr
    assert sorted(path.name for path in disk.iterdir()) == ["ballast"]
