"""Pivot phase in closed form: time integral, lift-off, events."""

import math

import numpy as np
import pytest

from dice_sweep.physics.kernel import REC_KIND, REC_STATE, SEG_PIVOT, SEG_PIVOT_ODE
from dice_sweep.roll import roll_config, sample_path
from tests.physics.conftest import TABLE1_RADIUS, make_config, make_params, run_one
from dice_sweep.physics import pivot
from dice_sweep.physics.pivot import (
    PIVOT_FLAT,
    PIVOT_LIFTOFF,
    PIVOT_TIMEOUT,
    PIVOT_WALL,
    carlson_rf,
    liftoff_factor,
    omega_squared,
    pivot_angle_at,
    pivot_energy,
    pivot_next,
    flat_angles,
    pivot_ode,
    pivot_ode_flat,
    pivot_time,
)

R, G, ALPHA = 0.0134, 9.81, 1.0 / 3.0


def quadrature_time(chi_a, chi_b, e, points=200_001):
    chi = np.linspace(chi_a, chi_b, points)
    inv = 1.0 / np.sqrt(omega_squared_np(chi, e))
    h = (chi_b - chi_a) / (points - 1)
    return abs(h / 3 * (inv[0] + inv[-1] + 4 * inv[1:-1:2].sum() + 2 * inv[2:-1:2].sum()))


def omega_squared_np(chi, e):
    return 2 * (e - G * R * np.sin(chi)) / (R * R * (1 + ALPHA))


def test_carlson_rf_reference_values():
    # R_F(1, 2, 0) = 1.3110287771461 (Carlson 1995, Table 1); R_F(x, x, x) = 1/sqrt(x)
    assert math.isclose(carlson_rf(1.0, 2.0, 0.0), 1.3110287771461, rel_tol=1e-12)
    assert math.isclose(carlson_rf(4.0, 4.0, 4.0), 0.5, rel_tol=1e-14)


@pytest.mark.parametrize("excess", [1.5, 1.01, 1.0 + 1e-6])
def test_pivot_time_matches_quadrature_and_is_fast_near_the_top(excess, monkeypatch):
    """Closed form = Simpson on a fine grid, including energies just above the top (where an
    adaptive quadrature once took seconds per call). What made it fast is counted, not timed:
    the time is two evaluations of Carlson's R_F, each a few duplication steps (at most 12 of
    its 200) however close the energy is to the top."""
    e = G * R * excess
    chi_a, chi_b = math.pi / 4, 3 * math.pi / 4 - 0.1
    exact = pivot_time(chi_a, chi_b, e, R, G, ALPHA)
    steps = []  # duplication steps of each R_F evaluation

    def counted_range(*args):
        steps.append(0)
        for i in range(*args):
            steps[-1] += 1
            yield i

    # the same functions run as Python (numba's py_func), with the loop of carlson_rf counted
    monkeypatch.setattr(pivot, "carlson_rf", carlson_rf.py_func)
    monkeypatch.setattr(pivot, "half_angle_integral", pivot.half_angle_integral.py_func)
    monkeypatch.setattr(pivot, "range", counted_range, raising=False)
    assert math.isclose(pivot_time.py_func(chi_a, chi_b, e, R, G, ALPHA), exact, rel_tol=1e-14)
    assert len(steps) == 2 and max(steps) <= 12, steps
    monkeypatch.undo()
    if excess > 1.001:
        assert math.isclose(exact, quadrature_time(chi_a, chi_b, e), rel_tol=1e-9)
    else:
        assert np.isfinite(exact) and exact > quadrature_time(chi_a, chi_b, G * R * 1.01)
    assert math.isclose(pivot_time(chi_b, chi_a, e, R, G, ALPHA), exact, rel_tol=1e-14)


