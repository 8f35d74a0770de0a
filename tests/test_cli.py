"""Tests of the dice-sweep command line: help texts, one-line errors, option parsing, wiring."""

import json
import os
import pathlib
import subprocess
import sys
import textwrap
import types
from unittest import mock

import click
import pytest

from dice_sweep import cli
from tests.helpers import CONFIGS as CONFIG_DIR
from tests.helpers import ROOT
from tests.helpers import corrupt_first_chunk, figure_pixels, map_region, png_size, read_png, share, small_sweep
from tests.helpers import run_cli as run
from tests.test_storage import held_open  # noqa: F401 - a fixture

Path = pathlib.Path

TABLE1 = str(CONFIG_DIR / "table1.toml")
DEMO = str(CONFIG_DIR / "demo.toml")


def assert_user_error(result, *fragments):
    """Exit code 2, one line ``error: ...`` on stderr naming every fragment, no traceback."""
    assert result.exit_code == 2, (result.stdout, result.stderr)
    assert result.exception is None or isinstance(result.exception, SystemExit)
    lines = result.stderr.splitlines()
    assert len(lines) == 1, result.stderr
    assert lines[0].startswith("error: ")
    assert "Traceback" not in result.stderr + result.stdout
    for fragment in fragments:
        assert fragment in lines[0]
    return lines[0]


@pytest.fixture
def calls(monkeypatch):
    """Replace the library calls of the commands with recorders; return the list of calls."""
    recorded = []

    def recorder(name, result=None):
        def record(*args, **kwargs):
            recorded.append((name, args, kwargs))
            return result

        return record

    report = types.SimpleNamespace(
        outcome=2, status=0, status_name="decided", impacts=7, t_decided=0.4321,
        to_dict=lambda: {"outcome": 2, "status": 0, "impacts": 7, "t_decided": 0.4321},
    )
    summary = types.SimpleNamespace(describe=lambda: "summary line")
    import dice_sweep.app.roll
    import dice_sweep.app.sweep
    import dice_sweep.plotting
    import dice_sweep.sweep

    monkeypatch.setattr(dice_sweep.app.roll, "roll_config", lambda cfg: recorded.append(("roll_config", (cfg,), {})) or report)
    monkeypatch.setattr(dice_sweep.sweep, "run_sweep", recorder("run_sweep", summary))
    monkeypatch.setattr(dice_sweep.sweep, "merge_parts", recorder("merge_parts", summary))
    monkeypatch.setattr(dice_sweep.app.sweep, "draw_sweep_file", recorder("draw_sweep_file", "the.png"))
    monkeypatch.setattr(dice_sweep.plotting, "plot_roll", recorder("plot_roll"))
    monkeypatch.setattr(dice_sweep.plotting, "animate_roll", recorder("animate_roll"))
    return recorded


# ---- help texts -----------------------------------------------------------------------------


COMMANDS = [("", cli.main)] + sorted(cli.main.commands.items())


def help_example(name):
    """The example that ends ``dice-sweep NAME --help``: its command lines, as printed."""
    result = run(*([name] if name else []), "--help")
    assert result.exit_code == 0, result.stderr
    text = result.stdout.rstrip("\n")
    head, mark, example = text.rpartition("\n  Example: ")
    assert mark and "Options:" in head, f"{name or 'dice-sweep'} --help does not end with its example after the options"
    return [line.strip() for line in example.splitlines()]


def test_every_command_has_help_ending_with_an_example():
    # at least the commands of the issues so far; any added command is checked the same way
    expected = {"", "roll", "sweep", "merge", "plot", "measure", "control", "calibrate", "fit", "diagnose", "forecast", "view"}
    assert expected <= {name for name, _ in COMMANDS}
    for name, _ in COMMANDS:
        lines = help_example(name)
        assert all(line.startswith("dice-sweep ") for line in lines), (name, lines)
        if name:  # the last line runs the command itself; earlier lines make its inputs
            assert lines[-1].split()[1] == name, (name, lines)


def test_help_examples_name_only_files_that_make_demo_or_an_earlier_line_makes():
    """Right after `make demo` (out/demo.h5, out/demo.png) each example runs as written: every
    input it names is a config, out/demo.h5 or an output of an earlier line, every output is
    under out/ and none is out/demo.h5 (sweep would refuse it: "exists")."""
    outputs = {"-o", "--output", "--json", "--md", "--png", "--gif"}
    for name, _ in COMMANDS:
        made = {"out/demo.h5"}
        for line in help_example(name):
            argv = line.split()
            written = {argv[i + 1] for i, arg in enumerate(argv[:-1]) if arg in outputs}
            assert all(path.startswith("out/") and path not in {"out/demo.h5", "out/demo.png"} for path in written), (name, line)
            for i, arg in enumerate(argv[2:], 2):
                is_path = arg.startswith(("out/", "configs/")) or arg.endswith((".h5", ".csv", ".gz", ".toml", ".json"))
                if is_path and argv[i - 1] not in outputs:
                    assert arg.startswith("configs/") and (ROOT / arg).exists() or arg in made, (name, line, arg)
            made |= written


# the examples of the measured-data commands fit and forecast (minutes): test_readme.py runs
# their lines in the README's order in the default suite, and -m slow runs each example here
MEASURED = {"simulate-drops", "calibrate", "fit", "diagnose", "forecast"}
SMALL_GRID = ["--set", "grid.x.num=16", "--set", "grid.y.num=16"]


