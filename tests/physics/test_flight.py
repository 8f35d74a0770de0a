"""Tests of dice_sweep.physics.flight: free flight, flight with air drag, and the contact search.

- The drag-free search takes exactly the steps of the generic scan (bit for bit): the scan as
  ``flight`` wrote it when ``search_free`` was derived from it is kept here, written out, as
  the reference (no private name of the module is used).
- The drag-free search against the exact gap: the contact it returns is the first. The gap of
  every corner to every surface is evaluated in closed form (from the flight's start state) on
  a fine time grid, each sampled local minimum refined by a bounded scalar minimisation. A
  search that stepped over a contact (or stopped inside a surface) leaves a corner below -tol
  before the returned time; a search that stopped early leaves no corner within tol of a
  surface at the returned time.
- Flight with quadratic drag: a straight drop against the closed form, a first-order delay,
  and flights at the fit's coarser tolerance against an independent integrator.
"""

import math

import numba
import numpy as np
import pytest
from hypothesis import HealthCheck, assume, given, settings
from hypothesis import strategies as st
from scipy.optimize import minimize_scalar

from dice_sweep.measured.fit import FIT_DRAG_MAX_STEP, FIT_DRAG_TOL
from dice_sweep.physics.flight import (
    HOP_AIM,
    HOP_BAND,
    HOP_CONCAVE,
    HOP_TURN,
    MAX_SEARCH_STEPS,
    NEAR_MIN_SIDES,
    NEAR_TURN,
    NO_CONTACT,
    REACH_MARGIN,
    STALLED,
    SURF_TABLE,
    advance_flight,
    flight_state,
    hop_step,
    next_contact,
    safe_step,
    surface_frame,
    turned_trig,
)
from dice_sweep.physics.kernel import CONTACT_SPEED, GAP_TOL, MIN_STEP, REC_T
from dice_sweep.physics.params import (
    CORNER_STRIDE,
    FP_COM_X,
    FP_COM_Y,
    FP_CORNER_RADIUS,
    FP_CORNERS,
    FP_DRAG_MAX_STEP,
    FP_DRAG_TOL,
    FP_G,
    FP_RHO_MAX,
    FP_WALL,
    IP_N,
)
from tests.physics.conftest import TABLE1_RADIUS, make_params, random_states, run_batch, run_one

G = 9.81
R = TABLE1_RADIUS


# --- the reference: the generic scan, written out -------------------------------------------


@numba.njit
def reference_touching_step(f, fp, m2, tol):
    """The step for a corner within tol of a surface not approaching faster than contact_speed
    (flight's docstring: to where the bound could reach -tol / 2; separating corners as if not)."""
    if fp > 0.0:
        if m2 <= 0.0:
            return math.inf
        if f + 0.5 * tol > 0.0:
            return max(2.0 * fp / m2, math.sqrt(2.0 * (f + 0.5 * tol) / m2))
        return 2.0 * fp / m2
    if f + 0.5 * tol > 0.0:
        return safe_step(f + 0.5 * tol, fp, m2)
    return 0.0


@numba.njit
def reference_turn_step(tight, wide, turn, omega):
    """A corner's step from its tighter bound's step (safe while the die turns by at most
    ``turn``) and the wide bound's: the tight one if it ends within the turn, else the longer of
    the turn's time and the wide one (with turn < 0, no tighter bound: the wide one)."""
    if turn < 0.0:
        return wide
    turn_time = turn / abs(omega) if omega != 0.0 else math.inf
    return tight if tight <= turn_time else max(turn_time, wide)


TURN_COS = (1.0 / 40320.0, -1.0 / 720.0, 1.0 / 24.0, -0.5)  # cos x - 1 = x^2 (-1/2 + x^2 (1/24 + ...))
TURN_SIN = (1.0 / 362880.0, -1.0 / 5040.0, 1.0 / 120.0, -1.0 / 6.0)


