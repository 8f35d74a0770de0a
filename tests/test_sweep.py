"""Tests of dice_sweep.sweep: grid values, tiles, workers, shards, merge, interruption, resume.

The kernel's outcomes are never hard-coded here: runs are compared with each other, bitwise.
"""

import os
import random
import signal
import subprocess
import sys

import h5py
import numpy as np
import pytest

from dice_sweep.config import parse_config
from dice_sweep.errors import DiceSweepError
from dice_sweep.mapper import Mapper, initial_states
from dice_sweep.physics import STATE_COLUMNS
from dice_sweep.storage import NOT_COMPUTED, SweepFile, read_sweep
from dice_sweep.sweep import (
    SweepInterrupted,
    SweepJob,
    SweepSummary,
    TileGrid,
    axis_values,
    default_tile_shape,
    merge_parts,
    run_sweep,
)
from tests.helpers import assert_same_maps, stop_after

# 7 rows x 10 columns in tiles of 3 x 4: 3 x 3 = 9 tiles, clipped at the bottom and right
CONFIG_TEXT = """
[initial]
phi0 = 0.3
vx0 = 0.1
[grid]
x = { param = "omega0", min = 0.0, max = 40.0, num = 10 }
y = { param = "y0", min = 0.03, max = 0.15, num = 7 }
"""
TILE = (3, 4)
N_TILES = 9


@pytest.fixture(scope="module")
def cfg():
    return parse_config(CONFIG_TEXT, "test.toml")


@pytest.fixture(scope="module")
def reference(cfg, tmp_path_factory):
    """An uninterrupted single-worker, unsharded sweep to compare every other run with."""
    path = tmp_path_factory.mktemp("reference") / "reference.h5"
    run_sweep(cfg, path, workers=1, tile_shape=TILE, progress=False)
    return read_sweep(path)


def sweep(cfg, path, **options):
    return run_sweep(cfg, path, tile_shape=TILE, progress=False, **options)


# --- grid and tiles ----------------------------------------------------------------------


def test_axis_values_are_cell_centres(cfg):
    values = axis_values(cfg.grid.y)
    assert values.dtype == np.float64 and len(values) == 7
    np.testing.assert_allclose(values, 0.03 + (np.arange(7) + 0.5) * 0.12 / 7, rtol=0, atol=1e-15)
    np.testing.assert_allclose(np.diff(values), 0.12 / 7)
    assert values[0] - 0.03 == pytest.approx(0.15 - values[-1])


def test_initial_states_run_x_fast_y_slow_and_keep_the_unswept_values(cfg):
    xs, ys = np.array([1.0, 2.0, 3.0]), np.array([0.05, 0.07])
    states = initial_states(cfg, xs, ys)
    assert states.shape == (6, len(STATE_COLUMNS))
    column = {name: states[:, STATE_COLUMNS.index(name)] for name in STATE_COLUMNS}
    assert column["omega0"].tolist() == [1.0, 2.0, 3.0, 1.0, 2.0, 3.0]
    assert column["y0"].tolist() == [0.05, 0.05, 0.05, 0.07, 0.07, 0.07]
    assert (column["phi0"] == 0.3).all() and (column["vx0"] == 0.1).all()
    assert (column["x0"] == cfg.initial.x0).all() and (column["vy0"] == cfg.initial.vy0).all()


def test_tiles_cover_the_grid_once_and_shards_partition_them():
    tiles = TileGrid((7, 10), TILE)
    assert tiles.count == N_TILES
    cover = np.zeros((7, 10), dtype=int)
    for index in range(tiles.count):
        cover[tiles.bounds(index)] += 1
    assert (cover == 1).all()
    assert tiles.bounds(8) == (slice(6, 7), slice(8, 10))
    shards = [tiles.shard_tiles((i, 4)) for i in range(4)]
    assert shards[1] == [1, 5]
    assert sorted(sum(shards, [])) == list(range(N_TILES))


