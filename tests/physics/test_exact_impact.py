"""Friction rules of the rigid law: "exact" (physics/exact_impact.py) and "sliding".

The exact impact is checked against an independent calculation written here: scipy's
solve_ivp integrating the contact point's velocity over the normal impulse, du/dp_n = K (f, 1),
regime by regime (slide, stick), with event detection for the slip stopping, the end of
compression and the terminal impulse (Newton or energetic), small steps. Then the invariants:
no energy gain, pushing and separating, mu = 0 frictionless, large mu sticking, slip reversal,
Newton's energy gain replaced and counted; the sliding rule against the aimed rule; two
contacts (the integration itself: test_two_contact_exact.py); whole rolls.
"""

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.integrate import solve_ivp

from dice_sweep.physics.exact_impact import exact_impulse
from dice_sweep.physics.flight import SURF_LEFT, SURF_RIGHT, SURF_TABLE, surface_frame
from dice_sweep.physics.impact import corner_impulse, corner_normal_velocity, corner_vector, exact_corner_impulse, resolve_impact
from dice_sweep.physics.kernel import REC_ENERGY, REC_EVENT, STATUS_DECIDED, STATUS_STALLED
from dice_sweep.physics.layout import C_CLIPS, EVENT_IMPACT
from dice_sweep.physics.multi_contact import resolve_two_contacts
from dice_sweep.physics.params import FP_INERTIA
from dice_sweep.physics.two_contact_exact import compliant_two_contacts
from tests.physics.conftest import TABLE1_RADIUS, corner_impacts, make_params, random_states, run_one

R = TABLE1_RADIUS
N_COUNTS = 6


# --- the independent reference -------------------------------------------------------------
def reference_impact(u_t, u_n, k, beta_n, mu, energetic, with_compression_end=False):
    """Impulse (p_t, p_n) of the exact impact by numerical integration over p_n (scipy)."""
    k_tt, k_tn, k_nn = k[0, 0], k[0, 1], k[1, 1]
    y = np.array([u_t, u_n, 0.0, 0.0, 0.0])  # u_t, u_n, p_t, compression work, restitution work
    compressing = True
    target = -beta_n * u_n
    p = 0.0
    stick = False
    direction = float(np.sign(u_t))
    scale = abs(u_n) / k_nn
    u_t_at_compression_end = math.nan
    for _ in range(10):
        if direction == 0.0 and not stick:
            if abs(k_tn) <= mu * k_tt:
                stick = True
            else:
                direction = float(np.sign(k_tn))
        f = -k_tn / k_tt if stick else -mu * direction

        def rhs(_, y, f=f, stick=stick, compressing=compressing):
            return [0.0 if stick else k_tt * f + k_tn, k_tn * f + k_nn, f,
                    y[1] if compressing else 0.0, 0.0 if compressing else y[1]]

        def compression_end(_, y):
            return y[1]

        def terminal(_, y):
            return y[4] + beta_n**2 * y[3] if energetic else y[1] - target

        def slip_stops(_, y):
            return y[0]

        compression_end.terminal = terminal.terminal = slip_stops.terminal = True
        compression_end.direction = terminal.direction = 1
        slip_stops.direction = -direction  # the slip stopping, not leaving zero
        if not compressing and terminal(0, y) >= 0:
            break
        events = [compression_end if compressing else terminal]
        if not stick and direction != 0.0:
            events.append(slip_stops)
        sol = solve_ivp(rhs, (p, p + 100 * scale), y, events=events, rtol=1e-12,
                        atol=1e-14 * (1 + abs(u_n) + abs(u_t)), max_step=scale / 200)
        p = sol.t[-1]
        y = sol.y[:, -1].copy()
        if len(sol.t_events[0]):
            if not compressing:
                break
            compressing = False
            y[1] = 0.0
            u_t_at_compression_end = y[0]
            continue
        assert len(sol.t_events) > 1 and len(sol.t_events[1]), "the reference found no event"
        y[0] = 0.0
        direction = 0.0
    if with_compression_end:
        return y[2], p, u_t_at_compression_end
    return y[2], p


def mass_matrix(inertia, a_t, a_n):
    """K per unit mass for r_perp components a_t, a_n (r_perp = z x r)."""
    return np.array([[1 + a_t * a_t / inertia, a_t * a_n / inertia], [a_t * a_n / inertia, 1 + a_n * a_n / inertia]])


