"""Every command of the README's shell blocks runs as written (issue 16), in order, in a
scratch folder, at a small size: sweeps get a 16 x 16 grid appended (``--set`` overrides
the config's), shards write under the scratch folder, a server (``dice-sweep view``) runs until
it answers and then gets Ctrl-C. The set-up block (``make demo``, ``make
test``) is what runs this test, so it is left out."""

import os
import re
import shlex
import signal
import subprocess
import sys
import urllib.request
from pathlib import Path

import pytest

from tests.helpers import ctrl_c_reaches_it

ROOT = Path(__file__).resolve().parent.parent
README = ROOT / "README.md"
SETUP = {"make demo", "make test"}
SMALL = ["--set", "grid.x.num=16", "--set", "grid.y.num=16"]
BIN = Path(sys.executable).parent  # the environment running the tests has dice-sweep


def readme_commands():
    """The README's shell commands, comments stripped, in order; the set-up block left out."""
    commands = []
    for block in re.findall(r"```sh\n(.*?)```", README.read_text(), re.S):
        for line in block.splitlines():
            command = line.split("  #")[0].split(" # ")[0].strip()
            if command and command not in SETUP:
                commands.append(command)
    return commands


COMMANDS = readme_commands()


def test_the_readme_has_commands_to_run():
    assert len(COMMANDS) >= 10
    assert any(c.startswith("dice-sweep sweep") for c in COMMANDS)


@pytest.fixture(scope="module")
def workdir(tmp_path_factory):
    path = tmp_path_factory.mktemp("readme")
    (path / "configs").symlink_to(ROOT / "configs")
    (path / "out").mkdir()  # as `make demo` leaves it
    return path


def _small(argv, workdir):
    """The command at a small size, and the folder to run it in."""
    if argv[:2] == ["dice-sweep", "sweep"]:
        return argv + SMALL, workdir
    if argv[:2] == ["make", "-j2"]:
        if not (ROOT / ".venv" / ".installed-stamp").exists():
            pytest.skip("make shards needs the .venv of `make test`")
        return argv + [f"SHARD_OUT={workdir / 'out'}", "SET=" + " ".join(SMALL)], ROOT
    return argv, workdir


@pytest.mark.parametrize("command", COMMANDS)
def test_readme_command_runs_as_written(command, workdir):
    argv = shlex.split(command)
    if argv[0] == "source":
        assert argv[1] == ".venv/bin/activate" and (BIN / "dice-sweep").exists()
        return
    argv, cwd = _small(argv, workdir)
    env = {**os.environ, "PATH": f"{BIN}{os.pathsep}{os.environ['PATH']}"}
    if argv[:2] == ["dice-sweep", "view"]:
        return serves(argv + ["--no-open"], cwd, env)
    done = subprocess.run(argv, cwd=cwd, env=env, capture_output=True, text=True, timeout=600)
    assert done.returncode == 0, (command, done.stdout[-2000:], done.stderr[-2000:])
    assert "Traceback" not in done.stderr


def serves(argv, cwd, env):
    """A server command (dice-sweep view) runs until it answers, then stops on Ctrl-C."""
    process = subprocess.Popen(argv, cwd=cwd, env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                               preexec_fn=ctrl_c_reaches_it)
    try:
        first = process.stdout.readline()
        assert first.startswith("serving on http://127.0.0.1:"), (first, process.stderr.read() if process.poll() is not None else "")
        with urllib.request.urlopen(first.split()[-1] + "api/file", timeout=60) as response:
            assert response.status == 200
    finally:
        process.send_signal(signal.SIGINT)
        out, err = process.communicate(timeout=60)
    assert process.returncode in (0, 130) and "Traceback" not in err, (out, err)


def test_the_readme_commands_leave_nothing_outside_out(workdir):
    """Run after the commands above (pytest keeps the file's order): the scratch folder, a copy
    of the repository's root, holds nothing new but out/ (git ignores it)."""
    assert sorted(p.name for p in workdir.iterdir()) == ["configs", "out"]


OUTPUT_OPTIONS = {"-o", "--output", "--json", "--md", "--png", "--gif"}


def readme_dice_sweep_commands():
    """Every dice-sweep command of the README: its shell blocks' and those quoted in its text."""
    quoted = [span for span in re.findall(r"`(dice-sweep [^`]*)`", README.read_text())]
    return [c for c in COMMANDS if c.startswith("dice-sweep ")] + quoted


def test_every_readme_output_goes_to_out():
    """Outputs under out/ (git ignores it), never a placeholder such as DIR."""
    commands = readme_dice_sweep_commands()
    assert len(commands) > 15
    for command in commands:
        argv = shlex.split(command)
        for option, value in zip(argv, argv[1:]):
            if option in OUTPUT_OPTIONS and not value.startswith("-"):  # roll's --json is a flag
                assert value.startswith("out/") and value.upper() != value, command


