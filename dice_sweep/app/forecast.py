"""The ``forecast`` command (issue 18): a track file and a fit in; side probabilities of the
held-out drops, their scores, the map of the release states, JSON, Markdown and pictures out.

The forecast itself is dice_sweep.measured.forecast, the map of the release states
dice_sweep.measured.release; pictures are dice_sweep.plotting's.
"""

import json
import time
from pathlib import Path

from dice_sweep.errors import DiceSweepError
from dice_sweep.executor import worker_count
from dice_sweep.inputs import not_a_file
from dice_sweep.measured import forecast as fc
from dice_sweep.measured.noise import tracking_noise
from dice_sweep.measured.release import release_map
from dice_sweep.measured.checks import check_measured
from dice_sweep.measured.report import jsonable
from dice_sweep.measured.split import CONFIRM_FRACTION
from dice_sweep.measured.tracks import load_tracks
from dice_sweep.outputs import FOLDER, JSON, MARKDOWN, check_outputs, make_folder, replace_atomically, write_json

MAP_SIZE = 512  # cells per axis of the release map: docs/chaos.md measures its maps at 512 x 512
MAP_SIZES = (16, 2048)  # --map-size (0: no map)
PICTURES = ("reliability.png", "skill_by_bounce.png", "release_map.png")


def load_fit_json(path):
    """The decoded JSON of a fit file, with one-line errors for a file that cannot be read
    (a FIFO among them) or is not JSON."""
    problem = not_a_file(path)  # a FIFO would hang the reader
    if problem:
        raise DiceSweepError(f"--fit: {path}: {problem}")
    try:
        text = Path(path).read_bytes()  # decoded by json.loads, inside the handler below
    except OSError as error:
        raise DiceSweepError(f"--fit: {path}: cannot be read ({error.strerror or error}) "
                             "(allowed: the JSON written by dice-sweep fit --json or dice-sweep diagnose --json)") from None
    try:
        return json.loads(text)
    except (json.JSONDecodeError, UnicodeDecodeError) as error:
        raise DiceSweepError(f"--fit: {path}: not JSON ({error}) "
                             "(allowed: the JSON written by dice-sweep fit --json or dice-sweep diagnose --json)") from None


def fit_source(data, path, cfg):
    """:func:`dice_sweep.measured.forecast.parse_fit` of a decoded fit JSON, its values checked
    (:func:`~dice_sweep.measured.forecast.check_fit_values`)."""
    source = fc.parse_fit(data, path, cfg, CONFIRM_FRACTION, 0)
    fc.check_fit_values(data, source, cfg, path)
    return source


def read_fit_file(path, cfg):
    """:func:`fit_source` of a JSON file (:func:`load_fit_json`)."""
    return fit_source(load_fit_json(path), path, cfg)


def parse_map_axes(text):
    """``"A,B"`` -> (A, B), two different initial values; None stays None (the default axes)."""
    if text is None:
        return None
    names = tuple(part.strip() for part in text.split(","))
    if len(names) != 2 or names[0] == names[1] or not all(name in fc.STATE_COLUMNS for name in names):
        raise DiceSweepError(f"--map-axes: {text!r} is not two different initial values (allowed: two of {', '.join(fc.STATE_COLUMNS)}, "
                             "e.g. phi0,omega0)")
    return names


def _check_map_size(size):
    low, high = MAP_SIZES
    if size != 0 and not low <= size <= high:
        raise DiceSweepError(f"--map-size: {size} is outside the allowed range [{low}, {high}] (or 0: no map)")


def _check_angle(source, angle):
    """The fit and the forecast must read the file's angle the same way."""
    reading = source.angle_reading
    if isinstance(reading, str) and ("as-is:" in reading) != (angle == "as-is"):
        other = "as-is" if angle == "auto" else "auto"
        raise DiceSweepError(f"--angle: {angle}: the fit was made with --angle {other} (its angle_reading: {reading[:60]}...) "
                             f"(allowed: the --angle the fit was made with, {other})")


# --- the command -------------------------------------------------------------------------------


