"""What the picture tests draw, in one place: a four-block outcome map and a sweep file of it
(written through dice_sweep.storage), a Table I config, and a roll's report and path made up
to draw (tests/plotting/, tests/app/test_sweep.py)."""

from types import SimpleNamespace

import numpy as np

from dice_sweep import config, storage

COLOR_TOLERANCE = 1.5 / 255  # PNG stores 8 bits per channel


def table_one_config(sides=4, separation=None):
    """The paper's Table I die with ``sides`` sides, walls ``separation`` m apart or none."""
    walls = "" if separation is None else f"[walls]\nseparation = {separation}\n"
    return config.parse_config(f"[die]\nsides = {sides}\n{walls}")


def fake_report(t_end=0.5, outcome=2, impacts=7):
    return SimpleNamespace(t_end=t_end, outcome=outcome, impacts=impacts)


def falling_path(cfg, report, times):
    """A die falling and spinning onto the table, then resting: (T, 6) states."""
    times = np.asarray(times)
    y = np.maximum(0.15 - 4.905 * times**2, cfg.die.circumradius)
    phi = 12.0 * np.minimum(times, 0.15)
    zeros = np.zeros_like(times)
    return np.column_stack([0.03 * times, y, phi, zeros, zeros, zeros])


def grid_centres(lo, hi, num):
    """Cell centres of the sweep grid convention (docs/dev/architecture.md)."""
    return lo + (np.arange(num) + 0.5) * (hi - lo) / num


# Four uniform 10 x 10 blocks: side 0, side 1 (bottom), side 3, undecided (top).
BLOCK_OUTCOME = np.block(
    [[np.full((10, 10), 0), np.full((10, 10), 1)], [np.full((10, 10), 3), np.full((10, 10), -1)]]
).astype(np.int8)
BLOCK_X = grid_centres(0.0, 60.0, 20)
BLOCK_Y = grid_centres(0.02, 0.30, 20)

BLOCK_CONFIG_TOML = """
[die]
sides = 4
[walls]
separation = 0.2
[grid]
x = { param = "omega0", min = 0.0, max = 60.0, num = 20 }
y = { param = "y0", min = 0.02, max = 0.30, num = 20 }
"""


def write_sweep_file(path, cfg, outcome, complete, rows=None):
    """A sweep file of ``cfg``'s grid holding ``outcome`` in one tile, through dice_sweep.storage;
    with ``rows``, tiles of that many rows, and only the first tile written."""
    rows = rows or outcome.shape[0]
    outcome = outcome[:rows]
    axes = [
        storage.SweepAxis(
            param=axis.param,
            unit=config.PARAM_UNITS[axis.param],
            values=grid_centres(axis.min, axis.max, axis.num),
            lo=axis.min,
            hi=axis.max,
        )
        for axis in (cfg.grid.x, cfg.grid.y)
    ]
    header = storage.SweepHeader(
        config_toml=config.config_to_toml(cfg),
        sides=cfg.die.sides,
        x=axes[0],
        y=axes[1],
        tile_shape=outcome.shape,  # the first tile
        shard=(0, 1),
        count_columns=("impacts",),
        status_names=("decided",),
    )
    rolls = outcome.size
    maps = storage.rolls_to_maps(
        header.count_columns, outcome.shape, outcome.ravel(), np.zeros(rolls), np.zeros((rolls, 1)), np.zeros(rolls)
    )
    with storage.SweepFile.create(path, header, n_tiles=-(-cfg.grid.y.num // rows)) as sweep_file:
        sweep_file.write_tile(0, slice(0, rows), slice(None), maps)
        if complete:
            sweep_file.mark_complete()
    return path


def write_block_sweep(path, complete=True):
    """A sweep file of the four-block map on the grid BLOCK_X x BLOCK_Y."""
    return write_sweep_file(path, config.parse_config(BLOCK_CONFIG_TOML), BLOCK_OUTCOME, complete)
