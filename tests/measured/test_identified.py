"""A parameter no track's residual moves with gets no interval and cannot be named.

On the real drops the flat_landing candidate stayed at its start value (a contact time
shorter than every landing's delay), its bootstrap interval had zero width, [3e-5, 3e-5] s,
and the report called its null value excluded."""

import math
from types import SimpleNamespace

import numpy as np

from dice_sweep.config import default_config
from dice_sweep.measured.diagnose import _at_a_bound_off_null
from dice_sweep.measured.reduced import describe_params, null_excluded


def _fit(names, values):
    return SimpleNamespace(free=tuple(names), params=dict(zip(names, values)), at_bound={})


def test_a_parameter_without_information_has_no_interval_and_excludes_nothing():
    cfg = default_config()
    names = ["beta_normal", "contact_time"]
    fit = _fit(names, [0.4, 3e-5])
    draws = np.column_stack([np.linspace(0.39, 0.41, 100), np.full(100, 3e-5)])  # zero width
    info = np.zeros((5, 2, 2))
    info[:, 0, 0] = 1.0  # each of 5 tracks informs beta_normal, none contact_time
    out = describe_params(fit, draws, cfg, SimpleNamespace(M=info))
    assert out["beta_normal"]["identified"] and out["beta_normal"]["ci95"][0] < 0.4 < out["beta_normal"]["ci95"][1]
    assert not out["contact_time"]["identified"]
    assert all(math.isnan(v) for v in out["contact_time"]["ci95"])
    assert not null_excluded("contact_time", out["contact_time"]["ci95"], cfg)
    # nor a zero-width interval from the tracks, nor a noise share, with the noise covariance
    out = describe_params(fit, draws, cfg, SimpleNamespace(M=info), noise_cov=np.diag([1e-6, 0.0]))
    assert all(math.isnan(v) for v in out["contact_time"]["ci95"] + out["contact_time"]["ci95_tracks"])
    assert math.isnan(out["contact_time"]["sd_noise"])
    assert out["beta_normal"]["ci95"][0] <= 0.4 - 1.96e-3 and out["beta_normal"]["ci95"][1] >= 0.4 + 1.96e-3  # spans the noise share
    # with any information the interval is kept and can exclude the null
    info[2, 1, 1] = 1e-3
    out = describe_params(fit, draws, cfg, SimpleNamespace(M=info))
    assert out["contact_time"]["identified"] and null_excluded("contact_time", out["contact_time"]["ci95"], cfg)


def test_a_bound_counts_for_a_refit_only_away_from_the_null():
    """fit_candidate refits a contact candidate at a bound, but not at its null bound (an absent
    effect): contact_time's bounds are 0 (its null) and 1e-3 s."""
    cfg = default_config()
    at = lambda value: SimpleNamespace(params={"contact_time": value}, at_bound={"contact_time": True})
    assert _at_a_bound_off_null(at(1e-3), "flat_landing", cfg)
    assert not _at_a_bound_off_null(at(0.0), "flat_landing", cfg)
    assert not _at_a_bound_off_null(at(1e-10), "flat_landing", cfg)  # at the null bound within at_bound's tolerance
    assert not _at_a_bound_off_null(SimpleNamespace(params={"contact_time": 5e-4}, at_bound={"contact_time": False}), "flat_landing", cfg)
    assert not _at_a_bound_off_null(SimpleNamespace(params={}, at_bound={}), "corner_impulse", cfg)  # no parameter