def energy_change(u, k, p):
    return float(p @ u + 0.5 * p @ k @ p)


def random_contact(rng):
    inertia = rng.uniform(0.1, 1.0)  # m^2 per unit corner distance 1
    ang = rng.uniform(-math.pi, 0.0)
    k = mass_matrix(inertia, -math.sin(ang), math.cos(ang))
    return k, rng.uniform(-2, 2), -rng.uniform(0.05, 2)


def kernel(u_t, u_n, k, beta_n, mu, energetic):
    return exact_impulse(u_t, u_n, k[0, 0], k[0, 1], k[1, 1], beta_n, mu, energetic)


# --- single contact against the reference --------------------------------------------------
@pytest.mark.parametrize("energetic", [False, True])
def test_exact_impact_matches_the_integrated_ode(energetic):
    """200 random contacts (geometry, slip, friction 0.05 to 3, beta_normal 0 to 1): the
    closed-form phases equal solve_ivp's integration to 1e-9 of the speed."""
    rng = np.random.default_rng(2026 + energetic)
    compared = 0
    for _ in range(200):
        k, u_t, u_n = random_contact(rng)
        mu = float(rng.choice([0.05, 0.1, 0.3, 0.8, 3.0]))
        beta_n = rng.uniform(0, 1)
        p_t, p_n, clipped = kernel(u_t, u_n, k, beta_n, mu, energetic)
        if clipped:
            continue  # Newton's gain replaced: tested below
        ref_t, ref_n = reference_impact(u_t, u_n, k, beta_n, mu, energetic)
        scale = abs(u_t) + abs(u_n)
        assert abs(p_t - ref_t) <= 1e-9 * scale and abs(p_n - ref_n) <= 1e-9 * scale
        compared += 1
    assert compared > 150


def test_energetic_restitution_balances_the_work_of_the_normal_impulse():
    """Stronge's law, checked on the kernel's own impulse: integrating u_n dp_n along the
    phases the reference sees, restitution work = beta^2 |compression work|; and without friction
    it leaves at beta |u_n| like Newton's."""
    k = mass_matrix(0.3, 0.8, -0.6)
    p_t, p_n, clipped = kernel(0.0, -1.0, k, 0.6, 0.0, True)
    assert clipped == 0 and p_t == 0.0
    u_n_after = -1.0 + k[1, 1] * p_n
    assert u_n_after == pytest.approx(0.6, rel=1e-12)


def test_frictionless_is_the_purely_normal_impulse():
    rng = np.random.default_rng(5)
    for _ in range(50):
        k, u_t, u_n = random_contact(rng)
        beta_n = rng.uniform(0, 1)
        for energetic in (False, True):
            p_t, p_n, _ = kernel(u_t, u_n, k, beta_n, 0.0, energetic)
            assert p_t == 0.0
            assert p_n == pytest.approx(-(1 + beta_n) * u_n / k[1, 1], rel=1e-12)


@pytest.mark.parametrize("mu", [5.0, 50.0, math.inf])
def test_large_friction_sticks_by_the_end_of_compression(mu):
    """With mu above the stick ratio and the slip stopped early, u_t = 0 at the end of
    compression (the reference) and after the impact (the kernel); mu = inf is the limit."""
    rng = np.random.default_rng(7)
    for _ in range(40):
        k, u_t, u_n = random_contact(rng)
        u_t *= 0.1  # a slip that friction stops within the compression
        assert abs(k[0, 1] / k[0, 0]) <= 5.0
        p_t, p_n, clipped = kernel(u_t, u_n, k, 0.5, mu, False)
        u = np.array([u_t, u_n]) + k @ np.array([p_t, p_n])
        assert abs(u[0]) <= 1e-12 * (abs(u_t) + abs(u_n))
        assert u[1] >= 0.0
        if not math.isinf(mu):
            *_, u_t_end = reference_impact(u_t, u_n, k, 0.5, mu, False, with_compression_end=True)
            assert abs(u_t_end) <= 1e-9
    # mu = inf is the limit of a growing mu
    k, u_t, u_n = random_contact(np.random.default_rng(8))
    at_inf = np.array(kernel(u_t, u_n, k, 0.5, math.inf, True)[:2])
    near = np.array(kernel(u_t, u_n, k, 0.5, 1e9, True)[:2])
    assert np.allclose(at_inf, near, rtol=1e-6, atol=1e-9)