@pytest.fixture(scope="module")
def after_make_demo(tmp_path_factory):
    """A folder as `make demo` leaves the repository: configs/, out/demo.h5 and out/demo.png
    (the demo at 16 x 16)."""
    folder = tmp_path_factory.mktemp("after_make_demo")
    (folder / "configs").symlink_to(CONFIG_DIR)
    (folder / "out").mkdir()
    made = run("sweep", DEMO, "-o", folder / "out" / "demo.h5", "--png", folder / "out" / "demo.png", "--quiet", *SMALL_GRID)
    assert made.exit_code == 0, made.stderr
    return folder


def run_help_example(name, after_make_demo, tmp_path, monkeypatch):
    """Run NAME's help example line by line, as written, in a copy of the folder `make demo`
    leaves (sweeps at 16 x 16; a server until it answers)."""
    import shlex
    import shutil

    from tests.test_readme import serves

    folder = tmp_path / "repo"
    shutil.copytree(after_make_demo, folder, symlinks=True)
    monkeypatch.chdir(folder)
    for line in help_example(name):
        argv = shlex.split(line)
        if argv[1] == "view":
            bin_dir = Path(sys.executable).parent
            serves([str(bin_dir / "dice-sweep"), *argv[1:]], folder, {**os.environ, "PATH": f"{bin_dir}{os.pathsep}{os.environ['PATH']}"})
            continue
        result = run(*argv[1:], *(SMALL_GRID if argv[1] == "sweep" else []))
        assert result.exit_code == 0, (line, result.stderr[-2000:])
    assert sorted(p.name for p in folder.iterdir()) == ["configs", "out"], "an example wrote outside out/"


@pytest.mark.parametrize("name", [name for name, _ in COMMANDS if name not in MEASURED])
def test_help_example_runs_as_written_after_make_demo(name, after_make_demo, tmp_path, monkeypatch):
    run_help_example(name, after_make_demo, tmp_path, monkeypatch)


@pytest.mark.slow
@pytest.mark.parametrize("name", sorted(MEASURED))
def test_measured_help_example_runs_as_written_after_make_demo(name, after_make_demo, tmp_path, monkeypatch):
    run_help_example(name, after_make_demo, tmp_path, monkeypatch)


def test_measured_help_examples_are_readme_lines_in_the_readme_order():
    """So test_readme.py runs them, in a folder that `make demo` left, in the default suite."""
    from tests.test_readme import COMMANDS as README_COMMANDS

    for name in MEASURED:
        lines = help_example(name)
        places = [README_COMMANDS.index(line) if line in README_COMMANDS else -1 for line in lines]
        assert -1 not in places and places == sorted(places), (name, lines)


def test_help_does_not_import_the_heavy_modules():
    code = "import sys; from dice_sweep import cli; print(sorted(m for m in ('numpy', 'numba', 'matplotlib', 'h5py') if m in sys.modules))"
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout
    assert out.strip() == "[]"


def test_python_dash_m_runs_the_cli():
    result = subprocess.run([sys.executable, "-m", "dice_sweep", "--help"], capture_output=True, text=True)
    assert result.returncode == 0
    assert "Example: dice-sweep" in result.stdout


PROGRAM = """
import atexit, sys
from dice_sweep.cli import run

class Teardown:
    def __del__(self):
        print("teardown ran", flush=True)

kept = Teardown()  # a module global: deleted by the interpreter's teardown, if there is one
atexit.register(lambda: print("atexit ran"))
sys.argv = ["dice-sweep", *sys.argv[1:]]
run()
"""


def test_the_program_ends_a_kernel_command_without_the_teardown_keeping_its_exit_code(tmp_path):
    """``run`` (the console script and python -m) skips the interpreter's teardown after a
    sweep, and keeps the exit code, the exit handlers, the output and a complete file."""
    from dice_sweep.config import load_config
    from dice_sweep.storage import read_sweep
    from tests.helpers import assert_same_maps

    grid = ["--set", "grid.x.num=8", "--set", "grid.y.num=6"]

    def program(*args):
        return subprocess.run([sys.executable, "-c", PROGRAM, *args], capture_output=True, text=True, cwd=ROOT, timeout=600)

    done = program("sweep", DEMO, "-o", tmp_path / "a.h5", "--workers", "2", *grid)
    assert done.returncode == 0, done.stderr
    assert "48 rolls" in done.stdout and "atexit ran" in done.stdout and "teardown ran" not in done.stdout
    small_sweep(load_config(DEMO, grid[1::2]), tmp_path / "b.h5")
    assert read_sweep(tmp_path / "a.h5").complete
    assert_same_maps(read_sweep(tmp_path / "a.h5"), read_sweep(tmp_path / "b.h5"))
    before = (tmp_path / "a.h5").read_bytes()
    refused = program("sweep", DEMO, "-o", tmp_path / "a.h5", *grid)  # a user error after the kernel's start
    assert refused.returncode == 2 and refused.stderr.startswith("error: ") and len(refused.stderr.splitlines()) == 1
    assert "exists" in refused.stderr and "teardown ran" not in refused.stdout
    assert (tmp_path / "a.h5").read_bytes() == before
    helped = program("--help")  # no kernel command: the usual end
    assert helped.returncode == 0 and "teardown ran" in helped.stdout


# ---- options given twice (issue 32) ---------------------------------------------------------


def value_options():
    """(command, option) of every option of every command that takes one value: given twice,
    click would silently keep the last."""
    return [(name, max(param.opts, key=len)) for name, command in sorted(cli.main.commands.items()) for param in command.params
            if isinstance(param, click.Option) and not param.is_flag and not param.multiple]


def test_there_are_value_options_to_check():
    options = value_options()
    assert len(options) > 40 and ("control", "--method") in options and ("fit", "--effects") in options


