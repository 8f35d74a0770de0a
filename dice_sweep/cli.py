"""The ``dice-sweep`` command line: roll, sweep, merge, plot.

The only module that imports click. Each command is a few lines over one call into the
application layer (:mod:`dice_sweep.app`, one function per command); the modules are imported
inside the commands so that ``dice-sweep --help`` starts fast.
A user error (any :class:`~dice_sweep.errors.DiceSweepError`, or a file that cannot be read or
written) is printed as one line ``error: ...`` on stderr with exit code 2, never a traceback.
Every path a command writes is checked before its work (:func:`dice_sweep.outputs.check_outputs`).
"""

import inspect
import json
import os
import sys

import click

from dice_sweep import __version__
from dice_sweep.effects import config_key_specs, names as effect_names
from dice_sweep.errors import DiceSweepError

USER_ERROR_EXIT = 2
INTERRUPTED_EXIT = 130  # the shell's code for a process stopped by SIGINT (Ctrl-C)
SET_HELP = ("Override one config value, e.g. --set initial.omega0=20 or --set grid.x.num=64 (repeatable). Effect keys: "
            + ", ".join(f"{key.dotted} ({key.unit or '|'.join(key.choices)})" for keys in config_key_specs().values() for key in keys.values())
            + " (docs/effects.md).")


def _exit_code(error):
    """Exit code of a user error: 130 for an interrupted sweep, else 2."""
    # an interrupted sweep can only come from dice_sweep.sweep, so it is imported already
    sweep = sys.modules.get("dice_sweep.sweep")
    interrupted = getattr(sweep, "SweepInterrupted", ())
    return INTERRUPTED_EXIT if interrupted and isinstance(error, interrupted) else USER_ERROR_EXIT


def _checked(no_check_units):
    """Run a measured-data command with the checks of its tracks before the work
    (dice_sweep.measured.checks; their warnings as warning lines), or without them."""
    from dice_sweep.measured.checks import settings

    return settings(enabled=not no_check_units, warn=_warn)


def _usage_error(ctx, error):
    """click's own usage errors (an unknown option, a value of the wrong type, a missing
    argument) on one line too, instead of click's usage block; exit code 2."""
    if isinstance(error, getattr(click.exceptions, "NoArgsIsHelpError", ())):
        raise error  # no arguments at all: click shows the help
    where = (error.ctx or ctx).command_path
    click.echo(f"error: {error.format_message().rstrip('.')} (see '{where} --help')", err=True)
    ctx.exit(error.exit_code)


def _refuse_repeats(command, ctx, args):
    """An option given twice would silently keep its last value: refuse it (click.UsageError,
    one line, exit 2). Repeatable options (multiple=True: --set, --sigma, --range) combine,
    each naming a different key (their callbacks refuse a key named twice); a flag given twice
    says the same thing twice."""
    _, _, order = command.make_parser(ctx).parse_args(args=list(args))
    seen = set()
    for param in order:
        if not isinstance(param, click.Option) or param.multiple or param.is_flag:
            continue
        if param.name in seen:
            name = max(param.opts, key=len)
            repeatable = [max(p.opts, key=len) for p in command.params if isinstance(p, click.Option) and p.multiple]
            also = f"; repeatable: {', '.join(repeatable)}" if repeatable else ""
            raise click.BadOptionUsage(name, f"{name} given twice (allowed: once{also})", ctx)
        seen.add(param.name)


EXAMPLE = "\b\nExample"  # the last paragraph of every command's docstring: its example


def _example_last(command):
    """Move the docstring's closing example paragraph to the epilog, so that --help ends with
    it (after the options) instead of showing it above them."""
    head, mark, example = inspect.cleandoc(command.help or "").rpartition(EXAMPLE)
    if mark:
        command.help, command.epilog = head.rstrip(), mark + example


class _Command(click.Command):
    """A command whose --help ends with its example and that refuses a non-repeatable option
    given twice (_refuse_repeats)."""

    def __init__(self, *args, **kwargs):
        super().__init__(*args, **kwargs)
        _example_last(self)

    def parse_args(self, ctx, args):
        _refuse_repeats(self, ctx, args)
        return super().parse_args(ctx, args)


