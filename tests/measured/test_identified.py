"""A parameter no track's residual moves with gets no interval and cannot be named.

On the real drops the flat_landing candidate stayed at its start value (a contact time
shorter than every landing's delay), its bootstrap interval had zero width, [3e-5, 3e-5] s,
and the report called its null value excluded."""

import math
from types import SimpleNamespace

import numpy as np

from dice_sweep.config import default_config
from dice_sweep.measured.diagnose import _describe_params, _null_excluded


def _fit(names, values):
    return SimpleNamespace(free=tuple(names), params=dict(zip(names, values)), at_bound={})


def test_a_parameter_without_information_has_no_interval_and_excludes_nothing():
    cfg = default_config()
    names = ["beta_normal", "contact_time"]
    fit = _fit(names, [0.4, 3e-5])
    draws = np.column_stack([np.linspace(0.39, 0.41, 100), np.full(100, 3e-5)])  # zero width
    info = np.zeros((5, 2, 2))
    info[:, 0, 0] = 1.0  # each of 5 tracks informs beta_normal, none contact_time
    out = _describe_params(fit, draws, cfg, SimpleNamespace(M=info))
    assert out["beta_normal"]["identified"] and out["beta_normal"]["ci95"][0] < 0.4 < out["beta_normal"]["ci95"][1]
    assert not out["contact_time"]["identified"]
    assert all(math.isnan(v) for v in out["contact_time"]["ci95"])
    assert not _null_excluded("contact_time", out["contact_time"]["ci95"], cfg)
    # with any information the interval is kept and can exclude the null
    info[2, 1, 1] = 1e-3
    out = _describe_params(fit, draws, cfg, SimpleNamespace(M=info))
    assert out["contact_time"]["identified"] and _null_excluded("contact_time", out["contact_time"]["ci95"], cfg)