@pytest.mark.parametrize(("name", "option"), value_options(), ids=[" ".join(pair) for pair in value_options()])
def test_a_value_option_given_twice_is_refused(name, option, calls, tmp_path):
    assert_user_error(run(name, "ARG", option, "1", option, "2"), f"{option} given twice", "allowed: once")
    short = [opt for opt in cli.main.commands[name].params if option in opt.opts][0].opts
    if len(short) > 1:  # -o and --output are one option
        assert_user_error(run(name, "ARG", short[0], "1", short[1], "2"), f"{option} given twice")
    assert calls == [] and list(tmp_path.iterdir()) == []


@pytest.mark.parametrize(("args", "fragments"), [
    (["control", "{h5}", "--sigma", "y0=0.002", "--sigma", "y0=0.004"], ["--sigma: y0 given twice", "each parameter once"]),
    (["simulate-drops", "{square}", "-o", "{tmp}/d.csv", "--tracks", "3", "--range", "y0=0.1:0.2", "--range", "y0=0.2:0.3"],
     ["--range: y0 given twice"]),
    (["roll", "{table1}", "--set", "initial.y0=0.2", "--set", "initial.y0=0.3"], ["--set: initial.y0: given twice", "each key once"]),
    (["roll", "{table1}", "--set", "initial.y0=0.2", "--set", " initial . y0 =0.3"], ["given twice"]),
    (["sweep", "{demo}", "-o", "{tmp}/s.h5", "--set", "grid.x.num=8", "--set", "grid.x={{param='y0', min=0.1, max=0.2, num=4}}"],
     ["--set: grid.x: overlaps grid.x.num, also set"]),
    (["fit", "{tmp}/d.csv", "--config", "{square}", "--effects", "air_drag,air_drag"], ["--effects: 'air_drag' given twice"]),
])
def test_a_repeatable_option_naming_its_key_twice_is_refused(args, fragments, tmp_path):
    names = {"h5": tmp_path / "none.h5", "square": CONFIG_DIR / "square_drops.toml", "table1": TABLE1, "demo": DEMO, "tmp": tmp_path}
    assert_user_error(run(*[arg.format(**names) for arg in args]), *fragments)
    assert list(tmp_path.iterdir()) == []


def test_repeatable_options_with_different_keys_combine_and_a_flag_may_repeat(calls):
    result = run("sweep", DEMO, "-o", "x.h5", "--set", "grid.x.num=4", "--set", "grid.y.num=6", "--quiet", "--quiet")
    assert result.exit_code == 0, result.stderr
    (_, (cfg, _), _), = calls
    assert (cfg.grid.x.num, cfg.grid.y.num) == (4, 6)


def test_version():
    assert run("--version").stdout.strip().endswith(cli.__version__)


# ---- config and --set errors end to end -----------------------------------------------------


def test_set_out_of_range_is_one_line_naming_file_key_and_range(calls):
    line = assert_user_error(run("roll", TABLE1, "--set", "contact.beta_normal=1.5"))
    assert line == f"error: {TABLE1} with --set: contact.beta_normal: 1.5 is outside the allowed range [0, 1]"
    assert calls == []


@pytest.mark.parametrize(
    ("override", "fragments"),
    [
        ("contact.beta_normal", ["--set: contact.beta_normal", "expected section.key=value"]),
        ("contact.beta_norml=0.3", ["--set: contact.beta_norml", "did you mean 'beta_normal'?"]),
        ("grid.x.nm=8", ["--set: grid.x.nm", "did you mean 'num'?"]),
        ("die.sides=2.5", ["die.sides", "expected an integer"]),
        ("integrator.method=rk4", ["integrator.method", "allowed values: event, fixed_step"]),
    ],
)
def test_bad_set_on_roll_and_sweep(calls, override, fragments):
    assert_user_error(run("roll", TABLE1, "--set", override), *fragments)
    assert_user_error(run("sweep", DEMO, "-o", "x.h5", "--set", override), *fragments)
    assert calls == []


def test_set_values_reach_the_library(calls):
    result = run("sweep", DEMO, "-o", "x.h5", "--set", "grid.x.num=4", "--set", "integrator.method=fixed_step", "--quiet")
    assert result.exit_code == 0, result.stderr
    (name, (cfg, out_path), kwargs), = calls
    assert (name, out_path) == ("run_sweep", "x.h5")
    assert cfg.grid.x.num == 4 and cfg.integrator.method == "fixed_step"


@pytest.mark.parametrize(
    ("text", "fragments"),
    [
        ("[die]\nsides = 2\n", ["die.sides", "2 is outside the allowed range [3, 127]"]),
        ("[contact]\nbeta_tangential = 2.0\n", ["contact.beta_tangential", "allowed range [-1, 1]"]),
        ("[walls]\nseparation = 0.01\n", ["walls.separation", "allowed range (0.0268701, inf) m"]),
        ("[initial]\ny0 = 0.001\n", ["initial.y0", "into the table"]),
        ("[initial]\nomega0 = nan\n", ["initial.omega0", "not a finite number"]),
        ("[die]\nsides = 4\n[contact\n", ["line 3", "TOML syntax error"]),
        ("[dye]\nsides = 4\n", ["dye", "did you mean 'die'?"]),
    ],
)
def test_bad_config_file_is_one_line_error(tmp_path, calls, text, fragments):
    path = tmp_path / "bad.toml"
    path.write_text(text)
    assert_user_error(run("roll", path), str(path), *fragments)
    assert calls == []


def test_missing_config_file(calls, tmp_path):
    assert_user_error(run("roll", tmp_path / "nope.toml"), "nope.toml", "No such file")


def test_sweep_needs_a_grid(calls):
    assert_user_error(run("sweep", TABLE1, "-o", "x.h5"), f"{TABLE1}: grid: missing")
    assert calls == []


# ---- option parsing -------------------------------------------------------------------------