def test_large_grids_get_larger_tiles_and_every_other_grid_64_x_64():
    assert default_tile_shape((1024, 1024)) == (128, 128)
    assert default_tile_shape((512, 4096)) == (128, 128)
    assert default_tile_shape((1023, 1024)) == (64, 64)
    assert default_tile_shape((7, 10)) == (64, 64)


# --- bitwise equality across workers, shards, tile orders ----------------------------------


def test_file_is_complete_with_every_cell_computed(reference):
    assert reference.complete and reference.computed.all()
    assert reference.outcome.shape == (7, 10)
    assert set(np.unique(reference.outcome)) <= set(range(-1, 4))


def test_two_workers_give_the_single_worker_maps_bitwise(cfg, reference, tmp_path):
    summary = sweep(cfg, tmp_path / "two.h5", workers=2)
    assert summary.complete and summary.rolls_computed == 70 and summary.shape == (7, 10)
    assert_same_maps(read_sweep(tmp_path / "two.h5"), reference)


def test_any_tile_order_gives_the_same_maps(cfg, reference):
    job = SweepJob.from_config(cfg, TILE)
    order = list(range(N_TILES))
    random.Random(1).shuffle(order)
    outcome = np.full((7, 10), 99, dtype=np.int8)
    t_decided = np.zeros((7, 10), dtype=np.float32)
    for index in order:
        rolls = job.tile_rolls(index)
        bounds = job.tiles.bounds(index)
        outcome[bounds] = rolls.outcome.reshape(outcome[bounds].shape)
        t_decided[bounds] = rolls.t_decided.reshape(t_decided[bounds].shape)
    assert outcome.tobytes() == reference.outcome.tobytes()
    assert t_decided.tobytes() == reference.t_decided.tobytes()


def test_shards_merged_equal_the_single_run_bitwise(cfg, reference, tmp_path):
    parts = [tmp_path / f"part{i}.h5" for i in range(2)]
    summaries = [sweep(cfg, part, workers=1, shard=(i, 2)) for i, part in enumerate(parts)]
    # tiles 0, 2, 4, 6, 8 hold 12 + 6 + 12 + 4 + 2 cells; tiles 1, 3, 5, 7 hold 12 + 12 + 6 + 4
    assert [s.rolls_computed for s in summaries] == [36, 34]
    part0 = read_sweep(parts[0])
    assert part0.complete and part0.shard == (0, 2) and not part0.computed.all()
    merged = merge_parts(parts[::-1], tmp_path / "merged.h5")
    assert merged.complete and merged.merged_parts == 2
    data = read_sweep(tmp_path / "merged.h5")
    assert data.complete and data.shard == (0, 1)
    assert_same_maps(data, reference)


# --- refusing ------------------------------------------------------------------------------


def test_existing_output_is_refused_without_resume(cfg, tmp_path):
    path = tmp_path / "out.h5"
    path.write_bytes(b"keep me")
    with pytest.raises(DiceSweepError, match="exists; use --resume or remove it"):
        sweep(cfg, path)
    assert path.read_bytes() == b"keep me"


@pytest.fixture(scope="module")
def shard_parts(cfg, tmp_path_factory):
    folder = tmp_path_factory.mktemp("parts")
    parts = [folder / f"part{i}of3.h5" for i in range(3)]
    for i, part in enumerate(parts):
        sweep(cfg, part, workers=1, shard=(i, 3))
    return parts


def test_merge_refuses_parts_of_another_config(cfg, shard_parts, tmp_path):
    other = parse_config(CONFIG_TEXT, "other.toml", overrides=["contact.beta_normal=0.3"])
    stranger = tmp_path / "other1of3.h5"
    sweep(other, stranger, workers=1, shard=(1, 3))
    with pytest.raises(DiceSweepError, match="not a part of the same sweep.*beta_normal") as caught:
        merge_parts([shard_parts[0], stranger, shard_parts[2]], tmp_path / "merged.h5")
    assert "other1of3.h5" in str(caught.value)
    assert not (tmp_path / "merged.h5").exists()


