"""The drag-free contact search against the exact gap: the contact it returns is the first.

The gap of every corner to every surface is evaluated in closed form (from the flight's start
state) on a fine time grid, each sampled local minimum refined by a bounded scalar minimisation.
A search that stepped over a contact (or stopped inside a surface) leaves a corner below -tol
before the returned time; a search that stopped early leaves no corner within tol of a surface
at the returned time.
"""

import math

import numpy as np
import pytest
from hypothesis import HealthCheck, assume, given, settings
from hypothesis import strategies as st
from scipy.optimize import minimize_scalar

from dice_sweep.physics.flight import NO_CONTACT, STALLED, next_contact
from dice_sweep.physics.kernel import CONTACT_SPEED, GAP_TOL, MIN_STEP
from dice_sweep.physics.params import CORNER_STRIDE, FP_CORNERS, FP_G, FP_RHO_MAX, FP_WALL, IP_N
from tests.physics.conftest import make_params


def tolerances(fpar):
    scale = fpar[FP_RHO_MAX]
    g = fpar[FP_G]
    return GAP_TOL * scale, MIN_STEP * math.sqrt(scale / g), CONTACT_SPEED * math.sqrt(g * scale)


def exact_gaps(fpar, n, s0, t):
    """Gaps (surface, corner, time) of the drag-free flight from s0 at the times t, and rates."""
    g = fpar[FP_G]
    half = fpar[FP_WALL]
    t = np.asarray(t, float)
    x = s0[0] + s0[3] * t
    y = s0[1] + s0[4] * t - 0.5 * g * t * t
    vy = s0[4] - g * t
    phi = s0[2] + s0[5] * t
    corners = fpar[FP_CORNERS:FP_CORNERS + CORNER_STRIDE * n].reshape(n, CORNER_STRIDE)
    rho, cg, sg = corners[:, 0:1], corners[:, 1:2], corners[:, 2:3]
    c, s = np.cos(phi), np.sin(phi)
    rx = rho * (c * cg - s * sg)
    ry = rho * (s * cg + c * sg)
    w = s0[5]
    gaps = [y + ry]
    rates = [vy + w * rx]
    if not math.isinf(half):
        gaps += [half + x + rx, half - x - rx]
        rates += [s0[3] - w * ry, -s0[3] + w * ry]
    return np.array(gaps), np.array(rates)


def lowest_gap_before(fpar, n, s0, t_end):
    """Smallest exact gap of any corner on [0, t_end]: a fine grid, then each low sampled
    local minimum refined (a contact stepped over by a grazing corner dips between samples)."""
    if t_end <= 0.0:
        return exact_gaps(fpar, n, s0, [0.0])[0].min()
    samples = int(min(max(2000, abs(s0[5]) * t_end / 0.005, 40.0 * t_end / 1e-4), 200_000))
    t = np.linspace(0.0, t_end, samples + 1)
    gaps, _ = exact_gaps(fpar, n, s0, t)
    lowest = gaps.min()
    threshold = 1e-4 * fpar[FP_RHO_MAX]
    for surf in range(gaps.shape[0]):
        for k in range(n):
            row = gaps[surf, k]
            interior = np.flatnonzero((row[1:-1] <= row[:-2]) & (row[1:-1] <= row[2:]) & (row[1:-1] < threshold)) + 1
            for i in interior[:20]:
                res = minimize_scalar(
                    lambda tt: exact_gaps(fpar, n, s0, [tt])[0][surf, k, 0],
                    bounds=(t[i - 1], t[i + 1]), method="bounded", options={"xatol": 1e-13},
                )
                lowest = min(lowest, res.fun)
    return lowest


def check_search(fpar, ipar, s0, tau_max):
    """Run next_contact and check its answer against the exact gap; returns (tau, hit)."""
    n = int(ipar[IP_N])
    tol, min_step, contact_speed = tolerances(fpar)
    hit = np.zeros(2, np.int64)
    out = np.empty(6)
    tau = next_contact(np.asarray(s0, float), fpar, ipar, tau_max, tol, min_step, contact_speed, hit, out)
    assert tau != STALLED
    t_end = tau_max if tau == NO_CONTACT else tau
    # no corner was ever inside a surface by more than tol before the answer
    assert lowest_gap_before(fpar, n, s0, t_end) >= -tol
    if tau >= 0.0:
        gaps, rates = exact_gaps(fpar, n, s0, [tau])
        surf, corner = int(hit[0]), int(hit[1])
        # the reported corner touches and approaches at the reported time
        assert gaps[surf, corner, 0] <= tol + 1e-16
        assert rates[surf, corner, 0] < -contact_speed * (1.0 - 1e-9)
        # the returned state is the flight's state at tau
        x = s0[0] + s0[3] * tau
        y = s0[1] + s0[4] * tau - 0.5 * fpar[FP_G] * tau * tau
        assert abs(out[0] - x) <= 1e-15 * max(1.0, abs(x))
        assert abs(out[1] - y) <= 1e-15 * max(1.0, abs(y))
    return tau, (int(hit[0]), int(hit[1]))


