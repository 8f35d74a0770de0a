"""The statistics of the measured-data loop: the rank test, bootstrap intervals over tracks,
the Sidak bound and the normal quantiles they use.

Tracks are the independent units throughout: every interval resamples tracks, and the rank
test compares per-track errors. Plain numbers and arrays in and out.
"""

import math

import numpy as np

LEVEL = 0.05  # the loop's test level: the chance that any candidate passes by chance
Z95 = 1.959963984540054  # two-sided 95 % normal quantile
BOOTSTRAP = 1000  # resamples of the tracks of an interval


def signed_rank_z(d):
    """One-sided Wilcoxon signed-rank statistic (normal approximation, ties at mean ranks)
    that the differences ``d`` are positive."""
    from scipy.stats import rankdata

    d = np.asarray(d, dtype=float)
    d = d[np.isfinite(d) & (d != 0.0)]
    n = d.size
    if n == 0:
        return 0.0
    ranks = rankdata(np.abs(d))
    w_plus = ranks[d > 0].sum()
    mean = n * (n + 1) / 4.0
    sd = math.sqrt(n * (n + 1) * (2 * n + 1) / 24.0)
    return float((w_plus - mean) / sd)


def sidak_bound(comparisons):
    """One-sided normal quantile that keeps the chance of any of ``comparisons`` passing by
    chance at LEVEL."""
    from statistics import NormalDist

    return NormalDist().inv_cdf((1.0 - LEVEL) ** (1.0 / max(comparisons, 1)))


def bootstrap_quantiles(values, statistic, rng, draws):
    """2.5 % and 97.5 % quantiles of ``statistic`` over resamples of ``values`` (tracks)."""
    stats = [statistic(values[rng.integers(0, values.size, values.size)]) for _ in range(draws)]
    return [float(np.quantile(stats, 0.025)), float(np.quantile(stats, 0.975))]


def _finite(values):
    values = np.asarray(values, dtype=float)
    return values[np.isfinite(values)]


def bootstrap_rms(errors, rng, draws=BOOTSTRAP):
    """95 % interval of the RMS over tracks of per-track errors, bootstrap over tracks."""
    errors = _finite(errors)
    if errors.size == 0:
        return [math.nan, math.nan]
    return [math.sqrt(q) for q in bootstrap_quantiles(errors**2, np.mean, rng, draws)]


def median_interval(errors, rng, draws=BOOTSTRAP):
    """Median over tracks of per-track errors and its 95 % interval (bootstrap over tracks)."""
    errors = _finite(errors)
    if errors.size == 0:
        return math.nan, [math.nan, math.nan]
    return float(np.median(errors)), bootstrap_quantiles(errors, np.median, rng, draws)


def excess_share(e_current, e_candidate, floor):
    """Share of the error above the noise floor that a candidate removes: median over tracks
    of the fall of the squared error over the median squared excess (medians, because a few
    tracks whose prediction crosses a near-flat landing diverge whatever the model)."""
    excess = float(np.median(e_current**2)) - floor**2
    if excess <= 0:
        return 0.0
    return float(np.median(e_current**2 - e_candidate**2)) / excess