@pytest.mark.parametrize(
    ("pick", "message"),
    [
        ([0, 2], "shards missing: 1/3"),
        ([0, 1, 1, 2], "are both shard 1/3"),
    ],
)
def test_merge_refuses_missing_and_overlapping_shards(shard_parts, tmp_path, pick, message):
    with pytest.raises(DiceSweepError, match=message):
        merge_parts([shard_parts[i] for i in pick], tmp_path / "merged.h5")


def test_merge_refuses_an_incomplete_part(cfg, shard_parts, tmp_path):
    unfinished = tmp_path / "unfinished2of3.h5"
    with pytest.raises(SweepInterrupted):
        sweep(cfg, unfinished, workers=1, shard=(2, 3), on_tile=stop_after(1))
    with pytest.raises(DiceSweepError, match="unfinished2of3.h5: not complete"):
        merge_parts([shard_parts[0], shard_parts[1], unfinished], tmp_path / "merged.h5")


def test_merge_refuses_an_existing_output(shard_parts):
    with pytest.raises(DiceSweepError, match="exists"):
        merge_parts(shard_parts, shard_parts[0])


# --- interruption and resume ---------------------------------------------------------------


@pytest.mark.parametrize("workers", [1, 2])
def test_interrupted_sweep_is_incomplete_and_resumes_to_the_same_maps(cfg, reference, tmp_path, workers):
    path = tmp_path / "interrupted.h5"
    with pytest.raises(SweepInterrupted, match="--resume") as caught:
        sweep(cfg, path, workers=workers, on_tile=stop_after(3))
    assert isinstance(caught.value, DiceSweepError) and "\n" not in str(caught.value)
    partial = read_sweep(path)
    assert not partial.complete
    assert partial.computed.sum() < 70 and (partial.status == NOT_COMPUTED).any()
    summary = sweep(cfg, path, workers=workers, resume=True)
    assert summary.complete and 0 < summary.rolls_computed < 70
    assert_same_maps(read_sweep(path), reference)
    assert read_sweep(path).complete


def test_resume_of_a_complete_file_does_nothing_and_says_so(cfg, tmp_path):
    path = tmp_path / "done.h5"
    sweep(cfg, path, workers=1)
    before = path.read_bytes()
    summary = sweep(cfg, path, workers=1, resume=True)
    assert summary.already_complete and summary.complete and summary.rolls_computed == 0
    assert "already complete" in summary.describe()
    assert path.read_bytes() == before


def test_resume_without_a_file_starts_afresh(cfg, reference, tmp_path):
    summary = sweep(cfg, tmp_path / "new.h5", workers=1, resume=True)
    assert summary.complete and summary.rolls_computed == 70
    assert_same_maps(read_sweep(tmp_path / "new.h5"), reference)


def test_resume_goes_on_in_the_tiles_the_file_was_started_with(cfg, reference, tmp_path):
    """A file begun in other tiles than the default (an older default, or given ones) is
    finished in its own tiles: resume without a tile shape reads them from the file."""
    path = tmp_path / "started.h5"
    with pytest.raises(SweepInterrupted):
        sweep(cfg, path, workers=1, on_tile=stop_after(2))
    assert TILE != default_tile_shape((7, 10))
    summary = run_sweep(cfg, path, workers=2, resume=True, progress=False)
    assert summary.complete and summary.rolls_computed == 70 - 24
    with SweepFile.open(path) as finished:
        assert tuple(finished.header.tile_shape) == TILE
    assert_same_maps(read_sweep(path), reference)
    other = tmp_path / "other.h5"
    with pytest.raises(SweepInterrupted):
        sweep(cfg, other, workers=1, on_tile=stop_after(1))
    with pytest.raises(DiceSweepError, match=r"cannot resume.*tile shape \(3, 4\) vs \(2, 2\)"):
        run_sweep(cfg, other, resume=True, tile_shape=(2, 2), progress=False)


