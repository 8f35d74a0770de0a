"""Tests of dice_sweep.app.sweep: the sweep and merge commands' own checks (made here, once,
before any work), that they join compute, storage and pictures, and a sweep file's picture
(draw_sweep_file: its size, the --box, the cells not computed, the --dpi check)."""

import numpy as np
import pytest

from dice_sweep import config, plotting, storage
from dice_sweep.app.sweep import diagram_title, draw_sweep_file, draw_sweep_files, merge, sweep
from dice_sweep.config import parse_config
from dice_sweep.errors import ConfigError, DiceSweepError
from dice_sweep.storage import read_sweep
from tests.helpers import assert_same_maps, figure_pixels, map_region, near, pixel_at, png_size, read_png
from tests.plotting.drawn import BLOCK_CONFIG_TOML, BLOCK_OUTCOME, COLOR_TOLERANCE, write_block_sweep, write_sweep_file
from tests.test_sweep import CONFIG_TEXT


@pytest.fixture(scope="module")
def cfg():
    """test_sweep's grid at 8 x 8 cells: refinement needs an even count."""
    return parse_config(CONFIG_TEXT, "test.toml", overrides=["grid.x.num=8", "grid.y.num=8"])


def quiet(cfg, path, **options):
    return sweep(cfg, path, **{"workers": 1, "progress": False, **options})


def test_config_without_grid_is_refused(tmp_path):
    with pytest.raises(ConfigError, match="grid: missing; sweep needs a \\[grid\\]"):
        quiet(parse_config("", "single.toml"), tmp_path / "out.h5")
    assert not (tmp_path / "out.h5").exists()


@pytest.mark.parametrize(
    ("options", "message"),
    [
        ({"executor": "spark"}, "--executor 'spark': allowed values are local, dask"),
        ({"scheduler": "tcp://h:8786"}, "--scheduler: only with --executor dask"),
        ({"executor": "dask", "scheduler": "tcp://h:8786", "workers": 2}, "--workers: not with --scheduler"),
        ({"refine_levels": 1, "shard": (0, 2)}, "--refine: cannot be combined with --shard"),
        ({"refine_levels": 1, "resume": True}, "--refine: cannot be combined"),
        ({"refine_levels": 4}, r"--refine 4: grid.y.num = 8 is not divisible by 2\^4 = 16"),
        ({"refine_levels": -1}, "--refine -1: outside the allowed range"),
    ],
)
def test_bad_options_are_refused_before_any_work(cfg, tmp_path, options, message):
    with pytest.raises(DiceSweepError, match=message):
        quiet(cfg, tmp_path / "x.h5", **options)
    assert not (tmp_path / "x.h5").exists()


def test_sweep_writes_the_file_and_its_picture(cfg, tmp_path):
    summary, written = quiet(cfg, tmp_path / "s.h5", png_path=tmp_path / "s.png")
    assert summary.complete and summary.rolls_computed == 64
    assert read_sweep(tmp_path / "s.h5").complete
    assert written == [tmp_path / "s.png"] and (tmp_path / "s.png").stat().st_size > 0


def test_refined_sweep_writes_a_complete_file_of_the_grid(cfg, tmp_path):
    full, _ = quiet(cfg, tmp_path / "full.h5")
    refined, _ = quiet(cfg, tmp_path / "refined.h5", refine_levels=2)
    assert refined.levels == 2 and refined.shape == full.shape
    assert read_sweep(tmp_path / "refined.h5").complete


def test_merge_joins_shards_into_the_unsharded_maps(cfg, tmp_path):
    quiet(cfg, tmp_path / "whole.h5")
    parts = [tmp_path / f"part{i}.h5" for i in range(2)]
    for i, part in enumerate(parts):
        quiet(cfg, part, shard=(i, 2))
    summary = merge(parts, tmp_path / "merged.h5")
    assert summary.complete and summary.merged_parts == 2
    assert_same_maps(read_sweep(tmp_path / "merged.h5"), read_sweep(tmp_path / "whole.h5"))


