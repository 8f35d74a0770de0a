"""Throughput of sweeps beyond one process: local workers, a dask cluster, and an estimate
for N machines from measured costs (issue 7; results in docs/scaling.md). Public API only.

Measures, on this machine:
1. the cost of one 64 x 64 tile (``SweepJob.stored_tile``: rolls and compression) for fig08 (n = 4) and fig10
   (n = 20, a zoom of the chaotic region): the unit of work of every executor;
2. what the writing process pays per tile: pickling a worker's result there and back (what
   crosses the network: the maps already compressed by the worker) and writing it to HDF5
   (chunks copied as they are, the tile recorded, a flush);
3. fig08 at --sweep-num with the local executor and with dask (a LocalCluster of 2
   single-threaded worker processes, started before the clock), both in this process, so
   the difference is dask's per-task overhead;
then estimates the wall time of a large sweep on N machines from (1) and (2).

    python scripts/bench_scaling.py [--sweep-num 1024] [--write]
"""

import argparse
import pickle
import sys
import tempfile
import time
from pathlib import Path

from dice_sweep.config import load_config
from dice_sweep.storage import SweepFile, chunk_shape, encode_tile
from dice_sweep.sweep import SweepJob, merge_parts, run_sweep

from _docs import publish  # scripts/_docs.py: the script's folder is on sys.path

ROOT = Path(__file__).resolve().parent.parent
TILE = (64, 64)
SAMPLE_TILES = 12  # tiles timed per config, spread over the grid
# dask's scheduler: "Each task suffers about 1ms of overhead" (https://distributed.dask.org,
# Motivation): a floor for dask runs that this machine cannot measure at cluster scale
DASK_TASK_SECONDS = 1e-3


def tile_cost(config_name, num):
    """(seconds per 64 x 64 tile, rolls/s) on one core, averaged over SAMPLE_TILES tiles."""
    cfg = load_config(ROOT / "configs" / config_name, [f"grid.x.num={num}", f"grid.y.num={num}"])
    job = SweepJob.from_config(cfg, TILE)
    job.warm_up()
    picks = [round(i * (job.tiles.count - 1) / (SAMPLE_TILES - 1)) for i in range(SAMPLE_TILES)]
    start = time.perf_counter()
    for index in picks:
        job.stored_tile(index)
    seconds = (time.perf_counter() - start) / len(picks)
    return seconds, TILE[0] * TILE[1] / seconds


def client_cost(job, path, tmp):
    """(pickle round trip s, pickled bytes, HDF5 write s) per tile of what workers send.

    The write is timed over every tile of the finished file ``path``, encoded as a worker
    encodes it and written into a new file as ``run_sweep`` writes it (data, record, flush).
    """
    encoded = job.stored_tile(0)
    start = time.perf_counter()
    for _ in range(50):
        blob = pickle.dumps((0, encoded), protocol=pickle.HIGHEST_PROTOCOL)
        pickle.loads(blob)
    pickled = (time.perf_counter() - start) / 50
    tiles = job.tiles
    chunk = chunk_shape(tiles.tile_shape, tiles.shape)
    with SweepFile.open(path) as source:
        header = source.header
        blocks = [encode_tile(source.read_block(*tiles.bounds(i)), chunk, header.count_columns) for i in range(tiles.count)]
    with SweepFile.create(Path(tmp) / "copy.h5", header, tiles.count) as target:
        start = time.perf_counter()
        for index, block in enumerate(blocks):
            target.write_tile(index, *tiles.bounds(index), block)
        written = (time.perf_counter() - start) / tiles.count
    return pickled, len(blob), written


