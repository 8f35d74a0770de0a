"""The measured-data commands (``calibrate``, ``fit``, ``diagnose``): a track file in; a fit,
a report in JSON and Markdown, and pictures out. The loop itself is dice_sweep.measured;
pictures are dice_sweep.plotting's.
"""

from pathlib import Path

from dice_sweep.measured import diagnose as loop
from dice_sweep.measured.calibrate import CalibrationResult, calibrate
from dice_sweep.measured.report import at_bound_lines, jsonable, markdown_report, parse_effects, residual_curves
from dice_sweep.measured.checks import check_measured
from dice_sweep.measured.forecast import parse_fit
from dice_sweep.measured.scatter import fitted_scatter
from dice_sweep.measured.split import CONFIRM_FRACTION
from dice_sweep.measured.tracks import load_tracks
from dice_sweep.outputs import FOLDER, JSON, MARKDOWN, check_outputs, make_folder, replace_atomically, write_json
from dice_sweep.plotting import image_formats, plot_calibration, plot_residual_curves

# fit's --effects parser and the at-a-bound warnings of fit and diagnose too
__all__ = ["run_calibrate", "run_fit", "run_diagnose", "parse_effects", "at_bound_lines"]


def _load(data_path, cfg, rate, angle, gaps="auto"):
    trackset = load_tracks(data_path, sides=cfg.die.sides, circumradius=cfg.die.circumradius, rate=rate, angle=angle, gaps=gaps)
    check_measured(trackset, cfg)  # units and conventions, before the work (issue 30)
    return trackset


def run_calibrate(data_path, cfg, *, rate=None, angle="as-is", gaps="auto", json_path=None, png_path=None) -> tuple[CalibrationResult, list]:
    """Measure the coefficients at every impact; write JSON and the histograms if asked
    (both paths checked before the work). Returns the result and the files written, in order."""
    check_outputs(("--json", json_path, JSON), ("--png", png_path, image_formats()))
    result = calibrate(_load(data_path, cfg, rate, angle, gaps), cfg)
    written = []
    if json_path:
        written.append(write_json(json_path, result.to_dict(), indent=1))
    if png_path:
        written.append(plot_calibration(result, png_path))
    return result, written


def _residual_pictures(residuals, prepared, segments, png_dir):
    """The residual picture: per-frame pose error against time from the first impact."""
    make_folder(png_dir)
    path = png_dir / "residual_error_vs_time.png"
    plot_residual_curves(residual_curves(residuals, prepared, segments), path)
    return [str(path)]


def _scatter_of(trackset, cfg, report, path, log=None):
    """The [scatter] spreads around a fit's law (dice_sweep.measured.scatter) on its selection
    tracks, for its JSON."""
    source = parse_fit(report, path or "<fit>", cfg, CONFIRM_FRACTION, 0)
    return fitted_scatter(trackset, cfg, source.effects, source.params, confirm_fraction=source.confirm_fraction, seed=source.seed,
                          log=log)


def run_fit(data_path, cfg, *, effects=(), rate=None, angle="as-is", json_path=None, png_dir=None, seed=0):
    """Fit the declared model plus ``effects`` on the selection tracks (multiple shooting),
    with 95 % intervals (bootstrap over tracks and the tracking noise's share), and score it on
    the confirmation tracks (:func:`dice_sweep.measured.diagnose.fit_report`)."""
    check_outputs(("--json", json_path, JSON), ("--png", png_dir, FOLDER))
    trackset = _load(data_path, cfg, rate, angle)
    result, split, residual_test = loop.fit_report(trackset, cfg, effects=effects, seed=seed)
    result["scatter"] = _scatter_of(trackset, cfg, jsonable(result), json_path)
    if json_path:
        write_json(json_path, jsonable(result))
    if png_dir:
        _residual_pictures({"fit": residual_test}, split.confirm, split.seg_confirm, Path(png_dir))
    return result


def run_diagnose(data_path, cfg, *, rate=None, angle="as-is", json_path=None, md_path=None, png_dir=None, log=None, **options):
    """The whole loop on a data file; writes REPORT.json (Markdown and pictures if asked)."""
    check_outputs(("--json", json_path, JSON), ("--md", md_path, MARKDOWN), ("--png", png_dir, FOLDER))
    trackset = _load(data_path, cfg, rate, angle)
    report = loop.diagnose(trackset, cfg, log=log, angle_reading=f"--angle {angle}: {trackset.angle_note}", **options)
    fits = report.pop("_fits")
    report["scatter"] = _scatter_of(trackset, cfg, jsonable(report), json_path, log)
    if png_dir:
        _, seg_confirm = fits["segments"]
        _, confirm = fits["prepared"]
        report["pictures"] = _residual_pictures(fits["confirm_residuals"], confirm, seg_confirm, Path(png_dir))
    report = jsonable(report)
    if json_path:
        write_json(json_path, report)
    if md_path:
        replace_atomically(md_path, lambda file: file.write(markdown_report(report).encode()))
    return report
