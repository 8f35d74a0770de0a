"""Rounded corners (effects.corner_radius = r): a die that is a core regular polygon of apothem
a - r grown by a disk of radius r (docs/physics.md, "Rounded corners").

Every expected value here is computed in the test from the geometry, with numpy and scipy:
the arc centres c_k = Rc e(phi + 2 pi k / n), Rc = (a - r) / cos(pi / n); a surface touched where
an arc centre is r from it; the contact point r below the arc centre on the table.
"""

import math

import numpy as np
import pytest
from scipy.integrate import solve_ivp
from scipy.optimize import brentq
from scipy.stats import chisquare

from dice_sweep.physics import COUNT_COLUMNS
from dice_sweep.physics.flight import SURF_LEFT, SURF_TABLE
from dice_sweep.physics.impact import resolve_impact
from dice_sweep.physics.kernel import REC_ENERGY, REC_KIND, REC_STATE, REC_T, SEG_PIVOT_ODE, STATUS_DECIDED
from dice_sweep.physics.outcome import decided_side, rest_height
from dice_sweep.physics.params import FP_INERTIA, FP_RHO_MAX
from dice_sweep.physics.pivot import PIVOT_TIMEOUT, pivot_ode
from tests.physics.conftest import TABLE1_RADIUS, follow_to_rest, make_params, random_states, run_batch, run_one

G = 9.81
R = TABLE1_RADIUS


def core_radius(n, r):
    """Arc centres' distance from the geometric centre: the core polygon keeps a - r."""
    return (R * math.cos(math.pi / n) - r) / math.cos(math.pi / n)


def arc_centres(n, r, x, y, phi, com=(0.0, 0.0)):
    """World positions (n x 2) of the arc centres of a die whose COM is at (x, y)."""
    angles = 2 * math.pi * np.arange(n) / n
    body = core_radius(n, r) * np.column_stack((np.cos(angles), np.sin(angles))) - np.asarray(com)
    c, s = math.cos(phi), math.sin(phi)
    return np.column_stack((x + c * body[:, 0] - s * body[:, 1], y + s * body[:, 0] + c * body[:, 1]))


# ---- geometry: rest height and barrier ---------------------------------------------------


@pytest.mark.parametrize("n", [3, 4, 6])
@pytest.mark.parametrize("ratio", [0.05, 0.3])
@pytest.mark.parametrize("com", [(0.0, 0.0), (0.12, -0.07)])
def test_rest_height_and_decision_barrier_from_geometry(n, ratio, com):
    """Lying on side k the COM is at the apothem (less d . u_k for a loaded die, u_k the side's
    outward normal); the side is decided just below g (min over its two arcs of |c - COM| + r)
    and not just above."""
    a = R * math.cos(math.pi / n)
    r = ratio * a
    d = (com[0] * a, com[1] * a)
    fpar, _ = make_params(sides=n, corner_radius=r, com_offset=d)
    body = arc_centres(n, r, 0.0, 0.0, 0.0, d)  # arc centres from the COM, body frame
    assert fpar[FP_RHO_MAX] == pytest.approx(np.hypot(*body.T).max() + r, rel=1e-14)
    for side in range(n):
        normal_angle = 2 * math.pi * (side + 0.5) / n
        height = a - (d[0] * math.cos(normal_angle) + d[1] * math.sin(normal_angle))
        assert rest_height(fpar, n, side) == pytest.approx(height, rel=1e-13)
        # on its side, flat: the side's outward normal points down
        phi = -math.pi / 2 - normal_angle
        barrier = G * (min(np.hypot(*body[side]), np.hypot(*body[(side + 1) % n])) + r)
        for factor, expected in ((1 - 1e-9, side), (1 + 1e-9, -1)):
            energy = factor * barrier
            speed = math.sqrt(2 * (energy - G * height))
            state = np.array([0.0, height, phi, speed, 0.0, 0.0])
            assert decided_side(state, fpar, n) == expected