def run_forecast_command(data_path, cfg, fit_path, *, from_bounce=0, members=fc.DEFAULT_MEMBERS, seed=0, rate=None, angle="as-is",
                         workers=None, map_size=MAP_SIZE, map_axes=None, json_path=None, md_path=None, png_dir=None, log=None):
    """Forecast the held-out drops of a track file from a fit; write JSON (Markdown and
    pictures if asked). Every input and output is checked before the work. Returns the report."""
    say = log or (lambda message: None)
    started = time.perf_counter()
    check_outputs(("--json", json_path, JSON), ("--md", md_path, MARKDOWN), ("--png", png_dir, FOLDER))
    fc.check_from_bounce(from_bounce)
    fc.check_members(members)
    _check_map_size(map_size)
    axes = parse_map_axes(map_axes) if isinstance(map_axes, str) else map_axes
    fit_json = load_fit_json(fit_path)
    source = fit_source(fit_json, fit_path, cfg)
    _check_angle(source, angle)
    workers = worker_count(workers)
    trackset = load_tracks(data_path, sides=cfg.die.sides, circumradius=cfg.die.circumradius, rate=rate, angle=angle)
    fc.check_split(fit_json, source, trackset, fit_path)
    check_measured(trackset, cfg)  # units and conventions, before the work (issue 30)
    table, noise, sigma = tracking_noise(trackset, cfg)
    loaded = time.perf_counter()
    intro = f"{len(trackset.tracks)} tracks; noise floor {noise['pose'] * 1000:.3f} mm; {source.parameter_note}"
    run = fc.run_forecast(trackset, cfg, source, sigma=sigma, table=table, from_bounce=from_bounce, members=members, seed=seed,
                          workers=workers, log=say, intro=intro)
    scores = fc.score_run(run, cfg.die.sides, seed)
    forecasted = time.perf_counter()
    summary = picture = None
    if map_size and run.release:
        summary, picture = release_map(cfg, source, run, map_size, axes, workers)
        say(f"release map {map_size} x {map_size} over {', '.join(summary['axes'])}: Sb = {summary['measures']['basin_entropy']['Sb']:.4f}")
    done = time.perf_counter()
    draws = min(fc.PARAM_DRAWS, members)
    report = {
        "command": "forecast",
        "question": "the probability of each side of a tracked drop, from what was seen before it landed, scored against the side it rested on",
        "data": {"path": str(data_path), "rate_hz": trackset.rate, "angle_reading": f"--angle {angle}: {trackset.angle_note}",
                 "table_height_m": table, **run.counts},
        "fit": {"path": str(fit_path), "kind": source.kind, "effects": list(source.spec(cfg).declared + source.effects), "params": source.params,
                "scatter": source.scatter, "scatter_scale": source.scatter_scale,
                "parameter_uncertainty": source.parameter_note, "data_path": source.data_path,
                "split": {"confirm_fraction": source.confirm_fraction, "seed": source.seed},
                "same_data": source.data_path is None or Path(str(source.data_path)).name == Path(str(data_path)).name},
        "noise": {k: noise[k] for k in ("sigma_x", "sigma_y", "sigma_phi", "pose")},
        "ensemble": {"from_bounce": from_bounce, "members": draws * -(-members // draws), "param_draws": draws,
                     "state_draws_per_param_draw": -(-members // draws), "smoothing": fc.SMOOTHING, "seed": seed,
                     "bootstrap_resamples": fc.BOOTSTRAP, "method": METHOD},
        "scores": scores,
        "headline": fc.headline(scores)[0],
        "warnings": fc.warnings(scores, source, cfg),
        "map": summary,
        "timing_s": {"load": loaded - started, "forecast": forecasted - loaded, "map": done - forecasted, "total": done - started},
    }
    report = jsonable(report)
    if png_dir:
        report["pictures"] = [str(path) for path in draw_pictures(report, picture, Path(png_dir), cfg.die.sides)]
    if json_path:
        write_json(json_path, report)
    if md_path:
        replace_atomically(md_path, lambda file: file.write(fc.markdown(report).encode()))
    return report


METHOD = [
    "state: the frames of flight K alone, fitted by the model's flight (the kernel at the fitted parameters); covariance from the "
    "Gauss-Newton normal matrix with the tracking noise, times the flight's reduced chi-square when above 1",
    "parameters: the fit's bootstrap draws (or Gaussians from ci95 when the JSON has none: see fit.parameter_uncertainty)",
    "members: parameter draws x state draws per track, starts inside the table drawn again, each rolled to rest by the sweep kernel",
    "probabilities: (members on a side + 0.5) / (members + n 0.5)",
    "scored on the held-out (confirmation) tracks of the fit's split that end at rest; intervals: 95 % bootstrap over tracks",
    "not in the ensemble: the model's own error, other optima of the fit, state-parameter correlations, non-white tracking noise",
]


def draw_pictures(report, picture, folder, sides):
    """reliability.png, skill_by_bounce.png and (with a map) release_map.png in ``folder``."""
    from dice_sweep.plotting import plot_release_map, plot_reliability, plot_skill_by_bounce

    make_folder(folder)
    scores = report["scores"]
    k = scores["from_bounce"]
    curves = [("ensemble", scores["reliability"])]
    if "recalibrated" in scores:
        curves.append(("recalibrated", scores["recalibrated"]["reliability"]))
    written = [plot_reliability(curves, folder / PICTURES[0], title=f"held-out tracks, forecast from flight {k} ({scores['n_tracks']} tracks)"),
               plot_skill_by_bounce(scores["by_bounce"], sides, folder / PICTURES[1], title="held-out tracks: skill against the flight forecast from")]
    if picture is not None:
        written.append(plot_release_map(picture, picture["cfg"], folder / PICTURES[2]))
    return written