def test_liftoff_factor_sign_is_the_released_corner_acceleration():
    """q(sin chi) < 0 exactly where omega^2 R sin(chi) > g."""
    rng = np.random.default_rng(5)
    for _ in range(500):
        chi = rng.uniform(math.pi / 4, 3 * math.pi / 4)
        omega = rng.uniform(-60, 60)
        e = pivot_energy(chi, omega, R, G, ALPHA)
        released = G - omega**2 * R * math.sin(chi)
        q = liftoff_factor(math.sin(chi), e, R, G, ALPHA)
        assert math.copysign(1, q) == math.copysign(1, released) or abs(released) < 1e-9


FPAR, _ = make_params(sides=4, radius=R)


def test_pivot_reaches_the_next_corner_and_time_inverts():
    out = np.zeros(3)
    hit = np.zeros(2, np.int64)
    # square, rolling right over the top (e > g R), slow enough never to lift off
    chi0, omega0 = math.pi / 2 + 0.5, -14.0
    kind = pivot_next(FPAR, 4, 0, 0.0, chi0, omega0, out, hit)
    assert kind == PIVOT_FLAT and hit[1] == 1
    assert math.isclose(out[0], math.pi / 4, rel_tol=1e-14)
    e = pivot_energy(chi0, omega0, R, G, ALPHA)
    assert math.isclose(out[1] ** 2, omega_squared(out[0], e, R, G, ALPHA), rel_tol=1e-12)
    half = pivot_angle_at(chi0, omega0, 0.5 * out[2], R, G, ALPHA, out[0])
    assert math.isclose(pivot_time(chi0, half, e, R, G, ALPHA), 0.5 * out[2], rel_tol=1e-9)


def test_fast_pivot_lifts_off_where_the_corner_would_leave():
    out = np.zeros(3)
    hit = np.zeros(2, np.int64)
    # just before the top, R omega^2 sin(chi) slightly below g; past the top omega grows
    # faster than sin(chi) falls, so the released corner would leave part-way down
    chi0, omega0 = math.pi - math.asin(0.99), -math.sqrt(730.0)
    assert omega0**2 * R * 0.99 < G
    kind = pivot_next(FPAR, 4, 0, 0.0, chi0, omega0, out, hit)
    assert kind == PIVOT_LIFTOFF
    assert out[0] < math.pi / 2 and out[2] > 0.0
    assert math.isclose(out[1] ** 2 * R * math.sin(out[0]), G, rel_tol=1e-9)


# ---- the contact ODE (pivot_ode): sliding, drag, events ------------------------------------

T_UNIT = math.sqrt(R / G)
MU = 0.3
INERTIA = ALPHA * R * R


def contact_rates(mode, y, mu=MU, drag=0.0):
    """Rates of (chi, omega, xp, up), normal force and friction (per unit mass), written
    again from the equations of docs/physics.md (sticking: mode 0, sliding: +-1)."""
    chi, w, _, up = y
    sc, cc = math.sin(chi), math.cos(chi)
    vx, vy = up - w * R * sc, w * R * cc
    speed = math.hypot(vx, vy)
    dx, dy = -drag * speed * vx, -drag * speed * vy
    if mode == 0:
        dw = (R * cc * (dy - G) - R * sc * dx) / (INERTIA + R * R)
        normal = G - dy + R * (cc * dw - sc * w * w)
        return [w, dw, 0.0, 0.0], normal, -R * (sc * dw + cc * w * w) - dx
    lever = cc + mode * mu * sc
    normal = (G - dy - R * w * w * sc) / (1 + R * R / INERTIA * cc * lever)
    dw = -R / INERTIA * normal * lever
    return [w, dw, up, -mode * mu * normal + dx + R * (sc * dw + cc * w * w)], normal, -mode * mu * normal


