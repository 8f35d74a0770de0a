"""Tests of dice_sweep.distributed: sweeps whose tiles are tasks on a dask.distributed cluster.

A LocalCluster of 2 worker processes (spawned, so they import dice_sweep and load the kernel
themselves, like remote machines) must give maps bitwise equal to the local run's, and
resume a file that it or the local executor left incomplete.
"""

import subprocess
import sys
from pathlib import Path

import pytest

distributed = pytest.importorskip("distributed")

from dice_sweep.config import load_config  # noqa: E402
from dice_sweep.distributed import check_workers, kernel_fingerprint  # noqa: E402
from dice_sweep.errors import DiceSweepError  # noqa: E402
from dice_sweep.storage import read_sweep  # noqa: E402
from dice_sweep.sweep import SweepInterrupted, run_sweep  # noqa: E402
from tests.helpers import ROOT, assert_same_maps, invoke, stop_after  # noqa: E402
from tests.test_sweep import TILE  # noqa: E402
from tests.test_sweep import cfg, reference  # noqa: E402, F401  (the same module-scoped fixtures)


@pytest.fixture(scope="module")
def cluster():
    with distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True, dashboard_address=None) as local:
        yield local


def test_dask_cluster_gives_the_local_maps_bitwise(cluster, tmp_path):
    """fig08 at 64 x 64 in 16 tiles: 2 dask workers against 1 local process."""
    fig08 = load_config(ROOT / "configs" / "fig08.toml", ["grid.x.num=64", "grid.y.num=64"])
    local, remote = tmp_path / "local.h5", tmp_path / "dask.h5"
    run_sweep(fig08, local, workers=1, tile_shape=(16, 16), progress=False)
    summary = run_sweep(fig08, remote, tile_shape=(16, 16), progress=False,
                        executor="dask", scheduler=cluster.scheduler_address)
    assert summary.complete and summary.rolls_computed == 64 * 64
    data = read_sweep(remote)
    assert data.complete and (data.status == 0).mean() > 0.99  # decided rolls, not placeholders
    assert_same_maps(data, read_sweep(local))


@pytest.mark.parametrize("first_executor", ["local", "dask"])
def test_dask_resumes_an_interrupted_file_to_the_same_maps(cluster, cfg, reference, tmp_path, first_executor):
    path = tmp_path / "interrupted.h5"
    dask = {"executor": "dask", "scheduler": cluster.scheduler_address}
    first = dask if first_executor == "dask" else {"workers": 1}
    with pytest.raises(SweepInterrupted, match="--resume"):
        run_sweep(cfg, path, tile_shape=TILE, progress=False, on_tile=stop_after(3), **first)
    assert not read_sweep(path).complete
    summary = run_sweep(cfg, path, tile_shape=TILE, progress=False, resume=True, **dask)
    assert summary.complete and 0 < summary.rolls_computed < 70
    assert_same_maps(read_sweep(path), reference)


def test_dask_shards_merge_to_the_local_maps(cluster, cfg, reference, tmp_path):
    from dice_sweep.sweep import merge_parts

    parts = [tmp_path / f"part{i}.h5" for i in range(2)]
    for i, part in enumerate(parts):
        run_sweep(cfg, part, tile_shape=TILE, progress=False, shard=(i, 2),
                  executor="dask", scheduler=cluster.scheduler_address)
    merge_parts(parts, tmp_path / "merged.h5")
    assert_same_maps(read_sweep(tmp_path / "merged.h5"), reference)


def test_unreachable_scheduler_is_one_line_error(cfg, tmp_path, monkeypatch):
    monkeypatch.setattr("dice_sweep.distributed.CONNECT_TIMEOUT_SECONDS", 2.0)
    with pytest.raises(DiceSweepError, match=r"--scheduler tcp://127.0.0.1:9: cannot connect") as caught:
        run_sweep(cfg, tmp_path / "x.h5", progress=False, executor="dask", scheduler="tcp://127.0.0.1:9")
    assert "\n" not in str(caught.value)
    assert not (tmp_path / "x.h5").exists()