class _Commands(click.Group):
    """A click group that turns user errors into one line on stderr and exit code 2."""

    command_class = _Command

    def __init__(self, *args, **kwargs):
        super().__init__(*args, **kwargs)
        _example_last(self)

    def parse_args(self, ctx, args):
        try:
            return super().parse_args(ctx, args)
        except click.UsageError as error:
            _usage_error(ctx, error)

    def invoke(self, ctx):
        from dice_sweep.outputs import together

        try:
            with together():  # a command's files appear together once it succeeds, or none does
                return super().invoke(ctx)
        except click.UsageError as error:
            _usage_error(ctx, error)
        except (DiceSweepError, OSError) as error:
            click.echo(f"error: {' '.join(str(error).split())}", err=True)  # one line, whatever the text
            ctx.exit(_exit_code(error))


IMAGE = "image"  # an output that is a picture: any format of dice_sweep.plotting.image_formats()


def _check_outputs(*outputs):
    """dice_sweep.outputs.check_outputs, asking plotting for the image formats only where a
    picture is written (it imports matplotlib)."""
    from dice_sweep.outputs import check_outputs

    if any(path and kind == IMAGE for _, path, kind in outputs):
        from dice_sweep.plotting import image_formats

        outputs = [(option, path, image_formats() if kind == IMAGE else kind) for option, path, kind in outputs]
    check_outputs(*outputs)


def _warn(line):
    click.echo(f"warning: {line}", err=True)


_fast_exit = []  # set by a command whose process may end without the interpreter's teardown


def _fast_kernel_start():
    # commands that only run our kernels skip numba's 0.3-0.5 s BLAS probe (see the module)
    from dice_sweep.startup import skip_numba_blas_probe

    skip_numba_blas_probe()
    _compile_notice()
    _fast_exit.append(True)


def run():
    """The program (``dice-sweep``, ``python -m dice_sweep``): :func:`main`, then, after a
    command that runs the kernels, an exit that skips the interpreter's teardown.

    Such a command has closed its files and joined its workers when it returns; the teardown
    of numba's and LLVM's objects after it took 0.25 s of CPU (medians of 6 ``sweep`` commands
    on 2 x 2 cells: 0.855 s of CPU with it, 0.595 without; docs/dev/sweep_time.md), a serial
    cost no worker shares. The exit handlers (atexit) still run, and stdout and stderr are
    flushed. Tests call :func:`main` in-process and so never exit here.
    """
    try:
        main()
    except SystemExit as ended:
        if not _fast_exit:
            raise
        code = ended.code
    else:
        return
    if code is not None and not isinstance(code, int):
        print(code, file=sys.stderr)  # what sys.exit does with a message
        code = 1
    import atexit

    atexit._run_exitfuncs()  # what the interpreter runs first at exit (no public name for it)
    sys.stdout.flush()
    sys.stderr.flush()
    os._exit(code or 0)


def _compile_notice():
    """Say on stderr, once, when numba starts compiling one of this package's kernels: with an
    empty or outdated cache the first run compiles for many seconds, silently otherwise (issue
    16). A compile starts only after every check of the input, so a bad input still gets one
    line."""
    if os.environ.get("DICE_SWEEP_COMPILE_NOTE", "1") == "0":  # the test suite turns it off
        return
    from dice_sweep.startup import COLD_COMPILE_SECONDS, notify_first_compile

    low, high = COLD_COMPILE_SECONDS
    notify_first_compile(lambda: click.echo(
        f"note: compiling the kernel (numba's cache is empty or out of date): about {low}-{high} s on 2 cores, "
        "once; later runs load it in about a second", err=True))


def _load(config_path, overrides):
    from dice_sweep.config import load_config

    return load_config(config_path, overrides)


def _parse_shard(ctx, param, text):
    from dice_sweep.executor import parse_shard  # not dice_sweep.sweep: numba is imported later, by _fast_kernel_start

    return parse_shard(text)


def _parse_box(ctx, param, text):
    if text is None:
        return None
    from dice_sweep.plotting import parse_box

    return parse_box(text)


def _at_least_one(ctx, param, value):
    if value is not None and value < 1:
        raise DiceSweepError(f"{max(param.opts, key=len)}: {value} is outside the allowed range [1, inf)")
    return value


def _workers(ctx, param, value):
    from dice_sweep.executor import worker_count

    return None if value is None else worker_count(value)


def _dpi(ctx, param, value):
    from dice_sweep.plotting import check_dpi

    return check_dpi(value)


def _distinct_sets(ctx, param, overrides):
    """--set given twice for one key, or for a key and a table holding it (grid.x and
    grid.x.num), is refused: the value would hang on their order. (The library applies
    overrides in order, later ones winning, as scripts that add their own rely on.)"""
    given = []
    for override in overrides:
        parts = tuple(part.strip() for part in override.partition("=")[0].split("."))
        for other in given:
            if other[:len(parts)] == parts or parts[:len(other)] == other:
                again = "given twice" if other == parts else f"overlaps {'.'.join(other)}, also set"
                raise DiceSweepError(f"--set: {'.'.join(parts)}: {again} (allowed: each key once, and not a key inside a table also set)")
        given.append(parts)
    return overrides


