"""The null calibration of the checks before the work (dice_sweep/measured/checks.py): their
measured values on clean drops of the independent generator (tests/measured/independent.py,
not the kernel) for several dice, frame rates and noise levels, two seeds each, on the real
drops when they are beside this checkout, and on the same drops with one unit or convention
wrong.

    python scripts/checks_calibration.py [--tracks 40] [--real PATH] [--out DIR]

Prints a Markdown table: per set, each check's median (or share) with its 95 % interval, and
the checks' verdict (the first error, else the warnings, else ok). docs/measured_method.md
("Checks before the work") quotes it. About a minute on 2 cores. Needs the tests folder (a
checkout), not only the package.
"""

import argparse
import csv
import math
import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

from dice_sweep.config import parse_config  # noqa: E402
from dice_sweep.errors import DiceSweepError  # noqa: E402
from dice_sweep.measured import checks  # noqa: E402
from dice_sweep.measured.tracks import load_tracks  # noqa: E402
from tests.measured.independent import Truth, simulate_drops, write_csv  # noqa: E402

REAL = ROOT.parent / "shared" / "data" / "mcube_square_drops" / "drops.csv.gz"
SQUARE_R = 0.06 / math.sqrt(2)

# name, Truth keywords, rate (Hz), noise (m, rad), simulate_drops keywords
NULL_SETS = [
    ("square 500 Hz", dict(sides=4), 500.0, (2e-4, 4e-3), {}),
    ("square 250 Hz", dict(sides=4), 250.0, (2e-4, 4e-3), {}),
    ("square 1000 Hz, low noise, friction", dict(sides=4, friction=0.3), 1000.0, (1e-4, 2e-3), {}),
    ("square 250 Hz, high noise, drops, glitches", dict(sides=4, beta_normal=0.6), 250.0, (5e-4, 1e-2), dict(drop_prob=0.01, glitch_prob=0.01)),
    ("triangle R 40 mm", dict(sides=3, circumradius=0.04), 500.0, (2e-4, 4e-3), {}),
    ("hexagon", dict(sides=6, circumradius=SQUARE_R), 500.0, (2e-4, 4e-3), {}),
    ("octagon R 30 mm 250 Hz", dict(sides=8, circumradius=0.03), 250.0, (2e-4, 4e-3), {}),
    ("square, air drag, loaded", dict(sides=4, air_drag=0.05, com_offset=(0.002, 0.0)), 500.0, (2e-4, 4e-3), {}),
    ("square, fast spin, inertia 0.8", dict(sides=4, friction=0.3, inertia=0.8), 500.0, (2e-4, 4e-3), dict(spin=(-25.0, 25.0))),
]


def config_text(sides, radius):
    return f'[die]\nsides = {sides}\ncircumradius = {radius!r}\n[contact]\nmodel = "rigid"\nbeta_normal = 0.4\nbeta_tangential = 0.0\n'


def transform(src, dst, change, header=None):
    """Rewrite a track CSV row by row (floats) through ``change``."""
    with open(src, newline="") as fh:
        rows = list(csv.reader(fh))
    with open(dst, "w", newline="") as fh:
        out = csv.writer(fh)
        out.writerow(header or rows[0])
        for row in rows[1:]:
            out.writerow(change([float(v) for v in row]))
    return dst