def test_the_sides_range_is_the_configs():
    """README: "n, 3 to 127" and why: the config takes exactly that range, and 127 is the
    largest side count an int8 outcome map holds (sides 0 .. n-1, -1 and -128 reserved)."""
    import numpy as np

    from dice_sweep.config import parse_config
    from dice_sweep.errors import ConfigError

    low, high = map(int, re.search(r"sides = \d+ +# n, (\d+) to (\d+): a sweep file stores each side in one byte \(int8\)",
                                   README.read_text()).groups())
    assert high - 1 == np.iinfo(np.int8).max - 1 and low == 3
    for sides in (low, high):
        assert parse_config(f"[die]\nsides = {sides}").die.sides == sides
    for sides in (low - 1, high + 1):
        with pytest.raises(ConfigError, match=f"die.sides: {sides} is outside the allowed range \\[{low}, {high}\\]"):
            parse_config(f"[die]\nsides = {sides}")


def test_the_readmes_config_block_is_the_defaults():
    """The README's annotated config (every section, its keys and their defaults) parses, and
    every value is the default it claims: with no section at all the config is the same, but
    for [walls] and [grid], which the block shows and a config leaves out to have none."""
    from dice_sweep.config import default_config, parse_config

    block = re.findall(r"```toml\n(.*?)```", README.read_text(), re.S)[0]
    cfg = parse_config(block)
    defaults = default_config()
    for section in ("die", "contact", "initial", "effects", "world", "integrator", "tracking"):
        assert getattr(cfg, section) == getattr(defaults, section), section
    assert defaults.walls.separation is None and cfg.walls == parse_config("[walls]").walls
    assert defaults.grid is None and cfg.grid is not None


def test_the_readme_says_which_defaults_are_table_is():
    """"the initial state is not (y0 = 0.1 m and omega0 = 10 rad/s; Table I's roll, in
    table1.toml, is y0 = 0.15 m and omega0 = 20 rad/s)": both pairs as the code has them."""
    from dice_sweep.config import TABLE1_CIRCUMRADIUS, default_config, load_config

    text = " ".join(README.read_text().split())
    pairs = re.findall(r"y0 = ([\d.]+) m and omega0 = ([\d.]+) rad/s", text)
    assert len(pairs) == 2
    defaults, table1 = default_config(), load_config(ROOT / "configs" / "table1.toml")
    assert tuple(map(float, pairs[0])) == (defaults.initial.y0, defaults.initial.omega0)
    assert tuple(map(float, pairs[1])) == (table1.initial.y0, table1.initial.omega0)
    assert pairs[0] != pairs[1]  # so the README must say the defaults are not Table I's
    assert "the die and contact law are Table I's" in text
    assert defaults.die == table1.die and defaults.die.circumradius == TABLE1_CIRCUMRADIUS
    assert (defaults.contact.beta_normal, defaults.contact.beta_tangential) == (table1.contact.beta_normal, table1.contact.beta_tangential)


def test_the_compile_time_is_the_measured_one():
    """The README's compile times are those measured by scripts/bench.py: the quiet machine's
    of dice_sweep.engine.COMPILE_SECONDS, and the last one docs/cold_start.md holds with the
    load it was made at (the README once said 18 s; a loaded 2-core machine took 28 s)."""
    from dice_sweep.engine import COMPILE_SECONDS

    text = " ".join(README.read_text().split())
    quiet = re.search(r"about (\d+) s on this project's 2-core machine when it was quiet \(`COMPILE_SECONDS`", text)
    assert quiet and int(quiet.group(1)) == round(COMPILE_SECONDS)
    loaded = re.search(r"docs/cold_start.md\)'s last measurement, at a load average of ([\d.]+) to ([\d.]+) on 2 cores, took "
                       r"(\d+) s \(the compile-forced `roll`, median of 3\)", text)
    assert loaded, "the README does not state the last measurement of docs/cold_start.md"
    measured = (ROOT / "docs" / "cold_start.md").read_text()
    forced = float(re.search(r"^\| `dice-sweep roll configs/table1.toml` \| [\d.]+ \| ([\d.]+) \|", measured, re.M).group(1))
    load = re.search(r"^Load average \(1 min, as `uptime` prints it\) on the 2 cores: ([\d.]+) when these runs started, "
                     r"([\d.]+) when they ended", measured, re.M)
    assert load, "docs/cold_start.md has no load: rerun python scripts/bench.py --cold --write"
    assert int(loaded.group(3)) == round(forced) and loaded.groups()[:2] == load.groups()
    assert "median of 3" in measured
