"""Tests of dice_sweep.chaos.control: what a thrower of given precision controls, by a blur
of the map or by Monte Carlo rolls of scattered starts (the command: tests/app/test_chaos.py)."""

import math

import numpy as np
import pytest

from dice_sweep.chaos import (
    blur_probabilities,
    choose_method,
    compare_control,
    control_map,
    monte_carlo_indices,
    monte_carlo_probabilities,
    parse_sigma,
    scattered_starts,
)
from dice_sweep.config import parse_config
from dice_sweep.errors import DiceSweepError
from dice_sweep.geometry import DOWN, support
from dice_sweep.storage import read_sweep


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


def test_parse_sigma():
    assert parse_sigma("omega0=0.5") == ("omega0", 0.5)
    with pytest.raises(DiceSweepError, match="PARAM=STD"):
        parse_sigma("omega0")


def test_monte_carlo_with_scattered_impacts_rolls_each_point_on_its_own_streams(tmp_path):
    """With [scatter] on and no scatter of the start, rolls of the whole grid are a probability
    sweep: the same shares (each point's draws on its own streams, not all on one)."""
    from dice_sweep.sweep import axis_values, run_sweep

    cfg = parse_config('[scatter]\ncorner = 0.1\nflat = 0.1\ndraws = 12\n[grid]\nx = { param = "omega0", min = 0.0, '
                       'max = 40.0, num = 4 }\ny = { param = "y0", min = 0.05, max = 0.2, num = 3 }\n', "mc.toml")
    run_sweep(cfg, tmp_path / "p.h5", workers=1, progress=False)
    shares = read_sweep(tmp_path / "p.h5").probability
    rolled = monte_carlo_probabilities(cfg, axis_values(cfg.grid.x), axis_values(cfg.grid.y), {"y0": 0.0}, 12)
    np.testing.assert_allclose(rolled, shares, rtol=0, atol=1e-6)
    assert (shares.max(axis=0) < 1).any()  # the draws of a point differ
