"""Tests of dice_sweep.view.pool: the bands of a map (whole rows, at most BAND_ROLLS rolls, at
least four per worker) and the spawned workers rolling them - the mapper's outcomes, every band
reported once, a cancel between bands."""

import numpy as np
import pytest

from dice_sweep.mapper import Mapper, initial_states
from dice_sweep.roll import initial_state
from dice_sweep.sweep import axis_values
from dice_sweep.view.pool import BAND_ROLLS, Cancelled, RollPool, bands
from tests.view.client import ZOOM, zoom_config


@pytest.mark.parametrize(
    ("ny", "nx", "workers", "expected"),
    [
        (7, 10, 1, [(0, 2), (2, 4), (4, 6), (6, 7)]),  # 4 bands for the one worker
        (100, 512, 2, [(k, min(k + 8, 100)) for k in range(0, 100, 8)]),  # 8 rows = BAND_ROLLS rolls
        (3, 10000, 1, [(0, 1), (1, 2), (2, 3)]),  # a row longer than BAND_ROLLS: a row a band
        (1, 1, 2, [(0, 1)]),
    ],
)
def test_bands_by_hand(ny, nx, workers, expected):
    assert bands(ny, nx, workers) == expected


@pytest.mark.parametrize(("ny", "nx", "workers"), [(512, 512, 2), (37, 3, 1), (5, 900, 4)])
def test_bands_cover_the_rows_once_within_the_roll_budget(ny, nx, workers):
    found = bands(ny, nx, workers)
    assert [first for first, _ in found] == [0] + [end for _, end in found[:-1]] and found[-1][1] == ny
    assert all((end - first) * nx <= max(BAND_ROLLS, nx) for first, end in found)


@pytest.fixture(scope="module")
def zoom():
    """The demo zoom's mapper and starts, and a pool of one spawned worker."""
    cfg = zoom_config(ZOOM)
    states = initial_states(cfg, axis_values(cfg.grid.x), axis_values(cfg.grid.y))
    mapper = Mapper.from_config(cfg)
    pool = RollPool(mapper, initial_state(cfg), 1)
    pool.start()
    yield mapper, states, pool
    pool.close()


def test_the_workers_roll_the_mappers_outcomes_and_report_every_band(zoom):
    mapper, states, pool = zoom
    shape = (ZOOM["ny"], ZOOM["nx"])
    reported = []
    outcome = pool.roll_map(mapper, states, shape, on_band=lambda first, end, rows, done: reported.append((first, end, rows.copy(), done)))
    expected = mapper.roll(states).outcome.reshape(shape)
    assert outcome.dtype == np.int8 and np.array_equal(outcome, expected)
    assert sorted((first, end) for first, end, _, _ in reported) == bands(*shape, 1)
    for first, end, rows, _ in reported:
        assert np.array_equal(rows, expected[first:end])
    assert sorted(done for *_, done in reported)[-1] == states.shape[0]


def test_a_cancel_stops_between_bands(zoom):
    mapper, states, pool = zoom
    asked = []
    with pytest.raises(Cancelled):
        pool.roll_map(mapper, states, (ZOOM["ny"], ZOOM["nx"]), cancelled=lambda: asked.append(1) or True)
    assert asked  # asked once at least, and the answer obeyed