@pytest.mark.parametrize("shard", ["3/2", "2/2", "-1/2", "a/b", "1", "1/2/3", "0/0"])
def test_bad_shard_is_one_line_error(calls, shard):
    assert_user_error(run("sweep", DEMO, "-o", "x.h5", "--shard", shard), "--shard")
    assert calls == []


@pytest.mark.parametrize(
    ("options", "fragments"),
    [
        (["--executor", "spark"], ["--executor 'spark'", "local, dask"]),
        (["--scheduler", "tcp://h:8786"], ["--scheduler", "only with --executor dask"]),
        (["--executor", "dask", "--scheduler", "tcp://h:8786", "--workers", "2"], ["--workers", "not with --scheduler"]),
    ],
)
def test_bad_executor_options_are_one_line_errors_and_write_nothing(tmp_path, options, fragments):
    out = tmp_path / "x.h5"
    assert_user_error(run("sweep", DEMO, "-o", out, *options), *fragments)
    assert not out.exists()


@pytest.mark.parametrize("workers", ["0", "-3", "1025", "abc"])
def test_bad_workers_is_one_line_error(calls, workers):
    assert_user_error(run("sweep", DEMO, "-o", "x.h5", "--workers", workers), "--workers")
    assert_user_error(run("control", "x.h5", "--sigma", "y0=0.01", "--workers", workers), "--workers")
    assert calls == []


@pytest.mark.parametrize("box", ["1,2,3", "a,b,c,d", "2,1,0,1", "0,1,1,0", "0,1,0,nan", "0,1,0,1,2"])
def test_bad_box_is_one_line_error(calls, box):
    assert_user_error(run("plot", "x.h5", "-o", "x.png", "--box", box), "--box")
    assert calls == []


@pytest.mark.parametrize("dpi", ["0", "9", "1001", "100000"])
def test_bad_dpi_is_one_line_error(calls, dpi):
    """--dpi 100000 ended in a MemoryError traceback (issue 16)."""
    assert_user_error(run("plot", "x.h5", "-o", "x.png", "--dpi", dpi), f"--dpi: {dpi} ", "[10, 1000]")
    assert calls == []


def assert_warns_on_stderr(warn):
    """``warn`` (what the CLI hands draw_sweep_file) writes its line to stderr as a warning."""
    said = []
    with mock.patch.object(cli.click, "echo", lambda text, err=False: said.append((text, err))):
        warn("200 of 400 cells not computed yet")
    assert said == [("warning: 200 of 400 cells not computed yet", True)]


# ---- wiring of the commands to the library ----------------------------------------------------


def test_sweep_passes_options_to_run_sweep_and_plots(calls):
    result = run("sweep", DEMO, "-o", "out.h5", "--png", "out.png", "--workers", "3", "--shard", "1/4", "--resume")
    assert result.exit_code == 0, result.stderr
    (name, (cfg, out_path), kwargs), plot_call = calls
    assert name == "run_sweep" and out_path == "out.h5"
    assert kwargs == {"workers": 3, "shard": (1, 4), "resume": True, "progress": True,
                      "executor": "local", "scheduler": None}
    assert cfg.grid.x.num == 128 and cfg.source == DEMO
    assert plot_call[:2] == ("draw_sweep_file", ("out.h5", "out.png")) and set(plot_call[2]) == {"warn"}
    assert_warns_on_stderr(plot_call[2]["warn"])
    assert result.stdout.splitlines() == ["summary line", "wrote the.png"]


def test_sweep_defaults(calls):
    result = run("sweep", DEMO, "-o", "out.h5", "--quiet")
    assert result.exit_code == 0, result.stderr
    assert calls[0][2] == {"workers": None, "shard": (0, 1), "resume": False, "progress": False,
                           "executor": "local", "scheduler": None}
    assert result.stdout == ""


def test_roll_prints_a_sentence_or_json(calls):
    result = run("roll", TABLE1)
    assert result.exit_code == 0, result.stderr
    assert result.stdout.strip() == "side 2 after 7 impacts, decided at t = 0.4321 s"
    result = run("roll", TABLE1, "--json", "--set", "initial.omega0=25")
    assert json.loads(result.stdout) == {"outcome": 2, "status": 0, "impacts": 7, "t_decided": 0.4321}
    assert calls[-1][1][0].initial.omega0 == 25.0


def test_roll_that_is_not_decided_says_why(calls, monkeypatch):
    report = types.SimpleNamespace(outcome=-1, status=1, status_name="t_max", impacts=900, t_decided=float("nan"))
    monkeypatch.setattr(sys.modules["dice_sweep.app.roll"], "roll_config", lambda cfg: report)
    assert run("roll", TABLE1).stdout.strip() == "no side: t_max (status 1) after 900 impacts"


def test_roll_draws_png_and_gif(calls):
    result = run("roll", TABLE1, "--png", "r.png", "--gif", "r.gif")
    assert result.exit_code == 0, result.stderr
    assert [(name, args[2]) for name, args, _ in calls[1:]] == [("plot_roll", "r.png"), ("animate_roll", "r.gif")]


def test_merge_and_plot_pass_their_arguments(calls):
    assert run("merge", "a.h5", "b.h5", "-o", "m.h5").exit_code == 0
    assert run("plot", "m.h5", "-o", "m.png", "--box", "1,2,0.1,0.2", "--dpi", "80").exit_code == 0
    warn = calls[1][2].pop("warn")
    assert calls == [
        ("merge_parts", (("a.h5", "b.h5"), "m.h5"), {}),
        ("draw_sweep_file", ("m.h5", "m.png"), {"box": (1.0, 2.0, 0.1, 0.2), "dpi": 80}),
    ]
    assert_warns_on_stderr(warn)


