"""Tests of dice_sweep.chaos on maps whose answers are known, and on small real sweeps.

Known answers: a straight boundary (alpha = 1; Sbb = the binary entropy of the split of its
boxes, about 1/2 for a tilted line), checkerboards (exact box entropies), a random map
(alpha = 0, Sb = the expected entropy of a multinomial sample), a middle-thirds Cantor
boundary (alpha = 1 - ln 2 / ln 3) and a Weierstrass graph (alpha = -ln a / ln b).
"""

import json
import math

import matplotlib
import numpy as np
import pytest

from dice_sweep import plotting
from dice_sweep.chaos import (
    LOG2,
    SMOOTH_BOUNDARY_SBB,
    basin_entropy,
    blur_probabilities,
    cantor_map,
    checkerboard_map,
    choose_method,
    compare_control,
    control_map,
    fit_power_law,
    monte_carlo_indices,
    outcome_fractions,
    parse_sigma,
    random_map_entropy,
    scattered_starts,
    straight_boundary_map,
    uncertainty_curve,
    weierstrass_map,
)
from dice_sweep.app.chaos import measure_file
from dice_sweep.config import load_config, parse_config
from dice_sweep.errors import DiceSweepError
from dice_sweep.geometry import DOWN, support
from dice_sweep.storage import read_sweep
from tests.helpers import figure_pixels, invoke, map_region, near, png_size, read_png, share, small_sweep

MAGMA, VIRIDIS = matplotlib.colormaps["magma"], matplotlib.colormaps["viridis"]


def binary_entropy(p):
    return -(p * math.log(p) + (1 - p) * math.log(1 - p))


# --- outcome fractions and basin entropy --------------------------------------------------


def test_fractions_count_every_side_and_the_undecided():
    outcome = np.array([[0, 0, 1, -1], [2, 2, 2, 2]])
    assert outcome_fractions(outcome, 3) == {-1: 1 / 8, 0: 2 / 8, 1: 1 / 8, 2: 4 / 8}


def test_straight_horizontal_boundary_has_the_entropy_of_its_split():
    outcome = straight_boundary_map((500, 500), 0.0, 252)  # boxes of rows 250-254: 2 rows of 0, 3 of 1
    entropy = basin_entropy(outcome, 5)
    assert entropy.boundary_boxes == 100
    assert entropy.sbb == pytest.approx(binary_entropy(0.4), rel=1e-12)
    assert entropy.sb == pytest.approx(binary_entropy(0.4) / 100, rel=1e-12)
    assert not entropy.fractal_by_log2


@pytest.mark.parametrize("slope", [0.1, (math.sqrt(5) - 1) / 2])
def test_tilted_straight_boundary_has_the_smooth_boundary_entropy(slope):
    entropy = basin_entropy(straight_boundary_map((500, 500), slope, 100.3), 5)
    # the share of one basin in a box the line crosses is about uniform: mean entropy 1/2
    assert entropy.sbb == pytest.approx(SMOOTH_BOUNDARY_SBB, abs=0.06)
    assert entropy.sbb < LOG2


def test_pixel_checkerboard_splits_every_box_13_to_12():
    entropy = basin_entropy(checkerboard_map((100, 100), 1), 5)
    assert entropy.sb == entropy.sbb == pytest.approx(binary_entropy(12 / 25), rel=1e-12)
    assert entropy.boundary_boxes == entropy.boxes
    assert entropy.sbb < LOG2  # two basins never pass the ln 2 criterion


def test_block_checkerboard_box_entropies_are_exact():
    # blocks of 10 pixels with edges at columns (and rows) 7, 17, ...: per 2 x 2 boxes one box
    # holds a corner (13 : 12), two hold one edge (2 : 3 columns or rows), one holds none
    entropy = basin_entropy(checkerboard_map((500, 500), 10, shift=7), 5)
    corner, edge = binary_entropy(12 / 25), binary_entropy(0.4)
    assert entropy.sb == pytest.approx((corner + 2 * edge) / 4, rel=1e-12)
    assert entropy.sbb == pytest.approx((corner + 2 * edge) / 3, rel=1e-12)


