"""The forecast from one flight with the fitted [scatter] spreads and floors multiplied by a
factor (on top of the fit's scatter_scale, if it has one): how much more scatter than the clean impacts show would
calibrate it (issue 31).

    python scripts/forecast_scatter_scale.py FACTOR FLIGHT [--fit out/forecast/fit_with_scatter.json] [--members 500]

Held-out tracks of the fit's split, as ``dice-sweep forecast`` makes them; prints the log
skill, the calibration z (log, Brier) and the share of most likely sides right. An
experiment, not a forecast: the factor is chosen by looking at the held-out tracks.
"""

import argparse
import dataclasses
import json
import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
DATA = ROOT.parent / "shared" / "data" / "mcube_square_drops" / "drops.csv.gz"


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("factor", type=float)
    parser.add_argument("flight", type=int)
    parser.add_argument("--fit", default=str(ROOT / "out" / "forecast" / "fit_with_scatter.json"))
    parser.add_argument("--members", type=int, default=500)
    args = parser.parse_args()
    if not DATA.exists():
        print(f"skipped: {DATA} not found")
        return 0
    from dice_sweep.config import load_config
    from dice_sweep.measured import forecast as fc
    from dice_sweep.measured.noise import tracking_noise
    from dice_sweep.measured.tracks import load_tracks

    cfg = load_config(ROOT / "configs" / "square_drops.toml")
    tracks = load_tracks(DATA, sides=cfg.die.sides, circumradius=cfg.die.circumradius, angle="auto")
    source = fc.parse_fit(json.loads(Path(args.fit).read_text()), args.fit, cfg, 0.3, 0)
    source = dataclasses.replace(source, scatter={k: v * args.factor for k, v in source.scatter.items()})
    _, confirm = tracks.split(source.confirm_fraction, source.seed)
    table, _, sigma = tracking_noise(tracks, cfg)
    observed = {t.traj: fc.observed_side(t, cfg, source.params) for t in tracks.tracks}
    prepared = fc.prepared_tracks(confirm.tracks, cfg, sigma, table, observed)
    out = fc.forecast_bounces(prepared, cfg, source, [args.flight], sigma=sigma, observed=observed, members=args.members, workers=2)
    s = fc.score_bounce(out[args.flight], cfg.die.sides, np.random.default_rng(0))
    print(json.dumps({"factor": args.factor, "flight": args.flight, "log_skill": s["log_skill"], "calibration_z": [
        s["calibration"]["log_score_z"], s["calibration"]["brier_z"]], "most_likely_right": s["share_correct_most_likely"]["value"]}))
    return 0


if __name__ == "__main__":
    sys.exit(main())