@numba.njit
def reference_trig(phi, anchor):
    """(cos phi, sin phi) as the search takes them: by the angle-addition identity from
    ``anchor`` = (angle, its libm cosine and sine) within HOP_TURN of it (Taylor series of the
    turn, Horner's rule), else from libm, which then becomes the anchor (updated in place)."""
    d = phi - anchor[0]
    if abs(d) <= HOP_TURN:
        u = d * d
        pc = 0.0
        ps = 0.0
        for i in range(4):
            pc = TURN_COS[i] + u * pc
            ps = TURN_SIN[i] + u * ps
        cos_m1 = u * pc
        sin_d = d + d * u * ps
        return anchor[1] + (anchor[1] * cos_m1 - anchor[2] * sin_d), anchor[2] + (anchor[2] * cos_m1 + anchor[1] * sin_d)
    anchor[0] = phi
    anchor[1] = math.cos(phi)
    anchor[2] = math.sin(phi)
    return anchor[1], anchor[2]


@numba.njit
def reference_scan(s, fpar, n, n_surf, accel_table, accel_wall, tol, min_step, contact_speed, hit, turn=-1.0, anchor=None):
    """Safe step (s) from state s, or -1 with ``hit`` set when a corner touches now: every
    surface, every corner, the quadratic bound of the module's docstring. With ``turn`` >= 0
    (rad; a fair die of NEAR_MIN_SIDES or more without walls) each corner also has the bound
    of its curvature over a turn of at most ``turn``, accel + omega^2 min(rho, n . r +
    |n . r_perp| turn + rho turn^2 / 2), safe for steps up to turn / |omega|; beyond, the wider
    bound's step is taken if longer; the corner whose step is the shortest, alone, may then
    take its hop_step instead, if longer (no further than the next corner's step).
    ``anchor``: the cosine and sine by :func:`reference_trig` (None: libm's), taken only
    when a surface is within the die's reach."""
    half_width = fpar[FP_WALL]
    rho_max = fpar[FP_RHO_MAX]
    arc = fpar[FP_CORNER_RADIUS]
    omega = s[5]
    cphi = math.nan
    sphi = math.nan
    step = math.inf
    best_corner = -1
    best_rate = 0.0
    for surf in range(n_surf):
        nx, ny, d = surface_frame(surf, half_width)
        h = d + nx * s[0] + ny * s[1]
        hv = nx * s[3] + ny * s[4]
        accel = accel_table if surf == SURF_TABLE else accel_wall
        if h - rho_max > REACH_MARGIN * rho_max:
            step = min(step, safe_step(h - rho_max, hv, accel))
            continue
        h -= arc
        if cphi != cphi:
            if anchor is None:
                cphi = math.cos(s[2])
                sphi = math.sin(s[2])
            else:
                cphi, sphi = reference_trig(s[2], anchor)
        corner_steps = np.full(n, math.inf)
        for k in range(n):
            base = FP_CORNERS + CORNER_STRIDE * k
            rho = fpar[base]
            rx = rho * (cphi * fpar[base + 1] - sphi * fpar[base + 2])
            ry = rho * (sphi * fpar[base + 1] + cphi * fpar[base + 2])
            f = h + nx * rx + ny * ry
            fp = hv + omega * (ny * rx - nx * ry)
            m2 = accel + rho * omega * omega
            reach = min(rho, nx * rx + ny * ry + abs(ny * rx - nx * ry) * max(turn, 0.0) + 0.5 * rho * turn * turn)
            m2_turn = accel + omega * omega * reach if turn >= 0.0 else m2
            if f <= tol:
                if fp < -contact_speed:
                    if best_corner < 0 or fp < best_rate:
                        hit[0] = surf
                        hit[1] = k
                        best_corner = k
                        best_rate = fp
                else:
                    wide = max(reference_touching_step(f, fp, m2, tol), min_step)
                    corner_steps[k] = reference_turn_step(max(reference_touching_step(f, fp, m2_turn, tol), min_step), wide, turn, omega)
            else:
                corner_steps[k] = reference_turn_step(safe_step(f, fp, m2_turn), safe_step(f, fp, m2), turn, omega)
        # a corner setting the step alone may take its hop_step, up to the next corner's step
        # (turn >= 0, on the table, gaps concave in time: rho omega^2 < g)
        limit = np.argmin(corner_steps)
        lowest = corner_steps[limit]
        corner_steps[limit] = math.inf
        hop = turn >= 0.0 and surf == SURF_TABLE and omega * omega * fpar[FP_CORNERS] < accel * (1.0 - HOP_CONCAVE)
        if hop and best_corner < 0 and lowest < corner_steps.min():
            hop_time = HOP_TURN / abs(omega) if omega != 0.0 else math.inf
            base = FP_CORNERS + CORNER_STRIDE * limit
            rx = fpar[base] * (cphi * fpar[base + 1] - sphi * fpar[base + 2])
            ry = fpar[base] * (sphi * fpar[base + 1] + cphi * fpar[base + 2])
            lowest = min(corner_steps.min(), max(lowest, hop_step(h + ry, hv + omega * rx, rx, ry, omega, accel, tol, lowest, hop_time)))
        step = min(step, lowest)
    if best_corner >= 0:
        return -1.0
    return step