# ---- flight: the first contact -------------------------------------------------------------


def first_touch(n, r, state, t_end, walls=None):
    """First time the die's support function, min over the arcs of (centre's distance) - r,
    crosses 0: dense samples of the closed-form flight, then brentq."""
    x0, y0, phi0, vx, vy, omega = state

    def gap(t):
        centres = arc_centres(n, r, x0 + vx * t, y0 + vy * t - 0.5 * G * t * t, phi0 + omega * t)
        distances = [centres[:, 1]]
        if walls is not None:
            distances += [walls + centres[:, 0], walls - centres[:, 0]]
        return np.min(distances) - r

    times = np.linspace(0.0, t_end, 200_001)
    gaps = np.array([gap(t) for t in times])
    i = np.flatnonzero(gaps < 0.0)[0]
    return brentq(gap, times[i - 1], times[i], xtol=1e-15, rtol=1e-15)


@pytest.mark.parametrize("n, ratio, state", [
    (4, 0.1, [0.0, 0.12, 0.3, 0.2, 0.0, 7.0]),
    (5, 0.25, [0.01, 0.08, -1.1, -0.4, 0.5, -23.0]),
    (3, 0.4, [0.0, 0.05, 2.0, 0.0, -0.3, 41.0]),
])
def test_first_contact_time_of_a_falling_rounded_die(n, ratio, state):
    r = ratio * R * math.cos(math.pi / n)
    _, _, _, _, rec, _ = run_one(make_params(sides=n, corner_radius=r), state)
    expected = first_touch(n, r, state, 0.4)
    assert rec[1, REC_T] == pytest.approx(expected, rel=1e-9, abs=1e-12)
    # the same throw with sharp corners touches earlier: the test can tell the two apart
    _, _, _, _, sharp, _ = run_one(make_params(sides=n), state)
    assert sharp[1, REC_T] < expected - 1e-6


def test_first_contact_time_against_a_wall():
    n, r, half = 4, 0.15 * R, 0.03
    state = [0.0, 0.1, 0.4, 1.5, 0.0, 5.0]  # flies to the right wall before it reaches the table
    _, _, _, _, rec, _ = run_one(make_params(sides=n, corner_radius=r, separation=2 * half), state)
    expected = first_touch(n, r, state, 0.2, walls=half)
    assert rec[1, REC_T] == pytest.approx(expected, rel=1e-9)


# ---- impact on the arc ---------------------------------------------------------------------


def rigid_impact_by_hand(v, omega, inertia, lever, normal, beta_n, beta_t):
    """Velocity after the rigid impulse at the contact point ``lever`` (from the COM) that sends
    its normal velocity to -beta_n u_n and its tangential to -beta_t u_t."""
    tangent = np.array([normal[1], -normal[0]])
    perp = np.array([-lever[1], lever[0]])  # z x lever
    u = v + omega * perp
    u_frame = np.array([u @ tangent, u @ normal])
    target = np.array([-beta_t * u_frame[0], -beta_n * u_frame[1]])
    basis = np.column_stack((tangent, normal))  # impulse = basis @ (p_t, p_n)
    # contact velocity change per unit impulse: K = B^T (1 + perp perp^T / I) B
    k = basis.T @ (np.eye(2) + np.outer(perp, perp) / inertia) @ basis
    p = np.linalg.solve(k, target - u_frame)
    impulse = basis @ p
    v_after = v + impulse
    omega_after = omega + (lever[0] * impulse[1] - lever[1] * impulse[0]) / inertia
    energy = 0.5 * (v_after @ v_after + inertia * omega_after**2) - 0.5 * (v @ v + inertia * omega**2)
    return v_after, omega_after, energy