def reference_pivot(chi0, w0, slip0, mu=MU, drag=0.0):
    """The pivot to its flat side or lift-off by scipy's DOP853 at rtol 1e-13, phase by phase
    with the friction transitions of pivot_ode. Returns (time, state, 'flat' or 'lift')."""
    from scipy.integrate import solve_ivp

    y, t = np.array([chi0, w0, 0.0, slip0], float), 0.0
    mode = 0 if slip0 == 0.0 else int(math.copysign(1, slip0))
    for _ in range(20):
        def flat(_, y):
            return (y[0] - math.pi / 4) * (3 * math.pi / 4 - y[0])

        if mode == 0:
            def change(_, y):  # slip starts
                _, normal, friction = contact_rates(0, y, mu, drag)
                return abs(friction) - mu * normal

            def lift(_, y):  # a released corner would leave
                chi, w = y[0], y[1]
                return w * w * R * math.sin(chi) - G - drag * R * abs(w) * w * R * math.cos(chi)
        else:
            def change(_, y, mode=mode):  # slip stops (not the round-off of a slip starting at 0)
                return mode * y[3] + 1e-15

            def lift(_, y, mode=mode):
                return -contact_rates(mode, y, mu, drag)[1]
        for event in (flat, change, lift):
            event.terminal = True
        sol = solve_ivp(lambda _, y, mode=mode: contact_rates(mode, y, mu, drag)[0], (0.0, 1.0), y,
                        method="DOP853", rtol=1e-13, atol=1e-16, events=(flat, change, lift))
        tau, which = min((te[0], i) for i, te in enumerate(sol.t_events) if te.size)
        y, t = sol.y_events[which][0].copy(), t + tau
        if which != 1:
            return t, y, ("flat", "", "lift")[which]
        if mode == 0:
            mode = 1 if contact_rates(0, y, mu, drag)[2] < 0 else -1
        else:
            y[3] = 0.0
            _, normal, friction = contact_rates(0, y, mu, drag)
            mode = 0 if abs(friction) <= mu * normal else -mode
    raise AssertionError("no end in 20 phases")


# (chi0, omega0 / sqrt(g/R), slip0 m/s): a slide that stops, sticks and slides again before
# the flat side; one that slides all the way; one that slips backwards first; one off the top.
SLIDING_CASES = [(3 * math.pi / 4 - 0.01, -0.7, 0.1), (3 * math.pi / 4 - 0.01, -0.7, 0.3),
                 (3 * math.pi / 4 - 0.2, -0.3, -0.05), (math.pi / 2, 0.3, 0.2)]


@pytest.mark.parametrize("drag", [0.0, 0.5])
@pytest.mark.parametrize("chi0, w0, slip0", SLIDING_CASES)
def test_sliding_pivot_ode_matches_a_tight_scipy_reference(chi0, w0, slip0, drag):
    """Slip, stick, slip again and the flat side, with and without drag: the event time to
    1e-10 sqrt(R/g) and the state to 1e-10 of its scales (measured: about 1e-13)."""
    fpar, _ = make_params(sides=4, radius=R, model="rigid", beta_t=0.0, friction=MU, air_drag=drag)
    w0 *= 1.0 / T_UNIT
    t_ref, y_ref, end = reference_pivot(chi0, w0, slip0, drag=drag)
    out = np.zeros(5)
    hit = np.zeros(2, np.int64)
    kind = pivot_ode(fpar, 4, 0, 0.0, chi0, w0, slip0, 10.0, False, out, hit)
    assert kind == {"flat": PIVOT_FLAT, "lift": PIVOT_LIFTOFF}[end]
    assert abs(out[2] - t_ref) < 1e-10 * T_UNIT
    assert abs(out[0] - y_ref[0]) < 1e-10
    assert abs(out[1] - y_ref[1]) < 1e-10 / T_UNIT
    assert abs(out[3] - y_ref[2]) < 1e-10 * R
    assert abs(out[4] - y_ref[3]) < 1e-10 * R / T_UNIT


def contact_energy(chi, w, up):
    vx, vy = up - w * R * math.sin(chi), w * R * math.cos(chi)
    return 0.5 * (vx * vx + vy * vy) + 0.5 * INERTIA * w * w + G * R * math.sin(chi)


