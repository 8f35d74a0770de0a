"""How often the 95 % intervals of `dice-sweep fit` cover the truth: drops from the independent
generator (tests/measured/independent.py), fitted with the true model, over many seeds.

    python scripts/coverage_measured.py [--seeds 20] [--tracks 90] [--sides 4 --circumradius R
        --rate 500 --noise 2e-4 4e-3]

The defaults are the shared data's square at its tracker's rate and noise; the options try other
dice and trackers (a hexagon at 1000 Hz: --sides 6 --circumradius 0.025 --rate 1000 --noise 1e-4 3e-3).

Prints, per parameter, the share of seeds whose interval covers the true value with its exact
95 % interval, the chance of so few hits if the coverage were 95 %, the mean error, the mean
half-width and the RMS of the tracking noise's share (sd_noise); each set's line on stderr has
its errors in those sds (z_noise). Needs the tests folder (a checkout), not only the package.
"""

import argparse
import json
import sys
import tempfile
from pathlib import Path

import numpy as np
from scipy.stats import beta, binom

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

from dice_sweep.config import parse_config  # noqa: E402
from dice_sweep.app.measured import run_fit  # noqa: E402
from tests.measured.cases import DECLARED_RIGID, NOISE, RADIUS, TRUE_COEFFICIENTS  # noqa: E402
from tests.measured.independent import Truth, simulate_drops, write_csv  # noqa: E402

TRUE = TRUE_COEFFICIENTS


def clopper_pearson(hits, count):
    """Exact 95 % interval of a coverage from ``hits`` of ``count`` sets."""
    low = float(beta.ppf(0.025, hits, count - hits + 1)) if hits > 0 else 0.0
    high = float(beta.ppf(0.975, hits + 1, count - hits)) if hits < count else 1.0
    return [low, high]


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seeds", type=int, default=20)
    parser.add_argument("--tracks", type=int, default=90)
    parser.add_argument("--sides", type=int, default=4)
    parser.add_argument("--circumradius", type=float, default=RADIUS, help="m")
    parser.add_argument("--rate", type=float, default=500.0, help="frames per second")
    parser.add_argument("--noise", type=float, nargs=2, default=NOISE, metavar=("XY", "PHI"), help="one sigma, m and rad")
    args = parser.parse_args()
    truth = Truth(contact="rigid", sides=args.sides, circumradius=args.circumradius, **TRUE)
    declared = DECLARED_RIGID.replace("sides = 4", f"sides = {args.sides}").replace(f"circumradius = {RADIUS!r}", f"circumradius = {args.circumradius!r}")
    rows = []
    with tempfile.TemporaryDirectory() as folder:
        for seed in range(args.seeds):
            path = Path(folder) / f"d{seed}.csv"
            write_csv(path, simulate_drops(truth, args.tracks, 100 + seed, rate=args.rate, noise=tuple(args.noise),
                                           drop_prob=0.01, glitch_prob=0.002))
            result = run_fit(path, parse_config(declared), seed=seed)
            rows.append({name: (result["params"][name]["value"], *result["params"][name]["ci95"], result["params"][name]["sd_noise"])
                         for name in TRUE})
            z = {name: (row[0] - TRUE[name]) / row[3] for name, row in rows[-1].items()}  # error in noise sds
            print(json.dumps({"seed": seed, **rows[-1], "z_noise": z}), file=sys.stderr)
    summary = {}
    for name, true in TRUE.items():
        values = np.array([row[name] for row in rows])
        covered = (values[:, 1] <= true) & (true <= values[:, 2])
        hits = int(covered.sum())
        summary[name] = {"true": true, "coverage": float(covered.mean()), "covered": hits, "seeds": len(rows),
                         "coverage_ci95": clopper_pearson(hits, len(rows)),
                         "p_value_if_95": float(binom.cdf(hits, len(rows), 0.95)),
                         "mean_error": float(np.mean(values[:, 0] - true)), "sd_of_estimates": float(np.std(values[:, 0])),
                         "mean_half_width": float(np.mean(values[:, 2] - values[:, 1]) / 2),
                         "rms_sd_noise": float(np.sqrt(np.mean(values[:, 3] ** 2)))}
    print(json.dumps(summary, indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())