def test_merge_refuses_an_output_that_is_not_a_sweep_file(cfg, tmp_path):
    quiet(cfg, tmp_path / "part.h5")
    with pytest.raises(DiceSweepError, match="--output: .*merged.png"):
        merge([tmp_path / "part.h5"], tmp_path / "merged.png")
    assert not (tmp_path / "merged.png").exists()
    with pytest.raises(DiceSweepError, match="--output: .: wrong file extension"):
        merge([tmp_path / "part.h5"], "")


# --- a sweep file's picture -------------------------------------------------------------------


@pytest.mark.parametrize("dpi", [30, 72])
def test_draw_sweep_file_writes_png_of_requested_size(tmp_path, dpi):
    h5 = write_block_sweep(tmp_path / "sweep.h5")
    png = draw_sweep_file(h5, tmp_path / "map.png", box=(10, 20, 0.1, 0.2), dpi=dpi)
    with open(png, "rb") as file:
        assert file.read(8) == b"\x89PNG\r\n\x1a\n"
    assert png_size(png) == figure_pixels(plotting.OUTCOME_FIGSIZE, dpi)
    # the --box rectangle: white (no side's colour) on the map, where the box is: omega0 10 to
    # 20 of 0 to 60, y0 0.1 to 0.2 of 0.02 to 0.30 (rows count down from 0.30)
    block_colours = [*plotting.outcome_colors(4), plotting.UNDECIDED_COLOR]
    region = map_region(read_png(png), block_colours, inset=0)
    rows, columns = np.nonzero(near(region, (1.0, 1.0, 1.0), tol=0.45))  # every channel > 0.55: no block's colour
    assert rows.size > 0, "no rectangle drawn"
    height, width = region.shape[:2]
    reach = 2.5 / width, 2.5 / height  # the frame's line, antialiased
    assert columns.min() / width == pytest.approx(10 / 60, abs=reach[0])
    assert columns.max() / width == pytest.approx(20 / 60, abs=reach[0])
    assert rows.min() / height == pytest.approx((0.30 - 0.2) / 0.28, abs=reach[1])
    assert rows.max() / height == pytest.approx((0.30 - 0.1) / 0.28, abs=reach[1])


def test_cells_not_computed_have_their_own_colour_legend_entry_and_warning(tmp_path):
    """Issue 16: an incomplete sweep was drawn with its cells not computed in the black of
    'undecided', and without a word."""
    half = write_sweep_file(tmp_path / "half.h5", config.parse_config(BLOCK_CONFIG_TOML), BLOCK_OUTCOME, False, rows=10)
    warnings = []
    png = draw_sweep_file(half, tmp_path / "half.png", dpi=60, warn=warnings.append)
    assert len(warnings) == 1 and warnings[0].startswith(f"{half}: 200 of 400 cells not computed yet")
    sweep_data = storage.read_sweep(half)
    fig = plotting.sweep_figure(sweep_data, diagram_title(sweep_data), dpi=60)
    fig.savefig(png, dpi=60)
    for x, y, expected in [(15.0, 0.09, plotting.outcome_colors(4)[0]), (45.0, 0.09, plotting.outcome_colors(4)[1]),
                           (15.0, 0.23, plotting.NOT_COMPUTED_COLOR), (45.0, 0.23, plotting.NOT_COMPUTED_COLOR)]:
        np.testing.assert_allclose(pixel_at(fig, x, y, png), expected, atol=COLOR_TOLERANCE)
    labels = [label.get_text() for label in fig.axes[1].get_yticklabels()]
    assert labels == ["not computed", "undecided", "side 0", "side 1", "side 2", "side 3"]
    assert fig.axes[0].get_title().endswith("(incomplete)")
    whole = write_block_sweep(tmp_path / "whole.h5")
    draw_sweep_file(whole, tmp_path / "whole.png", dpi=30, warn=warnings.append)
    assert len(warnings) == 1  # nothing to say about a complete sweep


