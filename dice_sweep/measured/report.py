"""One call per command: load tracks, fit or diagnose, write JSON / Markdown / pictures."""

import json
import math
from pathlib import Path

import numpy as np

from dice_sweep.errors import DiceSweepError
from dice_sweep.measured.diagnose import METRIC, diagnose
from dice_sweep.measured.fit import (
    EFFECTS,
    ModelSpec,
    TrackModel,
    declared_effects,
    fit_spec,
    held_out_error,
    prepare_tracks,
)
from dice_sweep.measured.tracks import load_tracks


def _load(data_path, cfg, rate, angle):
    return load_tracks(data_path, sides=cfg.die.sides, circumradius=cfg.die.circumradius, rate=rate, angle=angle)


def parse_effects(text):
    """``a,b`` -> ('a', 'b'), each a known effect (DiceSweepError naming --effects otherwise)."""
    names = tuple(name.strip() for name in text.split(",") if name.strip()) if text else ()
    unknown = [name for name in names if name not in EFFECTS]
    if unknown:
        raise DiceSweepError(f"--effects: unknown effect {unknown[0]!r} (allowed: {', '.join(EFFECTS)})")
    return names


def run_fit(data_path, cfg, *, effects=(), rate=None, angle="auto", json_path=None, png_dir=None):
    """Fit the declared model plus ``effects`` on the training split, score on the held-out
    split; returns the result dict (written to ``json_path`` if given)."""
    trackset = _load(data_path, cfg, rate, angle)
    train_set, test_set = trackset.split()
    train = prepare_tracks(train_set, cfg)
    test = prepare_tracks(test_set, cfg)
    extra = tuple(e for e in effects if e not in declared_effects(cfg))
    fit = fit_spec(cfg, ModelSpec(extra), train)
    result = {
        "metric": METRIC,
        "model": "rigid" if "corner_impulse" in extra else cfg.contact.model,
        "effects": list(declared_effects(cfg)) + list(extra),
        "params": fit.params,
        "train_error": fit.train_error,
        "test_error": held_out_error(cfg, fit, test),
        "train_tracks": len(train),
        "test_tracks": len(test),
        "angle_convention": trackset.angle_note,
        "glitch_frames": trackset.glitch_count,
    }
    if json_path:
        Path(json_path).write_text(json.dumps(result, indent=2) + "\n")
    if png_dir:
        _residual_pictures(cfg, [("fit", fit)], test, Path(png_dir))
    return result


def run_diagnose(data_path, cfg, *, rate=None, angle="auto", json_path=None, md_path=None, png_dir=None, log=None):
    """The whole loop on a data file; writes REPORT.json (and Markdown, pictures) and returns it."""
    trackset = _load(data_path, cfg, rate, angle)
    report = diagnose(trackset, cfg, log=log, keep_fits=bool(png_dir))
    fits = report.pop("_fits")
    if png_dir:
        _, test_set = trackset.split()
        _residual_pictures(cfg, fits, prepare_tracks(test_set, cfg), Path(png_dir))
        report["pictures"] = sorted(str(p) for p in Path(png_dir).glob("residual_*.png"))
    if json_path:
        Path(json_path).write_text(json.dumps(report, indent=2, default=float) + "\n")
    if md_path:
        Path(md_path).write_text(markdown_report(report))
    return report


def _residual_pictures(cfg, fits, prepared_test, png_dir):
    """Per-frame pose error against time from the first impact, one curve per fit."""
    from dice_sweep.plotting import plot_residual_curves

    png_dir.mkdir(parents=True, exist_ok=True)
    curves = []
    for label, fit in fits:
        model = TrackModel(cfg, fit.spec, prepared_test)
        errors = model.frame_errors(fit.params)
        since_impact = model.times - np.array([p.t_impact for p in prepared_test])[model.track_of_frame]
        curves.append((label, since_impact, errors))
    plot_residual_curves(curves, png_dir / "residual_error_vs_time.png")


def _mm(value):
    return "n/a" if value is None or not math.isfinite(value) else f"{value * 1000:.2f} mm"


def markdown_report(report):
    """A readable summary of a diagnose report."""
    lines = ["# Diagnosis of tracked drops", "", f"Metric: {report['metric']}.", "", f"Selection: {report['selection']}.", ""]
    data = report["data"]
    lines += [f"Data: {data['path']}: {data['tracks']} tracks at {data['rate_hz']:g} Hz; "
              f"{data['train_tracks_used']} training and {data['test_tracks_used']} held-out tracks usable; "
              f"{data['glitch_frames']} glitch frames in {data['glitch_tracks']} tracks excluded; {data['robust_loss']}.",
              f"Angle convention: {data['angle_convention']}", ""]
    base = report["baseline"]
    lines += ["## Baseline", "", f"Model {base['model']}, effects {base['effects'] or 'none'}: "
              f"train {_mm(base['train_error'])}, held-out {_mm(base['test_error'])}; params "
              + ", ".join(f"{k} = {v:.4g}" for k, v in base["params"].items()), "", "## Residual signatures", "",
              "| signature | value | unit | points to | meaning |", "|---|---|---|---|---|"]
    lines += [f"| {s['signature']} | {s['value']:.4g} | {s['unit']} | {s['points_to']} | {s['note']} |" for s in report["signatures"]]
    lines += ["", "## Candidates (first round)", "", "| effect | held-out error | params |", "|---|---|---|"]
    lines += [f"| {c['effect']} | {_mm(c['test_error'])} | " + ", ".join(f"{k} = {v:.4g}" for k, v in c["params"].items()) + " |"
              for c in report["candidates"]]
    lines += ["", "## Chain", ""]
    lines += [f"{step['step']}. best {step['best']}: held-out {_mm(step['test_error'])} "
              f"({step['gain']:+.1%}) -> {'added' if step['accepted'] else 'not added (below the threshold)'}" for step in report["chain"]]
    after = report["after"]
    fiv = report["first_impact_velocity_error"]
    side = report["final_side_agreement"]
    lines += ["", "## After", "", f"Effects {after['effects'] or 'none'}: held-out {_mm(after['test_error'])}; params "
              + ", ".join(f"{k} = {v:.4g}" for k, v in after["params"].items()),
              "", f"First-impact velocity error: {fiv['before']:.3f} m/s before, {fiv['after']:.3f} m/s after.",
              f"Simulated resting side equals the tracked one: {side['before']:.0%} before, {side['after']:.0%} after "
              f"({side['tracks']} held-out tracks at rest at their end).",
              "Spin after the first impact, simulated against tracked (held-out tracks): "
              + "; ".join(f"{when}: same sign in {spin['sign_agreement']:.0%}, correlation {spin['correlation']:.2f}, "
                          f"tracked {spin['measured_range_rad_s'][0]:.1f} to {spin['measured_range_rad_s'][1]:.1f} rad/s, "
                          f"simulated {spin['simulated_range_rad_s'][0]:.1f} to {spin['simulated_range_rad_s'][1]:.1f} rad/s"
                          for when, spin in report["first_impact_spin"].items()) + ".", ""]
    return "\n".join(lines)