@pytest.mark.parametrize("surf", [SURF_TABLE, SURF_LEFT])
def test_impact_on_the_arc_is_the_rigid_impulse_at_the_contact_point(surf):
    n, r, beta_n, beta_t = 4, 0.2 * R, 0.6, -0.35
    half = 0.05
    fpar, ipar = make_params(sides=n, corner_radius=r, model="rigid", beta_n=beta_n, beta_t=beta_t,
                             separation=2 * half)
    inertia = fpar[FP_INERTIA]
    phi, corner = 0.3, 2
    centre = arc_centres(n, r, 0.0, 0.0, phi)[corner]
    normal = np.array([0.0, 1.0]) if surf == SURF_TABLE else np.array([1.0, 0.0])
    # place the die with arc `corner` touching the surface
    if surf == SURF_TABLE:
        x, y = 0.0, r - centre[1]
    else:
        x, y = -half + r - centre[0], 0.05
    v = np.array([0.4, -1.2]) if surf == SURF_TABLE else np.array([-1.1, 0.3])
    omega = 9.0
    state = np.array([x, y, phi, v[0], v[1], omega])
    lever = centre - r * normal  # the contact point, r from the arc centre towards the surface
    v_exp, omega_exp, energy = rigid_impact_by_hand(v, omega, inertia, lever, normal, beta_n, beta_t)
    assert energy < 0.0  # no energy clip is involved: the target impulse itself
    counts = np.zeros(len(COUNT_COLUMNS), np.int32)
    resolve_impact(state, fpar, ipar, surf, corner, counts)
    assert state[3:5] == pytest.approx(v_exp, rel=1e-12, abs=1e-14)
    assert state[5] == pytest.approx(omega_exp, rel=1e-12)
    # the arc centre as the lever gives another answer: the test sees the difference
    v_centre, omega_centre, _ = rigid_impact_by_hand(v, omega, inertia, centre, normal, beta_n, beta_t)
    assert abs(omega_centre - omega_exp) > 1e-3 * abs(omega_exp)


# ---- the rolling pivot ---------------------------------------------------------------------


def rolling_rhs(rho, r, inertia):
    """Rolling without slip on an arc: L = J(chi) chi'^2 / 2 - g (r + rho sin chi) with
    J = I + |COM - contact|^2 = I + rho^2 + r^2 + 2 r rho sin chi, so
    J chi'' + (J'/2) chi'^2 + g rho cos chi = 0."""
    def rhs(_, y):
        chi, w = y
        j = inertia + rho**2 + r**2 + 2 * r * rho * math.sin(chi)
        dj = 2 * r * rho * math.cos(chi)
        return [w, -(0.5 * dj * w * w + G * rho * math.cos(chi)) / j]
    return rhs


@pytest.mark.parametrize("n, ratio, chi0, omega0", [
    (4, 0.2, math.pi / 2 + 0.1, -2.0),   # rocks up towards the top, turns back, falls flat
    (6, 0.4, math.pi / 2 - 0.2, 6.0),    # over the top and down the other side
])
def test_rolling_pivot_matches_the_lagrangian_and_keeps_its_energy(n, ratio, chi0, omega0):
    r = ratio * R * math.cos(math.pi / n)
    fpar, _ = make_params(sides=n, corner_radius=r)  # unlimited friction: rolling, no slip
    inertia = fpar[FP_INERTIA]
    rho = core_radius(n, r)
    half = math.pi / n
    chi_flat = (math.pi / 2 - half, math.pi / 2 + half)
    times = np.linspace(0.0, 0.06, 13)[1:]
    sol = solve_ivp(rolling_rhs(rho, r, inertia), (0.0, times[-1]), [chi0, omega0], rtol=1e-12, atol=1e-14,
                    t_eval=times, dense_output=True)
    out = np.zeros(5)
    hit = np.zeros(2, np.int64)

    def energy(chi, w):
        return 0.5 * (inertia + rho**2 + r**2 + 2 * r * rho * math.sin(chi)) * w * w + G * (r + rho * math.sin(chi))

    e0 = energy(chi0, omega0)
    compared = 0
    for t, chi_exp, w_exp in zip(times, *sol.y):
        if not chi_flat[0] < chi_exp < chi_flat[1]:
            break  # the next arc has landed
        kind = pivot_ode(fpar, n, 0, 0.0, chi0, omega0, 0.0, t, False, out, hit)
        assert kind == PIVOT_TIMEOUT and out[2] == t
        assert out[0] == pytest.approx(chi_exp, abs=1e-9)
        assert out[1] == pytest.approx(w_exp, abs=1e-8 * math.sqrt(G / R))
        assert out[3] == pytest.approx(-r * (out[0] - chi0), abs=1e-12)  # rolling: the centre moves by -r dchi
        assert out[4] == 0.0  # no slip
        assert energy(out[0], out[1]) == pytest.approx(e0, rel=1e-10)
        compared += 1
    assert compared >= 4


