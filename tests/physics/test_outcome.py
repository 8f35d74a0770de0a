"""Tests of dice_sweep.physics.outcome: the side below and the rest and barrier heights by hand,
decided_side's early exit answering exactly as the full rule, and a batch reusing its scratch
arrays answering row by row as single rolls do."""

import math

import numpy as np
import pytest

from dice_sweep.physics.flight import corner_offset
from dice_sweep.physics.impact import specific_energy
from dice_sweep.physics.outcome import DECISION_MARGIN, barrier_height, decided_side, decision_bound, rest_height, side_below
from dice_sweep.physics.params import CORNER_STRIDE, FP_CORNERS, FP_G, FP_RHO_MAX, IP_N
from tests.physics.conftest import TABLE1_RADIUS, make_params, random_states, run_batch, run_one

R = TABLE1_RADIUS


@pytest.mark.parametrize("n", [3, 4, 6, 20])
def test_a_fair_die_rests_at_its_apothem_and_rolls_over_at_its_circumradius(n):
    fpar, _ = make_params(sides=n)
    apothem = R * math.cos(math.pi / n)
    for side in range(n):
        assert rest_height(fpar, n, side) == pytest.approx(apothem, rel=1e-14)
        assert barrier_height(fpar, n, side) == pytest.approx(R, rel=1e-14)
    assert decision_bound(fpar) == fpar[FP_G] * R * (1.0 - DECISION_MARGIN)


def test_rounded_corners_raise_the_barrier_by_r_and_keep_the_rest_height():
    """A rounded die of circumradius R and corner radius r: arc centres (a - r) / cos(pi / n)
    from the centre, resting at the apothem a, rolling over at the arc centre's distance + r."""
    r, n = 0.002, 4
    fpar, _ = make_params(sides=n, corner_radius=r)
    apothem = R * math.cos(math.pi / n)
    assert rest_height(fpar, n, 0) == pytest.approx(apothem, rel=1e-14)
    assert barrier_height(fpar, n, 0) == pytest.approx((apothem - r) / math.cos(math.pi / n) + r, rel=1e-14)


@pytest.mark.parametrize("n", [3, 4, 5])
def test_the_side_below_is_the_one_the_vertical_ray_crosses(n):
    """Side k joins corners k and k + 1, corner k at body angle 2 pi k / n: with the die turned
    by phi the ray down (body angle -pi/2 - phi) lies between them for phi in that side's range."""
    fpar, _ = make_params(sides=n)
    width = 2 * math.pi / n
    for k in range(n):
        middle = k * width + width / 2  # body angle of side k's midpoint
        phi = -math.pi / 2 - middle  # turned so that the midpoint is straight below
        for offset in (-0.49 * width, 0.0, 0.49 * width):
            assert side_below(phi + offset, fpar, n) == k
            assert side_below(phi + offset + 2 * math.pi * 3, fpar, n) == k  # any turn


def test_a_die_lying_flat_is_decided_only_below_its_barrier():
    fpar, _ = make_params()
    phi = -math.pi / 2 - math.pi / 4  # side 0 flat below the centre
    at_rest = np.array([0.0, rest_height(fpar, 4, 0), phi, 0.0, 0.0, 0.0])
    assert decided_side(at_rest, fpar, 4) == 0
    lift = R - rest_height(fpar, 4, 0)  # the energy to bring the centre over a corner
    fast = at_rest.copy()
    fast[4] = math.sqrt(2 * fpar[FP_G] * lift) * 1.001
    assert decided_side(fast, fpar, 4) == -1
    fast[4] *= 0.99
    assert decided_side(fast, fpar, 4) == 0


PARAMS = [{}, {"sides": 3}, {"sides": 6}, {"com_offset": (0.003, -0.002)}, {"sides": 5, "com_offset": (-0.002, 0.001)}]


def full_decided_side(s, fpar, n):
    """decided_side without its early exit (the rule of docs/physics.md as written)."""
    k = side_below(s[2], fpar, n)
    rho_a = fpar[FP_CORNERS + CORNER_STRIDE * k]
    rho_b = fpar[FP_CORNERS + CORNER_STRIDE * ((k + 1) % n)]
    barrier = fpar[FP_G] * min(rho_a, rho_b) * (1.0 - DECISION_MARGIN)
    return k if specific_energy(s, fpar) < barrier else -1


