"""The null calibration of the proposals (dice_sweep/measured/propose.py): control drops from the
independent generator (tests/measured/independent.py) with the library's own physics, nothing
missing, the declared model fitted to them, and what the sparse regression makes of the residual.

    python scripts/propose_null.py [--seeds 30] [--tracks 40] [--first-seed 500] [--contact paper]

Per set (stderr): the fitted model, and per target the size cross-validation chose, the
held-out gain and its signed-rank statistic z. At the end (stdout): the largest z over the six
targets of each set, its quantiles over sets, how many sets would report a proposal at the
default threshold (propose.PROPOSAL_Z) and gain (propose.MIN_GAIN), and the largest held-out
gain of a formula that got past the cross-validation. Needs the tests folder (a checkout).
"""

import argparse
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

from dice_sweep.config import parse_config  # noqa: E402
from dice_sweep.measured import fit as shooting  # noqa: E402
from dice_sweep.measured import propose  # noqa: E402
from dice_sweep.measured.diagnose import fit_from_starts  # noqa: E402
from dice_sweep.measured.tracks import load_tracks  # noqa: E402
from tests.measured.cases import DECLARED_PAPER, DECLARED_RIGID, NOISE, TRUTH  # noqa: E402
from tests.measured.independent import Truth, simulate_drops, write_csv  # noqa: E402


def control_report(folder, seed, tracks, truth=None, declared=DECLARED_RIGID, noise=NOISE):
    """propose_report (threshold and gain at 0: every formula that got past cross-validation)
    on one control set, with the declared model fitted to it."""
    path = Path(folder) / f"control{seed}.csv"
    write_csv(path, simulate_drops(truth or Truth(**TRUTH), tracks, seed, rate=500.0, noise=noise, drop_prob=0.01, glitch_prob=0.002))
    cfg = parse_config(declared)
    trackset = load_tracks(path, sides=cfg.die.sides, circumradius=cfg.die.circumradius)
    sigma = np.array([noise[0], noise[0], noise[1]])
    prepared = shooting.prepare_tracks(trackset, cfg, noise=sigma, table=0.0)
    # the loop's baseline fit: from the config's values and from calibrate's, the lower cost kept
    fit, _ = fit_from_starts(cfg, shooting.ModelSpec.of(cfg), shooting.Segments(prepared, cfg.world.g), trackset)
    report = propose.propose_report(trackset, cfg, fit, sigma=sigma, table=0.0, prepared=prepared, seed=seed, threshold=0.0, min_gain=0.0)
    return fit, report


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seeds", type=int, default=30)
    parser.add_argument("--tracks", type=int, default=40)
    parser.add_argument("--first-seed", type=int, default=500)
    parser.add_argument("--contact", choices=("rigid", "paper"), default="rigid",
                        help="the truth's and the declared model's law (paper: beta_tangential -0.2, no friction cap)")
    args = parser.parse_args()
    if args.contact == "paper":
        truth, declared = Truth(contact="paper", beta_normal=0.4, beta_tangential=-0.2), DECLARED_PAPER
    else:
        truth, declared = Truth(**TRUTH), DECLARED_RIGID
    largest, gains, reported, excluded = [], [], 0, 0
    start = time.time()
    with tempfile.TemporaryDirectory() as folder:
        for seed in range(args.first_seed, args.first_seed + args.seeds):
            fit, report = control_report(folder, seed, args.tracks, truth, declared)
            zs = [r["z"] for r in report["targets"].values() if r["terms"]]
            largest.append(max(zs, default=0.0))
            gains += [r["heldout_gain"] for r in report["targets"].values() if r["terms"]]
            passing = [name for name, r in report["targets"].items()
                       if r["terms"] and r["z"] >= propose.PROPOSAL_Z and r["heldout_gain"] >= propose.MIN_GAIN]
            reported += bool(passing)
            excluded += sum(bool(r["terms"]) for r in report["targets"].values())
            line = ", ".join(f"{name} {r['size']} terms z {r['z']:.2f} gain {r['heldout_gain']:.3f} {r['terms']}"
                             for name, r in report["targets"].items() if r["size"])
            print(f"seed {seed}: {report['flights']} flights, {report['impacts']} impacts; fit "
                  + ", ".join(f"{k} {v:.4f}" for k, v in fit.params.items()) + f"; {line or 'no term chosen'}"
                  + (f"; REPORTED {passing}" if passing else ""), file=sys.stderr)
    largest = np.array(largest)
    print(f"{args.seeds} control sets of {args.tracks} tracks, {args.contact} law ({time.time() - start:.0f} s): largest z over the six targets per set: "
          f"median {np.median(largest):.2f}, 90 % {np.quantile(largest, 0.9):.2f}, 95 % {np.quantile(largest, 0.95):.2f}, "
          f"max {largest.max():.2f}; sets with a formula past cross-validation (its terms' intervals excluding 0): "
          f"{int(np.sum(largest > 0))} ({excluded} formulas), largest held-out gain {max(gains, default=0.0):.3f}; "
          f"sets that would report a proposal at z >= {propose.PROPOSAL_Z:.2f} and gain >= {propose.MIN_GAIN}: {reported}")


if __name__ == "__main__":
    main()
