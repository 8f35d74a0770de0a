"""Wall time of a sweep at 1 and 2 workers (or the counts given), and the size of its HDF5 file.

Usage::

    python scripts/bench_sweep.py configs/fig08.toml                    # 1 and 2 workers, 3 rounds
    python scripts/bench_sweep.py configs/fig08.toml --workers 1,2,4 --repeat 5 --set grid.x.num=128

Each run writes a fresh file in a temporary folder (removed afterwards). The first run also
compiles or loads the kernel, so a one-roll sweep goes first to keep that out of the times.
The worker counts take turns within each round, so that all see the same machine; printed are
min / median / max of the rounds, the speed-up of the medians over the first count, and the
machine's load average (``os.getloadavg``) before and after. The maps of all runs are checked
to be bitwise equal.
"""

import argparse
import os
import pathlib
import tempfile

import numpy as np

from dice_sweep.config import load_config
from dice_sweep.storage import read_sweep
from dice_sweep.sweep import run_sweep


def _worker_counts(text):
    return [int(part) for part in text.split(",")]


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("config", help="TOML config with a [grid]")
    parser.add_argument("--workers", type=_worker_counts, default=[1, 2], help="comma-separated worker counts (default 1,2)")
    parser.add_argument("--repeat", type=int, default=3, help="rounds (default 3)")
    parser.add_argument("--set", dest="overrides", action="append", default=[], metavar="SECTION.KEY=VALUE", help="config override, as for dice-sweep")
    args = parser.parse_args()

    cfg = load_config(args.config, args.overrides)
    ny, nx = cfg.grid.y.num, cfg.grid.x.num
    print(f"{args.config}: {ny} x {nx} = {ny * nx} rolls, n = {cfg.die.sides}, {cfg.integrator.method} integrator")
    with tempfile.TemporaryDirectory() as folder:
        folder = pathlib.Path(folder)
        warm_up = load_config(args.config, [*args.overrides, "grid.x.num=1", "grid.y.num=1"])
        run_sweep(warm_up, folder / "warm_up.h5", workers=1, progress=False)
        reference = None
        seconds = {workers: [] for workers in args.workers}
        load_before = os.getloadavg()
        for round_ in range(args.repeat):
            for workers in args.workers:
                path = folder / f"workers{workers}-{round_}.h5"
                summary = run_sweep(cfg, path, workers=workers, progress=False)
                seconds[workers].append(summary.seconds)
                outcome = read_sweep(path).outcome
                if reference is None:
                    reference = outcome
                    print(f"HDF5 file: {path.stat().st_size / 1e6:.2f} MB")
                elif outcome.tobytes() != reference.tobytes():
                    raise SystemExit(f"workers = {workers}: outcome map differs from workers = {args.workers[0]}")
                path.unlink()
        load_after = os.getloadavg()
    first = float(np.median(seconds[args.workers[0]]))
    for workers, times in seconds.items():
        median = float(np.median(times))
        print(f"workers = {workers}: {min(times):.2f} / {median:.2f} / {max(times):.2f} s wall (min / median / max of "
              f"{len(times)}), {ny * nx / median:,.0f} rolls/s, speed-up over {args.workers[0]} worker(s) {first / median:.2f}")
    print("load average (1, 5, 15 min) before: {:.2f} {:.2f} {:.2f}; after: {:.2f} {:.2f} {:.2f} on {} cores".format(
        *load_before, *load_after, os.cpu_count()))


if __name__ == "__main__":
    main()
