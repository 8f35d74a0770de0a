"""Tests of dice_sweep.app.roll: the roll command rolls the config's start (refusing one with a
corner in a surface, which a sweep's config may hold where its grid replaces it) and draws or
animates the path only when asked."""

import numpy as np
import pytest
from PIL import Image

from dice_sweep.app.roll import roll
from dice_sweep.config import load_config
from dice_sweep.errors import ConfigError
from dice_sweep.roll import roll_config
from tests.helpers import CONFIGS, png_size


def test_a_roll_is_roll_config_of_the_start_and_draws_nothing_unasked(tmp_path):
    cfg = load_config(CONFIGS / "demo.toml")
    report, written = roll(cfg)
    expected = roll_config(cfg)
    assert written == [] and list(tmp_path.iterdir()) == []
    assert (report.outcome, report.t_end, report.counts) == (expected.outcome, expected.t_end, expected.counts)
    np.testing.assert_array_equal(report.records, expected.records)


def test_pictures_are_written_when_asked(tmp_path):
    cfg = load_config(CONFIGS / "demo.toml")
    report, written = roll(cfg, png_path=tmp_path / "roll.png", gif_path=tmp_path / "roll.gif")
    assert written == [tmp_path / "roll.png", tmp_path / "roll.gif"]
    assert png_size(written[0])[0] > 100
    with Image.open(written[1]) as gif:
        assert gif.n_frames > 1


def test_a_start_inside_the_table_is_refused_even_where_a_grid_would_replace_it(tmp_path):
    cfg = load_config(CONFIGS / "fig08.toml", ["initial.y0=-1"])  # fig08 sweeps y0: loading accepts it
    with pytest.raises(ConfigError) as error:
        roll(cfg, ["initial.y0=-1"], png_path=tmp_path / "roll.png")
    assert error.value.key == "initial.y0" and "into the table" in error.value.message
    assert not (tmp_path / "roll.png").exists()
