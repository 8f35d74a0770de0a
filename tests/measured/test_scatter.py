"""The scatter of real bounces: the [scatter] spreads estimated from drops of the independent
generator (tests/measured/independent.py, no code of the package) with a known per-impact
scatter, and from drops without any."""

import math

import numpy as np
import pytest

from dice_sweep.config import parse_config
from dice_sweep.measured.scatter import ImpactResidual, estimate_spreads, impact_residuals, scatter_section
from dice_sweep.measured.tracks import load_tracks
from tests.measured.independent import Truth, simulate_drops, write_csv

LAW = dict(contact="rigid", beta_normal=0.4, beta_tangential=0.2, friction=0.5)
PARAMS = {"beta_normal": 0.4, "beta_tangential": 0.2, "friction": 0.5}
NOISE = (5e-5, 1e-3)  # m, rad: about the real tracker's (docs/forecast.md: 0.02-0.06 mm, 1.1 mrad)
SPREAD = 0.15  # the truth's relative spread, both kinds
DROPS = 80


def config(truth):
    return parse_config(f"[die]\nsides = 4\ncircumradius = {truth.circumradius!r}\n"
                        '[contact]\nmodel = "rigid"\nbeta_normal = 0.4\nbeta_tangential = 0.2\nfriction = 0.5\n')


def estimate(tmp_path_factory, spread, seed):
    truth = Truth(**LAW, scatter_corner=spread, scatter_flat=spread, scatter_seed=seed)
    drops = simulate_drops(truth, DROPS, seed, rate=500.0, duration=1.0, noise=NOISE)
    path = tmp_path_factory.mktemp(f"scatter{seed}") / "drops.csv"
    write_csv(path, drops)
    tracks = load_tracks(path, sides=4, circumradius=truth.circumradius)
    sigma = (NOISE[0], NOISE[0], NOISE[1])
    return estimate_spreads(impact_residuals(tracks.tracks, config(truth), (), PARAMS, sigma=sigma, seed=seed), seed=seed)


@pytest.mark.parametrize("seed", [11, 12])
def test_the_interval_covers_the_true_spread(tmp_path_factory, seed):
    spreads = estimate(tmp_path_factory, SPREAD, seed)
    for kind in ("corner", "flat"):
        got = spreads[kind]
        assert got["impacts"] >= 60, got
        low, high = got["ci95"]
        assert low <= SPREAD <= high, (kind, got)
        assert high - low < 0.08, (kind, got)  # informative: not "anything from 0 to 1"


def test_without_scatter_the_interval_holds_zero(tmp_path_factory):
    spreads = estimate(tmp_path_factory, 0.0, 13)
    for kind in ("corner", "flat"):
        got = spreads[kind]
        assert got["impacts"] >= 60, got
        assert got["ci95"][0] == 0.0 and got["ci95"][1] < 0.05, (kind, got)


def test_ratio_of_sums_by_hand():
    """sigma^2 = sum(|r|^2 - n) / (3 sum u^2) per kind; bootstrap over tracks; the TOML section."""
    rows = [ImpactResidual(1, "corner", 2.0, 0.13, 0.01, 0.01), ImpactResidual(2, "corner", 1.0, 0.04, 0.01, 0.01),
            ImpactResidual(2, "flat", 1.0, 0.0, 0.03, 0.0), ImpactResidual(3, "flat", 1.0, 9.0, 9.0, 9.0)]
    spreads = estimate_spreads(rows, draws=200)
    assert spreads["corner"]["variance"] == pytest.approx((0.12 + 0.03) / (3 * 5.0))
    assert spreads["corner"]["value"] == pytest.approx(math.sqrt(0.01))
    assert spreads["corner"]["tracks"] == 2
    # the flat impact of track 3 is unstable (its probe share is far above 0.1 u): left out
    assert spreads["flat"]["impacts"] == 1 and spreads["flat"]["unstable"] == 1
    assert spreads["flat"]["value"] == 0.0 and spreads["flat"]["variance"] < 0
    section = scatter_section(spreads)
    cfg = parse_config(section)
    assert cfg.scatter.corner == pytest.approx(0.1) and cfg.scatter.flat == 0.0
    low, high = spreads["corner"]["variance_ci95"]
    assert low <= spreads["corner"]["variance"] <= high and np.isfinite([low, high]).all()