def _set_option(command):
    return click.option("--set", "overrides", multiple=True, callback=_distinct_sets, metavar="SECTION.KEY=VALUE", help=SET_HELP)(command)


@click.group(cls=_Commands, name="dice-sweep", context_settings={"help_option_names": ["-h", "--help"]})
@click.version_option(__version__, prog_name="dice-sweep")
def main():
    """Final-state diagrams of a two-dimensional n-gon die dropped on a table (Smith 2014).

    Configs are TOML files in SI units (see configs/). Errors in a config are reported on one
    line with the file, the key and the allowed range, and exit with code 2. An option given
    twice is refused, except --set, --sigma and --range, which combine when each names a
    different key.

    \b
    Example: dice-sweep sweep configs/fig08.toml -o out/fig08.h5 --png out/fig08.png
    """


@main.command()
@click.argument("config")
@_set_option
@click.option("--json", "as_json", is_flag=True, help="Print one JSON object instead of a sentence.")
@click.option("--png", "png_path", metavar="PATH", help="Draw the path of the die to this PNG.")
@click.option("--gif", "gif_path", metavar="PATH", help="Animate the roll into this GIF.")
def roll(config, overrides, as_json, png_path, gif_path):
    """Roll the die once from the [initial] state of CONFIG and print the side it lands on.

    \b
    Example: dice-sweep roll configs/table1.toml --set initial.omega0=20 --json
    """
    from dice_sweep.outputs import GIF

    _check_outputs(("--png", png_path, IMAGE), ("--gif", gif_path, GIF))
    _fast_kernel_start()
    from dice_sweep.app.roll import roll as roll_command

    report, _ = roll_command(_load(config, overrides), overrides, png_path=png_path, gif_path=gif_path)
    click.echo(json.dumps(report.to_dict(), allow_nan=False) if as_json else _describe_roll(report))  # never NaN: not JSON


def _describe_roll(report):
    """One sentence about a roll: the side, the impacts and the time to decision."""
    if report.status == 0:
        return f"side {report.outcome} after {report.impacts} impacts, decided at t = {report.t_decided:.4f} s"
    return f"no side: {report.status_name} (status {report.status}) after {report.impacts} impacts"


@main.command()
@click.argument("config")
@click.option("-o", "--output", "out_path", required=True, metavar="OUT.h5", help="HDF5 file to write.")
@click.option("--png", "png_path", metavar="OUT.png", help="Also draw the final-state diagram to this picture (.png, .pdf, .svg, ...).")
@click.option("--workers", type=int, callback=_workers, help="Worker processes, 1 to 1024 [default: all cores].")
@click.option("--shard", default="0/1", show_default=True, callback=_parse_shard, metavar="I/N", help="Run only part I of N (0 <= I < N); join the parts with merge.")
@click.option("--resume", is_flag=True, help="Finish an interrupted OUT.h5 of the same config and shard.")
@_set_option
@click.option("--quiet", is_flag=True, help="No progress bar and no summary line.")
@click.option("--refine", "refine_levels", type=int, metavar="LEVELS", help="Sweep 2^LEVELS times coarser, then refine only where neighbours disagree (a probability sweep: where a cell's draws do not all agree); rolls the full grid instead where refining cannot save rolls, and says which on stderr (docs/chaos.md).")
@click.option("--executor", default="local", show_default=True, metavar="local|dask", help="Where tiles are computed: forked local workers, or tasks on a dask.distributed cluster (pip install 'dice-sweep[dask]').")
@click.option("--scheduler", metavar="ADDRESS", help="With --executor dask: the scheduler, e.g. tcp://10.0.0.5:8786 [default: start a local cluster of --workers processes].")
def sweep(config, out_path, png_path, workers, shard, resume, overrides, quiet, refine_levels=None, executor="local", scheduler=None):
    """Roll the die over the [grid] of CONFIG and write the outcome maps to OUT.h5.

    With --refine LEVELS the grid is computed as a quadtree: OUT.h5 has the same maps at the
    full resolution plus /simulated, the pixels rolled at their own centre (docs/hdf5.md).
    With --executor dask the tiles run on a dask cluster and this process writes OUT.h5 as
    they arrive; --shard and --resume work the same (docs/scaling.md). With [scatter] draws
    M > 1 every cell is rolled M times under the stochastic impact law, and OUT.h5 also holds
    the share of each side (/probability_k, /no_answer; docs/chaos.md, docs/hdf5.md).

    \b
    Example: dice-sweep sweep configs/fig08.toml -o out/fig08.h5 --png out/fig08.png --workers 2
    """
    from pathlib import Path

    from dice_sweep.outputs import SWEEP_FILE

    # -o is required: an empty name is checked too (as ".", which check_outputs would skip as "")
    _check_outputs(("--output", Path(out_path), SWEEP_FILE), ("--png", png_path, IMAGE))
    _fast_kernel_start()
    from dice_sweep.app.sweep import sweep as sweep_command

    summary, written = sweep_command(
        _load(config, overrides), out_path, png_path=png_path, workers=workers, shard=shard, resume=resume,
        progress=not quiet, refine_levels=refine_levels, executor=executor, scheduler=scheduler,
        log=None if quiet else lambda line: click.echo(line, err=True), warn=_warn)
    if not quiet:
        click.echo(summary.describe())
    for path in written:
        _report_written(path, quiet)