@pytest.mark.parametrize("drag", [0.0, 0.5])
def test_pivot_ode_energy_never_increases_and_timeouts_stop_on_time(drag):
    """Sampled at 200 times through a slide-stick-slide pivot (pivot_ode stopped by t_left,
    as sample_records does), the energy never increases beyond round-off and the time
    returned is t_left exactly."""
    fpar, _ = make_params(sides=4, radius=R, model="rigid", beta_t=0.0, friction=MU, air_drag=drag)
    chi0, w0, slip0 = 3 * math.pi / 4 - 0.01, -0.7 / T_UNIT, 0.1
    out = np.zeros(5)
    hit = np.zeros(2, np.int64)
    assert pivot_ode(fpar, 4, 0, 0.0, chi0, w0, slip0, 10.0, False, out, hit) == PIVOT_FLAT
    energy = []
    for tau in np.linspace(0.0, out[2], 201)[1:-1]:
        assert pivot_ode(fpar, 4, 0, 0.0, chi0, w0, slip0, tau, False, out, hit) == PIVOT_TIMEOUT
        assert out[2] == tau
        energy.append(contact_energy(out[0], out[1], out[4]))
    energy = np.array(energy)
    assert np.all(np.diff(energy) <= 1e-13 * energy[:-1])
    assert energy[-1] < energy[0] * (1 - 1e-3)  # friction did take some


@pytest.mark.parametrize("mu", [math.inf, 0.5, 2.0])
def test_closed_form_sticking_path_equals_the_ode(mu):
    """Drag-free sticking pivots take the exact path (closed form, events located in chi); a
    drag of 1e-300 sends the same pivots through the Runge-Kutta steps instead. Same event,
    same corner, time and state to 1e-11 of their scales, over random starts that include
    slip onsets, lift-offs and rocking dice below the top (turning points)."""
    rng = np.random.default_rng(7)
    kinds = set()
    for _ in range(60):
        chi0 = rng.uniform(math.pi / 4, 3 * math.pi / 4)
        w0 = rng.uniform(-2.0, 2.0) / T_UNIT
        results = []
        for drag in (0.0, 1e-300):
            fpar, _ = make_params(sides=4, radius=R, model="rigid", beta_t=0.0, friction=mu, air_drag=drag)
            out = np.zeros(5)
            hit = np.zeros(2, np.int64)
            kind = pivot_ode(fpar, 4, 0, 0.0, chi0, w0, 0.0, 10.0, False, out, hit)
            results.append((kind, tuple(hit), out.copy()))
        (kind_cf, hit_cf, cf), (kind_ode, hit_ode, ode) = results
        assert kind_cf == kind_ode
        if kind_cf == PIVOT_FLAT:
            assert hit_cf == hit_ode
        kinds.add(kind_cf)
        assert abs(cf[2] - ode[2]) < 1e-11 * T_UNIT
        assert abs(cf[0] - ode[0]) < 1e-11
        assert abs(cf[1] - ode[1]) < 1e-11 / T_UNIT
        assert abs(cf[3] - ode[3]) < 1e-11 * R
        assert abs(cf[4] - ode[4]) < 1e-11 * R / T_UNIT
    assert PIVOT_FLAT in kinds and PIVOT_LIFTOFF in kinds


# ---- drag-free slides in closed form (issue 33): the same pivots as the Runge-Kutta steps -----

LONG = np.longdouble


def slide_rates_in_chi(chi, y, mode, mu):
    """d/dchi of (omega, t, xp, up) of a slide, in extended precision, from the sliding
    equations of contact_rates (chi is the independent variable: the flat angle is exact)."""
    w, _, _, up = y
    sc, cc = np.sin(chi), np.cos(chi)
    lever = cc + mode * mu * sc
    normal = (LONG(G) - LONG(R) * w * w * sc) / (1 + LONG(R) * LONG(R) / LONG(INERTIA) * cc * lever)
    dw = -LONG(R) / LONG(INERTIA) * normal * lever
    dup = -mode * mu * normal + LONG(R) * (sc * dw + cc * w * w)
    return np.array([dw / w, 1 / w, up / w, dup / w])