def start_clear(fpar, n, s0):
    return exact_gaps(fpar, n, s0, [0.0])[0].min() >= 0.0


@settings(max_examples=150, deadline=None, suppress_health_check=[HealthCheck.too_slow, HealthCheck.filter_too_much])
@given(
    sides=st.integers(3, 20),
    walls=st.sampled_from([None, 0.04, 0.1]),
    height=st.floats(0.0, 0.15),
    touching=st.booleans(),
    x_frac=st.floats(-1.0, 1.0),
    phi=st.floats(-math.pi, math.pi),
    vx=st.floats(-3.0, 3.0),
    vy=st.floats(-3.0, 3.0),
    omega=st.one_of(st.floats(-60.0, 60.0), st.floats(-500.0, 500.0), st.just(0.0)),
    tau_max=st.sampled_from([0.02, 0.3]),
)
def test_random_flights_find_the_first_contact(sides, walls, height, touching, x_frac, phi, vx, vy, omega, tau_max):
    fpar, ipar = make_params(sides=sides, separation=walls)
    n = int(ipar[IP_N])
    rho_max = fpar[FP_RHO_MAX]
    half = fpar[FP_WALL]
    x = 0.0 if math.isinf(half) else x_frac * (half - rho_max)
    s0 = np.array([x, rho_max + height, phi, vx, vy, omega])
    if touching:
        # a corner exactly on the table, as at an impact or a lift-off
        s0[1] -= exact_gaps(fpar, n, s0, [0.0])[0][0].min()
    assume(start_clear(fpar, n, s0) or touching)
    check_search(fpar, ipar, s0, tau_max)


@pytest.mark.parametrize("sides", [3, 4, 7, 20])
@pytest.mark.parametrize("omega", [40.0, 200.0, -500.0])
@pytest.mark.parametrize("depth", [1e-6, 1e-9, 100.0 * GAP_TOL, -100.0 * GAP_TOL, -1e-9, -1e-6])
def test_grazing_corner(sides, omega, depth):
    """A corner swinging through its lowest point at t* with its gap's minimum at depth x R
    (positive: a near miss to step over; negative: a contact to find before t*)."""
    fpar, ipar = make_params(sides=sides)
    n = int(ipar[IP_N])
    g = fpar[FP_G]
    base = FP_CORNERS
    rho, gamma = fpar[base], math.atan2(fpar[base + 2], fpar[base + 1])
    t_star = 0.2 / abs(omega)  # the corner turns 0.2 rad before its lowest point
    phi0 = -0.5 * math.pi - gamma - omega * t_star
    # corner 0's gap below the CoM height y0, as a function of time (vy0 = 0)
    def relative(t):
        return -0.5 * g * t * t + rho * math.sin(phi0 + gamma + omega * t)

    window = (0.0, 2.0 * t_star)
    t = np.linspace(*window, 20001)
    i = int(np.argmin([relative(tt) for tt in t]))
    res = minimize_scalar(relative, bounds=(t[max(i - 1, 0)], t[min(i + 1, len(t) - 1)]), method="bounded",
                          options={"xatol": 1e-14})
    y0 = depth * fpar[FP_RHO_MAX] - res.fun
    s0 = np.array([0.0, y0, phi0, 0.0, 0.0, omega])
    assert start_clear(fpar, n, s0)
    tau, hit = check_search(fpar, ipar, s0, 0.3)
    if depth < 0.0:
        assert 0.0 < tau <= res.x  # corner 0 (or, on many-sided dice, a neighbour first)
    else:
        assert hit != (0, 0) or tau > res.x  # corner 0's near miss was stepped over


@pytest.mark.parametrize("sides", [3, 5, 12])
def test_walls_and_table(sides, rng):
    """Flights between walls close to the die, fast in x: wall contacts are found first."""
    fpar, ipar = make_params(sides=sides, separation=0.04)
    n = int(ipar[IP_N])
    rho_max = fpar[FP_RHO_MAX]
    half = fpar[FP_WALL]
    surfaces = set()
    for _ in range(60):
        s0 = np.array([
            rng.uniform(-1.0, 1.0) * (half - rho_max), rho_max + rng.uniform(0.0, 0.05),
            rng.uniform(-math.pi, math.pi), rng.uniform(-2.0, 2.0), rng.uniform(-1.0, 1.0), rng.uniform(-80.0, 80.0),
        ])
        tau, hit = check_search(fpar, ipar, s0, 0.3)
        if tau >= 0.0:
            surfaces.add(hit[0])
    assert surfaces == {0, 1, 2}  # the checks covered the table and both walls