@numba.njit
def reference_search(s0, fpar, ipar, tau_max, tol, min_step, contact_speed, hit, out):
    """The drag-free loop of next_contact as it was before the one-loop rewrite: the scan on
    the state from flight_state, step after step."""
    n = ipar[IP_N]
    g = fpar[FP_G]
    n_surf = 1 if math.isinf(fpar[FP_WALL]) else 3
    fair = fpar[FP_COM_X] == 0.0 and fpar[FP_COM_Y] == 0.0
    turn = NEAR_TURN if n >= NEAR_MIN_SIDES and fair and n_surf == 1 else -1.0
    out[:] = s0
    tau = 0.0
    anchor = np.array([math.nan, 0.0, 0.0])
    for _ in range(MAX_SEARCH_STEPS):
        step = reference_scan(out, fpar, n, n_surf, g, 0.0, tol, min_step, contact_speed, hit, turn, anchor)
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
        {"sides": 12},  # many sides: the search visits the corners near the lowest only
        {"sides": 20},
        {"sides": 20, "separation": 0.06},
    ],
)
def test_search_matches_the_generic_scan_bitwise(kwargs, rng):
    fpar, ipar = make_params(**kwargs)
    tol, min_step, contact_speed = tolerances(fpar)
    sides = ipar[IP_N]
    states = random_states(rng, 400, y_range=(0.0, 0.2))
    states[:, 0] = rng.uniform(-0.01, 0.01, len(states))
    # start some of them touching the table, as after an impact or a lift-off
    states[::4, 1] = fpar[FP_RHO_MAX] * rng.uniform(0.7, 1.0, len(states[::4]))
    states[1::5, 5] = 0.0  # no spin: the walls' curvature bound is zero
    # dropped flat without spin on the side from corner n-1 to corner 0: two corners touch at
    # once, equally fast (the lower index is the contact)
    states[2::7, 2] = -0.5 * math.pi + math.pi / sides
    states[2::7, 5] = 0.0
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
    anchor = np.array([math.nan, 0.0, 0.0])
    for steps in range(1, MAX_SEARCH_STEPS + 1):
        step = reference_scan(out, fpar, n, 1, g, 0.0, tol, min_step, contact_speed, hit, -1.0, anchor)
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
    fpar, ipar = make_params(sides=5)
    tol, min_step, contact_speed = tolerances(fpar)
    hit, out = np.zeros(2, np.int64), np.empty(6)
    s0 = np.array(GRAZING_START)
    tau, steps = counted_search(s0, fpar, ipar, 1.0, tol, min_step, contact_speed, hit, out)
    assert tau > 0.0 and steps < 1000  # 162,122 before
    assert next_contact(s0, fpar, ipar, 1.0, tol, min_step, contact_speed, hit, out) == tau
    assert lowest_gap_before(fpar, 5, s0, tau) >= -tol  # never deeper than the tolerance


@pytest.mark.parametrize("vx", [0.0, -1e-6, 1e-12])
def test_a_die_without_spin_resting_against_a_wall_falls_to_the_table(vx):
    """A triangle with a corner on the right wall and no spin (m2 = 0, gap 0): at rest there
    (rate 0), the search used to step by min_step and stall after MAX_SEARCH_STEPS (found by
    hypothesis in the random flights below); leaving the wall likewise (the step is unbounded);
    creeping into it at 1e-12 m/s, far slower than contact_speed, it stalled once past -tol / 2
    (an xfail until issue 33). The corner never hits the wall, so the contact is the table's, at the free-fall time of the
    lowest corner."""
    fpar, ipar = make_params(sides=3, separation=0.04)
    tol, min_step, contact_speed = tolerances(fpar)
    rho = fpar[FP_RHO_MAX]
    s0 = np.array([fpar[FP_WALL] - rho, rho, 0.0, vx, 0.0, 0.0])  # corner 0 points at the wall
    hit, out = np.zeros(2, np.int64), np.empty(6)
    tau = next_contact(s0, fpar, ipar, 1.0, tol, min_step, contact_speed, hit, out)
    lowest = rho * (1.0 - math.sin(math.pi / 3.0))  # the lowest corner's height: rho (1 - sin 60 deg)
    assert hit[0] == 0  # the table
    assert tau == pytest.approx(math.sqrt(2.0 * lowest / fpar[FP_G]), rel=1e-9)


