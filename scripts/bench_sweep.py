"""Wall and CPU time of a sweep at 1 and 2 workers (or the counts given), and the size of its HDF5 file.

Usage::

    python scripts/bench_sweep.py configs/fig08.toml --set grid.x.num=1024 --set grid.y.num=1024
    python scripts/bench_sweep.py configs/fig08.toml --cli --set grid.x.num=4096 --set grid.y.num=4096 --workers 2
    python scripts/bench_sweep.py configs/fig08.toml --workers 1,2,4 --repeat 5 --set grid.x.num=128

Two ways of timing, both with a warm numba cache (the kernel is compiled or loaded before the
first timed run):

- default: ``run_sweep`` in this process, which has loaded the kernel already (what a
  long-lived process pays: the sweep itself);
- ``--cli``: the whole ``dice-sweep sweep`` command in a fresh process (Python's start, the
  imports and loading the kernel from numba's cache included: what a user waits for). The
  package is byte-compiled first, as an installed one is (pip compiles at install): under
  PYTHONDONTWRITEBYTECODE=1 an editable checkout would compile its modules from source at
  every start, 0.06-0.07 s of CPU (docs/dev/speed_issue33.md).

Each run writes a fresh file in a temporary folder (removed afterwards). The worker counts
take turns within each round, so that all see the same machine. Printed per count: wall time,
the CPU time of the process that writes the file (default mode) and of its workers (all CPU of
the command with ``--cli``), each as min / median / max of the rounds; the speed-up of the
median wall times over the first count; and the load average (``os.getloadavg``, as ``uptime``
prints it) before and after every round: on a shared machine the wall times follow the load,
the CPU times much less. The maps of all runs are checked to be bitwise equal.
"""

import argparse
import compileall
import os
import pathlib
import resource
import subprocess
import sys
import tempfile
import time

import numpy as np

from dice_sweep.config import load_config
from dice_sweep.storage import read_sweep
from dice_sweep.sweep import SweepJob, run_sweep

CLI = [sys.executable, "-m", "dice_sweep"]


def _worker_counts(text):
    return [int(part) for part in text.split(",")]


def children_cpu():
    """CPU seconds (user + system) of the waited-for child processes so far."""
    usage = resource.getrusage(resource.RUSAGE_CHILDREN)
    return usage.ru_utime + usage.ru_stime


def timed_sweep(args, overrides, path, workers):
    """(wall s, this process's CPU s, children's CPU s) of one sweep of ``args.config`` with
    ``overrides`` into ``path``."""
    cfg = load_config(args.config, overrides)
    wall, cpu, children = time.perf_counter(), time.process_time(), children_cpu()
    if args.cli:
        command = [*CLI, "sweep", args.config, "-o", str(path), "--workers", str(workers), "--quiet"]
        for override in overrides:
            command += ["--set", override]
        subprocess.run(command, check=True, capture_output=True)
    else:
        run_sweep(cfg, path, workers=workers, progress=False)
    return time.perf_counter() - wall, time.process_time() - cpu, children_cpu() - children


def spread(values):
    return f"{min(values):.2f} / {float(np.median(values)):.2f} / {max(values):.2f}"


def load():
    return " ".join(f"{value:.2f}" for value in os.getloadavg())


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("config", help="TOML config with a [grid]")
    parser.add_argument("--workers", type=_worker_counts, default=[1, 2], help="comma-separated worker counts (default 1,2)")
    parser.add_argument("--repeat", type=int, default=3, help="rounds (default 3)")
    parser.add_argument("--cli", action="store_true", help="time the whole dice-sweep sweep command (a fresh process)")
    parser.add_argument("--set", dest="overrides", action="append", default=[], metavar="SECTION.KEY=VALUE", help="config override, as for dice-sweep")
    args = parser.parse_args()

    cfg = load_config(args.config, args.overrides)
    ny, nx = cfg.grid.y.num, cfg.grid.x.num
    job = SweepJob.from_config(cfg)
    mode = "the whole `dice-sweep sweep` command" if args.cli else "run_sweep in a process with the kernel loaded"
    print(f"{args.config} {' '.join(args.overrides)}: {ny} x {nx} = {ny * nx} rolls in {job.tiles.count} tiles of "
          f"{job.tiles.tile_shape[0]} x {job.tiles.tile_shape[1]}, n = {cfg.die.sides}, {cfg.integrator.method} integrator; {mode}")
    job.warm_up()  # compile, or load from numba's cache, before any timing (a fresh cache: the compile is not timed)
    if args.cli:
        import dice_sweep

        compileall.compile_dir(pathlib.Path(dice_sweep.__file__).parent, quiet=1)
    with tempfile.TemporaryDirectory() as folder:
        folder = pathlib.Path(folder)
        if args.cli:  # one untimed command: the files it reads are then in the OS's cache for every timed one
            tiny = [item for item in args.overrides if not item.startswith(("grid.x.num=", "grid.y.num="))]
            timed_sweep(args, [*tiny, "grid.x.num=2", "grid.y.num=2"], folder / "warm.h5", 1)
        reference = None
        times = {workers: [] for workers in args.workers}
        for round_ in range(args.repeat):
            print(f"round {round_ + 1}: load average (1, 5, 15 min) {load()} on {os.cpu_count()} cores", flush=True)
            for workers in args.workers:
                path = folder / f"workers{workers}-{round_}.h5"
                times[workers].append(timed_sweep(args, args.overrides, path, workers))
                outcome = read_sweep(path).outcome
                if reference is None:
                    reference = outcome
                    print(f"HDF5 file: {path.stat().st_size / 1e6:.2f} MB")
                elif outcome.tobytes() != reference.tobytes():
                    raise SystemExit(f"workers = {workers}: outcome map differs from workers = {args.workers[0]}")
                path.unlink()
        print(f"after the last round: load average {load()}")
    first = float(np.median([wall for wall, _, _ in times[args.workers[0]]]))
    print(f"min / median / max of {args.repeat} rounds:")
    for workers, runs in times.items():
        walls = [wall for wall, _, _ in runs]
        median = float(np.median(walls))
        if args.cli:
            cpu = f"CPU of the command and its workers {spread([children for _, _, children in runs])} s"
        else:
            cpu = (f"CPU of this process {spread([own for _, own, _ in runs])} s, of the worker processes "
                   f"{spread([children for _, _, children in runs])} s")
        print(f"workers = {workers}: wall {spread(walls)} s, {ny * nx / median:,.0f} rolls/s, speed-up over "
              f"{args.workers[0]} worker(s) {first / median:.2f}; {cpu}")


if __name__ == "__main__":
    main()
