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


# --- a corner grazing a surface ------------------------------------------------------------


@numba.njit
def counted_search(s0, fpar, ipar, tau_max, tol, min_step, contact_speed, hit, out):
    """reference_search, returning (tau, steps)."""
    n = ipar[IP_N]
    g = fpar[FP_G]
    out[:] = s0
    tau = 0.0
    for steps in range(1, MAX_SEARCH_STEPS + 1):
        step = _scan(out, fpar, n, 1, g, 0.0, tol, min_step, contact_speed, hit)
        if step < 0.0:
            return tau, steps
        if tau + step > tau_max:
            return NO_CONTACT, steps
        tau += step
        flight_state(s0, tau, g, out)
    return STALLED, MAX_SEARCH_STEPS


# The start of fig11's slowest flight (64 x 64 grid): after an impact the bottom corner of the
# pentagon rests on the table (gap 0, rate -5e-17 m/s) and rho omega^2 = 9.84 m/s^2 is close
# to g, so the corner barely accelerates into the table. Stepping by min_step there took
# 162,122 steps, 42 % of all of fig11's search steps on that grid.
GRAZING_START = [0.13362977980409033, 0.013396465054120675, -1.6465824130211544,
                 0.362518030145983, -0.027526542730405737, -27.060723010244747]


def test_a_corner_grazing_the_table_is_left_in_few_steps():
    from tests.physics.test_flight_search_exact import lowest_gap_before

    fpar, ipar = make_params(sides=5)
    tol, min_step, contact_speed = tolerances(fpar)
    hit, out = np.zeros(2, np.int64), np.empty(6)
    s0 = np.array(GRAZING_START)
    tau, steps = counted_search(s0, fpar, ipar, 1.0, tol, min_step, contact_speed, hit, out)
    assert tau > 0.0 and steps < 1000  # 162,122 before
    assert next_contact(s0, fpar, ipar, 1.0, tol, min_step, contact_speed, hit, out) == tau
    assert lowest_gap_before(fpar, 5, s0, tau) >= -tol  # never deeper than the tolerance


def test_touching_step_cases():
    from dice_sweep.physics.flight import _touching_step

    tol, m2 = 1e-14, 19.6
    assert _touching_step(0.0, 1e-3, m2, tol) == 2e-3 / m2  # separating: as before
    assert _touching_step(-tol, -1e-17, m2, tol) == 0.0  # deeper than tol / 2: min_step
    for f, fp in [(0.0, 0.0), (0.5 * tol, -1e-12), (-0.25 * tol, -1e-10)]:
        s = _touching_step(f, fp, m2, tol)
        assert s > 0.0
        assert f + fp * s - 0.5 * m2 * s * s == pytest.approx(-0.5 * tol, rel=1e-6)  # the bound's root


def test_a_die_without_spin_resting_against_a_wall_falls_to_the_table():
    """A triangle at rest with a corner on the right wall (m2 = 0, gap 0, rate 0): the search
    used to step by min_step there and stall after MAX_SEARCH_STEPS (found by hypothesis in
    test_flight_search_exact.py); the corner never moves into the wall, so the contact is the
    table's, at the free-fall time of the lowest corner."""
    fpar, ipar = make_params(sides=3, separation=0.04)
    tol, min_step, contact_speed = tolerances(fpar)
    rho = fpar[FP_RHO_MAX]
    s0 = np.array([fpar[FP_WALL] - rho, rho, 0.0, 0.0, 0.0, 0.0])  # corner 0 points at the wall
    hit, out = np.zeros(2, np.int64), np.empty(6)
    tau = next_contact(s0, fpar, ipar, 1.0, tol, min_step, contact_speed, hit, out)
    lowest = rho * (1.0 - math.sin(math.pi / 3.0))  # the lowest corner's height: rho (1 - sin 60 deg)
    assert hit[0] == 0  # the table
    assert tau == pytest.approx(math.sqrt(2.0 * lowest / fpar[FP_G]), rel=1e-9)


def test_touching_step_without_acceleration():
    from dice_sweep.physics.flight import _touching_step

    tol = 1e-14
    assert _touching_step(0.0, 0.0, 0.0, tol) == math.inf  # resting against a wall, no spin
    assert _touching_step(0.0, 1e-6, 0.0, tol) == math.inf  # leaving it
    assert _touching_step(0.0, -1e-12, 0.0, tol) == pytest.approx(0.5 * tol / 1e-12)  # creeping in