# --- against the exact gap -------------------------------------------------------------------


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


# --- the hop of a many-sided die's corner (flight.hop_step) -----------------------------------


def hop_start(fpar, n, rng):
    """Corner 0 of a fair n-gon on the table (gap 0) near its lowest point, leaving it at 1e-5
    to 0.05 m/s with the die turning at up to 0.9 sqrt(g / rho) (gaps concave in time), as
    after most impacts of fig09's 20-gon: (phi, h, hv, omega, cos phi, sin phi, rx, ry)."""
    base = FP_CORNERS
    rho = fpar[base]
    gamma = math.atan2(fpar[base + 2], fpar[base + 1])
    phi = -0.5 * math.pi - gamma + rng.uniform(-math.pi / n, math.pi / n)
    omega = rng.uniform(-0.9, 0.9) * math.sqrt(G / rho)
    c, sn = math.cos(phi), math.sin(phi)
    rx = rho * (c * fpar[base + 1] - sn * fpar[base + 2])
    ry = rho * (sn * fpar[base + 1] + c * fpar[base + 2])
    leave = 10.0 ** rng.uniform(-5.0, math.log10(0.05))
    return phi, -ry, leave - omega * rx, omega, c, sn, rx, ry


def exact_corner_gap(fpar, phi, h, hv, omega, t):
    """Corner 0's gap (m) and rate (m/s) over the drag-free flight, in extended precision (numpy
    long double sine and cosine of the turned angle, not flight's series)."""
    t = np.asarray(t, np.longdouble)
    rho = np.longdouble(fpar[FP_CORNERS])
    angle = np.longdouble(phi) + np.arctan2(np.longdouble(fpar[FP_CORNERS + 2]), np.longdouble(fpar[FP_CORNERS + 1]))
    w = np.longdouble(omega)
    gap = np.longdouble(h) + np.longdouble(hv) * t - np.longdouble(G) / 2 * t * t + rho * np.sin(angle + w * t)
    rate = np.longdouble(hv) - np.longdouble(G) * t + w * rho * np.cos(angle + w * t)
    return gap, rate


@pytest.mark.parametrize("sides", [12, 20])
def test_hop_step_lands_a_leaving_corner_within_its_band_before_it_comes_back(sides, rng):
    """From the quadratic bound's safe step, hop_step steps a corner that left the table to where
    its exact gap is HOP_AIM +- HOP_BAND tol, still above the table and falling, with no contact
    passed (the exact gap never below where it started) and within HOP_TURN of turn."""
    fpar, ipar = make_params(sides=sides)
    tol = tolerances(fpar)[0]
    rho = fpar[FP_CORNERS]
    found = within_turn = 0
    for _ in range(300):
        phi, h, hv, omega, c, sn, rx, ry = hop_start(fpar, sides, rng)
        fp = hv + omega * rx
        start = 2.0 * fp / (G + rho * omega * omega)  # the wide bound's return to the table: short of it
        s_max = HOP_TURN / abs(omega)
        step = hop_step(h + ry, fp, rx, ry, omega, G, tol, start, s_max)
        back = 2.0 * fp / (G + omega * omega * ry)  # about when it comes back
        within_turn += back < 0.9 * s_max
        if step == 0.0:
            assert back > 0.8 * s_max  # refused only where the series would not hold
            continue
        found += 1
        assert 0.0 < step <= s_max
        gap, rate = exact_corner_gap(fpar, phi, h, hv, omega, [step])
        assert abs(float(gap[0]) / tol - HOP_AIM) <= HOP_BAND + 1e-3
        assert rate[0] < 0.0
        gaps, _ = exact_corner_gap(fpar, phi, h, hv, omega, np.linspace(0.0, step, 2001))
        assert float(gaps.min()) >= float(min(gaps[0], 0.0)) - 1e-3 * tol
    assert found >= within_turn > 200  # the hops of such dice are found, not left to the bound's steps


