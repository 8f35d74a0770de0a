"""How often `--refine` fills a pixel of a probability sweep wrongly (issue 31): the refined
maps of a config with the [scatter] law of --spreads (times --scale) against its full
probability sweep, both computed here. Prints the pixels whose shares differ from the full
sweep's, the pixels filled, the cells rolled (each its M draws) and what `--refine` with its
fallback to the full grid decides. docs/chaos.md, "Refining a probability sweep", quotes it.

    python scripts/refine_probability.py [--config configs/fig08.toml] [--num 256] [--levels 3]
        [--draws 64] [--spreads configs/scatter_real.toml] [--scale 1] [--workers 2]
"""

import argparse
import os
import tempfile
import time
from pathlib import Path

import numpy as np

from dice_sweep.config import load_config
from dice_sweep.effects import get_key, noise_model
from dice_sweep.refine import refine_maps
from dice_sweep.storage import probability_names, read_sweep
from dice_sweep.sweep import run_sweep

LAW_KEYS = tuple(p.key for p in noise_model("scattered_impacts").params)  # the spreads and floors, from the registry


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--config", default="configs/fig08.toml")
    parser.add_argument("--num", type=int, default=256)
    parser.add_argument("--levels", type=int, default=3)
    parser.add_argument("--draws", type=int, default=64)
    parser.add_argument("--spreads", default="configs/scatter_real.toml", help="a config whose [scatter] law is used")
    parser.add_argument("--scale", type=float, default=1.0, help="factor on the law's spreads and floors")
    parser.add_argument("--workers", type=int, default=2)
    args = parser.parse_args()
    spreads = load_config(args.spreads)
    law = [f"{key}={args.scale * get_key(spreads, key)!r}" for key in LAW_KEYS]
    cfg = load_config(args.config, [f"grid.x.num={args.num}", f"grid.y.num={args.num}", f"scatter.draws={args.draws}", *law])
    started = time.perf_counter()
    refined = refine_maps(cfg, args.levels, workers=args.workers, fallback=False)
    refine_seconds = time.perf_counter() - started
    with tempfile.TemporaryDirectory() as folder:
        started = time.perf_counter()
        run_sweep(cfg, Path(folder) / "full.h5", workers=args.workers, progress=False)
        full_seconds = time.perf_counter() - started
        full = read_sweep(Path(folder) / "full.h5").probability
    mine = np.stack([refined.maps[name] for name in probability_names(cfg.die.sides)])
    differ = np.any(mine != full, axis=0)
    filled = ~refined.simulated
    cells = args.num * args.num
    print(f"{Path(args.config).stem} {args.num} x {args.num}, --refine {args.levels} without fallback, {args.draws} draws, law of "
          f"{args.spreads} x {args.scale:g}: pixels whose shares differ from the full sweep's {differ.sum()} "
          f"({100 * differ.mean():.4f} %), of them rolled at their own centre {differ[~filled].sum()}; filled {filled.sum()} "
          f"({100 * filled.mean():.2f} %), each p = 1: {bool(np.all(mine[:, filled].max(axis=0) == 1.0))}; cells rolled "
          f"{refined.rolls} ({100 * refined.rolls / cells:.1f} % of the full grid's {cells}); pixels with p = 1 in the full "
          f"sweep {100 * np.mean(full.max(axis=0) == 1.0):.1f} %; refined {refine_seconds:.1f} s, full {full_seconds:.1f} s "
          f"({args.workers} workers, load average now {' '.join(f'{v:.2f}' for v in os.getloadavg())})", flush=True)
    decided = []
    refine_maps(cfg, args.levels, workers=args.workers, log=decided.append)
    print(f"with the fallback: {decided[0]}")


if __name__ == "__main__":
    main()