def test_slip_reversal_of_a_steep_corner():
    """A slender rod (I = L^2 / 3 per unit mass) striking with its end at 30 degrees to the
    table: |K_tn / K_tt| exceeds mu = 0.2, so a slip against sign(K_tn) stops and reverses; the
    kernel agrees with the reference and the corner leaves slipping the other way."""
    half = 1.0
    inertia = half * half / 3
    ang = math.radians(30)
    rx, ry = -half * math.cos(ang), -half * math.sin(ang)
    k = mass_matrix(inertia, -ry, rx)
    ratio = k[0, 1] / k[0, 0]
    assert abs(ratio) > 0.2
    u_t = -math.copysign(0.1, ratio)
    for energetic in (False, True):
        p_t, p_n, clipped = kernel(u_t, -1.0, k, 0.5, 0.2, energetic)
        u_after = np.array([u_t, -1.0]) + k @ np.array([p_t, p_n])
        assert math.copysign(1, u_after[0]) == math.copysign(1, ratio) and abs(u_after[0]) > 1e-3
        if not clipped:
            ref = reference_impact(u_t, -1.0, k, 0.5, 0.2, energetic)
            assert np.allclose([p_t, p_n], ref, rtol=1e-9, atol=1e-12)
    # with mu above the ratio the same impact sticks instead
    p_t, p_n, _ = kernel(u_t, -1.0, k, 0.5, 1.01 * abs(ratio), True)
    assert abs(u_t + k[0, 0] * p_t + k[0, 1] * p_n) < 1e-12


def test_newton_energy_gain_is_replaced_by_the_energetic_impulse_and_counted():
    """Newton's law with friction can gain energy (the reference shows it for some state);
    the kernel then uses the energetic terminal impulse, returns a clip, and gains nothing."""
    rng = np.random.default_rng(13)
    found = 0
    for _ in range(3000):
        k, u_t, u_n = random_contact(rng)
        mu, beta_n = float(rng.choice([0.1, 0.3, 1.0])), rng.uniform(0.7, 1.0)
        u = np.array([u_t, u_n])
        p_t, p_n, clipped = kernel(u_t, u_n, k, beta_n, mu, False)
        assert energy_change(u, k, np.array([p_t, p_n])) <= 1e-12 * u @ u
        if clipped:
            found += 1
            assert energy_change(u, k, np.array(reference_impact(u_t, u_n, k, beta_n, mu, False))) > 0
            assert (p_t, p_n) == kernel(u_t, u_n, k, beta_n, mu, True)[:2]
    assert found > 0
    # through resolve_impact the replacement is counted as an energy clip
    fpar, ipar = make_params(sides=4, model="rigid", beta_n=1.0, friction=0.3, friction_rule="exact")
    counts = np.zeros(N_COUNTS, np.int32)
    for _ in range(2000):
        s = np.array([0.0, 0.1, rng.uniform(-math.pi, math.pi), *rng.uniform(-2, 2, 2), rng.uniform(-100, 100)])
        corner = int(rng.integers(4))
        if corner_normal_velocity(s, *corner_vector(s, fpar, corner), 0.0, 1.0) < 0:
            resolve_impact(s, fpar, ipar, SURF_TABLE, corner, counts)
    assert counts[C_CLIPS] > 0


# --- through resolve_impact: every surface, loaded dice, both laws -------------------------
state_strategy = st.tuples(st.floats(-math.pi, math.pi), st.floats(-3.0, 3.0), st.floats(-3.0, 3.0), st.floats(-80.0, 80.0))


@settings(max_examples=400, deadline=None)
@given(state=state_strategy, sides=st.integers(3, 20), beta_n=st.floats(0.0, 1.0),
       surf=st.sampled_from([SURF_TABLE, SURF_LEFT, SURF_RIGHT]), corner=st.integers(0, 19),
       model=st.sampled_from(["paper", "rigid"]), rule=st.sampled_from(["sliding", "exact"]),
       restitution=st.sampled_from(["newton", "energetic"]),
       friction=st.sampled_from([math.inf, 0.0, 0.1, 0.5, 2.0]),
       offset=st.tuples(st.floats(-0.004, 0.004), st.floats(-0.004, 0.004)))