def extended_slide(chi0, w0, slip0, chi1, mu, steps):
    """(omega, t, xp, up) at chi1 of a slide that stays sliding: classic Runge-Kutta in chi
    with ``steps`` steps in long double, then with twice as many, Richardson-extrapolated."""
    mode = 1 if slip0 > 0 else -1
    results = []
    for n in (steps, 2 * steps):
        y = np.array([LONG(w0), LONG(0), LONG(0), LONG(slip0)])
        h = (LONG(chi1) - LONG(chi0)) / n
        for i in range(n):
            chi = LONG(chi0) + i * h
            k1 = slide_rates_in_chi(chi, y, mode, LONG(mu))
            k2 = slide_rates_in_chi(chi + h / 2, y + h / 2 * k1, mode, LONG(mu))
            k3 = slide_rates_in_chi(chi + h / 2, y + h / 2 * k2, mode, LONG(mu))
            k4 = slide_rates_in_chi(chi + h, y + h * k3, mode, LONG(mu))
            y = y + h / 6 * (k1 + 2 * k2 + 2 * k3 + k4)
        results.append(y)
    coarse, fine = results
    return (fine + (fine - coarse) / 15).astype(float), np.abs((fine - coarse).astype(float))


# (chi0, omega0 / sqrt(g/R), slip0 m/s, mu): slides that keep sliding to the flat side
PURE_SLIDES = [(3 * math.pi / 4 - 0.01, -0.7, 0.3, 0.3), (math.pi / 4 + 0.02, 1.0, -0.4, 0.5),
               (math.pi / 2, -0.5, 0.3, 0.2)]


@pytest.mark.parametrize("chi0, w0, slip0, mu", PURE_SLIDES)
def test_drag_free_slide_is_as_accurate_as_an_extended_precision_reference(chi0, w0, slip0, mu):
    """A slide from start to flat side: the closed form (no drag) and the Runge-Kutta steps
    (drag 1e-300) against classic Runge-Kutta in chi in long double. The closed form is within
    1e-14 of the die's scales and no further off than the steps (measured: about 1e-16 against
    2e-14 to 1e-13); the two differ, so both paths ran."""
    w0 /= T_UNIT
    got = {}
    for drag in (0.0, 1e-300):
        fpar, _ = make_params(sides=4, radius=R, model="rigid", beta_t=0.0, friction=mu, air_drag=drag)
        out = np.zeros(5)
        hit = np.zeros(2, np.int64)
        assert pivot_ode(fpar, 4, 0, 0.0, chi0, w0, slip0, 10.0, False, out, hit) == PIVOT_FLAT
        got[drag] = out.copy()
    assert got[0.0][0] in pivot.flat_angles(fpar, 4, 0)
    reference, change = extended_slide(chi0, w0, slip0, got[0.0][0], mu, 1000)
    scale = np.array([1 / T_UNIT, T_UNIT, R, R / T_UNIT])
    assert np.all(change / scale < 1e-10)  # fourth order: the extrapolation is far closer still
    errors = {drag: np.abs(out[1:] - reference) / scale for drag, out in got.items()}
    assert errors[0.0].max() < 1e-14
    assert errors[0.0].max() <= errors[1e-300].max()
    assert not np.array_equal(got[0.0], got[1e-300])

# (chi0, omega0 / sqrt(g/R), slip0 m/s, mu): slides whose normal force reaches 0 on the way
SLIDES_LIFTING_OFF = [(0.947347200235578, 1.0923927455840365, 0.785847134604919, 0.5),
                      (2.2646906778345395, -1.0465503045132682, 0.20820524901453097, 0.5)]