def test_random_map_has_the_multinomial_entropy_and_no_power_law_scale():
    outcome = np.random.default_rng(1).integers(0, 4, (400, 400))
    entropy = basin_entropy(outcome, 5)
    assert entropy.sb == pytest.approx(random_map_entropy(25, 4), abs=0.01)
    assert entropy.fractal_by_log2
    curve = uncertainty_curve(outcome)
    assert curve.fraction == pytest.approx(1 - 4.0**-4, abs=0.01)  # a neighbour differs
    assert curve.fit.alpha == pytest.approx(0.0, abs=0.01)
    assert curve.fit.saturated


def test_grid_not_divisible_by_the_box_leaves_out_the_top_rows_and_right_columns():
    outcome = np.zeros((13, 12), dtype=np.int8)
    outcome[10:, :] = 1  # only in the rows left out
    outcome[:, 10:] = 2  # only in the columns left out
    entropy = basin_entropy(outcome, 5)
    assert entropy.used_shape == (10, 10)
    assert entropy.sb == 0.0 and math.isnan(entropy.sbb)


def test_box_larger_than_the_map_is_refused():
    with pytest.raises(DiceSweepError, match="box size"):
        basin_entropy(np.zeros((4, 8)), 5)


# --- uncertainty exponent -----------------------------------------------------------------


def test_straight_boundary_has_alpha_one():
    for slope, offset in ((0.0, 252), (0.3, 180.3)):
        fit = uncertainty_curve(straight_boundary_map((500, 500), slope, offset)).fit
        assert fit.power_law
        assert fit.alpha == pytest.approx(1.0, abs=0.01)


def test_block_checkerboard_has_alpha_one_below_the_block_size():
    fit = uncertainty_curve(checkerboard_map((1024, 1024), 128), eps=[1, 2, 3, 4, 6, 8]).fit
    assert fit.alpha == pytest.approx(1.0, abs=0.05)


def test_cantor_boundary_has_alpha_one_minus_its_dimension():
    # boundary: a middle-thirds Cantor set (dimension ln 2 / ln 3) times a line; perturbations
    # of 3^k pixels sample f(eps) at one phase of its log-periodic wobble
    outcome = cantor_map(8, 3**5)
    fit = uncertainty_curve(outcome, eps=3 ** np.arange(5)).fit
    assert fit.power_law and fit.points == 5
    assert fit.alpha == pytest.approx(1 - math.log(2) / math.log(3), abs=0.015)


def test_weierstrass_graph_boundary_has_alpha_two_minus_its_dimension():
    # the graph of W(x) = sum a^k cos(2 pi b^k x + k) has dimension 2 + ln a / ln b
    a, b = 0.5, 4.0
    fit = uncertainty_curve(weierstrass_map(1024, a, b)).fit
    # the pixel grid samples only 5 octaves of W: the fit is good to about 0.05
    assert fit.alpha == pytest.approx(-math.log(a) / math.log(b), abs=0.06)


def test_fit_finds_the_power_law_range_before_saturation():
    eps = np.unique(np.round(np.logspace(0, np.log10(64), 16)))
    fraction = np.minimum(0.01 * eps, 0.16)  # power law up to eps = 16, then flat
    fit = fit_power_law(eps, fraction)
    assert fit.power_law
    assert fit.alpha == pytest.approx(1.0, abs=1e-9)
    assert fit.eps_lo == 1 and fit.eps_hi == 16


def test_fit_leaves_out_the_saturated_part_of_the_curve():
    eps = np.unique(np.round(np.logspace(0, np.log10(64), 16)))
    fraction = 1 - np.exp(-0.1 * eps)  # ~ 0.1 eps while small, flattening towards 1
    fit = fit_power_law(eps, fraction)
    assert fit.eps_hi <= 10 * math.log(2)  # where f reaches 1/2
    assert not fit.saturated
    assert fit.alpha > 0.8


def test_fit_without_a_power_law_says_so():
    eps = np.arange(1, 17, dtype=float)
    fraction = np.where(eps % 2 == 1, 0.5, 0.05)  # jumps by 10 between neighbours
    fit = fit_power_law(eps, fraction)
    assert not fit.power_law
    assert fit.points == len(eps)