def test_no_impact_gains_energy_pulls_or_keeps_approaching(state, sides, beta_n, surf, corner, model, rule,
                                                          restitution, friction, offset):
    corner %= sides
    fpar, ipar = make_params(sides=sides, radius=0.0134, beta_n=beta_n, separation=0.2, model=model,
                             friction=friction, com_offset=offset, friction_rule=rule, restitution=restitution)
    phi, vx, vy, omega = state
    s = np.array([0.0, 0.1, phi, vx, vy, omega])
    nx, ny, _ = surface_frame(surf, 0.1)
    rx, ry = corner_vector(s, fpar, corner)
    u_n = corner_normal_velocity(s, rx, ry, nx, ny)
    if u_n >= 0.0:
        return
    inertia = fpar[FP_INERTIA]
    before = 0.5 * (vx * vx + vy * vy + inertia * omega * omega)
    v_before = s[3:].copy()
    u_after = resolve_impact(s, fpar, ipar, surf, corner, np.zeros(N_COUNTS, np.int32))
    assert 0.5 * (s[3] ** 2 + s[4] ** 2 + inertia * s[5] ** 2) <= before * (1 + 1e-12) + 1e-15
    assert u_after >= -1e-12 * (1 + abs(vx) + abs(vy) + 0.0134 * abs(omega))
    p_n = nx * (s[3] - v_before[0]) + ny * (s[4] - v_before[1])  # the normal impulse pushes
    assert p_n >= -1e-12 * (1 + abs(vx) + abs(vy))


def test_exact_corner_impulse_applies_the_impulse_in_the_surface_frame():
    """The left wall is the mirror image of the right one under the exact rule too."""
    inertia = 0.3 * R * R
    right = np.array([0.09, 0.05, 0.3, 1.2, -0.4, 7.0])
    left = np.array([-0.09, 0.05, math.pi - 0.3, -1.2, -0.4, -7.0])
    for energetic in (False, True):
        a, b = right.copy(), left.copy()
        nx, ny, _ = surface_frame(SURF_RIGHT, 0.1)
        exact_corner_impulse(a, inertia, 0.5, 0.3, energetic, 0.8 * R, -0.6 * R, nx, ny)
        nx, ny, _ = surface_frame(SURF_LEFT, 0.1)
        exact_corner_impulse(b, inertia, 0.5, 0.3, energetic, -0.8 * R, -0.6 * R, nx, ny)
        assert np.allclose([-b[3], b[4], -b[5]], a[3:], rtol=1e-13)


# --- the sliding rule against the aimed rule -----------------------------------------------
def test_sliding_rule_differs_from_aimed_only_where_the_normal_impulse_throws_the_corner_back():
    """Same impulse unless the target leaves the cone on the side of the incoming slip (the
    case impact.py's docstring describes); there, unclipped, P_t = -sign(u_t) mu P_n."""
    inertia = R * R / 3
    mu = 0.3
    differ = 0
    for s, rx, ry in corner_impacts(np.random.default_rng(11), 3000, R):
        target, aimed, sliding = s.copy(), s.copy(), s.copy()
        corner_impulse(target, inertia, 0.2, 0.0, math.inf, rx, ry, 0.0, 1.0)
        corner_impulse(aimed, inertia, 0.2, 0.0, mu, rx, ry, 0.0, 1.0, False)
        clipped = corner_impulse(sliding, inertia, 0.2, 0.0, mu, rx, ry, 0.0, 1.0, True)
        p_target_t, p_target_n = target[3] - s[3], target[4] - s[4]
        u_t = s[3] - s[5] * ry
        outside = p_target_n <= 0 or abs(p_target_t) > mu * p_target_n
        if not outside or math.copysign(1, p_target_t) == -math.copysign(1, u_t):
            assert np.array_equal(aimed, sliding)
            continue
        differ += 1
        assert not np.array_equal(aimed, sliding)
        if not clipped:
            p_t, p_n = sliding[3] - s[3], sliding[4] - s[4]
            assert p_t == pytest.approx(-math.copysign(mu * p_n, u_t), rel=1e-9)
    assert differ > 0