def states_near_rest(rng, fpar, n, count):
    """COM states lying on a side, tilted a little or not, with energies around the barriers."""
    states = np.zeros((count, 6))
    for i in range(count):
        side = rng.integers(n)
        a = corner_offset(fpar, side, 1.0, 0.0)
        b = corner_offset(fpar, (side + 1) % n, 1.0, 0.0)
        phi = -math.atan2(b[1] - a[1], b[0] - a[0])  # side k along +x, below the COM
        tilt = rng.choice([0.0, 0.0, 1e-12, 1e-3, 0.3]) * rng.choice([-1.0, 1.0])
        states[i, 2] = phi + tilt + 2 * math.pi * rng.integers(-3, 4)
        states[i, 1] = rest_height(fpar, n, side)
        speed = rng.choice([0.0, 1e-7, 1e-3, 0.1, 0.3])
        states[i, 3:6] = speed * rng.normal(size=3) * np.array([1.0, 1.0, 30.0])
        states[i, 1] += rng.choice([0.0, 0.0, 1e-13, 1e-6, 1e-3])
    return states


@pytest.mark.parametrize("kwargs", PARAMS)
def test_early_exits_change_no_answer(kwargs, rng):
    fpar, ipar = make_params(**kwargs)
    n = int(ipar[IP_N])
    states = np.concatenate((states_near_rest(rng, fpar, n, 3000), random_states(rng, 1000, y_range=(0.0, 0.03))))
    decided = 0
    for s in states:
        assert decided_side(s, fpar, n) == full_decided_side(s, fpar, n)
        decided += full_decided_side(s, fpar, n) >= 0
    assert 500 < decided < len(states)  # both answers were exercised


@pytest.mark.parametrize("kwargs", [{}, {"com_offset": (0.002, 0.0)}])
def test_decided_side_at_exactly_the_bound(kwargs, rng):
    """Energies within a few ulps of g rho_max (1 - margin), the early exit's bound (and, for a
    fair die, the barrier itself): the early exit and the full rule agree."""
    fpar, ipar = make_params(**kwargs)
    n = int(ipar[IP_N])
    y_bound = fpar[FP_G] * fpar[FP_RHO_MAX] * (1.0 - DECISION_MARGIN) / fpar[FP_G]
    decided = 0
    for phi in rng.uniform(-math.pi, math.pi, 50):
        s = np.array([0.0, y_bound, phi, 0.0, 0.0, 0.0])
        for _ in range(6):
            s[1] = np.nextafter(s[1], 0.0)
        for _ in range(12):
            assert decided_side(s, fpar, n) == full_decided_side(s, fpar, n)
            decided += full_decided_side(s, fpar, n) >= 0
            s[1] = np.nextafter(s[1], 1.0)
    if not kwargs:
        assert decided > 0  # a fair die's barrier is the bound itself: both answers occur


@pytest.mark.parametrize("kwargs", [{}, {"separation": 0.06, "friction": 0.4, "model": "rigid"}, {"method": "fixed_step"}])
def test_batch_rows_equal_single_rolls(kwargs, rng):
    """roll_batch reuses its scratch arrays from roll to roll; each row must still be what
    roll_one gives for that state alone, in any order."""
    params = make_params(**kwargs)
    states = random_states(rng, 120, y_range=(0.02, 0.2))
    outcome, status, counts, t = run_batch(params, states)
    order = rng.permutation(len(states))
    outcome_p, status_p, counts_p, t_p = run_batch(params, states[order])
    for i, state in enumerate(states):
        one = run_one(params, state)
        assert (outcome[i], status[i]) == (one[0], one[1])
        assert tuple(counts[i]) == tuple(one[5])
        assert t[i] == one[2] or (math.isnan(t[i]) and math.isnan(one[2]))
    assert np.array_equal(outcome_p, outcome[order]) and np.array_equal(counts_p, counts[order])
    assert np.array_equal(t_p, t[order], equal_nan=True)