@pytest.mark.parametrize("chi0, omega0, slip0", [(math.pi / 2 + 0.2, -3.0, 0.2), (math.pi / 2 - 0.3, 4.0, -0.15)])
def test_sliding_pivot_on_an_arc_matches_newton_euler(chi0, omega0, slip0):
    """A rounded die sliding on an arc under Coulomb friction, against Newton-Euler equations of
    the whole body in Cartesian coordinates (solve_ivp): the normal force from the arc centre
    staying at height r, friction -sign(slip) mu N at the contact point r below it."""
    n, mu = 4, 0.3
    r = 0.2 * R * math.cos(math.pi / 4)
    fpar, _ = make_params(sides=n, corner_radius=r, model="rigid", friction=mu)
    inertia = fpar[FP_INERTIA]
    rho = core_radius(n, r)
    body = np.array([rho, 0.0])  # arc centre 0 from the COM (fair die), body frame
    direction = math.copysign(1.0, slip0)

    def parts(z):
        x, y, phi, vx, vy, w = z
        c, s = math.cos(phi), math.sin(phi)
        centre = np.array([c * body[0] - s * body[1], s * body[0] + c * body[1]])  # from the COM
        lever = centre - np.array([0.0, r])  # the contact point
        return centre, lever

    def rhs(_, z):
        x, y, phi, vx, vy, w = z
        centre, lever = parts(z)
        # (Y + centre_y)'' = 0 with Y'' = N - g, omega' = (l_x N - l_y F) / I, F = -direction mu N
        normal = (G + w * w * centre[1]) / (1.0 + centre[0] * (lever[0] + direction * mu * lever[1]) / inertia)
        friction = -direction * mu * normal
        return [vx, vy, w, friction, normal - G, (lever[0] * normal - lever[1] * friction) / inertia]

    # the COM state at the start: arc centre at (0, r), COM at rho e(chi0) from it
    vx0 = slip0 - omega0 * (rho * math.sin(chi0) + r)
    z0 = [rho * math.cos(chi0), r + rho * math.sin(chi0), chi0 - math.pi, vx0, omega0 * rho * math.cos(chi0), omega0]
    times = np.linspace(0.0, 0.02, 11)[1:]
    sol = solve_ivp(rhs, (0.0, times[-1]), z0, method="DOP853", rtol=1e-12, atol=1e-15, t_eval=times)
    out = np.zeros(5)
    hit = np.zeros(2, np.int64)
    energy = [0.5 * (vx0**2 + z0[4] ** 2 + inertia * omega0**2) + G * z0[1]]
    compared = 0
    for t, z in zip(times, sol.y.T):
        centre, lever = parts(z)
        slip = z[3] - z[5] * lever[1]
        if slip * direction <= 0.0 or abs(z[2] + math.pi - math.pi / 2) >= math.pi / 4:
            break  # the slip stopped, or the next arc landed: another phase
        kind = pivot_ode(fpar, n, 0, 0.0, chi0, omega0, slip0, t, False, out, hit)
        assert kind == PIVOT_TIMEOUT
        chi = math.atan2(-centre[1], -centre[0])  # the COM seen from the arc centre
        assert out[0] == pytest.approx(chi, abs=1e-9)
        assert out[1] == pytest.approx(z[5], abs=1e-8 * math.sqrt(G / R))
        assert out[3] == pytest.approx(z[0] + centre[0], abs=1e-11)  # the arc centre, from x = 0
        assert out[4] == pytest.approx(slip, abs=1e-9)
        energy.append(0.5 * (z[3] ** 2 + z[4] ** 2 + inertia * z[5] ** 2) + G * z[1])
        compared += 1
    assert compared >= 4
    assert np.all(np.diff(energy) < 0.0)  # friction only dissipates