def _report_written(path, quiet=False):
    if not quiet:
        click.echo(f"wrote {path}")


@main.command()
@click.argument("parts", nargs=-1, required=True, metavar="PART.h5...")
@click.option("-o", "--output", "out_path", required=True, metavar="OUT.h5", help="Merged HDF5 file to write.")
def merge(parts, out_path):
    """Join the shard files of one sweep (from sweep --shard I/N) into one complete OUT.h5.

    \b
    Example: dice-sweep sweep configs/fig08.toml -o out/part0.h5 --shard 0/2
             dice-sweep sweep configs/fig08.toml -o out/part1.h5 --shard 1/2
             dice-sweep merge out/part0.h5 out/part1.h5 -o out/fig08_merged.h5
    """
    from dice_sweep.app.sweep import merge

    click.echo(merge(parts, out_path).describe())


@main.command()
@click.argument("h5_path", metavar="OUT.h5")
@click.option("-o", "--output", "png_path", required=True, metavar="OUT.png", help="Picture to write: .png, or any format matplotlib's Agg canvas writes (.pdf, .svg, .jpg, ...).")
@click.option("--box", callback=_parse_box, metavar="XMIN,XMAX,YMIN,YMAX", help="Draw a zoom rectangle, in the units of the axes.")
@click.option("--dpi", type=int, default=150, show_default=True, callback=_dpi, help="Pixels per inch, 10 to 1000 (the figure is 7 x 5 inches).")
def plot(h5_path, png_path, box, dpi):
    """Draw the final-state diagram of a sweep file OUT.h5 as a PNG.

    A sweep that is not complete (interrupted, or one shard) is drawn too, with exit code 0:
    the cells not computed yet are grey, "not computed" on the colour bar, and one warning
    line on stderr says how many there are.

    \b
    Example: dice-sweep plot out/demo.h5 -o out/demo_box.png --box 40,50,0.2,0.25 --dpi 200
    """
    from dice_sweep.app.sweep import draw_sweep_file

    _check_outputs(("--output", png_path, IMAGE))
    _report_written(draw_sweep_file(h5_path, png_path, box=box, dpi=dpi, warn=_warn))


# --- chaos measures and control maps (issue 6, docs/chaos.md) -----------------------------


@main.command()
@click.argument("h5_path", metavar="OUT.h5")
@click.option("--json", "json_path", metavar="OUT.json", help="Write every number (and the whole f(eps) curve) to this JSON file.")
@click.option("--png", "png_dir", metavar="DIR", help="Draw uncertainty.png and box_entropy.png into this folder.")
@click.option("--box-size", type=int, default=5, show_default=True, callback=_at_least_one, help="Box side in pixels for Sb and Sbb.")
def measure(h5_path, json_path, png_dir, box_size):
    """Measure the chaos of a sweep file: outcome fractions, Sb, Sbb and the uncertainty exponent;
    for a probability sweep ([scatter] draws > 1) also the predictable share (one side p >= 0.9)
    and the basin entropy (mean outcome entropy, nats).

    \b
    Example: dice-sweep measure out/demo.h5 --json out/demo_chaos.json --png out/demo_chaos
    """
    from dice_sweep.app.chaos import run_measure

    click.echo(run_measure(h5_path, box_size=box_size, json_path=json_path, png_dir=png_dir).describe())


def _distinct_keys(option, pairs):
    """(key, value) pairs of a repeatable option as a dict; a key named twice is refused."""
    chosen = {}
    for key, value in pairs:
        if key in chosen:
            raise DiceSweepError(f"{option}: {key} given twice (allowed: each parameter once)")
        chosen[key] = value
    return chosen


