"""What each piece of contact physics buys on the real drops: the declared model plus a list of
effects, fitted on the selection tracks and scored on the confirmation tracks (the split and
metric of docs/measured.md), one row per model. Skips cleanly without ../shared/data.

    python scripts/measured_ablation.py [--data PATH] [--config configs/square_drops.toml] [--md FILE]

Each row is `dice-sweep fit DATA --config C --angle auto --effects ...` (dice_sweep.app.measured.run_fit);
a row with `restitution = energetic` sets `[contact] restitution` in the config.
"""

import argparse
import json
import sys
import time
from pathlib import Path

import numpy as np

from dice_sweep.app.measured import run_fit
from dice_sweep.config import load_config

ROOT = Path(__file__).resolve().parent.parent
DEFAULT_DATA = ROOT.parent / "shared" / "data" / "mcube_square_drops" / "drops.csv.gz"

RIGID = ("corner_impulse", "coulomb_friction")
EXACT = ("exact_coulomb", "coulomb_friction")
MODELS = (  # (label, effects, config overrides)
    ("declared paper law", (), ()),
    ("rigid law, aimed friction (the loop's model before issue 28)", RIGID, ()),
    ("rigid law, sliding friction", ("sliding_friction", "coulomb_friction"), ()),
    ("exact Coulomb impact, Newton", EXACT, ()),
    ("exact Coulomb impact, energetic", EXACT, ("contact.restitution=energetic",)),
    ("exact + inertia", EXACT + ("inertia",), ()),
    ("exact + rounded corners", EXACT + ("rounded_corners",), ()),
    ("exact + inertia + rounded corners", EXACT + ("inertia", "rounded_corners"), ()),
    ("exact + inertia + rounded corners + speed restitution + flat landing", EXACT + ("inertia", "rounded_corners", "speed_restitution", "flat_landing"), ()),
)


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--data", default=str(DEFAULT_DATA))
    parser.add_argument("--config", default=str(ROOT / "configs" / "square_drops.toml"))
    parser.add_argument("--md", help="write the table as Markdown to this file")
    parser.add_argument("--json", help="write the rows as JSON to this file")
    args = parser.parse_args()
    if not Path(args.data).exists():
        print(f"skipped: {args.data} not found")
        return 0
    rows = []
    for label, effects, overrides in MODELS:
        start = time.perf_counter()
        result = run_fit(args.data, load_config(args.config, overrides), effects=effects, angle="auto")
        floor = result["noise_floor"]
        params = {k: v["value"] for k, v in result["params"].items()}
        rows.append({"label": label, "effects": list(effects), "overrides": list(overrides), "params": params,
                     "test_error": result["test_error"], "ci95": list(result["ci95"]), "noise_floor": floor,
                     "seconds": time.perf_counter() - start})
        low, high = result["ci95"]
        print(f"{label}: {result['test_error'] * 1e3:.3f} mm [{low * 1e3:.3f}, {high * 1e3:.3f}] "
              f"({result['test_error'] / floor:.1f} x floor); " + ", ".join(f"{k} {v:.4g}" for k, v in params.items()), flush=True)
    lines = ["| model | confirmation RMS | 95 % interval | x floor | fitted parameters |", "|---|---|---|---|---|"]
    for row in rows:
        low, high = row["ci95"]
        params = ", ".join(f"{k} {v:.4g}" for k, v in row["params"].items())
        lines.append(f"| {row['label']} | {row['test_error'] * 1e3:.3f} mm | [{low * 1e3:.3f}, {high * 1e3:.3f}] mm | "
                     f"{row['test_error'] / row['noise_floor']:.1f} | {params} |")
    text = "\n".join(lines)
    print(text)
    if args.md:
        Path(args.md).write_text(text + "\n")
    if args.json:
        Path(args.json).write_text(json.dumps(rows, indent=1, default=float))
    return 0


if __name__ == "__main__":
    sys.exit(main())