@pytest.mark.parametrize("command", [("sweep", DEMO), ("merge", "a.h5")])
def test_an_empty_output_name_is_refused_before_any_work(calls, command):
    """-o "" is checked as "." (the path the writer would get), not skipped as an option not given."""
    assert_user_error(run(*command, "-o", ""), "--output: .: wrong file extension")
    assert calls == []


def test_library_user_errors_and_os_errors_become_one_line(calls, monkeypatch):
    import dice_sweep.sweep
    from dice_sweep.errors import DiceSweepError

    def refuse(*args, **kwargs):
        raise DiceSweepError("x.h5: exists; use --resume or remove it")

    monkeypatch.setattr(dice_sweep.sweep, "run_sweep", refuse)
    assert_user_error(run("sweep", DEMO, "-o", "x.h5"), "x.h5: exists")

    def unwritable(*args, **kwargs):
        raise PermissionError(13, "Permission denied", "x.h5")

    monkeypatch.setattr(dice_sweep.sweep, "merge_parts", unwritable)
    assert_user_error(run("merge", "a.h5", "-o", "x.h5"), "Permission denied")


def test_interrupted_sweep_exits_130(calls, monkeypatch):
    import dice_sweep.sweep

    def interrupted(*args, **kwargs):
        raise dice_sweep.sweep.SweepInterrupted("x.h5: interrupted; run again with --resume")

    monkeypatch.setattr(dice_sweep.sweep, "run_sweep", interrupted)
    result = run("sweep", DEMO, "-o", "x.h5")
    assert result.exit_code == 130
    assert result.stderr.strip() == "error: x.h5: interrupted; run again with --resume"


def test_bugs_are_not_hidden(calls, monkeypatch):
    import dice_sweep.sweep

    monkeypatch.setattr(dice_sweep.sweep, "run_sweep", lambda *a, **k: 1 / 0)
    result = run("sweep", DEMO, "-o", "x.h5")
    assert result.exit_code == 1
    assert isinstance(result.exception, ZeroDivisionError)


# ---- end to end with the real kernel ---------------------------------------------------------


@pytest.mark.parametrize("overrides", [[], ["initial.omega0=35", "contact.beta_normal=0.5"]], ids=["as-is", "set"])
def test_roll_table1_json_end_to_end(overrides):
    """The real roll of configs/table1.toml (and with --set) is the library's roll of the same
    config, number for number: outcome, status, impacts, t_decided and every counter."""
    from dice_sweep.config import load_config
    from dice_sweep.roll import roll_config

    sets = [arg for override in overrides for arg in ("--set", override)]
    result = run("roll", TABLE1, *sets, "--json")
    assert result.exit_code == 0, result.stderr
    report = json.loads(result.stdout)
    expected = roll_config(load_config(TABLE1, overrides))
    assert report == json.loads(json.dumps(expected.to_dict()))
    assert (report["outcome"], report["status_code"], report["impacts"], report["t_decided"]) == (
        expected.outcome, expected.status, expected.impacts, expected.t_decided)
    assert report["status"] == "decided" and report["outcome"] in range(4)
    # the centre falls 0.15 - R before the first corner can touch: decided after that
    assert report["t_decided"] > (2 * (0.15 - 0.0135) / 9.81) ** 0.5
    if overrides:  # the --set values reached the roll: not the roll of the file as it is
        plain = roll_config(load_config(TABLE1))
        assert (report["outcome"], report["impacts"], report["t_decided"]) != (plain.outcome, plain.impacts, plain.t_decided)


def test_click_is_imported_only_by_the_cli():
    package = pathlib.Path(cli.__file__).parent
    importers = sorted(
        path.relative_to(package).as_posix()
        for path in package.rglob("*.py")
        if "import click" in path.read_text() or "from click" in path.read_text()
    )
    assert importers == ["cli.py"]
    assert isinstance(cli.main, click.Group)


def test_roll_refuses_an_initial_start_in_the_table_when_a_grid_sweeps_it():
    """fig08 sweeps y0; `roll` starts from initial.y0, which -1 put 1 m into the table (it
    printed "side 3 after 0 impacts", exit 0)."""
    result = run("roll", CONFIG_DIR / "fig08.toml", "--set", "initial.y0=-1")
    assert_user_error(result, "fig08.toml", "initial.y0", "into the table", "y0 >= ")
    assert result.stdout == ""


# ---- bad input of issue 16: checked before the work, nothing written ------------------------

SQUARE = str(CONFIG_DIR / "square_drops.toml")
SMALL = ["--set", "grid.x.num=8", "--set", "grid.y.num=8"]
IMAGE_KINDS = "ending in .png, "  # the start of the list of image formats every picture option names
# Every output of every command: (arguments, "{}" where the output goes and "{tmp}" for the test's
# folder; the option; a good name of the output's kind, or None for a folder of pictures).
OUTPUTS = [
    (["sweep", DEMO, *SMALL, "-o", "{}"], "--output", "s.h5"),
    (["sweep", DEMO, *SMALL, "-o", "{tmp}/ok.h5", "--png", "{}"], "--png", "s.png"),
    (["merge", "{tmp}/p0.h5", "{tmp}/p1.h5", "-o", "{}"], "--output", "m.h5"),
    (["plot", "{tmp}/s.h5", "-o", "{}"], "--output", "p.png"),
    (["roll", TABLE1, "--png", "{}"], "--png", "r.png"),
    (["roll", TABLE1, "--gif", "{}"], "--gif", "r.gif"),
    (["measure", "{tmp}/s.h5", "--json", "{}"], "--json", "m.json"),
    (["measure", "{tmp}/s.h5", "--png", "{}"], "--png", None),
    (["control", "{tmp}/s.h5", "--sigma", "y0=0.002", "--json", "{}"], "--json", "c.json"),
    (["control", "{tmp}/s.h5", "--sigma", "y0=0.002", "--png", "{}"], "--png", None),
    (["control", "{tmp}/s.h5", "--sigma", "y0=0.002", "-o", "{}"], "--output", "c.npz"),
    (["calibrate", "{tmp}/d.csv", "--config", SQUARE, "--json", "{}"], "--json", "cal.json"),
    (["calibrate", "{tmp}/d.csv", "--config", SQUARE, "--png", "{}"], "--png", "cal.png"),
    (["fit", "{tmp}/d.csv", "--config", SQUARE, "--json", "{}"], "--json", "f.json"),
    (["fit", "{tmp}/d.csv", "--config", SQUARE, "--png", "{}"], "--png", None),
    (["diagnose", "{tmp}/d.csv", "--config", SQUARE, "--json", "{}"], "--json", "r.json"),
    (["diagnose", "{tmp}/d.csv", "--config", SQUARE, "--json", "{tmp}/r.json", "--md", "{}"], "--md", "r.md"),
    (["diagnose", "{tmp}/d.csv", "--config", SQUARE, "--json", "{tmp}/r.json", "--png", "{}"], "--png", None),
    (["simulate-drops", SQUARE, "--tracks", "2", "-o", "{}"], "--output", "d.csv"),
]