@pytest.mark.parametrize("dpi", [0, 9, 1001, 100000])
def test_dpi_outside_its_range_is_refused_before_drawing(tmp_path, dpi):
    """Issue 16: --dpi 100000 ended in a MemoryError traceback."""
    with pytest.raises(DiceSweepError, match=r"--dpi: .* allowed range \[10, 1000\]"):
        draw_sweep_file(write_block_sweep(tmp_path / "sweep.h5"), tmp_path / "map.png", dpi=dpi)
    assert not (tmp_path / "map.png").exists()



def test_several_files_are_drawn_side_by_side_titled_by_their_configs(tmp_path):
    whole = write_block_sweep(tmp_path / "whole.h5")
    half = write_sweep_file(tmp_path / "half.h5", config.parse_config(BLOCK_CONFIG_TOML), BLOCK_OUTCOME, False, rows=10)
    png = draw_sweep_files([whole, half], tmp_path / "both.png", dpi=30)
    width, height = figure_pixels(plotting.OUTCOME_FIGSIZE, 30)
    assert png_size(png) == (2 * width, height)
    assert diagram_title(storage.read_sweep(half)).endswith("(incomplete)")
    assert not diagram_title(storage.read_sweep(whole)).endswith("(incomplete)")


def test_refine_refuses_one_draw_of_a_random_law_before_any_work(cfg, tmp_path):
    scattered = parse_config(CONFIG_TEXT + "\n[scatter]\ncorner = 0.1\n", "p.toml", overrides=["grid.x.num=8", "grid.y.num=8"])
    with pytest.raises(DiceSweepError, match=r"--refine: p.toml: \[scatter\] draws = 1 with spreads above 0 is one draw"):
        quiet(scattered, tmp_path / "x.h5", refine_levels=1)
    assert not (tmp_path / "x.h5").exists()


def test_a_refined_probability_sweep_writes_the_shares_of_the_pixels_it_rolled(tmp_path):
    """A probability sweep with --refine: a complete file with its share maps; the pixels
    rolled at their own centre have the full sweep's shares, the filled ones p = 1."""
    scattered = parse_config(CONFIG_TEXT + "\n[scatter]\ncorner = 0.1\nflat = 0.1\ndraws = 4\n", "p.toml",
                             overrides=["grid.x.num=16", "grid.y.num=16"])
    quiet(scattered, tmp_path / "r.h5", refine_levels=1)
    quiet(scattered, tmp_path / "f.h5")
    refined, full = read_sweep(tmp_path / "r.h5"), read_sweep(tmp_path / "f.h5")
    rolled = storage.read_refinement_maps(tmp_path / "r.h5")[0]
    assert refined.complete and refined.probability is not None and refined.draws == 4
    assert np.array_equal(refined.probability[:, rolled], full.probability[:, rolled])
    assert np.all(refined.probability[:, ~rolled].max(axis=0) == 1.0)


def test_a_probability_sweep_is_drawn_as_shaded_sides_beside_its_entropy(tmp_path):
    """Two panels (the picture twice as wide); with spreads 0 every share is 0 or 1, so the
    left panel holds the full side colours only, no faded ones."""
    draws = parse_config(CONFIG_TEXT + "\n[scatter]\ndraws = 4\n", "p.toml", overrides=["grid.x.num=8", "grid.y.num=8"])
    summary, written = quiet(draws, tmp_path / "p.h5", png_path=tmp_path / "p.png", )
    assert summary.rolls_computed == 64 * 4 and written == [tmp_path / "p.png"]
    width, height = png_size(tmp_path / "p.png")
    assert (width, height) == figure_pixels((2 * plotting.OUTCOME_FIGSIZE[0], plotting.OUTCOME_FIGSIZE[1]), 150)
