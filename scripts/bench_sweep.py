"""Wall time of a sweep at several worker counts, and the size of its HDF5 file.

Usage::

    python scripts/bench_sweep.py configs/fig08.toml                    # 1 and 2 workers
    python scripts/bench_sweep.py configs/fig08.toml --workers 1,2,4 --set grid.x.num=128

Each run writes a fresh file in a temporary folder (removed afterwards). The first run also
compiles or loads the kernel, so a one-roll sweep goes first to keep that out of the times.
The maps of all runs are checked to be bitwise equal.
"""

import argparse
import pathlib
import tempfile

from dice_sweep.config import load_config
from dice_sweep.storage import read_sweep
from dice_sweep.sweep import run_sweep


def _worker_counts(text):
    return [int(part) for part in text.split(",")]


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("config", help="TOML config with a [grid]")
    parser.add_argument("--workers", type=_worker_counts, default=[1, 2], help="comma-separated worker counts (default 1,2)")
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
        for workers in args.workers:
            path = folder / f"workers{workers}.h5"
            summary = run_sweep(cfg, path, workers=workers, progress=False)
            print(f"workers = {workers}: {summary.seconds:.2f} s wall, {summary.rolls_computed / summary.seconds:.0f} rolls/s")
            outcome = read_sweep(path).outcome
            if reference is None:
                reference = outcome
                print(f"HDF5 file: {path.stat().st_size / 1e6:.2f} MB")
            elif outcome.tobytes() != reference.tobytes():
                raise SystemExit(f"workers = {workers}: outcome map differs from workers = {args.workers[0]}")


if __name__ == "__main__":
    main()