def bad_output(case, tmp_path, good):
    """(path, fragment of the error) of an output that cannot be written, made in tmp_path."""
    name = good or "pictures"
    if case == "missing folder":
        return tmp_path / "missing" / name, "folder " + str(tmp_path / "missing") + " does not exist"
    if case == "under a file":
        (tmp_path / "file.txt").write_text("a file")
        return tmp_path / "file.txt" / name, "is a file, not a folder"
    if case == "folder for a file" and good:
        (tmp_path / good).mkdir()
        return tmp_path / good, "is a folder"
    if case == "folder for a file":  # a folder of pictures given where a file is
        (tmp_path / name).write_text("a file")
        return tmp_path / name, "is a file"
    if case == "wrong extension":
        return tmp_path / "out.xyz", "wrong file extension"
    if not Path("/sys").is_dir() or os.access("/sys", os.W_OK) and os.geteuid() != 0:
        pytest.skip("needs a folder nobody may write to (/sys)")
    return Path("/sys") / name, "folder /sys cannot be written to"


BAD_OUTPUTS = [  # a folder has no extension to be wrong
    (*output, case) for output in OUTPUTS
    for case in ("missing folder", "under a file", "folder for a file", "wrong extension", "unwritable folder")
    if output[2] or case != "wrong extension"
]


@pytest.mark.parametrize(("args", "option", "good", "case"), BAD_OUTPUTS,
                         ids=[f"{a[0]} {o} {case}" for a, o, _, case in BAD_OUTPUTS])
def test_every_output_is_checked_before_the_work(tmp_path, args, option, good, case):
    """Issue 16: `sweep --png /missing/dir/a.png` failed only after the whole sweep, and `plot -o
    b.xyz` in a ValueError traceback. Each output of each command is refused on one line naming
    the option and the path, and nothing is written."""
    path, fragment = bad_output(case, tmp_path, good)
    before = sorted(tmp_path.rglob("*"))
    argv = [arg.replace("{}", str(path)).replace("{tmp}", str(tmp_path)) for arg in args]
    line = assert_user_error(run(*argv), f"{option}: {path}: ", fragment, "(allowed: ")
    if good and good.endswith(".png"):
        assert IMAGE_KINDS in line
    assert sorted(tmp_path.rglob("*")) == before


def test_two_outputs_on_one_path_are_refused(tmp_path):
    same = tmp_path / "same.json"
    assert_user_error(run("measure", tmp_path / "s.h5", "--json", same, "--png", same), f"--png: {same}: also given to --json")
    assert list(tmp_path.iterdir()) == []


def test_picture_formats_are_checked_before_the_sweep(calls, tmp_path):
    """Issue 16: `sweep CONFIG -o a.h5 --png x.h5` ran the whole sweep, then a ValueError traceback."""
    assert_user_error(run("sweep", DEMO, "-o", tmp_path / "a.h5", "--png", tmp_path / "x.h5"), "--png", "x.h5", ".png")
    assert_user_error(run("plot", tmp_path / "f.h5", "-o", tmp_path / "b.xyz"), "--output", "b.xyz", ".svg")
    assert calls == [] and list(tmp_path.iterdir()) == []


@pytest.fixture(scope="module")
def inputs(tmp_path_factory):
    """Inputs for the probes: sweeps of demo.toml at 16 x 16 in tiles of 8 x 8 ("whole", and
    "half" with only shard 0 of 2 computed); 4 simulated drops ("drops", at 250 Hz), with their
    times in ns ("ns") and slowed 100 times ("slow")."""
    from dice_sweep.config import load_config

    folder = tmp_path_factory.mktemp("inputs")
    cfg = load_config(DEMO, ["grid.x.num=16", "grid.y.num=16"])
    paths = {name: folder / f"{name}.h5" for name in ("whole", "half")}
    small_sweep(cfg, paths["whole"], tile_shape=(8, 8))
    small_sweep(cfg, paths["half"], shard=(0, 2), tile_shape=(8, 8))
    paths["drops"] = folder / "drops.csv"
    assert run("simulate-drops", SQUARE, "-o", paths["drops"], "--tracks", 4).exit_code == 0
    header, *rows = paths["drops"].read_text().splitlines()
    for name, scale in (("ns", 1e-9), ("slow", 100.0)):
        paths[name] = folder / f"{name}.csv"
        scaled = [",".join([row.split(",")[0], repr(float(row.split(",")[1]) * scale), *row.split(",")[2:]]) for row in rows]
        paths[name].write_text("\n".join([header, *scaled]) + "\n")
    return paths


