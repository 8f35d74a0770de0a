"""Proposals (dice_sweep/measured/propose.py) for what a fitted model leaves on tracked drops.

    python scripts/propose_measured.py ../shared/data/mcube_square_drops/drops.csv.gz \
        --config configs/square_drops.toml --angle auto --effects exact_coulomb,coulomb_friction \
        [--params beta_normal=0.4607,friction=0.08111] [--json proposals.json]

The model is the config's declared model plus ``--effects``. With ``--params`` it is taken at
those values (e.g. the loop's fitted values from diagnose's JSON); without, it is fitted to all
tracks first (diagnose's baseline fit: from the config's values and from calibrate's, the lower
cost kept). Prints every target's formula, whether it is proposed and why not, and the time the
proposals took (the fit's time apart).
"""

import argparse
import json
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

from dice_sweep.config import load_config  # noqa: E402
from dice_sweep.measured import fit as shooting  # noqa: E402
from dice_sweep.measured import propose  # noqa: E402
from dice_sweep.measured.diagnose import fit_from_starts, tracking_noise  # noqa: E402
from dice_sweep.measured.report import jsonable  # noqa: E402
from dice_sweep.measured.tracks import load_tracks  # noqa: E402


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("tracks")
    parser.add_argument("--config", required=True)
    parser.add_argument("--angle", default="as-is")
    parser.add_argument("--effects", default="", help="effects added to the declared model, comma separated")
    parser.add_argument("--params", default="", help="NAME=VALUE,...: the model at these values (no fit)")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--json", help="write the report here")
    args = parser.parse_args()
    cfg = load_config(args.config)
    trackset = load_tracks(args.tracks, sides=cfg.die.sides, circumradius=cfg.die.circumradius, angle=args.angle)
    spec = shooting.ModelSpec.of(cfg, [e for e in args.effects.split(",") if e])
    start = time.time()
    table, _, sigma = tracking_noise(trackset, cfg)
    prepared = shooting.prepare_tracks(trackset, cfg, noise=sigma, table=table)
    if args.params:
        params = shooting.start_values(cfg, spec)
        params.update({k: float(v) for k, v in (item.split("=") for item in args.params.split(","))})
        model = (spec, params)
        fitted = 0.0
    else:
        begin = time.time()
        model, _ = fit_from_starts(cfg, spec, shooting.Segments(prepared, cfg.world.g), trackset)
        fitted = time.time() - begin
        params = model.params
    report = propose.propose_report(trackset, cfg, model, sigma=sigma, table=table, prepared=prepared, seed=args.seed)
    took = time.time() - start - fitted
    print(f"model: {', '.join(spec.declared + spec.effects) or 'declared'} at " + ", ".join(f"{k} = {v:.5g}" for k, v in params.items())
          + (f" (fitted to all tracks in {fitted:.0f} s)" if fitted else ""))
    print(f"{len(trackset.tracks)} tracks: {report['flights']} flights, {report['impacts']} clean impacts; proposals in {took:.1f} s "
          f"(noise, flights, impacts and the regressions); threshold z {report['threshold_z']:.2f}, gain {report['min_gain']}")
    for name, r in report["targets"].items():
        terms = ", ".join(f"{t} {v:+.4g} [{lo:+.4g}, {hi:+.4g}]" for (t, v), (lo, hi) in zip(r["terms"].items(), r["ci95"].values()))
        verdict = "PROPOSED" if r["proposed"] else f"not proposed: {r['reason']}"
        print(f"  {name} ({r['unit']}): {terms or '-'}; held-out gain {r['heldout_gain']:.3f}, z {r['z']:.2f}, "
              f"{r['tracks']} tracks, {r['rows']} rows; {verdict}")
    if args.json:
        Path(args.json).write_text(json.dumps(jsonable(report), indent=1))


if __name__ == "__main__":
    main()