class _FakeClient:
    def __init__(self, answers):
        self.answers = answers

    def run(self, function):
        return self.answers


def test_workers_with_another_kernel_are_refused():
    version, digest = kernel_fingerprint()
    assert check_workers(_FakeClient({"tcp://a:1": (version, digest)}), "tcp://s:1") == 1
    with pytest.raises(DiceSweepError, match="worker tcp://b:2 runs dice_sweep"):
        check_workers(_FakeClient({"tcp://a:1": (version, digest), "tcp://b:2": (version, "0" * 64)}), "tcp://s:1")
    with pytest.raises(DiceSweepError, match="has no workers"):
        check_workers(_FakeClient({}), "tcp://s:1")


def test_cli_sweep_on_a_dask_scheduler(cluster, tmp_path):
    out = tmp_path / "cli.h5"
    result = invoke("sweep", ROOT / "configs" / "demo.toml", "-o", out, "--set", "grid.x.num=16",
                    "--set", "grid.y.num=16", "--executor", "dask", "--scheduler", cluster.scheduler_address)
    assert result.exit_code == 0, result.output
    assert "256 rolls" in result.output and "complete" in result.output
    assert read_sweep(out).complete


def test_cli_refuses_refine_with_dask(tmp_path):
    result = invoke("sweep", ROOT / "configs" / "demo.toml", "-o", tmp_path / "x.h5", "--refine", "2", "--executor", "dask")
    assert result.exit_code == 2 and "--refine: cannot be combined" in result.output


def test_missing_dask_is_one_line_error_naming_the_extra(cfg, tmp_path, monkeypatch):
    monkeypatch.setitem(__import__("sys").modules, "distributed", None)  # import now fails
    with pytest.raises(DiceSweepError, match=r"pip install 'dice-sweep\[dask\]'"):
        run_sweep(cfg, tmp_path / "x.h5", progress=False, executor="dask")
    assert not (tmp_path / "x.h5").exists()


def test_scheduler_file_is_accepted(cluster, cfg, reference, tmp_path):
    """--scheduler PATH.json: the file `dask scheduler --scheduler-file` writes."""
    import json

    scheduler_file = tmp_path / "scheduler.json"
    scheduler_file.write_text(json.dumps({"address": cluster.scheduler_address}))
    run_sweep(cfg, tmp_path / "f.h5", tile_shape=TILE, progress=False, executor="dask", scheduler=str(scheduler_file))
    assert_same_maps(read_sweep(tmp_path / "f.h5"), reference)
    with pytest.raises(DiceSweepError, match="missing.json: No such file"):
        run_sweep(cfg, tmp_path / "g.h5", progress=False, executor="dask", scheduler=str(tmp_path / "missing.json"))
    (tmp_path / "bad.json").write_text("[1, 2]")
    with pytest.raises(DiceSweepError, match="bad.json: not a dask scheduler file"):
        run_sweep(cfg, tmp_path / "g.h5", progress=False, executor="dask", scheduler=str(tmp_path / "bad.json"))


def test_a_worker_with_another_kernel_is_refused_by_its_tasks(cluster, cfg, tmp_path, monkeypatch):
    """A worker that joins after the check at the start (simulated: the check is skipped and
    the client announces another kernel) fails its first task; the sweep stops with a one-line
    error naming the worker, and the file is left incomplete, not looking done."""
    import dice_sweep.distributed as dask_executor

    monkeypatch.setattr(dask_executor, "check_workers", lambda client, scheduler: 1)
    monkeypatch.setattr(dask_executor, "kernel_fingerprint", lambda: ("0.0.0", "0" * 64))
    path = tmp_path / "mixed.h5"
    with pytest.raises(DiceSweepError, match=r"worker tcp://\S+ runs dice_sweep .* this client 0\.0\.0") as raised:
        run_sweep(cfg, path, tile_shape=TILE, progress=False, executor="dask", scheduler=cluster.scheduler_address)
    assert "\n" not in str(raised.value)
    data = read_sweep(path)
    assert not data.complete and (data.status == 255).all()  # 255: not computed


