"""Tests of dice_sweep.chaos.measures on maps whose answers are known.

Known answers: a straight boundary (alpha = 1; Sbb = the binary entropy of the split of its
boxes, about 1/2 for a tilted line), checkerboards (exact box entropies), a random map
(alpha = 0, Sb = the expected entropy of a multinomial sample), a middle-thirds Cantor
boundary (alpha = 1 - ln 2 / ln 3) and a Weierstrass graph (alpha = -ln a / ln b). The maps
themselves: tests/chaos/test_known_maps.py; the measures of a sweep file: tests/app/test_chaos.py.
"""

import json
import math

import numpy as np
import pytest

from dice_sweep.chaos import (
    LOG2,
    SMOOTH_BOUNDARY_SBB,
    basin_entropy,
    cantor_map,
    checkerboard_map,
    fit_power_law,
    PREDICTABLE_PROBABILITY,
    measure_map,
    measure_probability,
    outcome_fractions,
    shannon_entropy,
    wilson_bounds,
    random_map_entropy,
    straight_boundary_map,
    uncertainty_curve,
    weierstrass_map,
)
from dice_sweep.errors import DiceSweepError


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


# --- all measures of a map ----------------------------------------------------------------


def test_measure_map_joins_the_measures_and_its_json_states_eps_in_the_axes_units():
    outcome = straight_boundary_map((200, 200), 0.0, 101)  # rows 0-100 side 0, the rest side 1
    outcome[:5, :5] = -1  # 25 undecided pixels
    measures = measure_map(outcome, 2, x_step=0.5, y_step=0.001)
    assert measures.shape == (200, 200) and measures.sides == 2
    assert measures.fractions == {-1: 25 / 40000, 0: (101 * 200 - 25) / 40000, 1: 99 * 200 / 40000}
    assert (measures.entropy.sb, measures.entropy.sbb) == (basin_entropy(outcome).sb, basin_entropy(outcome).sbb)
    assert measures.uncertainty.fit.alpha == uncertainty_curve(outcome).fit.alpha
    numbers = json.loads(json.dumps(measures.to_dict()))  # JSON-ready: no NaN, no numpy scalar
    assert numbers["shape"] == [200, 200]
    assert numbers["fractions"] == {"undecided": 25 / 40000, "0": (101 * 200 - 25) / 40000, "1": 99 * 200 / 40000}
    assert numbers["basin_entropy"]["Sb"] == pytest.approx(measures.entropy.sb, rel=1e-15)
    assert numbers["uncertainty"]["alpha"] == pytest.approx(measures.uncertainty.fit.alpha, rel=1e-15)
    assert (numbers["uncertainty"]["eps_x_per_pixel"], numbers["uncertainty"]["eps_y_per_pixel"]) == (0.5, 0.001)
    assert "eps_x_per_pixel" not in measure_map(outcome, 2).to_dict()["uncertainty"]
    described = measures.describe()
    assert "map 200 x 200, n = 2" in described and f"alpha = {measures.uncertainty.fit.text()}" in described


# --- probability maps (issue 31) ----------------------------------------------------------


def shares_map(rows):
    """(n + 1, 1, len(rows)) shares from one row of shares per pixel."""
    return np.asarray(rows, dtype=float).T[:, None, :]


def test_entropy_is_0_where_all_draws_agree_and_ln_k_for_k_equal_outcomes():
    p = shares_map([[1, 0, 0, 0, 0], [0, 0, 0, 0, 1], [0.5, 0.5, 0, 0, 0], [0.2] * 5])
    entropy = shannon_entropy(p)[0]
    assert entropy[0] == 0.0 and entropy[1] == 0.0
    assert entropy[2] == pytest.approx(math.log(2)) and entropy[3] == pytest.approx(math.log(5))


def test_predictable_share_counts_sides_at_0_9_not_the_no_answer_share():
    # p(side) 1, 0.9, 0.875 and no answer 1: only the first two are predictable
    p = shares_map([[1, 0, 0, 0, 0], [0.9, 0.1, 0, 0, 0], [0.875, 0.125, 0, 0, 0], [0, 0, 0, 0, 1]])
    measures = measure_probability(p, 40)
    assert PREDICTABLE_PROBABILITY == 0.9 and measures.predictable == 0.5
    assert measures.no_answer == 0.25 and measures.entropy_map[0, 0] == 0.0
    assert measures.basin_entropy == pytest.approx(np.mean([0, binary_entropy(0.9), binary_entropy(0.875), 0]))


def test_predictable_range_from_the_draws_brackets_the_share_and_narrows_with_more_draws():
    p = shares_map([[1, 0, 0, 0, 0], [0.9, 0.1, 0, 0, 0], [0.85, 0.15, 0, 0, 0], [0.6, 0.4, 0, 0, 0]])
    few, many = measure_probability(p, 20), measure_probability(p, 20000)
    assert few.predictable_range[0] <= few.predictable <= few.predictable_range[1]
    # 20 draws: p = 1 (20 of 20) is not surely >= 0.9 (Wilson low 0.84), 0.85 possibly is
    assert few.predictable_range == (0.0, 0.75)
    assert many.predictable_range == (0.25, 0.5)


def test_wilson_bounds_cover_the_share_and_match_the_closed_form():
    low, high = wilson_bounds(np.array([0.0, 0.5, 1.0]), 100)
    assert low[0] == pytest.approx(0.0, abs=1e-12) and high[2] == pytest.approx(1.0) and low[1] < 0.5 < high[1]
    assert high[0] == pytest.approx(3.84 / 103.84, abs=1e-3)  # z^2 / (n + z^2) at 0 hits


def test_miller_madow_correction_adds_seen_outcomes_minus_one_over_2m():
    p = shares_map([[0.5, 0.5, 0, 0, 0], [1, 0, 0, 0, 0]])
    measures = measure_probability(p, 10)
    assert measures.basin_entropy_corrected - measures.basin_entropy == pytest.approx((1 / 20 + 0) / 2)


def test_measure_map_reports_the_probability_map_in_its_text_and_json():
    outcome = np.zeros((12, 12), dtype=int)
    outcome[:, 6:] = 1
    p = np.zeros((5, 12, 12))
    p[0, :, :6] = 1.0
    p[1, :, 6:] = 0.5
    p[2, :, 6:] = 0.5
    measures = measure_map(outcome, 4, probability=p, draws=64)
    assert measures.probability.predictable == 0.5
    data = json.loads(json.dumps(measures.to_dict()))
    assert data["probability"]["predictable_share"] == 0.5 and data["probability"]["draws"] == 64
    assert "predictable (one side p >= 0.9) 0.5000" in measures.describe()
    assert "probability" not in measure_map(outcome, 4).to_dict()