def test_rolling_pivot_in_a_whole_roll_conserves_energy():
    """A rounded die tipped onto an arc with unlimited friction rolls (ODE pivot segments) and
    keeps its energy along each pivot; impacts only take energy away."""
    n, r = 4, 0.2 * R * math.cos(math.pi / 4)
    rho = core_radius(n, r)
    chi0, omega0 = math.pi / 2 + math.pi / 4 - 1e-6, -math.sqrt(0.9 * G / R)
    # COM state of a die rolling on arc 0 (arc centre at (0, r)), contact point at rest
    state = [rho * math.cos(chi0), r + rho * math.sin(chi0), chi0 + math.pi,
             -omega0 * (rho * math.sin(chi0) + r), omega0 * rho * math.cos(chi0), omega0]
    _, status, _, _, rec, _ = run_one(make_params(sides=n, corner_radius=r, beta_n=0.0, beta_t=0.0), state)
    assert status == STATUS_DECIDED
    assert np.any(rec[:, REC_KIND] == SEG_PIVOT_ODE)
    energy = rec[:, REC_ENERGY]
    assert np.all(np.diff(energy) <= 1e-10 * energy[:-1])


# ---- r -> 0 --------------------------------------------------------------------------------


def test_tiny_radius_is_close_to_sharp_corners(rng):
    states = random_states(rng, 400, y_range=(0.03, 0.1), omega_max=20.0)
    sharp = make_params(sides=5)
    tiny = make_params(sides=5, corner_radius=1e-9 * R)
    out_s, status_s, _, _ = run_batch(sharp, states)
    out_t, status_t, _, _ = run_batch(tiny, states)
    assert np.all(status_t == STATUS_DECIDED)
    assert np.mean(out_s == out_t) > 0.97  # chaos amplifies 1e-9 R near basin boundaries
    for state in states[:20]:
        _, _, _, _, rec_s, _ = run_one(sharp, state)
        _, _, _, _, rec_t, _ = run_one(tiny, state)
        # the first impacts: the same times and states to about r
        m = min(4, len(rec_s), len(rec_t))
        assert rec_t[1:m, REC_T] == pytest.approx(rec_s[1:m, REC_T], rel=1e-5)
        assert rec_t[1:m, REC_STATE:REC_STATE + 2] == pytest.approx(rec_s[1:m, REC_STATE:REC_STATE + 2], abs=1e-6 * R)


# ---- whole rolls ---------------------------------------------------------------------------


@pytest.mark.parametrize("kwargs", [
    dict(),
    dict(model="rigid", friction=0.4),
    dict(separation=0.07),
    dict(air_drag=0.05),
    dict(com_offset=(0.002, -0.001)),
    dict(method="fixed_step", dt=1e-4, t_max=10.0),
])
def test_random_rounded_rolls_end_decided_without_stalls(kwargs, rng):
    params = make_params(sides=4, corner_radius=0.15 * R, **kwargs)
    states = random_states(rng, 300)
    if "separation" in kwargs:
        states[:, 0] = rng.uniform(-0.015, 0.015, len(states))
    outcome, status, _, _ = run_batch(params, states)
    assert np.all(status == STATUS_DECIDED), np.bincount(status)
    assert np.all(outcome >= 0)


@pytest.mark.parametrize("model, friction, separation", [("paper", math.inf, None), ("rigid", 0.5, None),
                                                         ("rigid", math.inf, 0.07)])