def test_resume_refuses_another_config_or_shard(cfg, tmp_path):
    path = tmp_path / "started.h5"
    with pytest.raises(SweepInterrupted):
        sweep(cfg, path, workers=1, on_tile=stop_after(1))
    other = parse_config(CONFIG_TEXT, "test.toml", overrides=["grid.x.num=11"])
    with pytest.raises(DiceSweepError, match="cannot resume.*different run.*num") as caught:
        sweep(other, path, workers=1, resume=True)
    assert "\n" not in str(caught.value)
    with pytest.raises(DiceSweepError, match="cannot resume.*shard 0/1 vs 1/2"):
        sweep(cfg, path, workers=1, resume=True, shard=(1, 2))
    assert read_sweep(path).computed.sum() == 12  # one 3 x 4 tile, untouched


SWEEP_PROCESS = """
import os, signal, sys, time
from dice_sweep.config import parse_config
from dice_sweep.sweep import SweepInterrupted, run_sweep

config_text, path, kill_after_two_tiles = sys.argv[1:]

def on_tile(index, rolls):
    print("tile", index, flush=True)
    if kill_after_two_tiles == "yes" and rolls >= 2:
        os.kill(os.getpid(), signal.SIGKILL)
    time.sleep(0.3)  # leave the test time to press Ctrl-C while tiles remain

try:
    run_sweep(parse_config(config_text, "test.toml"), path, workers=2,
              tile_shape=(3, 4), progress=False, on_tile=on_tile)
except SweepInterrupted as error:
    print(error, file=sys.stderr)
    sys.exit(130)
"""


def start_sweep_process(path, kill_after_two_tiles):
    """A `run_sweep` of CONFIG_TEXT on 2 workers in its own process group."""
    return subprocess.Popen(
        [sys.executable, "-c", SWEEP_PROCESS, CONFIG_TEXT, str(path), kill_after_two_tiles],
        stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, start_new_session=True,
    )


def assert_resumes_to_reference(cfg, reference, path):
    partial = read_sweep(path)
    assert not partial.complete and 0 < partial.computed.sum() < 70
    sweep(cfg, path, workers=2, resume=True)
    assert_same_maps(read_sweep(path), reference)


def test_sigkilled_sweep_leaves_a_resumable_file(cfg, reference, tmp_path):
    process = start_sweep_process(tmp_path / "killed.h5", kill_after_two_tiles="yes")
    _, stderr = process.communicate(timeout=300)
    assert process.returncode == -signal.SIGKILL, stderr
    assert_resumes_to_reference(cfg, reference, tmp_path / "killed.h5")


def test_ctrl_c_stops_parent_and_workers_cleanly(cfg, reference, tmp_path):
    process = start_sweep_process(tmp_path / "stopped.h5", kill_after_two_tiles="no")
    assert process.stdout.readline().startswith("tile")
    os.killpg(process.pid, signal.SIGINT)  # as a terminal does: the whole process group
    _, stderr = process.communicate(timeout=60)
    assert process.returncode == 130, stderr
    assert "--resume" in stderr and "Traceback" not in stderr
    assert_resumes_to_reference(cfg, reference, tmp_path / "stopped.h5")


def test_an_error_in_a_worker_reaches_the_parent_with_its_traceback(cfg):
    """A tile that raises in a forked worker raises the error it raises in this process,
    caused by the worker's traceback, instead of a tile to write."""
    import dataclasses

    from dice_sweep.executor import StopRequest, tile_results

    job = SweepJob.from_config(cfg, TILE)
    broken = dataclasses.replace(job, mapper=dataclasses.replace(job.mapper, fpar=None))  # roll_batch refuses None
    with pytest.raises(Exception) as here:
        broken.stored_tile(0)
    with pytest.raises(Exception) as raised, StopRequest() as stop:
        with tile_results(broken.task(), list(range(N_TILES)), 2, stop) as results:
            next(iter(results))
    assert not isinstance(raised.value, DiceSweepError)
    assert type(raised.value) is type(here.value)
    worker_traceback = str(raised.value.__cause__)
    assert worker_traceback.lstrip().startswith("Traceback (most recent call last)")
    assert type(here.value).__name__ in worker_traceback


