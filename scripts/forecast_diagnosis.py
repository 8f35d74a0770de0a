"""Why forecasts from flight 1 are overconfident, measured on the SELECTION tracks only (issue 31).

    python scripts/forecast_diagnosis.py residuals [--power 1]  # (a) impact residuals against the law, by impact / speed / kind
    python scripts/forecast_diagnosis.py flights     # (b) the flight-K states: frames, reduced chi-square, sds
    python scripts/forecast_diagnosis.py calibration [--members 500] [--scale S]  # forecasts of the selection tracks, every K
    python scripts/forecast_diagnosis.py scale       # fit_scatter_scale on the selection tracks -> out/forecast/<fit>_scaled.json
    python scripts/forecast_diagnosis.py release_width [--law ...]  # the K = 0 log skill at every factor on the law

The fit is the cross-fitted diagnose's held-out model (out/measured/report.json, or --fit):
fold 0's model, chosen and fitted on fold 1's tracks, which are the selection tracks here; the
held-out half is never read. Prints JSON lines; docs/dev/forecast_flight1.md is written from them.
"""

import argparse
import dataclasses
import json
import math
import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
DATA = ROOT.parent / "shared" / "data" / "mcube_square_drops" / "drops.csv.gz"
CONFIG = ROOT / "configs" / "square_drops.toml"
OUT = ROOT / "out" / "forecast"


def context(args):
    from dice_sweep.app.forecast import read_fit_file
    from dice_sweep.config import load_config
    from dice_sweep.measured.noise import tracking_noise
    from dice_sweep.measured.tracks import load_tracks

    cfg = load_config(CONFIG)
    source = read_fit_file(args.fit, cfg)
    tracks = load_tracks(DATA, sides=cfg.die.sides, circumradius=cfg.die.circumradius, angle="auto")
    table, _, sigma = tracking_noise(tracks, cfg)
    select_set, _ = tracks.split(source.confirm_fraction, source.seed)  # the held-out half is not kept
    return cfg, source, select_set, table, sigma


def parse_law(text):
    """--law's [scatter] keys, in the registry's order: corner, corner_floor, flat, flat_floor, power,
    tail_share, tail_factor, spin (the ones left out: their null values)."""
    from dice_sweep.effects import scatter_law_keys

    return dict(zip(scatter_law_keys(), (float(v) for v in text.split(","))))


def law_variance(kind, u, law, speed):
    """The law's per-component variance ((m/s)^2) at approach u (m/s) of (vx, vy, sqrt(I/M) omega),
    shape included: a share tail_share of jumps tail_factor times wider, each capped at u as the
    kernel caps it, and the spin component spin^2 times the others."""
    from dice_sweep.measured.scatter import jump_sd

    sd = jump_sd(law, kind, u / speed) * speed
    w, k, s = law.get("tail_share", 0.0), law.get("tail_factor", 1.0), law.get("spin", 1.0)
    both = (1.0 - w) * sd**2 + w * min(k * sd, u) ** 2
    return both * np.array([1.0, 1.0, s * s])