def test_drag_free_slides_with_transitions_match_the_reference():
    """Random slides (mu 0.2 to 1) that stop and stick, slip again, land on the next corner or
    lift off where the normal force reaches 0, in closed form, against the phase-by-phase
    DOP853 reference: the same end, time and state to 1e-11 of their scales. Energy is never
    gained and, at a lift-off, the normal force is 0 to 1e-12 g."""
    rng = np.random.default_rng(11)
    starts = [(rng.uniform(math.pi / 4, 3 * math.pi / 4), rng.uniform(-2.0, 2.0),
               rng.choice([rng.uniform(-1.0, 1.0), rng.uniform(-1e-4, 1e-4)]), rng.choice([0.2, 0.5, 1.0]))
              for _ in range(40)]
    starts += SLIDES_LIFTING_OFF
    ends = set()
    for chi0, w0, slip0, mu in starts:
        w0 /= T_UNIT
        fpar, _ = make_params(sides=4, radius=R, model="rigid", beta_t=0.0, friction=mu)
        out = np.zeros(5)
        hit = np.zeros(2, np.int64)
        kind = pivot_ode(fpar, 4, 0, 0.0, chi0, w0, slip0, 10.0, False, out, hit)
        if kind == PIVOT_LIFTOFF and out[2] == 0.0:
            continue  # lifts off at once: the reference does not test its start
        t_ref, y_ref, end = reference_pivot(chi0, w0, slip0, mu=mu)
        assert kind == {"flat": PIVOT_FLAT, "lift": PIVOT_LIFTOFF}[end]
        ends.add(end)
        assert abs(out[2] - t_ref) < 1e-11 * T_UNIT
        assert abs(out[0] - y_ref[0]) < 1e-11
        assert abs(out[1] - y_ref[1]) < 1e-11 / T_UNIT
        assert abs(out[3] - y_ref[2]) < 1e-11 * R
        assert abs(out[4] - y_ref[3]) < 1e-11 * R / T_UNIT
        start = contact_energy(chi0, w0, slip0)
        assert contact_energy(out[0], out[1], out[4]) <= start * (1 + 1e-14)
        if kind == PIVOT_LIFTOFF and out[4] != 0.0:
            mode = 1 if out[4] > 0.0 else -1
            assert abs(contact_rates(mode, [out[0], out[1], out[3], out[4]], mu)[1]) < 1e-12 * G
    assert ends == {"flat", "lift"}



def test_drag_free_slide_towards_a_wall_meets_it_as_the_ode_does():
    """A pentagon's corner sliding at 0.5 m/s towards a wall it is out of reach of at the
    start: the closed form must not slide past the wall. Same event (a wall), corner, time and
    state as the Runge-Kutta steps (drag 1e-300) to 1e-11 of their scales. (A closed form that
    checked the wall's reach only at the start turned a pentagon of
    tests/physics/test_exact_impact.py's whole rolls into an event-budget loop.)"""
    start = (0.009990919970697534, 1.698134923860578, -13.359627846184317, 0.5266553590131222)
    got = []
    for drag in (0.0, 1e-300):
        fpar, _ = make_params(sides=5, model="rigid", friction=0.3, separation=0.08, friction_rule="sliding", air_drag=drag)
        out = np.zeros(5)
        hit = np.zeros(2, np.int64)
        got.append((pivot_ode(fpar, 5, 4, *start, 10.0, True, out, hit), tuple(hit), out.copy()))
    (kind_cf, hit_cf, cf), (kind_ode, hit_ode, ode) = got
    assert kind_cf == kind_ode == PIVOT_WALL and hit_cf == hit_ode
    t_unit = math.sqrt(TABLE1_RADIUS / G)
    assert abs(cf[2] - ode[2]) < 1e-11 * t_unit
    assert abs(cf[0] - ode[0]) < 1e-11
    assert abs(cf[1] - ode[1]) < 1e-11 / t_unit
    assert abs(cf[3] - ode[3]) < 1e-11 * TABLE1_RADIUS
    assert abs(cf[4] - ode[4]) < 1e-11 * TABLE1_RADIUS / t_unit