def test_a_killed_worker_stops_the_sweep_with_a_resumable_file(cfg, reference, tmp_path, monkeypatch):
    """A worker killed mid-sweep (as by the OOM killer) is a one-line error, not a file
    that looks complete or a hang; --resume finishes the file."""
    rolled, parent = Mapper.roll, os.getpid()
    tile_4 = SweepJob.from_config(cfg, TILE).tile_states(4)

    def dies_on_tile_4(self, states, engine=None):
        if os.getpid() != parent and np.array_equal(states, tile_4):
            os.kill(os.getpid(), signal.SIGKILL)
        return rolled(self, states, engine)

    monkeypatch.setattr(Mapper, "roll", dies_on_tile_4)  # the workers are forked
    path = tmp_path / "killed_worker.h5"
    with pytest.raises(DiceSweepError, match="worker process ended with exit code -9.*--resume") as raised:
        sweep(cfg, path, workers=2)
    assert "\n" not in str(raised.value)
    assert not read_sweep(path).complete
    monkeypatch.undo()
    sweep(cfg, path, workers=2, resume=True)
    assert_same_maps(read_sweep(path), reference)


def test_summary_describes_the_run():
    summary = SweepSummary("out.h5", (7, 10), (1, 2), 30, 30, 1.5, True)
    assert summary.describe() == "out.h5 (7 x 10, shard 1/2): 30 rolls in 1.5 s (20 rolls/s), complete"


def test_summary_rate_leaves_out_a_compile():
    """Issue 16: make demo on a cold cache said 757 rolls/s, the compile counted as rolling."""
    summary = SweepSummary("out.h5", (128, 128), (0, 1), 16384, 16384, 21.6, True, kernel_seconds=20.6)
    assert summary.describe() == ("out.h5 (128 x 128, shard 0/1): 16384 rolls in 21.6 s "
                                  "(16384 rolls/s after 20.6 s compiling the kernel), complete")
    loaded = SweepSummary("out.h5", (128, 128), (0, 1), 16384, 16384, 1.3, True, kernel_seconds=0.3)
    assert "(16384 rolls/s), complete" in loaded.describe()  # a cached load is not called a compile


def test_resume_recomputes_a_tile_recorded_without_its_data(cfg, reference, tmp_path):
    path = tmp_path / "torn.h5"
    sweep(cfg, path, workers=1)
    with h5py.File(path, "r+") as h5:  # damage it as an unordered write-back could
        h5.attrs["complete"] = False
        h5["status"][0:3, 4:8] = NOT_COMPUTED  # tile 1 still recorded in /done_tiles
    summary = sweep(cfg, path, workers=1, resume=True)
    assert summary.complete and summary.rolls_computed == 12
    assert_same_maps(read_sweep(path), reference)


# --- probability sweeps: M draws per cell under the stochastic impact law (issue 31) ---------

DRAWS = 48
# t_max 0.3 s: the high drops end undecided, so the no-answer share is not always 0
SCATTERED = "\n[scatter]\ncorner = 0.05\nflat = 0.05\ndraws = 48\nseed = 5\n[integrator]\nt_max = 0.3\n"


@pytest.fixture(scope="module")
def scattered_cfg():
    return parse_config(CONFIG_TEXT + SCATTERED, "scattered.toml")


@pytest.fixture(scope="module")
def scattered(scattered_cfg, tmp_path_factory):
    path = tmp_path_factory.mktemp("scattered") / "scattered.h5"
    summary = sweep(scattered_cfg, path, workers=1)
    assert summary.complete and summary.rolls_computed == 70 * DRAWS
    return read_sweep(path)


def plain_monte_carlo(cfg, first_draw):
    """Shares (n + 1, ny, nx) of DRAWS rolls per cell, each a single roll of the mapper on the
    stream (j nx + i, first_draw + m): the test's own loop, row n the rolls without a side."""
    mapper = Mapper.from_config(cfg)
    xs, ys = axis_values(cfg.grid.x), axis_values(cfg.grid.y)
    shares = np.zeros((cfg.die.sides + 1, len(ys), len(xs)))
    for j, y in enumerate(ys):
        for i, x in enumerate(xs):
            start = initial_states(cfg, [x], [y])
            for m in range(DRAWS):
                side = int(mapper.roll(start, streams=np.array([[j * len(xs) + i, first_draw + m]], dtype=float)).outcome[0])
                shares[side if side >= 0 else cfg.die.sides, j, i] += 1.0 / DRAWS
    return shares


