"""Wall time of a probability sweep (issue 31 item 5): fig08 at 512 x 512 with [scatter]
draws = 64 on 2 workers, target 60 s. A benchmark, not a test: it prints min / median / max
of the repeats and the machine's load (os.getloadavg), which on a shared machine says more
than any single number. The kernel is compiled (or loaded) before the first timed run.

    python scripts/bench_probability.py [--num 512] [--draws 64] [--workers 2] [--repeat 3]
        [--spreads configs/scatter_real.toml] [--config configs/fig08.toml]

The law (the [scatter] law keys of the effect registry) is that of real bounces, read from --spreads.
"""

import argparse
import os
import statistics
import tempfile
import time
from pathlib import Path

from dice_sweep.config import load_config
from dice_sweep.effects import scatter_law_keys
from dice_sweep.sweep import SweepJob, run_sweep

LAW_KEYS = scatter_law_keys()  # what the --spreads file gives: spreads, floors, the power and the shape
TARGET_SECONDS = 60.0  # issue 31 item 5, at 512 x 512, 64 draws, 2 cores


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--config", default="configs/fig08.toml")
    parser.add_argument("--num", type=int, default=512)
    parser.add_argument("--draws", type=int, default=64)
    parser.add_argument("--workers", type=int, default=2)
    parser.add_argument("--repeat", type=int, default=3)
    parser.add_argument("--spreads", default="configs/scatter_real.toml", help="a config whose [scatter] law is used")
    args = parser.parse_args()
    spreads = load_config(args.spreads).scatter
    law = [f"scatter.{key}={getattr(spreads, key)!r}" for key in LAW_KEYS]
    cfg = load_config(args.config, [f"grid.x.num={args.num}", f"grid.y.num={args.num}", f"scatter.draws={args.draws}", *law])
    SweepJob.from_config(cfg).warm_up()  # compile or load before timing
    seconds = []
    with tempfile.TemporaryDirectory() as folder:
        for k in range(args.repeat):
            load_before = os.getloadavg()[0]
            started = time.perf_counter()
            summary = run_sweep(cfg, Path(folder) / f"run{k}.h5", workers=args.workers, progress=False)
            seconds.append(time.perf_counter() - started)
            print(f"run {k}: {seconds[-1]:.1f} s, {summary.rolls_computed / seconds[-1]:,.0f} rolls/s "
                  f"(load average {load_before:.2f} before, {os.getloadavg()[0]:.2f} after)", flush=True)
    print(f"{Path(args.config).stem} {args.num} x {args.num}, {args.draws} draws, "
          f"{', '.join(f'{key} {getattr(spreads, key):.4g}' for key in LAW_KEYS)}, "
          f"{args.workers} workers: min {min(seconds):.1f} s, median {statistics.median(seconds):.1f} s, "
          f"max {max(seconds):.1f} s over {len(seconds)} runs (target {TARGET_SECONDS:g} s); "
          f"{os.cpu_count()} cores, load average now {' '.join(f'{v:.2f}' for v in os.getloadavg())}")


if __name__ == "__main__":
    main()