@pytest.fixture(scope="module")
def half_sweep(inputs):
    return inputs["half"]


def test_plot_of_an_incomplete_sweep_warns_on_one_line(half_sweep, tmp_path):
    """Issue 16: it exited 0 without a word, cells not computed drawn as 'undecided'."""
    result = run("plot", half_sweep, "-o", tmp_path / "half.png")
    assert result.exit_code == 0, result.stderr
    assert result.stderr.splitlines() == [f"warning: {half_sweep}: 128 of 256 cells not computed yet, drawn grey as "
                                          "'not computed' (finish the sweep with --resume, or merge its shards)"]
    assert "not computed" in run("plot", "--help").stdout
    # the picture: 7 x 5 inches at the default 150 dpi; on the map, half the cells grey (not
    # computed) and every side's colour in the share of the cells that rolled it
    from dice_sweep import plotting
    from dice_sweep.storage import read_sweep

    png = tmp_path / "half.png"
    assert png_size(png) == figure_pixels(plotting.OUTCOME_FIGSIZE, 150)
    sweep = read_sweep(half_sweep)
    drawn = {plotting.NOT_COMPUTED_COLOR: ~sweep.computed, plotting.UNDECIDED_COLOR: sweep.computed & (sweep.outcome == -1)}
    for side, colour in enumerate(plotting.outcome_colors(sweep.sides)):
        drawn[tuple(colour)] = sweep.computed & (sweep.outcome == side)
    region = map_region(read_png(png), drawn)
    for colour, cells in drawn.items():
        assert share(region, colour) == pytest.approx(cells.mean(), abs=0.02), colour
    assert share(region, plotting.NOT_COMPUTED_COLOR) == pytest.approx(0.5, abs=0.02)


def test_plot_of_a_damaged_file_names_it_and_writes_nothing(half_sweep, tmp_path):
    """Issue 16: a corrupt chunk gave 'error: Can't synchronously read data (...)', no file named."""
    damaged = tmp_path / "damaged.h5"
    damaged.write_bytes(half_sweep.read_bytes())
    corrupt_first_chunk(damaged)
    assert_user_error(run("plot", damaged, "-o", tmp_path / "d.png"), f"{damaged}: cannot read", "damaged")
    assert_user_error(run("measure", damaged), f"{damaged}: cannot read")
    assert not (tmp_path / "d.png").exists()


def test_missing_folder_and_running_sweep_files_get_their_own_messages(held_open, tmp_path):
    """Issue 16: all got 'if a kill damaged it, remove it and rerun', even a running sweep's file."""
    (tmp_path / "folder.h5").mkdir()
    assert_user_error(run("plot", tmp_path / "nope.h5", "-o", tmp_path / "p.png"), "nope.h5: no such file")
    assert_user_error(run("plot", tmp_path / "folder.h5", "-o", tmp_path / "p.png"), "folder.h5: is a folder")
    running = held_open("r+")
    for args in (["plot", running, "-o", tmp_path / "p.png"], ["sweep", DEMO, "-o", running, "--resume"],
                 ["sweep", DEMO, "-o", running], ["merge", tmp_path / "nope.h5", "-o", running]):
        line = assert_user_error(run(*args), str(running), "a sweep or merge may be running on it")
        assert "remove" not in line
    assert not (tmp_path / "p.png").exists()


# ---- further bad input found probing every command (issue 16) --------------------------------

# (arguments, with {name} for an input of the `inputs` fixture and {tmp} for the test's folder;
# fragments of the one error line)
PROBES = [
    (["roll", TABLE1, "--bogus"], ["No such option '--bogus'", "'dice-sweep roll --help'"]),
    (["sweep", DEMO, "-o", "{tmp}/x.h5", "--workers", "abc"], ["'--workers': 'abc' is not a valid integer"]),
    (["sweep", DEMO, "--workers", "2"], ["Missing option '-o' / '--output'"]),
    (["bogus"], ["No such command 'bogus'"]),
    (["roll", TABLE1, "--set", "die.circumradius=1e-308"], ["die.circumradius", "allowed range [1e-09, inf) m"]),
    (["roll", TABLE1, "--set", "integrator.max_events=99999999999999999999"], ["integrator.max_events", "allowed range [1, "]),
    (["plot", "{whole}", "-o", "{tmp}/p.png", "--box", "100,200,5,6"], ["--box: 100,200,5,6 is not inside the map", "[0, 60]"]),
    (["plot", "{whole}", "-o", "{tmp}/.png"], ["--output", "nothing before the extension"]),
    (["measure", "{whole}", "--box-size", "0"], ["--box-size: 0 is outside the allowed range"]),
    (["control", "{whole}", "--sigma", "y0=1e308"], ["--sigma 'y0=1e308'", "0 <= STD <= 1e+300"]),
    (["control", "{whole}", "--sigma", "y0=0.01", "--method", "monte_carlo", "--samples", "100000000000"],
     ["--samples 100000000000", "at most 10000000"]),
    (["control", "{whole}", "--sigma", "y0=0.01", "--method", "monte_carlo", "--seed", "-1"], ["--seed: -1", "[0, inf)"]),
    (["simulate-drops", SQUARE, "-o", "{tmp}/x.csv", "--tracks", "2", "--noise", "1e308,0,0"], ["--noise", "a sigma above 1", ">= 0 and at most 1"]),
    (["calibrate", "{drops}", "--config", SQUARE, "--rate", "1e9"], ["rate: 1e+09 Hz", "1 to 1e+06 Hz"]),
    (["calibrate", "{drops}", "--config", SQUARE, "--rate", "1e-300"], ["rate: 1e-300 Hz", "1 to 1e+06 Hz"]),
    (["calibrate", "{ns}", "--config", SQUARE], ["ns.csv: column 't'", "are the times in s?"]),
    (["fit", "{slow}", "--config", SQUARE, "--rate", "1e6"], ["slow.csv: trajectory 1", "at most 1e+07 a track"]),
    (["diagnose", "{tmp}/missing.csv", "--config", SQUARE, "--json", "{tmp}/r.json"], ["missing.csv: file: no such file"]),
    (["calibrate", "{tmp}", "--config", SQUARE], ["file: is a folder"]),
]