def test_hop_step_refuses_what_it_cannot_show():
    """Controls, nothing to find: a corner back only after turning far beyond HOP_TURN, a hop
    too low to reach the band, a corner still rising at the step it is given."""
    fpar, _ = make_params(sides=20)
    tol = tolerances(fpar)[0]
    phi, h, _, _, c, sn, rx, ry = hop_start(fpar, 20, np.random.default_rng(7))
    omega = 10.0
    s_max = HOP_TURN / omega
    long_hop = 0.5 - omega * rx  # leaves at 0.5 m/s: back after about 0.1 s, 1 rad
    assert hop_step(h + ry, long_hop + omega * rx, rx, ry, omega, G, tol, 1e-3, s_max) == 0.0
    low_hop = math.sqrt(2.0 * G * 0.1 * tol) - omega * rx  # rises to about 0.1 tol
    assert hop_step(h + ry, low_hop + omega * rx, rx, ry, omega, G, tol, 1e-9, s_max) == 0.0
    rising = 0.01 - omega * rx  # 1 um up, rising at 0.01 m/s for another ms
    assert hop_step(h + ry + 1e-6, rising + omega * rx, rx, ry, omega, G, tol, 1e-5, s_max) == 0.0
    # the same corner from a step near its return (about 2.46 ms) is found
    assert hop_step(h + ry + 1e-6, rising + omega * rx, rx, ry, omega, G, tol, 2.4e-3, s_max) > 2.4e-3


def test_turned_trig_is_within_two_ulp_of_the_cosine_and_sine_of_the_angle(rng):
    """The search's cosine and sine of an angle within HOP_TURN of its anchor (from the anchor's
    libm values by the angle-addition identity) against numpy's long double cosine and sine of
    that angle; the anchor is kept. Beyond HOP_TURN (control): libm's own values, and the angle
    becomes the anchor."""
    anchors = np.concatenate([rng.uniform(-300.0, 300.0, 3000), rng.uniform(-0.1, 0.1, 1000)])
    turns = rng.uniform(-HOP_TURN, HOP_TURN, len(anchors))
    turns[:8] = [0.9999 * HOP_TURN, -0.9999 * HOP_TURN, 1e-300, -1e-12, 0.0, 3e-4, -2e-3, 0.5 * HOP_TURN]
    worst = 0.0
    for anchor, turn in zip(anchors, turns):
        phi = anchor + turn
        c, sn, a_phi, a_cos, a_sin = turned_trig(phi, anchor, math.cos(anchor), math.sin(anchor))
        assert (a_phi, a_cos, a_sin) == (anchor, math.cos(anchor), math.sin(anchor))
        exact = np.longdouble(phi)
        worst = max(worst, float(abs(c - np.cos(exact))), float(abs(sn - np.sin(exact))))
    assert worst <= 2.0 * np.spacing(1.0)
    for anchor, turn in [(1.0, 1.01 * HOP_TURN), (-40.0, -0.3), (2.0, math.nan)]:
        phi = anchor + turn if turn == turn else 2.5
        c, sn, a_phi, a_cos, a_sin = turned_trig(phi, anchor if turn == turn else math.nan, 0.3, 0.4)
        assert (c, sn) == (math.cos(phi), math.sin(phi))
        assert (a_phi, a_cos, a_sin) == (phi, c, sn)


@pytest.mark.parametrize("sides", [12, 20])
def test_hops_of_many_sided_dice_find_the_first_contact(sides, rng):
    """The whole search from such hops (the corner that just hit, leaving) against the exact gap;
    it comes back to the table within the hop's band (the search took hop_step's step)."""
    fpar, ipar = make_params(sides=sides)
    tol = tolerances(fpar)[0]
    in_band = 0
    for _ in range(40):
        phi, h, hv, omega, *_ = hop_start(fpar, sides, rng)
        s0 = np.array([0.0, h, phi, 0.3 * rng.uniform(-1.0, 1.0), hv, omega])
        tau, hit = check_search(fpar, ipar, s0, 0.3)
        assert tau > 0.0
        gap, _ = exact_gaps(fpar, sides, s0, [tau])
        in_band += abs(gap[hit[0], hit[1], 0] / tol - HOP_AIM) <= HOP_BAND + 1e-3
    assert in_band >= 36


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