def test_too_small_a_map_is_refused():
    with pytest.raises(DiceSweepError, match="too small"):
        uncertainty_curve(np.zeros((10, 10)), eps=[1, 5])


# --- on sweep files -----------------------------------------------------------------------


@pytest.fixture(scope="module")
def fig08_file(tmp_path_factory):
    """fig08 at 128 x 128, the physical ranges of the paper's figure."""
    cfg = load_config("configs/fig08.toml", ["grid.x.num=128", "grid.y.num=128"])
    path = tmp_path_factory.mktemp("fig08") / "fig08.h5"
    small_sweep(cfg, path)
    return path


def test_measure_file_matches_the_map_and_the_cli_writes_json_and_pictures(fig08_file, tmp_path):
    measures = measure_file(fig08_file)
    outcome = read_sweep(fig08_file).outcome
    assert measures.entropy.sb == basin_entropy(outcome).sb
    result = invoke("measure", fig08_file, "--json", tmp_path / "m.json", "--png", tmp_path / "png")
    assert result.exit_code == 0, result.output
    assert "uncertainty exponent alpha" in result.output
    numbers = json.loads((tmp_path / "m.json").read_text())
    assert numbers["basin_entropy"]["Sb"] == pytest.approx(measures.entropy.sb)
    assert numbers["uncertainty"]["alpha"] == pytest.approx(measures.uncertainty.fit.alpha)
    # f(eps): one panel at 100 dpi, the points and the fitted line in the first curve colour,
    # across the plot and rising with eps (the uncertain share grows with the perturbation)
    png = tmp_path / "png" / "uncertainty.png"
    assert png_size(png) == figure_pixels(plotting.PANEL_FIGSIZE, 100)
    rows, columns = np.nonzero(near(read_png(png), plotting.curve_colors(1)[0], tol=0.1))
    assert rows.size > 300
    assert np.ptp(columns) > 0.5 * png_size(png)[0]
    quarter = np.ptp(columns) / 4
    left, right = columns < columns.min() + quarter, columns > columns.max() - quarter
    assert np.median(rows[left]) > np.median(rows[right]) + 50  # rows count down the picture
    # box entropies: the map's black (magma at 0 nats) is the share of boxes off every boundary
    png = tmp_path / "png" / "box_entropy.png"
    assert png_size(png) == figure_pixels(plotting.PANEL_FIGSIZE, 100)
    region = map_region(read_png(png))
    assert share(region, MAGMA(0.0)) == pytest.approx(np.mean(measures.entropy.box_entropy == 0), abs=0.02)
    assert 0.3 < share(region, MAGMA(0.0)) < 0.9  # boxes on and off a boundary both drawn


def test_measure_refuses_an_incomplete_sweep(tmp_path):
    cfg = load_config("configs/fig08.toml", ["grid.x.num=16", "grid.y.num=16"])
    path = tmp_path / "part.h5"
    small_sweep(cfg, path, shard=(0, 2), tile_shape=(8, 8))
    result = invoke("measure", path)
    assert result.exit_code == 2
    assert result.output.count("\n") == 1 and "not computed" in result.output


# --- control maps -------------------------------------------------------------------------


def test_blur_of_a_straight_boundary_is_the_normal_cdf():
    outcome = np.zeros((40, 200), dtype=np.int8)
    outcome[:, 100:] = 1
    probability, weight = blur_probabilities(outcome, 2, (0.0, 5.0))
    centres = np.arange(60, 140) + 0.5  # well inside the map: the whole Gaussian lies on it
    expected = 0.5 * (1 + np.vectorize(math.erf)((centres - 100) / (5.0 * math.sqrt(2))))
    assert probability[1, 20, 60:140] == pytest.approx(expected, abs=2e-3)
    assert weight[20, 60:140] == pytest.approx(1.0)
    assert probability.sum(axis=0) == pytest.approx(np.ones((40, 200)))


def test_method_is_blur_only_where_the_map_resolves_the_scatter(fig08_file):
    sweep = read_sweep(fig08_file)  # cells: omega0 0.47 rad/s, y0 2.2 mm
    assert choose_method(sweep, {"omega0": 1.0, "y0": 0.005}) == "blur"
    assert choose_method(sweep, {"omega0": 0.5, "y0": 0.005}) == "monte_carlo"  # 1 cell
    assert choose_method(sweep, {"vx0": 0.01}) == "monte_carlo"  # not an axis of the map
    with pytest.raises(DiceSweepError, match="monte_carlo"):
        control_map(sweep, {"vx0": 0.01}, method="blur")


