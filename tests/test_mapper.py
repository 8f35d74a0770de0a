"""Tests of dice_sweep.mapper: starts + model -> sides, in this process or on the pool.

The kernel's outcomes are never hard-coded here: the mapper is compared with the full grid's
file and with itself (other orders, chunks, worker counts), bitwise.
"""

import numpy as np
import pytest

from dice_sweep import mapper as mapper_module
from dice_sweep.config import parse_config
from dice_sweep.mapper import Mapper, Plane, Rolls, initial_states, roll_states, start_pixels
from dice_sweep.physics.layout import COUNT_COLUMNS, STATE_COLUMNS
from dice_sweep.storage import COUNT_MAX
from tests.test_sweep import CONFIG_TEXT
from tests.test_sweep import cfg, reference  # noqa: F401  (the 7 x 10 grid and its sweep file, in tiles of 3 x 4)


@pytest.fixture(scope="module")
def starts(cfg):
    """Every cell of the grid, twice, in a shuffled order, and where each sits (rows, cols)."""
    rng = np.random.default_rng(5)
    rows, cols = np.indices((cfg.grid.y.num, cfg.grid.x.num)).reshape(2, -1)
    pick = rng.permutation(np.concatenate([np.arange(rows.size)] * 2))
    rows, cols = rows[pick], cols[pick]
    states = Plane.from_config(cfg).cells(cfg.grid.x.values()[cols], cfg.grid.y.values()[rows])
    return states, rows, cols


def _bits(rolls):
    return [np.asarray(values).tobytes() for values in rolls]


def test_arbitrary_starts_get_the_grid_pixels_of_the_same_starts(cfg, reference, starts):
    states, rows, cols = starts
    rolls = Mapper.from_config(cfg).roll(states)
    assert len(set(rolls.outcome.tolist())) > 1  # the grid crosses a boundary: a real check
    assert np.array_equal(rolls.outcome, reference.outcome[rows, cols])
    assert np.array_equal(rolls.status, reference.status[rows, cols])
    # the file keeps the decision time as float32 and the counters clipped to uint16
    assert rolls.t_decided.astype(np.float32).tobytes() == reference.t_decided[rows, cols].tobytes()
    for k, name in enumerate(COUNT_COLUMNS):
        assert np.array_equal(np.minimum(rolls.counts[:, k], COUNT_MAX), reference.maps[name][rows, cols])


def test_pool_and_local_give_identical_arrays(cfg, starts, monkeypatch):
    states = starts[0]
    local = Mapper.from_config(cfg).roll(states)
    monkeypatch.setattr(mapper_module, "CHUNK_ROLLS", 23)  # many chunks of a small batch; workers are forked
    chunk_sizes = []
    pooled = roll_states(Mapper.from_config(cfg), states, workers=2, on_chunk=chunk_sizes.append)
    assert isinstance(pooled, Rolls)
    assert _bits(pooled) == _bits(local)
    assert len(chunk_sizes) == -(-len(states) // 23) and sum(chunk_sizes) == len(states)
    assert _bits(roll_states(Mapper.from_config(cfg), states, workers=1)) == _bits(local)


def test_a_start_gets_the_same_answer_in_any_batch(cfg, starts):
    states = starts[0]
    mapper = Mapper.from_config(cfg)
    whole = mapper.roll(states)
    order = np.random.default_rng(1).permutation(len(states))
    reordered = mapper.roll(states[order])
    assert _bits(reordered) == _bits(Rolls(*(values[order] for values in whole)))
    one = mapper.roll(states[7:8])
    assert _bits(one) == _bits(Rolls(*(values[7:8] for values in whole)))


def test_rolls_have_the_kernel_dtypes_and_shapes(cfg, starts):
    states = starts[0][:5]
    rolls = Mapper.from_config(cfg).roll(states)
    assert rolls.outcome.dtype == np.int8 and rolls.outcome.shape == (5,)
    assert rolls.status.dtype == np.uint8 and rolls.status.shape == (5,)
    assert rolls.counts.dtype == np.int32 and rolls.counts.shape == (5, len(COUNT_COLUMNS))
    assert rolls.t_decided.dtype == np.float64 and rolls.t_decided.shape == (5,)
    assert set(rolls.outcome.tolist()) <= set(range(-1, cfg.die.sides))


def test_no_starts_give_empty_rolls(cfg):
    rolls = roll_states(Mapper.from_config(cfg), np.empty((0, len(STATE_COLUMNS))), workers=2)
    assert [values.shape[0] for values in rolls] == [0, 0, 0, 0]
    assert rolls.counts.shape == (0, len(COUNT_COLUMNS))


def test_another_model_gives_other_sides(cfg, starts):
    """The mapper rolls its own model, not a default: the same starts under another contact
    coefficient land otherwise somewhere."""
    states = starts[0]
    other = parse_config(CONFIG_TEXT, "other.toml", overrides=["contact.beta_normal=0.3"])
    assert not np.array_equal(Mapper.from_config(cfg).roll(states).outcome, Mapper.from_config(other).roll(states).outcome)


def test_plane_cells_change_only_the_two_swept_columns(cfg):
    plane = Plane.from_config(cfg)
    cells = plane.cells(np.array([1.0, 2.0]), np.array([0.05, 0.07]))
    column = {name: cells[:, STATE_COLUMNS.index(name)] for name in STATE_COLUMNS}
    assert column["omega0"].tolist() == [1.0, 2.0] and column["y0"].tolist() == [0.05, 0.07]
    assert (column["phi0"] == 0.3).all() and (column["vx0"] == 0.1).all()
    assert (column["x0"] == cfg.initial.x0).all() and (column["vy0"] == cfg.initial.vy0).all()


def test_initial_states_run_x_fast_y_slow(cfg):
    states = initial_states(cfg, [1.0, 2.0, 3.0], [0.05, 0.07])
    assert states.shape == (6, len(STATE_COLUMNS)) and states.dtype == np.float64
    assert states[:, STATE_COLUMNS.index("omega0")].tolist() == [1.0, 2.0, 3.0] * 2
    assert states[:, STATE_COLUMNS.index("y0")].tolist() == [0.05] * 3 + [0.07] * 3


def test_start_pixels_are_the_grids_pixels_on_it_and_hashed_streams_off_it():
    """On a cell centre (bit for bit) a start has the sweep's pixel j nx + i; elsewhere a number
    in [2^52, 2^53) that depends on its two values only (either one changed changes it), and
    -0.0 is 0.0."""
    grid_xs, grid_ys = np.array([0.1, 0.2, 0.3]), np.array([1.0, 2.0])
    xs = np.array([0.2, 0.3, 0.1, 0.25, 0.25, 0.25, np.nextafter(0.2, 1.0), 0.0, -0.0])
    ys = np.array([2.0, 1.0, 1.0, 1.0, 1.5, 1.0, 2.0, 1.0, 1.0])
    pixels = start_pixels(grid_xs, grid_ys, xs, ys)
    assert pixels[:3].tolist() == [4, 2, 0]
    off = pixels[3:]
    assert np.all((off >= 2**52) & (off < 2**53))
    assert len(set(off[[0, 1, 3, 4]].tolist())) == 4  # another x or y, even by one ulp: another stream
    assert pixels[3] == pixels[5] and off[-1] == off[-2]  # the same start twice: one stream
    assert np.array_equal(start_pixels(grid_xs, grid_ys, xs[::-1], ys[::-1]), pixels[::-1])  # not the order of the batch
