"""Tests of dice_sweep.executor's tile interface: the pool runs any TileTask, knowing nothing
else of a sweep."""

import os

import pytest

from dice_sweep.errors import DiceSweepError
from dice_sweep.executor import StopRequest, TileTask, check_executor, parse_shard, tile_results


def _square_and_pid(index):
    """A task unrelated to sweeps: what the pool runs must be only what it is given."""
    return index * index, os.getpid()


@pytest.mark.parametrize("workers", [1, 2])
def test_the_pool_runs_the_tasks_run_on_every_tile_to_do(workers):
    todo = [5, 2, 9, 0, 7]
    with StopRequest() as stop, tile_results(TileTask(_square_and_pid), todo, workers, stop) as results:
        got = dict(results)
    assert {index: value[0] for index, value in got.items()} == {index: index * index for index in todo}
    in_this_process = {pid == os.getpid() for _, pid in got.values()}
    assert in_this_process == ({True} if workers == 1 else {False})


@pytest.mark.parametrize(
    ("options", "message"),
    [
        (("spark", None, None), "--executor 'spark': allowed values are local, dask"),
        (("local", "tcp://h:8786", None), "--scheduler: only with --executor dask"),
        (("dask", "tcp://h:8786", 2), "--workers: not with --scheduler"),
    ],
)
def test_executor_options_that_do_not_combine_are_refused(options, message):
    with pytest.raises(DiceSweepError, match=message):
        check_executor(*options)
    check_executor("dask", "tcp://h:8786", None)
    check_executor("local", None, 3)


def test_parse_shard_accepts_i_of_n_only():
    assert parse_shard("2/5") == (2, 5)
    for text in ("5/5", "-1/3", "1", "a/b", "1/0"):
        with pytest.raises(DiceSweepError, match="--shard"):
            parse_shard(text)