def _parse_sigmas(ctx, param, texts):
    from dice_sweep.chaos import parse_sigma

    return _distinct_keys("--sigma", (parse_sigma(text) for text in texts))


@main.command()
@click.argument("h5_path", metavar="OUT.h5")
@click.option("--sigma", "sigmas", multiple=True, callback=_parse_sigmas, metavar="PARAM=STD", help="Standard deviation of one initial value, in its SI unit (repeatable).")
@click.option("--method", default="auto", show_default=True, metavar="auto|blur|monte_carlo", help="blur the map's outcomes, or roll; auto blurs when the map resolves every sigma.")
@click.option("--samples", type=int, default=256, show_default=True, callback=_at_least_one, help="Monte Carlo rolls per point.")
@click.option("--points", type=int, default=64, show_default=True, callback=_at_least_one, help="Monte Carlo points per axis, at most.")
@click.option("--seed", type=int, default=0, show_default=True, help="Seed of the Monte Carlo draws.")
@click.option("--workers", type=int, callback=_workers, help="Worker processes for Monte Carlo, 1 to 1024 [default: all cores].")
@click.option("--json", "json_path", metavar="OUT.json", help="Write the summary to this JSON file.")
@click.option("--png", "png_dir", metavar="DIR", help="Draw control.png (most likely side, its probability, entropy) into this folder.")
@click.option("-o", "--output", "npz_path", metavar="OUT.npz", help="Save the probability maps as NumPy arrays.")
def control(h5_path, sigmas, method, samples, points, seed, workers, json_path, png_dir, npz_path):
    """Probability of each side for a thrower whose initial values scatter by --sigma.

    \b
    Example: dice-sweep control out/demo.h5 --sigma y0=0.002 --sigma omega0=0.5 --png out/demo_control
    """
    from dice_sweep.app.chaos import run_control

    control_map = run_control(
        h5_path, sigmas, json_path=json_path, png_dir=png_dir, npz_path=npz_path,
        method=method, samples=samples, max_points=points, seed=seed, workers=workers,
    )
    click.echo(control_map.describe())


def _data_options(command):
    """Options shared by the measured-data commands."""
    command = click.option("--no-check-units", "no_check_units", is_flag=True,
                           help="Skip the checks of the data's units and conventions (g, the angle's unit, the die, the angle's zero) "
                                "made before the work (docs/measured_method.md, 'Checks before the work').")(command)
    command = click.option("--angle", default="as-is", show_default=True, metavar="as-is|auto",
                           help="as-is: the file's phi is the model's angle; auto: measure its sign and zero from tracks that end at rest (refused when none does).")(command)
    command = click.option("--rate", type=float, metavar="HZ", help="Frame rate, for files with a frame column instead of t.")(command)
    command = click.option("--config", "config_path", required=True, metavar="CONFIG", help="The die and the declared model ([contact], [effects]).")(command)
    return command


@main.command(name="fit")
@click.argument("data", metavar="DATA")
@_data_options
@click.option("--effects", "effects_text", default="", metavar="A,B", help=f"Effects to add to the declared model ({', '.join(effect_names())}; docs/effects.md).")
@click.option("--json", "json_path", metavar="OUT.json", help="Write the fit to this JSON file.")
@click.option("--png", "png_dir", metavar="DIR", help="Draw the residual against time into this folder.")
def fit_command(data, config_path, rate, angle, no_check_units, effects_text, json_path, png_dir):
    """Fit the declared model (plus --effects) to whole tracked drops by multiple shooting on
    the selection tracks, with 95 % intervals (bootstrap over tracks and tracking noise);
    score it on the confirmation tracks (RMS pose error, m) against the tracking noise.

    \b
    Example: dice-sweep simulate-drops configs/square_drops.toml -o out/drops.csv --tracks 40 --seed 1
             dice-sweep fit out/drops.csv --config configs/square_drops.toml --json out/fit.json
    """
    from dice_sweep.app.measured import at_bound_lines, parse_effects, run_fit

    _compile_notice()
    with _checked(no_check_units):
        result = run_fit(data, _load(config_path, ()), effects=parse_effects(effects_text), rate=rate, angle=angle,
                         json_path=json_path, png_dir=png_dir)
    params = ", ".join(f"{k} = {p['value']:.4g} [{p['ci95'][0]:.4g}, {p['ci95'][1]:.4g}]" for k, p in result["params"].items())
    click.echo(f"{result['model']} + {result['effects'] or 'no effects'}: {params}; "
               f"error train {result['train_error'] * 1000:.3f} mm, held-out {result['test_error'] * 1000:.3f} mm "
               f"({result['test_error'] / result['noise_floor']:.1f} x the noise floor {result['noise_floor'] * 1000:.3f} mm)")
    for line in at_bound_lines(result["params"]):
        _warn(line)