def test_energy_never_rises_at_an_impact(model, friction, separation, rng):
    params = make_params(sides=5, corner_radius=0.2 * R, model=model, friction=friction, separation=separation,
                         beta_t=0.0 if model == "rigid" else -0.35)
    states = random_states(rng, 40, y_range=(0.03, 0.15))
    states[:, 0] = rng.uniform(-0.01, 0.01, len(states))
    for state in states:
        _, _, _, _, rec, _ = run_one(params, state)
        energy = rec[:, REC_ENERGY]
        assert np.all(np.diff(energy) <= 1e-10 * np.abs(energy[:-1]) + 1e-15)


def test_fair_rounded_square_gives_each_side_a_quarter(rng):
    states = random_states(rng, 4000, y_range=(0.05, 0.25), omega_max=60.0)
    outcome, status, _, _ = run_batch(make_params(sides=4, corner_radius=0.2 * R), states)
    assert np.all(status == STATUS_DECIDED)
    counts = np.bincount(outcome, minlength=4)
    assert chisquare(counts).pvalue > 1e-3, counts


def test_no_arc_ever_inside_the_table_or_a_wall(rng):
    """Sampled densely along event-driven paths, every arc centre stays at least r from the
    table and the walls, to round-off."""
    from dice_sweep.roll import roll_config, sample_path
    from tests.physics.conftest import make_config

    n, separation, r = 5, 0.07, 0.2 * R
    cfg = make_config(sides=n, beta_n=0.5, separation=separation, corner_radius=r)
    for state in random_states(rng, 10, y_range=(0.04, 0.12)):
        report = roll_config(cfg, state=state)
        times = np.linspace(0.0, report.t_end, 3000)
        path = sample_path(cfg, report, times)
        for x, y, phi in path[:, :3]:
            centres = arc_centres(n, r, x, y, phi)
            assert centres[:, 1].min() - r > -1e-9 * R
            assert np.abs(centres[:, 0]).max() + r < separation / 2 + 1e-9 * R


def test_continued_rounded_roll_comes_to_rest_on_the_decided_side(rng):
    """Followed past the decision (IP_CONTINUE, as a fit does), a rounded die comes to rest on
    the side decided, its centre at the apothem (which rounding keeps), no longer moving."""
    from dice_sweep.physics.kernel import side_below

    fpar, ipar = make_params(corner_radius=0.2 * R, t_max=3.0)
    stopped, final = follow_to_rest((fpar, ipar), random_states(rng, 30, y_range=(0.03, 0.15)))
    assert np.allclose(final[:, 1], R * math.cos(math.pi / 4), atol=1e-6)
    assert np.all(np.abs(final[:, 3:]) < 1e-3)
    assert [side_below(phi, fpar, 4) for phi in final[:, 2]] == list(stopped)


def test_no_stalls_for_any_sides_radius_and_friction():
    """The stall fuzz of tests/physics/test_stalls.py (half the starts flat and sliding, half
    dropped) with a random corner radius up to half the apothem: every roll ends decided. (Run
    by hand at 36,000 rolls, seed 3: all decided.)"""
    from tests.physics.test_stalls import fuzz_starts

    rng = np.random.default_rng(7)
    for sides in range(3, 21):
        for model in ("rigid", "paper"):
            apothem = R * math.cos(math.pi / sides)
            params = make_params(sides=sides, model=model, beta_n=float(rng.uniform(0.05, 0.8)),
                                 beta_t=float(rng.uniform(-0.8, 0.8)), corner_radius=float(rng.uniform(0.0, 0.5)) * apothem,
                                 friction=float(rng.uniform(0.05, 2.0)) if model == "rigid" else math.inf)
            _, status, _, _ = run_batch(params, fuzz_starts(rng, 40, sides))
            assert np.all(status == STATUS_DECIDED), (sides, model, np.bincount(status))