# --- flight with air drag --------------------------------------------------------------------


def test_quadratic_drag_fall_matches_the_closed_form():
    """Straight down with a = -g - c |v| v: y(t) = y0 - (v_t^2/g) ln cosh(g t / v_t), v_t =
    sqrt(g/c); the corner pointing down touches when y = R."""
    c, y0 = 0.8, 0.5
    params = make_params(air_drag=c)
    _, _, _, _, rec, _ = run_one(params, [0.0, y0, -math.pi / 2, 0.0, 0.0, 0.0])
    v_t = math.sqrt(G / c)
    expected = v_t / G * math.acosh(math.exp((y0 - R) * G / v_t**2))
    assert math.isclose(rec[1, REC_T], expected, rel_tol=1e-10)
    assert rec[1, REC_T] > math.sqrt(2 * (y0 - R) / G)  # slower than free fall


def test_tiny_drag_delays_a_drop_by_its_first_order_amount_and_changes_no_outcome(rng):
    """A drag c small enough to change no outcome still acts: a straight drop from y0 reaches the
    table later by c g t0^3 / 12 (first order in c of y = y0 - g t^2/2 + c g^2 t^4/12), which a
    kernel ignoring the drag slot fails; and 200 random rolls keep their outcomes."""
    c, y0 = 1e-6, 0.3
    start = [0.0, y0, -math.pi / 2, 0.0, 0.0, 0.0]
    plain_time = run_one(make_params(), start)[4][1, REC_T]
    drag_time = run_one(make_params(air_drag=c), start)[4][1, REC_T]
    t0 = math.sqrt(2 * (y0 - R) / G)
    assert drag_time - plain_time == pytest.approx(c * G * t0**3 / 12, rel=1e-3)
    states = random_states(rng, 200, y_range=(0.03, 0.1), omega_max=20.0)
    plain, _, _, _ = run_batch(make_params(), states)
    tiny, _, _, _ = run_batch(make_params(air_drag=1e-12), states)
    assert np.mean(plain == tiny) > 0.99


def _drag_flight_reference(state, c, tau):
    """Flight with a = -g - c |v| v by SciPy's DOP853 at rtol 1e-13: an integrator that is not
    the kernel's."""
    from scipy.integrate import solve_ivp

    def rates(_, u):
        speed = math.hypot(u[2], u[3])
        return [u[2], u[3], -c * speed * u[2], -G - c * speed * u[3]]

    sol = solve_ivp(rates, (0.0, tau), [state[0], state[1], state[3], state[4]], method="DOP853", rtol=1e-13, atol=1e-15)
    return sol.y[:2, -1]


@pytest.mark.parametrize("c", [0.05, 0.5, 2.0])
def test_drag_flight_at_the_fits_tolerance_stays_within_a_nanometre(c):
    """The fit runs flights with drag at coarser Runge-Kutta steps than a sweep (FIT_DRAG_TOL,
    FIT_DRAG_MAX_STEP in fpar): the centre after 0.3 s stays within 1e-9 m of an independent
    integrator at both settings, and a far coarser setting is visibly worse (fpar is read)."""
    state = np.array([0.0, 0.6, 0.3, 1.5, 2.0, 12.0])
    tau = 0.3
    expected = _drag_flight_reference(state, c, tau)
    out = np.empty(6)
    for tol, max_step in [(None, None), (FIT_DRAG_TOL, FIT_DRAG_MAX_STEP)]:
        fpar, _ = make_params(air_drag=c)
        if tol is not None:
            fpar[FP_DRAG_TOL], fpar[FP_DRAG_MAX_STEP] = tol, max_step
        advance_flight(state, tau, fpar, out)
        assert np.abs(out[:2] - expected).max() < 1e-9, (tol, out[:2] - expected)
        assert math.isclose(out[2], state[2] + state[5] * tau, rel_tol=1e-12)  # rotation: omega constant
    fpar, _ = make_params(air_drag=c)
    fpar[FP_DRAG_TOL], fpar[FP_DRAG_MAX_STEP] = 1e-2, tau  # one step
    advance_flight(state, tau, fpar, out)
    assert np.abs(out[:2] - expected).max() > 1e-9