def row(label, path, config, rate=None, angle="as-is"):
    cfg = parse_config(config) if isinstance(config, str) else config
    try:
        tracks = load_tracks(path, sides=cfg.die.sides, circumradius=cfg.die.circumradius, rate=rate, angle=angle)
    except DiceSweepError as error:
        return f"| {label} | " + " | ".join(["-"] * 7) + f" | loader: {str(error).split(': ', 2)[-1][:70]} |"
    findings = checks.judge(checks.measure(tracks, cfg), cfg)
    cells = []
    for f in findings:
        if f.name == "evidence":
            continue
        cells.append("-" if f.status == "skipped" else f"{f.value:.3g} [{f.interval[0]:.3g}, {f.interval[1]:.3g}]"
                     + {"error": " **E**", "warn": " *w*"}.get(f.status, ""))
    errors = [f.name for f in findings if f.status == "error"]
    warns = [f.name for f in findings if f.status == "warn"]
    verdict = f"error: {errors[0]}" if errors else f"warn: {', '.join(warns)}" if warns else "ok"
    return f"| {label} | " + " | ".join(cells) + f" | {verdict} |"


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--tracks", type=int, default=40)
    parser.add_argument("--real", default=str(REAL))
    parser.add_argument("--out", help="folder for the CSVs [default: a temporary one]")
    args = parser.parse_args()
    folder = Path(args.out or tempfile.mkdtemp(prefix="checks_calibration_"))
    folder.mkdir(parents=True, exist_ok=True)
    names = [n for n in ("gravity (m/s^2)", "angle_unit", "angle_wrap", "rest_height", "rest_angle", "contact_height (R)", "contact_share")]
    print("| set | " + " | ".join(names) + " | verdict |")
    print("|---" * (len(names) + 2) + "|")
    made = {}
    for name, truth_kw, rate, noise, extra in NULL_SETS:
        truth = Truth(**truth_kw)
        for seed in (1, 2):
            path = folder / f"{name.split(',')[0].replace(' ', '_')}_{len(made)}_s{seed}.csv"
            write_csv(path, simulate_drops(truth, args.tracks, seed, rate=rate, noise=noise, **extra))
            made[(name, seed)] = (path, truth)
            print(row(f"null: {name}, seed {seed}", path, config_text(truth.sides, truth.circumradius)), flush=True)
    real = Path(args.real)
    square = config_text(4, SQUARE_R)
    hexagon = config_text(6, SQUARE_R)
    if real.exists():
        cfg = parse_config((ROOT / "configs" / "square_drops.toml").read_text())
        print(row("real drops, --angle auto", real, cfg, angle="auto"), flush=True)
        print(row("real drops, --angle as-is (the file's own angle)", real, cfg), flush=True)
        print(row("real drops, --angle auto, a hexagon's config", real, hexagon, angle="auto"), flush=True)
        print(row("real drops, --angle auto, a triangle's config", real, config_text(3, SQUARE_R), angle="auto"), flush=True)
    for seed in (1, 2):
        sq, _ = made[("square 500 Hz", seed)]
        hx, _ = made[("hexagon", seed)]
        spin, _ = made[("square, fast spin, inertia 0.8", seed)]
        cases = [
            ("phi in degrees", transform(sq, folder / f"deg_{seed}.csv", lambda r: [r[0], r[1], r[2], r[3], math.degrees(r[4])]), square, None),
            ("x, y in mm", transform(sq, folder / f"mm_{seed}.csv", lambda r: [r[0], r[1], 1e3 * r[2], 1e3 * r[3], r[4]]), square, None),
            ("x, y in cm", transform(sq, folder / f"cm_{seed}.csv", lambda r: [r[0], r[1], 1e2 * r[2], 1e2 * r[3], r[4]]), square, None),
            ("t in ms", transform(sq, folder / f"ms_{seed}.csv", lambda r: [r[0], 1e3 * r[1], r[2], r[3], r[4]]), square, None),
        ]
        frames = transform(sq, folder / f"frame_{seed}.csv", lambda r: [r[0], round(500 * r[1]), r[2], r[3], r[4]], ["traj", "frame", "x", "y", "phi"])
        cases += [(f"frames of 500 Hz read with --rate {hz:g}", frames, square, hz) for hz in (250.0, 400.0, 600.0, 1000.0)]
        cases += [
            ("a hexagon's drops, a square's config", hx, square, None),
            ("a square's drops, a hexagon's config", sq, hexagon, None),
            ("a square's drops, R 60 mm in the config", sq, config_text(4, 0.06), None),
            ("phi + half a side (45 deg)", transform(sq, folder / f"half_{seed}.csv", lambda r: [r[0], r[1], r[2], r[3], r[4] + math.pi / 4]), square, None),
            ("hexagon phi + half a side (30 deg)", transform(hx, folder / f"halfhex_{seed}.csv", lambda r: [r[0], r[1], r[2], r[3], r[4] + math.pi / 6]), hexagon, None),
            ("phi + a quarter side (22.5 deg)", transform(sq, folder / f"quarter_{seed}.csv", lambda r: [r[0], r[1], r[2], r[3], r[4] + math.pi / 8]), square, None),
            ("y + 1 cm (table not at 0)", transform(sq, folder / f"table_{seed}.csv", lambda r: [r[0], r[1], r[2], r[3] + 0.01, r[4]]), square, None),
            ("phi wrapped into [0, 90 deg)", transform(spin, folder / f"wrap90_{seed}.csv", lambda r: [r[0], r[1], r[2], r[3], r[4] % (math.pi / 2)]), square, None),
            ("phi wrapped into [-180, 180 deg)", transform(spin, folder / f"wrap360_{seed}.csv",
                                                        lambda r: [r[0], r[1], r[2], r[3], (r[4] + math.pi) % (2 * math.pi) - math.pi]), square, None),
        ]
        for label, path, config, rate in cases:
            print(row(f"{label}, seed {seed}", path, config, rate=rate), flush=True)


if __name__ == "__main__":
    main()
