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


def test_the_readmes_config_block_is_a_valid_config():
    """The README's annotated config (every section, its keys and their defaults) parses, and
    its values are the defaults it claims, the registry's keys among them."""
    from dice_sweep.config import default_config, parse_config

    block = re.findall(r"```toml\n(.*?)```", README.read_text(), re.S)[0]
    cfg = parse_config(block)
    defaults = default_config()
    assert cfg.contact == defaults.contact and cfg.effects == defaults.effects and cfg.world == defaults.world
