"""The drag-free contact search takes exactly the steps of the generic scan (bit for bit)."""

import math

import numba
import numpy as np
import pytest

from dice_sweep.physics.flight import MAX_SEARCH_STEPS, NO_CONTACT, STALLED, _scan, flight_state, next_contact
from dice_sweep.physics.kernel import CONTACT_SPEED, GAP_TOL, MIN_STEP
from dice_sweep.physics.params import FP_G, FP_RHO_MAX, FP_WALL, IP_N
from tests.physics.conftest import make_params, random_states


@numba.njit
def reference_search(s0, fpar, ipar, tau_max, tol, min_step, contact_speed, hit, out):
    """The drag-free loop of next_contact as it was before the one-loop rewrite: _scan on the
    state from flight_state, step after step."""
    n = ipar[IP_N]
    g = fpar[FP_G]
    n_surf = 1 if math.isinf(fpar[FP_WALL]) else 3
    out[:] = s0
    tau = 0.0
    for _ in range(MAX_SEARCH_STEPS):
        step = _scan(out, fpar, n, n_surf, g, 0.0, tol, min_step, contact_speed, hit)
        if step < 0.0:
            return tau
        if tau + step > tau_max:
            return NO_CONTACT
        tau += step
        flight_state(s0, tau, g, out)
    return STALLED


def tolerances(fpar):
    scale = fpar[FP_RHO_MAX]
    g = fpar[FP_G]
    return GAP_TOL * scale, MIN_STEP * math.sqrt(scale / g), CONTACT_SPEED * math.sqrt(g * scale)


@pytest.mark.parametrize(
    "kwargs",
    [
        {},
        {"sides": 3},
        {"sides": 7, "separation": 0.06},
        {"separation": 0.04, "com_offset": (0.002, -0.001)},
        {"separation": 0.05, "beta_t": 0.0},
    ],
)
def test_search_matches_the_generic_scan_bitwise(kwargs, rng):
    fpar, ipar = make_params(**kwargs)
    tol, min_step, contact_speed = tolerances(fpar)
    states = random_states(rng, 400, y_range=(0.0, 0.2))
    states[:, 0] = rng.uniform(-0.01, 0.01, len(states))
    # start some of them touching the table, as after an impact or a lift-off
    states[::4, 1] = fpar[FP_RHO_MAX] * rng.uniform(0.7, 1.0, len(states[::4]))
    states[1::5, 5] = 0.0  # no spin: the walls' curvature bound is zero
    hit_a = np.zeros(2, np.int64)
    hit_b = np.zeros(2, np.int64)
    out_a = np.empty(6)
    out_b = np.empty(6)
    contacts = 0
    for state, tau_max in zip(states, rng.choice([0.01, 0.3, 30.0], len(states))):
        tau_a = next_contact(state, fpar, ipar, tau_max, tol, min_step, contact_speed, hit_a, out_a)
        tau_b = reference_search(state, fpar, ipar, tau_max, tol, min_step, contact_speed, hit_b, out_b)
        assert tau_a == tau_b or (math.isnan(tau_a) and math.isnan(tau_b))
        assert out_a.tobytes() == out_b.tobytes()
        if tau_a >= 0.0:
            contacts += 1
            assert tuple(hit_a) == tuple(hit_b)
    assert contacts > 100  # the comparison covered real contacts, not only horizons