def test_blur_and_monte_carlo_agree_on_fig08(fig08_file):
    sweep = read_sweep(fig08_file)
    sigmas = {"y0": 0.006, "omega0": 1.5}
    blurred = control_map(sweep, sigmas, method="blur")
    rolled = control_map(sweep, sigmas, method="monte_carlo", samples=128, max_points=16, workers=1)
    agreement = compare_control(blurred, rolled, monte_carlo_indices(128, 16), monte_carlo_indices(128, 16))
    assert agreement.points >= 150
    assert agreement.share_within_3_se >= 0.97
    assert agreement.mean_abs_difference < 0.02


def test_scattered_starts_never_put_a_corner_into_the_table():
    cfg = parse_config("[die]\nsides = 4\n[initial]\ny0 = 0.0135\n[grid]\n"
                       'x = { param = "phi0", min = 0.0, max = 1.0, num = 4 }\n'
                       'y = { param = "y0", min = 0.0135, max = 0.02, num = 2 }\n')
    centres = np.zeros((1, 6))
    centres[0, 1] = 0.0135  # a corner 0.1 mm above the table at phi0 = 0
    starts = scattered_starts(cfg, centres, {"y0": 0.001, "phi0": 0.3}, 2000, np.random.default_rng(0))
    lowest = starts[:, 1] - support(4, cfg.die.circumradius, starts[:, 2], DOWN)
    assert lowest.min() >= 0.0
    assert starts[:, 1].std() > 0.0005  # still scattered, not stuck at the aimed start


def test_control_cli_writes_the_maps_and_rejects_bad_sigmas(fig08_file, tmp_path):
    result = invoke("control", fig08_file, "--sigma", "y0=0.006", "--sigma", "omega0=1.5",
                    "--png", tmp_path / "png", "--json", tmp_path / "c.json", "-o", tmp_path / "c.npz")
    assert result.exit_code == 0, result.output
    assert "Gaussian blur" in result.output
    assert json.loads((tmp_path / "c.json").read_text())["method"] == "blur"
    maps = np.load(tmp_path / "c.npz")
    assert maps["probability"].shape == (5, 128, 128)
    # three panels at 100 dpi: the most likely side in the side colours, its probability
    # (viridis, 0 to 1) and the entropy (magma, 0 to ln 4), each colour in the share of the
    # cells the maps give it
    png = tmp_path / "png" / "control.png"
    width, height = figure_pixels(plotting.PANEL_FIGSIZE, 100)
    assert png_size(png) == (3 * width, height)
    image = read_png(png)
    colours = {tuple(c): maps["most_likely"] == side for side, c in enumerate(plotting.outcome_colors(4))}
    colours[plotting.UNDECIDED_COLOR] = maps["most_likely"] == -1
    region = map_region(image[:, :width], colours)
    for colour, cells in colours.items():
        assert share(region, colour) == pytest.approx(cells.mean(), abs=0.02), colour
    # the cells sure of their side: probability 1 (viridis' yellow), entropy 0 (magma's black)
    for panel, cmap, scaled, sure in ((1, VIRIDIS, maps["p_max"], 1.0), (2, MAGMA, maps["entropy"] / math.log(4), 0.0)):
        region = map_region(image[:, panel * width : (panel + 1) * width])
        expected = near(cmap(scaled), cmap(sure)).mean()
        assert 0.05 < expected < 0.95
        assert share(region, cmap(sure)) == pytest.approx(expected, abs=0.02), panel
    for bad in (["--sigma", "y0=-1"], ["--sigma", "spin=1"], []):
        result = invoke("control", fig08_file, *bad)
        assert result.exit_code == 2 and result.output.count("\n") == 1, result.output


def test_parse_sigma():
    assert parse_sigma("omega0=0.5") == ("omega0", 0.5)
    with pytest.raises(DiceSweepError, match="PARAM=STD"):
        parse_sigma("omega0")