@main.command()
@click.argument("data", metavar="DATA")
@_data_options
@click.option("--json", "json_path", required=True, metavar="REPORT.json", help="Write the report to this JSON file (docs/measured.md: its keys).")
@click.option("--md", "md_path", metavar="REPORT.md", help="Also write a readable Markdown report.")
@click.option("--png", "png_dir", metavar="DIR", help="Draw residual pictures, before and after, into this folder.")
@click.option("--quiet", is_flag=True, help="No progress lines.")
def diagnose(data, config_path, rate, angle, no_check_units, json_path, md_path, png_dir, quiet):
    """Fit the declared model to whole tracks, test every effect of the registry on tracks it
    was not fitted to, add one only when its gain is significant and its value not null,
    repeat; report the verdict (explained / improved / unexplained) against the tracking noise.

    \b
    Example: dice-sweep simulate-drops configs/square_drops.toml -o out/drops.csv --tracks 40 --seed 1
             dice-sweep diagnose out/drops.csv --config configs/square_drops.toml --json out/report.json --md out/report.md --png out/report
    """
    from dice_sweep.app.measured import at_bound_lines, run_diagnose

    _compile_notice()
    with _checked(no_check_units):
        report = run_diagnose(data, _load(config_path, ()), rate=rate, angle=angle, json_path=json_path, md_path=md_path,
                              png_dir=png_dir, log=None if quiet else lambda line: click.echo(line, err=True))
    click.echo(f"{report['verdict']}: effects added {report['effects_added'] or 'none'}; confirmation error "
               f"{report['baseline']['test_error'] * 1000:.3f} mm before, {report['after']['test_error'] * 1000:.3f} mm after "
               f"({report['after']['multiple_of_floor']:.1f} x the noise floor {report['noise_floor'] * 1000:.3f} mm)")
    for line in at_bound_lines(report["params"]):
        _warn(line)


def _parse_noise(ctx, param, text):
    from dice_sweep.app.simulate import parse_noise

    return parse_noise(text)


def _parse_ranges(ctx, param, texts):
    from dice_sweep.app.simulate import parse_range

    return _distinct_keys("--range", (parse_range(text) for text in texts))


def _number(kind, allowed):
    """A callback reading an option as int or float, with a one-line error (click's own is
    three lines); the library checks the range."""
    def convert(ctx, param, text):
        try:
            return kind(text)
        except ValueError:
            what = "a whole number" if kind is int else "a number"
            raise DiceSweepError(f"{max(param.opts, key=len)}: {text!r} is not {what} (allowed: {allowed})") from None
    return convert