# --- two contacts ---------------------------------------------------------------------------
def flat_state(sides, v_t, v_n, omega, tilt=0.0):
    """Side 0 flat on the table (plus ``tilt``), centre at the apothem."""
    phi = -math.pi / 2 - math.pi / sides + tilt
    return np.array([0.0, R * math.cos(math.pi / sides), phi, v_t, v_n, omega])


@pytest.mark.parametrize("rule", ["sliding", "exact"])
@pytest.mark.parametrize("restitution", ["newton", "energetic"])
def test_two_contact_rules_never_gain_energy_or_leave_a_contact_approaching(rule, restitution):
    rng = np.random.default_rng(17)
    for _ in range(300):
        sides = int(rng.integers(3, 9))
        friction = float(rng.choice([0.0, 0.2, 0.6, math.inf]))
        fpar, ipar = make_params(sides=sides, model="rigid", beta_n=rng.uniform(0, 1), friction=friction,
                                 friction_rule=rule, restitution=restitution)
        s = flat_state(sides, rng.uniform(-1, 1), -rng.uniform(0.1, 2), rng.uniform(-30, 30), rng.uniform(-1e-7, 1e-7))
        corners = [(SURF_TABLE, 0), (SURF_TABLE, 1)]
        us = [corner_normal_velocity(s, *corner_vector(s, fpar, c), 0.0, 1.0) for _, c in corners]
        if max(us) >= 0:
            continue
        before = s.copy()
        counts = np.zeros(N_COUNTS, np.int32)
        assert resolve_two_contacts(s, fpar, ipar, SURF_TABLE, 0, SURF_TABLE, 1, 1.0, counts)
        inertia = fpar[FP_INERTIA]
        kin = lambda v: 0.5 * (v[3] ** 2 + v[4] ** 2 + inertia * v[5] ** 2)  # noqa: E731
        assert kin(s) <= kin(before) * (1 + 1e-12)
        for _, c in corners:
            assert corner_normal_velocity(s, *corner_vector(s, fpar, c), 0.0, 1.0) >= -1e-9


def test_two_contact_sliding_opposes_the_slip_and_exact_sticks():
    """A flat landing while sliding: with small friction both rules slide, the shared tangential
    impulse opposing the slip at mu times the normal impulse (per unit mass, dv_x = -mu dv_y;
    the sliding rule's enumeration also keeps Newton's u_n' at both corners); with large
    friction the exact rule leaves the side's midpoint stuck (u_t' = 0)."""
    sides, v_t, v_n = 4, 0.8, -1.0
    for rule in ("sliding", "exact"):
        fpar, ipar = make_params(sides=sides, model="rigid", beta_n=0.4, friction=0.2, friction_rule=rule)
        s = flat_state(sides, v_t, v_n, 0.0)
        assert resolve_two_contacts(s, fpar, ipar, SURF_TABLE, 0, SURF_TABLE, 1, 1.0, np.zeros(N_COUNTS, np.int32))
        if rule == "sliding":
            assert s[4] == pytest.approx(0.4, rel=1e-12)
            assert s[5] == pytest.approx(0.0, abs=1e-9)
        assert s[3] - v_t == pytest.approx(-0.2 * (s[4] - v_n), rel=1e-9)
    fpar, ipar = make_params(sides=sides, model="rigid", beta_n=0.4, friction=2.0, beta_t=0.5, friction_rule="exact")
    s = flat_state(sides, 0.3, v_n, 0.0)
    assert resolve_two_contacts(s, fpar, ipar, SURF_TABLE, 0, SURF_TABLE, 1, 1.0, np.zeros(N_COUNTS, np.int32))
    apothem = R * math.cos(math.pi / sides)
    assert s[3] + s[5] * apothem == pytest.approx(0.0, abs=1e-4)  # the midpoint below the centre