def test_pivot_ode_flat_is_pivot_ode_given_the_flat_angles():
    """The roll loop passes each corner's flat angles (kept per corner) and pivot_ode_flat takes
    its scratch in one allocation: the same pivots, bit for bit, as pivot_ode, on slides that
    stop and stick, slip again, land or lift off (a loaded die's corners: flat angles that differ
    from corner to corner). Run in a row, so that a call could only see its own scratch."""
    rng = np.random.default_rng(5)
    fpar, _ = make_params(sides=5, model="rigid", beta_t=0.0, friction=0.5, com_offset=(0.002, -0.001))
    for _ in range(20):
        corner = int(rng.integers(5))
        chi0 = rng.uniform(math.pi / 4, 3 * math.pi / 4)
        args = (fpar, 5, corner, 0.0, chi0, rng.uniform(-2.0, 2.0) / T_UNIT, rng.choice([0.0, rng.uniform(-0.3, 0.3)]), 10.0, True)
        got = []
        for flats in (None, flat_angles(fpar, 5, corner)):
            out = np.zeros(5)
            hit = np.zeros(2, np.int64)
            kind = pivot_ode(*args, out, hit) if flats is None else pivot_ode_flat(*args, *flats, out, hit)
            got.append((kind, tuple(hit), out.tobytes()))
        assert got[0] == got[1]


# --- pivots with friction, in whole rolls (issue 4) ----------------------------------------------


def test_sticking_pivot_ode_matches_the_closed_form():
    """A huge but finite friction sends pivots through the ODE path; they must reproduce the
    closed-form (elliptic) pivot: same transfers, same omega after each, to 1e-7."""
    sides = 6
    chi0 = math.pi / 2 + math.pi / sides - 1e-6
    omega0 = -math.sqrt(0.5 * G / TABLE1_RADIUS)
    state = [TABLE1_RADIUS * math.cos(chi0), TABLE1_RADIUS * math.sin(chi0), chi0 + math.pi,
             omega0 * -TABLE1_RADIUS * math.sin(chi0), omega0 * TABLE1_RADIUS * math.cos(chi0), omega0]
    exact = run_one(make_params(sides=sides, beta_n=0.0, beta_t=0.0), state)
    ode = run_one(make_params(sides=sides, beta_n=0.0, beta_t=0.0, friction=1e6), state)
    assert exact[0] == ode[0]
    assert math.isclose(exact[2], ode[2], rel_tol=1e-7)  # time of decision
    w_exact = exact[4][exact[4][:, REC_KIND] == SEG_PIVOT, REC_STATE + 5]
    w_ode = ode[4][ode[4][:, REC_KIND] == SEG_PIVOT_ODE, REC_STATE + 5]
    assert len(w_ode) == len(w_exact) >= 2  # the transfers happen at the same corners
    assert np.allclose(w_ode, w_exact, rtol=1e-7)  # with omega after each transfer


def test_low_friction_lets_a_pivoting_corner_slide():
    """A square rolling over a corner: with unlimited friction the corner stays put while the
    die turns about it; with mu = 0.05 it slides."""
    chi0 = math.pi / 2 + math.pi / 4 - 1e-6
    omega0 = -math.sqrt(0.7 * G / TABLE1_RADIUS)  # over the top, no lift-off (as in the rolling test)
    state = [TABLE1_RADIUS * math.cos(chi0), TABLE1_RADIUS * math.sin(chi0), chi0 + math.pi,
             omega0 * -TABLE1_RADIUS * math.sin(chi0), omega0 * TABLE1_RADIUS * math.cos(chi0), omega0]
    drift = {}
    for friction in (math.inf, 0.05):
        cfg = make_config(model="rigid", beta_t=0.0, friction=friction)
        report = roll_config(cfg, state=state)
        path = sample_path(cfg, report, np.linspace(0.0, 0.01, 11))
        corner_x = path[:, 0] + TABLE1_RADIUS * np.cos(path[:, 2])  # corner 0, the pivot
        drift[friction] = np.ptp(corner_x)
    assert drift[math.inf] < 1e-9
    assert drift[0.05] > 1e-5