@main.command(name="simulate-drops")
@click.argument("config")
@click.option("-o", "--output", "out_path", required=True, metavar="OUT.csv", help="Track file to write (.csv or .csv.gz); the provenance goes to OUT.csv.json.")
@click.option("--tracks", required=True, callback=_number(int, "1 to 100000"), metavar="N", help="Number of drops, 1 to 100000.")
@click.option("--seed", default="0", show_default=True, callback=_number(int, "a whole number >= 0"), metavar="S", help="Seed of every random draw (>= 0): the same seed gives the same file.")
@click.option("--rate", default="250", show_default=True, callback=_number(float, "> 0 Hz"), metavar="HZ", help="Frame rate of the file's clock.")
@click.option("--noise", default="2e-4,2e-4,5.236e-3", show_default=True, callback=_parse_noise, metavar="SX,SY,SPHI", help="Gaussian noise sigmas of x, y (m) and phi (rad).")
@click.option("--drop-prob", default="0.002", show_default=True, callback=_number(float, "0 to 0.5"), metavar="P", help="Probability that a frame is dropped (row removed), 0 to 0.5.")
@click.option("--glitch-prob", default="0.002", show_default=True, callback=_number(float, "0 to 0.5"), metavar="P", help="Probability that a frame is a glitch (pose jumped by R), 0 to 0.5.")
@click.option("--duration", default="1.5", show_default=True, callback=_number(float, "> 0 s, up to the config's integrator.t_max"), metavar="S", help="Longest track, s; a track ends 0.2 s after its die comes to rest.")
@click.option("--initial", "initial", default="drops", show_default=True, metavar="drops|config", help="drops: y0 0.1 to 0.3 m, any phi0, vx0 -0.3 to 0.3 m/s, vy0 -0.5 to 0 m/s, omega0 -10 to 10 rad/s, x0 = 0, each uniform; config: the config's [initial] values.")
@click.option("--range", "ranges", multiple=True, callback=_parse_ranges, metavar="PARAM=LOW:HIGH", help="Draw one initial value (x0, y0, phi0, vx0, vy0, omega0; SI) uniformly from this range instead (repeatable).")
@click.option("--renumber", is_flag=True, help="Number the rows left after dropped frames consecutively, as some trackers do (the loader finds the gaps).")
@_set_option
def simulate_drops_command(config, out_path, tracks, seed, rate, noise, drop_prob, glitch_prob, duration, initial, ranges, renumber, overrides):
    """Write SYNTHETIC tracked drops of the die of CONFIG, made by this project's own kernel, to
    try calibrate, fit and diagnose on or to test a pipeline: the contact law and [effects] of
    CONFIG in the kernel, its [tracking] effects on the tracker's view, then noise, dropped
    frames and glitches. The CSV (traj,t,x,y,phi) has no room for a note: OUT.csv.json says
    that the data are synthetic and holds the config, the seed, the options and the truth.
    Not an independent test of the model: the loop fits with the same kernel (docs/simulate_drops.md).

    \b
    Example: dice-sweep simulate-drops configs/square_drops.toml -o out/drops.csv --tracks 40 --seed 1
    """
    _fast_kernel_start()
    from dice_sweep.app.simulate import run_simulate_drops

    drops = run_simulate_drops(_load(config, overrides), out_path, tracks, seed=seed, rate=rate, noise=noise,
                               drop_prob=drop_prob, glitch_prob=glitch_prob, duration=duration, initial=initial,
                               ranges=ranges, renumber=renumber)
    click.echo(drops.describe(out_path))


@main.command(name="calibrate")
@click.argument("data", metavar="DATA")
@_data_options
@click.option("--gaps", default="auto", show_default=True, metavar="auto|as-is", help="Re-insert frames the file dropped, or keep its times.")
@click.option("--json", "json_path", metavar="OUT.json", help="Write every impact and the summary to this JSON file.")
@click.option("--png", "png_path", metavar="OUT.png", help="Draw histograms of the coefficients to this PNG.")
def calibrate_command(data, config_path, rate, angle, no_check_units, gaps, json_path, png_path):
    """Measure the restitution coefficients at every impact of the tracks in DATA, as the paper
    did by hand (eqs 9 and 10), with their corner-impulse counterparts, spread and outliers.

    \b
    Example: dice-sweep simulate-drops configs/square_drops.toml -o out/drops.csv --tracks 40 --seed 1
             dice-sweep calibrate out/drops.csv --config configs/square_drops.toml --json out/cal.json --png out/cal.png
    """
    from dice_sweep.app.measured import run_calibrate

    with _checked(no_check_units):
        result, written = run_calibrate(data, _load(config_path, ()), rate=rate, angle=angle, gaps=gaps, json_path=json_path,
                                        png_path=png_path)
    click.echo(result.describe())
    for path in written:
        _report_written(path)


# --- side forecasts of tracked drops (issue 18, docs/forecast.md) ----------------------------