def residuals(args):
    from dice_sweep.measured.impacts import find_impacts
    from dice_sweep.measured.scatter import KINDS, ImpactResidual, estimate_shape, estimate_spreads, impact_residuals, shape_law, spreads_law

    cfg, source, select_set, table, sigma = context(args)
    speed = math.sqrt(source.params.get("g", cfg.world.g) * cfg.die.circumradius)
    cache = OUT / f"selection_residuals_{Path(args.fit).stem}.json"
    if cache.exists():  # the residuals of the same fit and tracks (delete it after changing either)
        saved = json.loads(cache.read_text())
        rows = [ImpactResidual(**{**r, "components2": tuple(r.get("components2", ())), "noise_components2": tuple(r.get("noise_components2", ()))})
                for r in saved["rows"]]
        found = {int(k): v for k, v in saved["found"].items()}
    else:
        rows = impact_residuals(select_set.tracks, cfg, source.effects, source.params, sigma=sigma, table=table, seed=source.seed)
        found = {}
        for track in select_set.tracks:
            n = len(find_impacts(track.t, track.y, track.phi, track.usable, sides=cfg.die.sides, circumradius=cfg.die.circumradius,
                                 table=table, g=source.params.get("g", cfg.world.g)))
            for k in range(n):
                found[min(k, 4)] = found.get(min(k, 4), 0) + 1
    spreads = estimate_spreads(rows, speed=speed, seed=source.seed, power=args.power)
    # the law the forecast uses: the mixture's, unless --power holds the Gaussian law's power
    shape = None if args.power is not None else estimate_shape(rows, speed=speed, seed=source.seed)
    law = shape_law(shape) if shape else spreads_law(spreads)
    OUT.mkdir(parents=True, exist_ok=True)
    cache.write_text(json.dumps({"rows": [dataclasses.asdict(r) for r in rows], "law": spreads, "scatter": law, "found": found}, default=float))
    if args.law:  # another law to test against the same residuals
        law = parse_law(args.law)
    print(json.dumps({"law": law}))
    ratio = np.array([((r.residual2 - r.noise2) / 3.0) / law_variance(r.kind, r.approach, law, speed).mean() for r in rows])
    index = np.array([min(r.impact, 4) for r in rows])
    u = np.array([r.approach for r in rows]) / speed
    kind = np.array([r.kind for r in rows])

    def group(mask):
        got = ratio[mask]
        if not got.size:
            return {"impacts": 0}
        boot = np.random.default_rng(0).choice(got, size=(2000, got.size)).mean(axis=1)
        # a Gaussian jump's |r|^2 / 3 is the law's variance times chi-square(3) / 3: mean / median 1.27
        return {"impacts": int(got.size), "mean_ratio": round(float(got.mean()), 3),
                "ci95": [round(float(v), 3) for v in np.quantile(boot, [0.025, 0.975])], "median_ratio": round(float(np.median(got)), 3),
                "median_u_sqrtgR": round(float(np.median(u[mask])), 2)}

    for k in range(5):
        print(json.dumps({"by_impact": k if k < 4 else "4+", "found": found.get(k, 0), **group(index == k)}))
    for low, high in ((0, 0.5), (0.5, 1.0), (1.0, 1.5), (1.5, 2.5), (2.5, 99)):
        print(json.dumps({"by_u_sqrtgR": [low, high], **group((u >= low) & (u < high))}))
    for name in KINDS:
        for first in (True, False):
            print(json.dumps({"kind": name, "first_impact": first, **group((kind == name) & ((index == 0) == first))}))
    # each component against its own variance in the law (the spin's: spin^2 times): 1 each if the law is right
    parts = np.array([np.subtract(r.components2, r.noise_components2) if r.components2 else np.full(3, np.nan) for r in rows])
    variance = np.array([law_variance(r.kind, r.approach, law, speed) for r in rows])
    for name in KINDS:
        for first in (True, False):
            mask = (kind == name) & ((index == 0) == first)
            if mask.any():
                print(json.dumps({"kind": name, "first_impact": first, "component_ratio_vx_vy_spin": [
                    round(float(v), 2) for v in np.nanmean(parts[mask], axis=0) / variance[mask].mean(axis=0)]}))


def flights(args):
    from dice_sweep.measured import forecast as fc

    cfg, source, select_set, table, sigma = context(args)
    observed = {t.traj: fc.observed_side(t, cfg, source.params) for t in select_set.tracks}
    prepared = fc.prepared_tracks(select_set.tracks, cfg, sigma, table, observed)
    for k in range(4):
        states = fc.flight_states(cfg, source.spec(cfg), source.params, prepared, k, sigma)
        sd = np.array([np.sqrt(np.diag(f.cov)) for f in states])
        print(json.dumps({"flight": k, "tracks": len(states), "frames_median": float(np.median([f.frames for f in states])),
                          "birge_median": float(np.median([f.birge for f in states])),
                          "birge_q90": float(np.quantile([f.birge for f in states], 0.9)),
                          "sd_median": {"x_mm": 1e3 * float(np.median(sd[:, 0])), "y_mm": 1e3 * float(np.median(sd[:, 1])),
                                        "phi_mrad": 1e3 * float(np.median(sd[:, 2])), "vx_mm_s": 1e3 * float(np.median(sd[:, 3])),
                                        "vy_mm_s": 1e3 * float(np.median(sd[:, 4])), "omega_rad_s": float(np.median(sd[:, 5]))}}))