def test_probability_maps_are_the_shares_of_each_cells_own_streams(scattered_cfg, scattered):
    """The same streams rolled one by one give the file's shares (and its no-answer share)."""
    assert scattered.draws == DRAWS and scattered.probability.shape == (5, 7, 10)
    np.testing.assert_allclose(scattered.probability, plain_monte_carlo(scattered_cfg, 0), rtol=0, atol=1e-6)
    assert scattered.probability[-1].max() > 0  # some draws without a side: the test covers them


def test_probability_maps_match_an_independent_monte_carlo_within_binomial_noise(scattered_cfg, scattered):
    """Other draws (streams DRAWS .. 2 DRAWS - 1) of the same pixels: the shares agree within
    4.5 standard deviations of the difference of two binomial shares, at every pixel and side."""
    other = plain_monte_carlo(scattered_cfg, DRAWS)
    pooled = (scattered.probability + other) / 2
    sd = np.sqrt(np.maximum(pooled * (1 - pooled), 1.0 / DRAWS) * 2 / DRAWS)
    assert (np.abs(scattered.probability - other) <= 4.5 * sd).all()
    assert 0 < (scattered.probability.max(axis=0) < 1).mean()  # the law scatters: not a deterministic map


def test_shares_of_a_cell_sum_to_one_with_the_no_answer_share(scattered):
    np.testing.assert_allclose(scattered.probability.sum(axis=0), 1.0, rtol=0, atol=1e-6)
    draws = scattered.probability * DRAWS
    np.testing.assert_allclose(draws, np.round(draws), rtol=0, atol=1e-4)  # whole draws


def test_draws_with_spreads_0_give_the_deterministic_map(cfg, reference, tmp_path):
    """[scatter] draws = 8 with both spreads 0: every share 0 or 1, on the deterministic side,
    and the per-roll maps (draw 0) bit for bit the deterministic sweep's."""
    unscattered = parse_config(CONFIG_TEXT + "\n[scatter]\ndraws = 8\n", "draws.toml")
    sweep(unscattered, tmp_path / "draws.h5", workers=1)
    data = read_sweep(tmp_path / "draws.h5")
    assert set(np.unique(data.probability)) <= {0.0, 1.0}
    codes = np.where(reference.outcome < 0, 4, reference.outcome)
    assert (np.argmax(data.probability, axis=0) == codes).all()
    assert_same_maps(data, reference)


@pytest.mark.parametrize("options", [{"workers": 2}, {"tile_shape": (5, 2)}, {"workers": 2, "tile_shape": (2, 7)}])
def test_probability_maps_do_not_depend_on_workers_or_tiles(scattered_cfg, scattered, tmp_path, options):
    run_sweep(scattered_cfg, tmp_path / "other.h5", progress=False, **{"workers": 1, "tile_shape": TILE, **options})
    data = read_sweep(tmp_path / "other.h5")
    assert data.probability.tobytes() == scattered.probability.tobytes()
    assert_same_maps(data, scattered)


def test_probability_sweep_interrupted_resumes_and_shards_merge_to_the_same_arrays(scattered_cfg, scattered, tmp_path):
    path = tmp_path / "interrupted.h5"
    with pytest.raises(SweepInterrupted):
        sweep(scattered_cfg, path, workers=1, on_tile=stop_after(2))
    assert np.isnan(read_sweep(path).probability).any()  # cells not computed: NaN shares
    sweep(scattered_cfg, path, workers=1, resume=True)
    assert read_sweep(path).probability.tobytes() == scattered.probability.tobytes()
    parts = [tmp_path / f"part{i}.h5" for i in range(2)]
    for i, part in enumerate(parts):
        sweep(scattered_cfg, part, workers=1, shard=(i, 2))
    merge_parts(parts, tmp_path / "merged.h5")
    merged = read_sweep(tmp_path / "merged.h5")
    assert merged.probability.tobytes() == scattered.probability.tobytes() and merged.draws == DRAWS