def test_a_failing_task_raises_its_error(cluster, cfg, tmp_path):
    """An error inside a task reaches the client as that error (not as a tile to write, nor as
    another error wrapping it): the type and message a local run of the same tile raises, and a
    traceback running through the worker's frames down to the mapper's roll."""
    import dataclasses
    import re
    import traceback

    from numba.core.errors import TypingError

    from dice_sweep.distributed import dask_tile_results
    from dice_sweep.sweep import SweepJob

    job = SweepJob.from_config(cfg, TILE)
    broken = dataclasses.replace(job, mapper=dataclasses.replace(job.mapper, fpar=None))  # roll_batch refuses None
    with pytest.raises(TypingError) as here:
        broken.task().run(0)

    class Running:
        requested = False

    with dask_tile_results(broken.task(), [0, 1], Running(), scheduler=cluster.scheduler_address) as results:
        with pytest.raises(Exception) as raised:
            next(iter(results))
    assert type(raised.value) is TypingError
    def message(error):  # the object addresses numba names differ from process to process
        return re.sub(r"0x[0-9a-f]+", "0x", str(error))

    assert message(raised.value) == message(here.value) and "getitem(none" in message(raised.value)  # fpar typed as none
    frames = [(Path(frame.filename).name, frame.name) for frame in traceback.extract_tb(raised.tb)]
    assert ("distributed.py", "_run_tile") in frames and ("mapper.py", "roll") in frames, frames


def test_a_cancelled_tile_is_a_one_line_error_not_a_tile():
    """A task the scheduler cancelled comes back as (future, FutureCancelledError): it must not
    reach the writer as a tile (it once raised 'cannot unpack non-iterable FutureCancelledError')."""
    from dice_sweep.distributed import completed_tiles

    class Future:
        status = "cancelled"

        def release(self):
            raise AssertionError("a cancelled tile is not consumed")

    class Finished:
        def __init__(self):
            self.batches = [[(Future(), distributed.client.FutureCancelledError("tile", "cancelled"))]]

        def is_empty(self):
            return not self.batches

        def next_batch(self, block=False):
            return self.batches.pop(0)

    class FakeDistributed:
        @staticmethod
        def as_completed(futures, with_results, raise_errors):
            return Finished()

    class Running:
        requested = False

    with pytest.raises(DiceSweepError, match="cancelled a tile.*--resume"):
        next(completed_tiles(FakeDistributed, set(), Running(), "local cluster"))


RACE = """
import contextlib, os, sys, time
import distributed
from dice_sweep.distributed import quiet_cluster_logs
cluster = distributed.LocalCluster(n_workers=1, threads_per_worker=1, processes=True, dashboard_address=None)
client = distributed.Client(cluster)
quiet = quiet_cluster_logs(client) if sys.argv[1] == "quiet" else contextlib.nullcontext()
with quiet:
    cluster.sync(cluster.scheduler.close)  # the scheduler first: the worker's next heartbeat fails
    client.close()
    with contextlib.suppress(Exception):
        cluster.close(timeout=4)  # without its scheduler it would wait 30 s for its worker
    os._exit(0)
"""


@pytest.mark.parametrize("mode", ["loud", "quiet"])
def test_a_local_clusters_shutdown_race_prints_no_traceback(mode):
    """The shutdown race of dask/distributed#7105, forced by closing the scheduler before its
    worker: it prints tracebacks (the control, so the race is real here) unless the closing
    runs in quiet_cluster_logs, as every local-cluster sweep's does. The README's dask
    command failed its no-traceback check once on this race."""
    done = subprocess.run([sys.executable, "-c", RACE, mode], capture_output=True, text=True, timeout=300, cwd=ROOT)
    assert done.returncode == 0, done.stderr[-2000:]
    assert ("Traceback" in done.stderr) == (mode == "loud"), done.stderr[-2000:]