@main.command(name="forecast")
@click.argument("data", metavar="DATA")
@_data_options
@click.option("--fit", "fit_path", required=True, metavar="FIT.json", help="The JSON of dice-sweep fit --json or diagnose --json on this die: the model, its parameters and their bootstrap draws, and the split (its confirmation tracks are the held-out tracks).")
@click.option("--from-bounce", "from_bounce", default="0", show_default=True, callback=_number(int, "0 to 5"), metavar="K", help="Forecast from the flight after bounce K (0: from the release), 0 to 5; every other flight enough held-out tracks have is scored too (by_bounce).")
@click.option("--members", default="2000", show_default=True, callback=_number(int, "1000 to 1000000"), metavar="N", help="Ensemble members per track and forecast point, 1000 to 1000000.")
@click.option("--seed", default="0", show_default=True, callback=_number(int, "a whole number >= 0"), metavar="S", help="Seed of the ensembles' draws.")
@click.option("--workers", type=int, callback=_workers, help="Worker processes, 1 to 1024 [default: all cores].")
@click.option("--map-size", "map_size", default="512", show_default=True, callback=_number(int, "16 to 2048, or 0"), metavar="N", help="Cells per axis of the final-state map of the release states (as docs/chaos.md's maps), 16 to 2048; 0: no map.")
@click.option("--map-axes", "map_axes", metavar="A,B", help="The map's two initial values, e.g. phi0,omega0 [default: the two that vary most over the drops].")
@click.option("--json", "json_path", required=True, metavar="OUT.json", help="Write the forecasts and scores to this JSON file (docs/forecast.md: its keys).")
@click.option("--md", "md_path", metavar="OUT.md", help="Also write a readable Markdown report.")
@click.option("--png", "png_dir", metavar="DIR", help="Draw reliability.png, skill_by_bounce.png and release_map.png into this folder.")
@click.option("--quiet", is_flag=True, help="No progress lines.")
def forecast_command(data, config_path, rate, angle, no_check_units, fit_path, from_bounce, members, seed, workers, map_size, map_axes, json_path, md_path,
                     png_dir, quiet):
    """Probability of each side for the held-out tracked drops of DATA, from what was seen before
    they landed: for every track an ensemble drawn from the uncertainty of its state in the
    frames of the flight forecast from (and of the fit's parameters), rolled to rest; scored
    against the side it rested on (log score, Brier score, beside 1/n and the deterministic
    forecast, with 95 % intervals over tracks), from every flight; and where the throws sit in
    the final-state map of their release states.

    \b
    Example: dice-sweep simulate-drops configs/square_drops.toml -o out/drops.csv --tracks 40 --seed 1
             dice-sweep fit out/drops.csv --config configs/square_drops.toml --json out/fit.json
             dice-sweep forecast out/drops.csv --config configs/square_drops.toml --fit out/fit.json --json out/forecast.json --png out/forecast
    """
    from dice_sweep.app.forecast import run_forecast_command

    _compile_notice()
    with _checked(no_check_units):
        report = run_forecast_command(data, _load(config_path, ()), fit_path, from_bounce=from_bounce, members=members, seed=seed, rate=rate,
                                      angle=angle, workers=workers, map_size=map_size, map_axes=map_axes, json_path=json_path,
                                      md_path=md_path, png_dir=png_dir, log=None if quiet else lambda line: click.echo(line, err=True))
    if report["warnings"]:
        _warn("; ".join(report["warnings"]))  # one line, before the result
    s = report["scores"]
    from dice_sweep.measured.forecast import headline

    name, first = headline(s)
    click.echo(f"from flight {s['from_bounce']}, {s['n_tracks']} held-out tracks, {name}: log score {first['log_score']['value']:.3f} "
               f"[{first['log_score']['ci95'][0]:.3f}, {first['log_score']['ci95'][1]:.3f}] (uniform {s['log_score_uniform']['value']:.3f}), "
               f"skill {first['log_skill']['value']:.3f} [{first['log_skill']['ci95'][0]:.3f}, {first['log_skill']['ci95'][1]:.3f}] nats, "
               f"Brier {first['brier']['value']:.3f} [{first['brier']['ci95'][0]:.3f}, {first['brier']['ci95'][1]:.3f}] "
               f"(uniform {s['brier_uniform']['value']:.3f}), calibration z log {first['calibration']['log_score_z']:.1f}, "
               f"Brier {first['calibration']['brier_z']:.1f}; most likely side right {100 * s['share_correct_most_likely']['value']:.0f} %, "
               f"deterministic {100 * s['share_correct_deterministic']['value']:.0f} %")


# --- the map in the browser (issue 19, docs/view.md) ---------------------------------------


@main.command()
@click.argument("h5_path", metavar="FILE.h5")
@click.option("--host", default="127.0.0.1", show_default=True, help="Address to listen on; the default serves this machine only.")
@click.option("--port", type=int, metavar="N", help="Port, 0 to 65535; 0 picks a free one [default: 8765, or a free one if it is taken].")
@click.option("--no-open", is_flag=True, help="Do not open a browser (the address is the first line printed).")
@click.option("--workers", type=int, callback=_workers, help="Processes rolling zoomed maps, 1 to 1024 [default: all cores].")
def view(h5_path, host, port, no_open, workers):
    """Explore the final-state diagram of a sweep file in the browser: hover for a pixel's
    initial condition and side, drag a box or scroll to zoom (the kernel recomputes the view
    at screen resolution), click a pixel to play its roll; the view's shares and basin
    entropy; export the view as PNG and as a TOML config for dice-sweep sweep. Prints
    "serving on http://HOST:PORT/" first; Ctrl-C stops it.

    \b
    Example: dice-sweep view out/demo.h5 --no-open
    """
    from dice_sweep.app.view import view as view_command

    view_command(h5_path, host=host, port=port, open_browser=not no_open, workers=workers, echo=click.echo, warn=_warn)