@pytest.mark.parametrize("restitution", ["newton", "energetic"])
def test_two_contact_exact_is_one_contacts_exact_impact_when_the_other_is_never_pressed(restitution):
    """A hexagon landing flat with spin, one corner receding: when the compliant two-contact
    integration never compresses it (physics/two_contact_exact.py, checked against a plain integrator in
    test_two_contact_exact.py), the answer is the other corner's exact impact (the solve_ivp
    reference here, applied with plain numpy), with the config's restitution law."""
    rng = np.random.default_rng(23)
    sides, beta_n, mu = 6, 0.5, 0.3
    fpar, ipar = make_params(sides=sides, model="rigid", beta_n=beta_n, friction=mu, friction_rule="exact",
                             restitution=restitution)
    energetic = restitution == "energetic"
    inertia = fpar[FP_INERTIA]
    matched = 0
    for _ in range(60):
        s = flat_state(sides, rng.uniform(-1, 1), -rng.uniform(0.2, 1), 0.0)
        s[5] = rng.uniform(-4, 4) * abs(s[4]) / (0.5 * R)  # often one corner recedes
        r = [np.array(corner_vector(s, fpar, c)) for c in (0, 1)]
        u = [np.array([s[3] - s[5] * ri[1], s[4] + s[5] * ri[0]]) for ri in r]
        if min(ui[1] for ui in u) >= 0:
            continue
        contacts = np.array([[0.0, 1.0, *r[0]], [0.0, 1.0, *r[1]]])
        loaded = np.zeros(2, np.bool_)
        assert compliant_two_contacts(s[3:].copy(), inertia, mu, contacts, np.array([beta_n, beta_n]), True, loaded)
        after = s.copy()
        assert resolve_two_contacts(after, fpar, ipar, SURF_TABLE, 0, SURF_TABLE, 1, 1.0, np.zeros(N_COUNTS, np.int32))
        if loaded.all():
            continue
        i = 0 if loaded[0] else 1
        k = mass_matrix(inertia, -r[i][1], r[i][0])
        p_t, p_n = reference_impact(u[i][0], u[i][1], k, beta_n, mu, energetic)
        if energy_change(u[i], k, np.array([p_t, p_n])) > 0:
            continue  # Newton's gain: the kernel would clip; not this test's case
        v = s[3:].copy() + [p_t, p_n, (r[i][0] * p_n - r[i][1] * p_t) / inertia]
        j = 1 - i
        if v[1] + v[2] * r[j][0] < 0:
            continue  # the closed form leaves the other corner approaching: the integration stands
        scale = abs(s[3]) + abs(s[4]) + R * abs(s[5])
        assert np.allclose(after[3:5], v[:2], atol=1e-9 * scale) and R * abs(after[5] - v[2]) <= 1e-9 * scale
        matched += 1
    assert matched > 5


# --- whole rolls ----------------------------------------------------------------------------
@pytest.mark.parametrize("rule,restitution,friction,model,method", [
    ("exact", "newton", 0.3, "rigid", "event"), ("exact", "energetic", 0.3, "rigid", "event"),
    ("exact", "newton", math.inf, "rigid", "event"), ("exact", "energetic", 1.0, "rigid", "event"),
    ("exact", "newton", 0.3, "paper", "event"), ("exact", "energetic", 0.3, "rigid", "fixed_step"),
    ("sliding", "newton", 0.3, "rigid", "event"), ("sliding", "newton", 1.0, "rigid", "event"),
    ("sliding", "newton", 0.3, "paper", "event"),
])
def test_whole_rolls_are_decided_and_energy_never_rises_at_an_impact(rule, restitution, friction, model, method, rng):
    """Pentagons thrown between walls: every roll is decided (none stalls, none runs out of
    time or events) and the energy recorded after each event never rises."""
    params = make_params(sides=5, model=model, friction=friction, separation=0.08, method=method, dt=1e-4,
                         friction_rule=rule, restitution=restitution)
    states = random_states(rng, 40, y_range=(0.03, 0.15))
    states[:, 0] = rng.uniform(-0.02, 0.02, 40)
    impacts = 0
    for state in states:
        outcome, status, _, _, rec, counts = run_one(params, state)
        assert status == STATUS_DECIDED and status != STATUS_STALLED and outcome >= 0
        energy = rec[:, REC_ENERGY]
        assert np.all(np.diff(energy) <= 1e-12 * np.abs(energy[:-1]) + 1e-15)
        impacts += int(np.sum(rec[:, REC_EVENT] == EVENT_IMPACT))
    assert impacts > 0
