"""Where a local sweep's wall time goes, per process: a timeline of every tile and CPU times.

Usage::

    python scripts/profile_sweep.py configs/fig08.toml --num 1024 --workers 2 [--repeat 3] [--tile 64]

Runs ``run_sweep`` in this process (after a warm-up that loads the compiled kernel) with
``SweepJob.stored_tile`` and ``SweepFile.write_tile`` wrapped to log wall and CPU clocks of
each call, in the workers and in the parent. Prints, per run: the wall time and its parts
before the first tile (engine choice, warm-up, fork, file creation), each worker's tiles,
busy wall and CPU, its idle time at the start and at the end (the tail: a worker done while
the other still rolls), the parent's CPU (writes and the rest), and the workers' CPU from
``getrusage``. CPU below wall inside a tile means the process waited for a core: on a shared
machine compare CPU, not wall. Public API only (the wrapping is this script's).
"""

import argparse
import os
import pathlib
import resource
import tempfile
import time

import numpy as np

from dice_sweep.config import load_config
from dice_sweep.storage import SweepFile
from dice_sweep.sweep import SweepJob, run_sweep


def _clocks():
    return time.perf_counter(), time.process_time()


def instrument(log_dir):
    """Wrap the tile work (in every process) and the parent's writes; returns the writes' log."""
    stored_tile, write_tile = SweepJob.stored_tile, SweepFile.write_tile
    writes = []

    def logged_tile(self, index):
        wall0, cpu0 = _clocks()
        result = stored_tile(self, index)
        wall1, cpu1 = _clocks()
        with open(log_dir / f"{os.getpid()}.txt", "a") as log:
            log.write(f"{index} {wall0!r} {wall1!r} {cpu0!r} {cpu1!r}\n")
        return result

    def logged_write(self, *args):
        wall0, cpu0 = time.perf_counter(), time.thread_time()
        write_tile(self, *args)
        writes.append((wall0, time.perf_counter(), time.thread_time() - cpu0))

    SweepJob.stored_tile, SweepFile.write_tile = logged_tile, logged_write
    return writes


def children_cpu():
    usage = resource.getrusage(resource.RUSAGE_CHILDREN)
    return usage.ru_utime + usage.ru_stime


def profile_once(cfg, path, workers, tile, log_dir, writes):
    for old in log_dir.glob("*.txt"):
        old.unlink()
    writes.clear()
    children0 = children_cpu()
    wall0, cpu0 = _clocks()
    run_sweep(cfg, path, workers=workers, progress=False, tile_shape=(tile, tile))
    wall1, cpu1 = _clocks()
    children = children_cpu() - children0
    wall = wall1 - wall0
    logs = {int(p.stem): np.loadtxt(p, ndmin=2) for p in log_dir.glob("*.txt")}
    first_tile = min(log[:, 1].min() for log in logs.values())
    last_write = max((w[1] for w in writes), default=wall1)
    print(f"  wall {wall:.3f} s: {first_tile - wall0:.3f} before the first tile starts, "
          f"{wall1 - last_write:.3f} after the last write (closing, marking complete)")
    print(f"  parent CPU {cpu1 - cpu0:.3f} s, of which writes {sum(w[2] for w in writes):.3f} s "
          f"({len(writes)} tiles, {1e3 * sum(w[2] for w in writes) / max(1, len(writes)):.2f} ms each); "
          f"children CPU (getrusage) {children:.3f} s")
    busy_cpu = 0.0
    for pid, log in sorted(logs.items()):
        starts, ends, cpu = log[:, 1], log[:, 2], log[:, 4] - log[:, 3]
        busy_cpu += cpu.sum()
        gaps = starts[1:] - ends[:-1]
        print(f"  pid {pid}: {len(log)} tiles, busy {np.sum(ends - starts):.3f} s wall / {cpu.sum():.3f} s CPU; "
              f"idle: start {starts[0] - wall0:.3f} s, between tiles {gaps.sum():.3f} s, "
              f"tail {wall1 - ends[-1]:.3f} s; tile wall median {1e3 * np.median(ends - starts):.1f} ms, "
              f"max {1e3 * np.max(ends - starts):.1f} ms")
    in_workers = children if workers > 1 else 0.0
    print(f"  CPU in tiles {busy_cpu:.3f} s; workers' CPU outside tiles {in_workers - (busy_cpu if workers > 1 else 0):.3f} s")
    return wall


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("config")
    parser.add_argument("--num", type=int, default=1024, help="cells per axis")
    parser.add_argument("--workers", type=int, default=2)
    parser.add_argument("--tile", type=int, default=64, help="tile side, cells")
    parser.add_argument("--repeat", type=int, default=1)
    parser.add_argument("--set", dest="overrides", action="append", default=[], metavar="SECTION.KEY=VALUE")
    args = parser.parse_args()
    cfg = load_config(args.config, [*args.overrides, f"grid.x.num={args.num}", f"grid.y.num={args.num}"])
    print(f"{args.config} at {args.num} x {args.num}, {args.workers} worker(s), tiles {args.tile} x {args.tile}; "
          f"load {' '.join(f'{v:.2f}' for v in os.getloadavg())} on {os.cpu_count()} cores")
    with tempfile.TemporaryDirectory() as folder:
        folder = pathlib.Path(folder)
        SweepJob.from_config(cfg).warm_up()  # load the kernel here, as a long-lived process would
        writes = instrument(folder)
        walls = []
        for round_ in range(args.repeat):
            print(f"run {round_ + 1}:")
            walls.append(profile_once(cfg, folder / f"run{round_}.h5", args.workers, args.tile, folder, writes))
    print(f"wall min / median / max: {min(walls):.3f} / {np.median(walls):.3f} / {max(walls):.3f} s; "
          f"load after {' '.join(f'{v:.2f}' for v in os.getloadavg())}")


if __name__ == "__main__":
    main()