@pytest.mark.parametrize(("args", "fragments"), PROBES, ids=[" ".join(args[:2] + args[-2:]) for args, _ in PROBES])
def test_probed_bad_input_is_one_line_before_any_work(inputs, tmp_path, args, fragments):
    """Each of these was a traceback (an OverflowError, ZeroDivisionError, MemoryError,
    ValueError), several lines of click usage, or silently nothing (a --box off the map, a
    '.png' written as '.png.png')."""
    names = {name: str(path) for name, path in inputs.items()}
    argv = [arg.format(tmp=tmp_path, **names) for arg in args]
    assert_user_error(run(*argv), *fragments)
    assert list(tmp_path.iterdir()) == []


def test_a_blur_wider_than_the_map_is_the_map_average(inputs):
    """--sigma y0=1e300 (allowed) was an OverflowError sizing the blur's kernel."""
    result = run("control", inputs["whole"], "--sigma", "y0=1e300")
    assert result.exit_code == 0, result.stderr
    assert "by Gaussian blur of the map; sigma: y0 1e+300 m" in result.stdout


def test_simulate_drops_never_replaces_tracked_data(inputs, tmp_path):
    tracked = tmp_path / "tracked.csv"
    tracked.write_bytes(inputs["drops"].read_bytes())  # as a tracker wrote it: no sidecar
    assert_user_error(run("simulate-drops", SQUARE, "-o", tracked, "--tracks", 2), f"--output: {tracked}: exists and was not written")
    assert tracked.read_bytes() == inputs["drops"].read_bytes() and list(tmp_path.iterdir()) == [tracked]
    again = tmp_path / "again.csv"
    for _ in range(2):  # its own output it may write again
        assert run("simulate-drops", SQUARE, "-o", again, "--tracks", 2).exit_code == 0


def test_a_compile_of_a_kernel_is_announced_once_on_stderr(tmp_path):
    """Issue 16: a cold start compiled for 20 s without a word. A command that runs kernels
    registers the note before it reads its input; the note comes when numba starts compiling a
    function of this package (a cache miss), once per process, and not for other modules'
    functions. In a fresh process: the command is refused at its config (nothing compiled),
    then fresh functions stand in for the kernel."""
    script = textwrap.dedent(f"""
        import sys
        sys.path.insert(0, {str(ROOT)!r})
        import numba
        from click.testing import CliRunner
        from dice_sweep.cli import main

        def roll_refused():
            assert CliRunner().invoke(main, ["roll", {str(TABLE1)!r}, "--set", "die.sides=2"]).exit_code == 2

        def say(line):
            sys.stderr.write(line + "\\n")
            sys.stderr.flush()

        roll_refused()
        other = {{"__name__": "elsewhere.module"}}
        exec("def other(x):\\n    return x + 1\\n", other)
        numba.njit(other["other"])(1)
        say("compiled elsewhere")
        ours = {{"__name__": "dice_sweep.probe"}}
        exec("def ours(x):\\n    return x + 2\\n\\ndef again(x):\\n    return x + 3\\n", ours)
        numba.njit(ours["ours"])(1)
        say("compiled ours")
        numba.njit(ours["again"])(1)
        roll_refused()  # a second registration in the same process adds nothing
        numba.njit(ours["ours"])(2.5)
        say("compiled again")
    """)
    env = {**os.environ, "DICE_SWEEP_COMPILE_NOTE": "1"}
    done = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, env=env, cwd=tmp_path, timeout=120)
    assert done.returncode == 0, done.stderr
    lines = done.stderr.splitlines()
    assert lines[0] == "compiled elsewhere" and lines[2:] == ["compiled ours", "compiled again"], lines
    assert lines[1].startswith("note: compiling the kernel") and "s on 2 cores" in lines[1]

@pytest.mark.parametrize("at_bound", [["beta_tangential"], []], ids=["at a bound", "inside"])
def test_diagnose_prints_a_warning_line_per_parameter_at_a_bound(monkeypatch, tmp_path, at_bound):
    """The line fit prints (tests/app/test_measured.py runs that one on drops), from diagnose's
    report: one warning line per parameter the report marks at a bound, none otherwise."""
    import dice_sweep.app.measured

    params = {"beta_normal": {"value": 0.2, "at_bound": False}, "beta_tangential": {"value": -1.0, "at_bound": bool(at_bound)}}
    report = {"verdict": "unexplained", "effects_added": [], "noise_floor": 3e-4, "params": params,
              "baseline": {"test_error": 5e-3}, "after": {"test_error": 5e-3, "multiple_of_floor": 16.7, "params": params}}
    monkeypatch.setattr(dice_sweep.app.measured, "run_diagnose", lambda *args, **kwargs: report)
    result = run("diagnose", tmp_path / "d.csv", "--config", CONFIG_DIR / "square_drops.toml", "--json", tmp_path / "r.json", "--quiet")
    assert result.exit_code == 0, result.stderr
    warned = [line.split()[1] for line in result.stderr.splitlines() if line.startswith("warning: ") and "sits at a bound" in line]
    assert warned == at_bound and result.stderr.count("\n") == len(at_bound)
