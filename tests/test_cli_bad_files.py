"""Issue 32, items 2 and 3, through the command line: forged sweep files, FIFOs and devices as
inputs, and configs a roll cannot compute each give one line naming the file and the key,
exit 2, before any work, and leave no output (the suite's share of scripts/bad_inputs.py's
issue-32 block; the full disk is tests/test_full_disk.py)."""

import os

import h5py
import numpy as np
import pytest

from tests.helpers import CONFIGS, run_cli, set_first, small_sweep

DEMO = str(CONFIGS / "demo.toml")
TABLE1 = str(CONFIGS / "table1.toml")
SQUARE = str(CONFIGS / "square_drops.toml")


def assert_one_line(result, *fragments):
    assert result.exit_code == 2, (result.exit_code, result.stdout, result.stderr)
    lines = result.stderr.splitlines()
    assert len(lines) == 1 and lines[0].startswith("error: ") and "Traceback" not in result.stderr, result.stderr
    for fragment in fragments:
        assert fragment in lines[0], (fragment, lines[0])


@pytest.fixture(scope="module")
def good(tmp_path_factory):
    from dice_sweep.config import load_config

    path = tmp_path_factory.mktemp("bad_files") / "good.h5"
    small_sweep(load_config(DEMO, ["grid.x.num=16", "grid.y.num=16"]), path)
    return path


FORGED = {  # name -> (change, key, fragment)
    "outcome 50": (set_first("outcome", 50), "/outcome", "50 in a computed cell"),
    "sides 0": (lambda h5: h5.attrs.__setitem__("sides", 0), "sides", "0 sides"),
    "x axis = y axis": (lambda h5: h5.attrs.__setitem__("x_param", h5.attrs["y_param"]), "y_param", "also the x axis"),
    "axis inf": (set_first("omega0", np.inf), "/omega0", "strictly increasing"),
}
COMMANDS = {  # name -> (arguments after the file, the output it would write)
    "plot": (["-o", "{tmp}/p.png"], "p.png"),
    "merge": (["-o", "{tmp}/m.h5"], "m.h5"),
    "measure": (["--json", "{tmp}/m.json"], "m.json"),
    "control": (["--sigma", "y0=0.01", "-o", "{tmp}/c.npz"], "c.npz"),
}


@pytest.mark.parametrize("command", sorted(COMMANDS))
@pytest.mark.parametrize("case", sorted(FORGED))
def test_a_forged_sweep_file_is_refused_by_every_reader(good, tmp_path, case, command):
    change, key, fragment = FORGED[case]
    forged = tmp_path / "forged.h5"
    forged.write_bytes(good.read_bytes())
    with h5py.File(forged, "r+") as h5:
        change(h5)
    args, out = COMMANDS[command]
    assert_one_line(run_cli(command, forged, *(arg.format(tmp=tmp_path) for arg in args)), f"{forged}: {key}: ", fragment)
    assert not (tmp_path / out).exists()
    assert_one_line(run_cli("sweep", DEMO, "-o", forged, "--resume", "--set", "grid.x.num=16", "--set", "grid.y.num=16"), key)


def test_the_unforged_file_is_read_by_every_reader(good, tmp_path):
    """The control: the same commands on the file as sweep wrote it."""
    for command, (args, out) in COMMANDS.items():
        result = run_cli(command, good, *(arg.format(tmp=tmp_path) for arg in args))
        assert result.exit_code == 0, (command, result.stderr)
        assert (tmp_path / out).exists()


@pytest.fixture
def fifo(tmp_path):
    path = tmp_path / "pipe"
    os.mkfifo(path)
    return path


@pytest.mark.parametrize("where", ["config of roll", "config of sweep", "data of fit", "data of calibrate", "config of fit",
                                   "sweep file of plot", "sweep file of merge", "fit of forecast"])
@pytest.mark.parametrize("source", ["fifo", "/dev/zero"])
def test_a_fifo_or_a_device_is_refused_not_read_forever(fifo, good, tmp_path, where, source):
    if source == "/dev/zero" and not os.path.exists(source):
        pytest.skip("no /dev/zero")
    path = str(fifo) if source == "fifo" else source
    args = {
        "config of roll": ["roll", path],
        "config of sweep": ["sweep", path, "-o", tmp_path / "s.h5"],
        "data of fit": ["fit", path, "--config", SQUARE],
        "data of calibrate": ["calibrate", path, "--config", SQUARE],
        "config of fit": ["fit", good, "--config", path],
        "sweep file of plot": ["plot", path, "-o", tmp_path / "p.png"],
        "sweep file of merge": ["merge", path, "-o", tmp_path / "m.h5"],
        "fit of forecast": ["forecast", good, "--config", SQUARE, "--fit", path, "--json", tmp_path / "f.json"],
    }[where]
    assert_one_line(run_cli(*args), path, "not a regular file")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["pipe"]


@pytest.mark.parametrize(("args", "fragments"), [
    (["roll", TABLE1, "--set", "initial.vx0=1e200", "--json"], ["initial.vx0", "at most 1000 m/s"]),
    (["roll", TABLE1, "--set", "integrator.dt=1e-12", "--set", f"integrator.max_events={2**62}"], ["integrator.max_events", "at most 1e+08"]),
    (["roll", TABLE1, "--set", "integrator.method=fixed_step", "--set", "integrator.dt=1e-12"], ["integrator.dt", "3e+13 steps"]),
    (["sweep", DEMO, "-o", "{tmp}/s.h5", "--set", "grid.x.min=-1e308", "--set", "grid.x.max=1e308"], ["grid.x", "not finite, distinct"]),
    (["sweep", DEMO, "-o", "{tmp}/s.h5", "--set", "grid.x.max=1e9"], ["grid.x", "omega0 up to 1e+09 rad/s"]),
    (["simulate-drops", SQUARE, "-o", "{tmp}/d.csv", "--tracks", "2", "--set", f"integrator.max_events={2**62}"], ["integrator.max_events"]),
])
def test_what_a_roll_cannot_compute_is_refused_before_it(tmp_path, args, fragments):
    assert_one_line(run_cli(*(str(arg).format(tmp=tmp_path) for arg in args)), *fragments)
    assert list(tmp_path.iterdir()) == []
