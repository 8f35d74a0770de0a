"""Cause or stand-in, and the verdict's stability, calibrated on drops from the independent
generator (tests/measured/independent.py, not the kernel): ``diagnose`` on sets where an effect
of the library is really present (what it names should be a ``cause``) and on sets with physics
outside the library or outside the declared model (what it names should be a ``stand_in``),
each on two independent draws (issue 30, items 1 and 3).

    python scripts/cause_calibration.py [--cases inertia,compliant] [--seeds 1,2] [--tracks 90] [--out DIR]

One JSON line per set on stdout: the verdict, the verdicts over re-splits, each named effect
with cause or stand-in and the comparisons that failed, what each fold added, the median error
before and after in floors, the proposals, the seconds it took. ``--out`` keeps each report.
Needs the tests folder (a checkout); minutes per set on two cores.
"""

import argparse
import json
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

from dice_sweep.config import parse_config  # noqa: E402
from dice_sweep.measured.diagnose import diagnose  # noqa: E402
from dice_sweep.measured.report import jsonable  # noqa: E402
from dice_sweep.measured.tracks import load_tracks  # noqa: E402
from tests.measured.cases import DECLARED_PAPER, DECLARED_RIGID, NOISE, RADIUS, TRUTH  # noqa: E402
from tests.measured.independent import Truth, simulate_drops, write_csv  # noqa: E402

# name: (physics added to the control truth, declared config, expected: "cause" or "stand_in")
CASES = {
    # an effect of the library really present
    "air_drag": ({"air_drag": 0.8}, DECLARED_RIGID, "cause"),
    "com_offset": ({"com_offset": (0.004, -0.002)}, DECLARED_RIGID, "cause"),
    "gravity": ({"g": 9.3}, DECLARED_RIGID, "cause"),
    "table_offset": ({"table_offset": 0.002}, DECLARED_RIGID, "cause"),
    "speed_restitution": ({"speed_restitution": 0.6}, DECLARED_RIGID, "cause"),
    "inertia": ({"inertia": 0.8}, DECLARED_RIGID, "cause"),
    "loaded_paper": ({"com_offset": (0.004, -0.002)}, DECLARED_PAPER, "cause"),  # friction and a loaded die, the paper law declared
    # a weak speed-dependent restitution (k = 0.1 s/m): before cross-fitting one set got table_offset
    "speed_restitution_weak": ({"speed_restitution": 0.1}, DECLARED_RIGID, "cause"),
    # physics outside the library
    "compliant": ({"compliant_time": 5e-4}, DECLARED_RIGID, "stand_in"),
    "spin_drag": ({"spin_drag": 0.02}, DECLARED_RIGID, "stand_in"),
    "table_tilt": ({"table_tilt": 0.05236}, DECLARED_RIGID, "stand_in"),
    "corner_beta": ({"corner_beta_normal": (0.4, 0.4, 0.7, 0.4)}, DECLARED_RIGID, "stand_in"),
    "magnus": ({"magnus": 0.1}, DECLARED_RIGID, "stand_in"),
}


def run(name, seed, tracks, folder, out=None):
    physics, declared, expected = CASES[name]
    truth = dict(TRUTH, **physics)
    table = truth.pop("table_offset", 0.0)  # the generator's table is at y = 0: the tracker's zero moved here
    drops = simulate_drops(Truth(**truth), tracks, seed, rate=500.0, noise=NOISE, drop_prob=0.01, glitch_prob=0.002)
    for drop in drops:
        drop["y"] = drop["y"] + table
    path = Path(folder) / f"{name}_{seed}.csv"
    write_csv(path, drops)
    cfg = parse_config(declared)
    start = time.perf_counter()
    report = diagnose(load_tracks(path, sides=4, circumradius=RADIUS), cfg, seed=0, null_simulations=100, bootstrap=400)
    report.pop("_fits")
    report = jsonable(report)
    if out:
        (Path(out) / f"{name}_{seed}.json").write_text(json.dumps(report, indent=1))
    return {"case": name, "seed": seed, "expected": expected, "verdict": report["verdict"],
            "verdict_spread": report["verdict_spread"]["verdicts"],
            "named": {e: report["effects"][e]["cause"] for e in report["effects_added"]},
            "failed": {e: report["effects"][e]["consistency"]["failed"] for e in report["effects_added"]},
            "folds": [f["effects_added"] for f in report["folds"]],
            "median_x_floor": [round(report["baseline"]["median_multiple_of_floor"], 2), round(report["after"]["median_multiple_of_floor"], 2)],
            "rms_x_floor": [round(report["baseline"]["multiple_of_floor"], 2), round(report["after"]["multiple_of_floor"], 2)],
            "proposals": [{"target": p["target"], "terms": {k: round(v, 4) for k, v in p["terms"].items()},
                           "heldout_gain": round(p["heldout_gain"], 3)} for p in report["proposals"]],
            "seconds": round(time.perf_counter() - start)}


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--cases", default=",".join(CASES), help=f"comma-separated, of {', '.join(CASES)}")
    parser.add_argument("--seeds", default="1,2")
    parser.add_argument("--tracks", type=int, default=90)
    parser.add_argument("--out", help="a folder for each set's report JSON")
    args = parser.parse_args()
    names = [n for n in args.cases.split(",") if n]
    unknown = [n for n in names if n not in CASES]
    if unknown:
        parser.error(f"unknown case {unknown[0]!r} (allowed: {', '.join(CASES)})")
    with tempfile.TemporaryDirectory() as folder:
        for name in names:
            for seed in (int(s) for s in args.seeds.split(",")):
                print(json.dumps(run(name, seed, args.tracks, folder, args.out)), flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
