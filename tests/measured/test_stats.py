"""dice_sweep.measured.stats against hand-computed values."""

import math
from statistics import NormalDist

import numpy as np
import pytest

from dice_sweep.measured import stats


def test_signed_rank_statistic_by_hand():
    # |d| ranks 1, 2, 3, 4; W+ = 1 + 2 + 4 = 7; mean n(n+1)/4 = 5; sd sqrt(n(n+1)(2n+1)/24) = sqrt(7.5)
    assert stats.signed_rank_z([1.0, 2.0, -3.0, 4.0]) == pytest.approx(2.0 / math.sqrt(7.5), rel=1e-12)
    # zeros and non-finite values are dropped; ties take their mean rank
    assert stats.signed_rank_z([0.0, np.nan, 1.0, 2.0, -3.0, 4.0]) == stats.signed_rank_z([1.0, 2.0, -3.0, 4.0])
    assert stats.signed_rank_z([1.0, -1.0]) == pytest.approx(0.0)
    assert stats.signed_rank_z([]) == 0.0
    assert stats.signed_rank_z(-np.arange(1.0, 5.0)) == pytest.approx(-10.0 / 2 / math.sqrt(7.5))


def test_sidak_bound_keeps_the_chance_of_any_pass_at_the_level():
    assert stats.sidak_bound(1) == pytest.approx(NormalDist().inv_cdf(0.95))
    for comparisons in (2, 15, 40):
        z = stats.sidak_bound(comparisons)
        assert 1.0 - NormalDist().cdf(z) ** comparisons == pytest.approx(stats.LEVEL, rel=1e-9)
    assert stats.sidak_bound(0) == stats.sidak_bound(1)
    assert stats.Z95 == pytest.approx(NormalDist().inv_cdf(0.975), rel=1e-15)


def test_bootstrap_intervals_over_tracks():
    rng = np.random.default_rng(0)
    assert stats.bootstrap_rms(np.full(10, 2.0), rng, 50) == [2.0, 2.0]
    assert all(math.isnan(v) for v in stats.bootstrap_rms([np.nan], rng))
    errors = np.concatenate([np.full(20, 1.0), np.full(20, 3.0), [np.nan]])
    low, high = stats.bootstrap_rms(errors, rng, 400)
    assert low < math.sqrt(5.0) < high and 1.0 < low and high < 3.0
    median, (m_low, m_high) = stats.median_interval(errors, rng, 400)
    assert median == 2.0 and m_low <= 2.0 <= m_high and m_low >= 1.0 and m_high <= 3.0
    assert math.isnan(stats.median_interval([], rng)[0])
    quantiles = stats.bootstrap_quantiles(np.arange(100.0), np.mean, np.random.default_rng(1), 500)
    assert quantiles[0] < 49.5 < quantiles[1] and quantiles[1] - quantiles[0] == pytest.approx(2 * 1.96 * 29.0 / 10, rel=0.2)


def test_excess_share_by_hand():
    current, candidate = np.full(5, 2.0), np.full(5, 1.0)
    assert stats.excess_share(current, candidate, floor=1.0) == pytest.approx(1.0)  # (4 - 1) of the excess 4 - 1
    assert stats.excess_share(current, np.full(5, math.sqrt(3.0)), floor=1.0) == pytest.approx(1.0 / 3.0)
    assert stats.excess_share(current, candidate, floor=2.5) == 0.0  # nothing above the floor to remove