def calibration(args):
    from dice_sweep.measured import forecast as fc
    from dice_sweep.measured.scatter import spreads_law

    cfg, source, select_set, table, sigma = context(args)
    if source.scatter is None:  # the law the residuals run estimated
        saved = json.loads((OUT / f"selection_residuals_{Path(args.fit).stem}.json").read_text())
        source = dataclasses.replace(source, scatter=saved.get("scatter") or spreads_law(saved["law"]))
    if args.law:
        source = dataclasses.replace(source, scatter=parse_law(args.law))
    source = dataclasses.replace(source, scatter=fc.scaled_scatter(source.scatter, args.scale))
    observed = {t.traj: fc.observed_side(t, cfg, source.params) for t in select_set.tracks}
    prepared = fc.prepared_tracks(select_set.tracks, cfg, sigma, table, observed)
    out = fc.forecast_bounces(prepared, cfg, source, [int(k) for k in args.flights.split(",")], sigma=sigma, observed=observed, members=args.members, workers=2)
    for k, b in out.items():
        s = fc.score_bounce(b, cfg.die.sides, np.random.default_rng(0))
        print(json.dumps({"scale": args.scale, "law": source.scatter, "flight": k, "tracks": s["n_tracks"], "log_skill": s["log_skill"],
                          "z": [s["calibration"]["log_score_z"], s["calibration"]["brier_z"]],
                          "most_likely_right": s["share_correct_most_likely"]["value"]}), flush=True)


def scale(args):
    """fit_scatter_scale on the selection tracks; the fit JSON with it written to out/forecast/<fit>_scaled.json."""
    from dice_sweep.measured import forecast as fc
    from dice_sweep.measured.report import jsonable

    cfg, source, select_set, table, sigma = context(args)
    observed = {t.traj: fc.observed_side(t, cfg, source.params) for t in select_set.tracks}
    prepared = fc.prepared_tracks(select_set.tracks, cfg, sigma, table, observed)
    bounces = [k for k, count in enumerate(fc.flight_counts(prepared)) if count >= fc.MIN_BOUNCE_TRACKS]
    found = fc.fit_scatter_scale(prepared, cfg, source, bounces, sigma=sigma, observed=observed, workers=2,
                                 log=lambda line: print(line, file=sys.stderr))
    data = json.loads(Path(args.fit).read_text())
    data["scatter_scale"] = found
    (OUT / f"{Path(args.fit).stem}_scaled.json").write_text(json.dumps(jsonable(data), indent=1))
    print(json.dumps({k: v for k, v in found.items() if k != "rule"}))


def release_width(args):
    """How good the forecast from the release can get by the law's width alone, on the selection
    tracks: the factor on the law (the fit's, or --law) whose forecasts from flight 0 alone have
    the best log score, and that score's skill at every factor (in-sample: an optimistic bound
    for a law of this form)."""
    from dice_sweep.measured import forecast as fc

    cfg, source, select_set, table, sigma = context(args)
    if args.law:
        source = dataclasses.replace(source, scatter=parse_law(args.law))
    observed = {t.traj: fc.observed_side(t, cfg, source.params) for t in select_set.tracks}
    prepared = fc.prepared_tracks(select_set.tracks, cfg, sigma, table, observed)
    found = fc.fit_scatter_scale(prepared, cfg, source, (0,), sigma=sigma, observed=observed, members=args.members, workers=2)
    print(json.dumps({"law": source.scatter, "best_factor": found["value"], "ci95": found["ci95"], "tracks": found["pairs"],
                      "log_skill_by_factor": {f"{g:g}": round(v + math.log(cfg.die.sides), 4) for g, v in zip(found["grid"], found["mean_log_score"])}}))


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("what", choices=("residuals", "flights", "calibration", "scale", "release_width"))
    parser.add_argument("--fit", default=str(ROOT / "out" / "measured" / "report.json"))
    parser.add_argument("--members", type=int, default=500)
    parser.add_argument("--scale", type=float, default=1.0)
    parser.add_argument("--law", help="test this law instead of the fit's: corner,corner_floor,flat,flat_floor[,power,tail_share,tail_factor,spin]")
    parser.add_argument("--power", type=float, help="residuals: estimate the law at this power (default: the power estimated too)")
    parser.add_argument("--flights", default="0,1,2,3", help="calibration: the forecast points")
    args = parser.parse_args()
    if not DATA.exists():
        print(f"skipped: {DATA} not found")
        return 0
    {"residuals": residuals, "flights": flights, "calibration": calibration, "scale": scale, "release_width": release_width}[args.what](args)
    return 0


if __name__ == "__main__":
    sys.exit(main())