def sweep_seconds(cfg, path, **options):
    start = time.perf_counter()
    run_sweep(cfg, path, progress=False, tile_shape=TILE, **options)
    return time.perf_counter() - start


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--sweep-num", type=int, default=1024, help="cells per axis of the fig08 sweeps")
    parser.add_argument("--write", action="store_true", help="write docs/scaling.md")
    args = parser.parse_args()
    import distributed

    num = args.sweep_num
    fig08 = load_config(ROOT / "configs" / "fig08.toml", [f"grid.x.num={num}", f"grid.y.num={num}"])
    lines = ["| tile of 64 x 64 rolls, one core | s per tile | rolls/s |", "|---|---|---|"]
    costs = {}
    for name in ("fig08.toml", "fig10.toml"):
        seconds, rate = tile_cost(name, num)
        costs[name] = (seconds, rate)
        lines.append(f"| {name} ({SAMPLE_TILES} tiles spread over its {num} x {num} grid) | {seconds * 1e3:.1f} ms | {rate:,.0f} |")
    with tempfile.TemporaryDirectory() as tmp:
        local = {w: sweep_seconds(fig08, Path(tmp) / f"local{w}.h5", workers=w) for w in (1, 2)}
        job = SweepJob.from_config(fig08, TILE)
        n_tiles = job.tiles.count
        pickled, size, written = client_cost(job, Path(tmp) / "local1.h5", tmp)
        start = time.perf_counter()
        merge_parts([Path(tmp) / "local1.h5"], Path(tmp) / "merged.h5")  # a one-part merge: every tile copied
        merged = (time.perf_counter() - start) / n_tiles
        start = time.perf_counter()
        with distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True, dashboard_address=None) as cluster:
            cluster_start = time.perf_counter() - start
            first = sweep_seconds(fig08, Path(tmp) / "dask1.h5", executor="dask", scheduler=cluster.scheduler_address)
            again = sweep_seconds(fig08, Path(tmp) / "dask2.h5", executor="dask", scheduler=cluster.scheduler_address)
    per_tile_client = pickled + written
    lines += ["", f"Per tile, in the process that writes the file: pickle round trip {pickled * 1e3:.2f} ms "
              f"({size / 1e3:.1f} kB pickled), HDF5 write {written * 1e3:.2f} ms (mean over the "
              f"{n_tiles} tiles of the file): **{per_tile_client * 1e3:.2f} ms**, so one client can take in at most "
              f"**{TILE[0] * TILE[1] / per_tile_client:,.0f} rolls/s** ({1 / per_tile_client:,.0f} tiles/s). "
              f"A 1 Gbit/s link carries {125e6 / size:,.0f} such tiles/s. `merge` copies "
              f"{merged * 1e3:.2f} ms per tile.", "",
              f"| fig08 at {num} x {num} ({n_tiles} tiles), in this process | wall time (s) | rolls/s |",
              "|---|---|---|"]
    rolls = num * num
    rows = [("local executor, 1 worker (in-process)", local[1]), ("local executor, 2 forked workers", local[2]),
            ("dask, LocalCluster of 2 worker processes, first sweep (workers load the kernel)", first),
            ("dask, same cluster, second sweep", again)]
    for name, seconds in rows:
        lines.append(f"| {name} | {seconds:.2f} | {rolls / seconds:,.0f} |")
    overhead = (again - local[2]) / n_tiles
    lines += ["", f"Starting the LocalCluster took {cluster_start:.1f} s (not in the times above). "
              f"dask against local workers: {overhead * 1e3:+.1f} ms per tile.", ""]
    # estimate: compute spread over the cores, bounded below by what one client can take in
    big = 16384
    lines += [f"Estimate for fig10 at {big} x {big} ({big * big / 1e6:.0f} M rolls, "
              f"{big * big // (TILE[0] * TILE[1]):,} tiles) on N machines of C cores, from the fig10 "
              "tile cost above: T = tiles x max(tile cost / (N C), floor per tile) + start-up (not "
              "included). With one dask cluster the floor is the client's cost per tile or the "
              f"scheduler's (about {DASK_TASK_SECONDS * 1e3:g} ms per task, from dask's documentation), "
              "whichever is larger; with one shard per machine (SLURM array, `make -j`) every machine "
              "writes its own file, so the client floor is shared N ways, and the merge adds the "
              "tiles x its cost per tile:", "",
              "| machines x cores | compute-bound | dask floor | estimate, one dask cluster | estimate, N shards + merge |",
              "|---|---|---|---|---|"]
    tiles_big = big * big // (TILE[0] * TILE[1])
    tile_s = costs["fig10.toml"][0]
    client_floor = tiles_big * per_tile_client
    dask_floor = tiles_big * max(per_tile_client, DASK_TASK_SECONDS)
    for machines, cores in ((1, 2), (4, 8), (16, 32), (64, 32), (256, 32)):
        compute = tiles_big * tile_s / (machines * cores)
        lines.append(f"| {machines} x {cores} | {compute:,.0f} s | {dask_floor:,.0f} s | "
                     f"{max(compute, dask_floor):,.0f} s | {max(compute, client_floor / machines) + tiles_big * merged:,.0f} s |")
    lines += ["", f"One writing client keeps up with about **{tile_s / per_tile_client:,.0f} cores** on fig10's tiles, "
              f"one dask scheduler with about **{tile_s / max(per_tile_client, DASK_TASK_SECONDS):,.0f}** "
              "(tile cost / floor per tile); beyond that, split the sweep with --shard so that several "
              "clients (or clusters) write, and merge the parts. Configs with cheaper tiles reach the "
              "floor with fewer cores (fig08's are about 100 times cheaper)."]
    publish("\n".join(lines), "scaling.md", "scaling_intro.md", args.write, heading="## Measured here\n\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
