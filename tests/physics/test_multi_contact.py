"""Two contacts at once (issue 15): flat landings and flat wall hits as one impact.

Properties of dice_sweep/physics/multi_contact.py, checked on states built here with plain
numpy: a flat impact without spin or slip leaves without spin, for every n, both laws and every
surface; flat impacts are exact mirror images; no impact gains energy or leaves a contact
approaching; the frictionless case equals an independent quadratic-programme solution; and
whole rolls keep the side that was down, at tilt 0 and at tilts inside the contact window.
"""

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.optimize import minimize

from dice_sweep.physics.params import FP_INERTIA
from dice_sweep.physics.multi_contact import resolve_two_contacts, second_contact
from dice_sweep.physics.params import FP_INERTIA
from tests.physics.conftest import TABLE1_RADIUS, make_params, run_batch, run_one

R = TABLE1_RADIUS
SURF_TABLE, SURF_LEFT, SURF_RIGHT = 0, 1, 2
N_COUNTS = 6


def corner_vectors(sides, phi, com=(0.0, 0.0), radius=R):
    """Corners (m) seen from the centre of mass, body offset ``com`` (plain numpy)."""
    angles = phi + 2 * np.pi * np.arange(sides) / sides
    c, s = math.cos(phi), math.sin(phi)
    ox, oy = c * com[0] - s * com[1], s * com[0] + c * com[1]
    return np.stack([radius * np.cos(angles) - ox, radius * np.sin(angles) - oy], axis=1)


def flat_angle(sides, side, surface):
    """phi that puts ``side`` flat against ``surface`` (its outward normal along -n)."""
    outward = {SURF_TABLE: -math.pi / 2, SURF_LEFT: math.pi, SURF_RIGHT: 0.0}[surface]
    return outward - math.pi / sides - 2 * math.pi * side / sides


def impact(params, state, contacts):
    """Apply the two-contact impact to a copy of the centre-of-mass ``state``."""
    fpar, ipar = params
    s = np.array(state, float)
    counts = np.zeros(N_COUNTS, np.int32)
    (sa, ca), (sb, cb) = contacts
    assert resolve_two_contacts(s, fpar, ipar, sa, ca, sb, cb, 1.0, counts)
    return s, counts


def normal_velocity(s, r, normal):
    return normal[0] * (s[3] - s[5] * r[1]) + normal[1] * (s[4] + s[5] * r[0])


NORMALS = {SURF_TABLE: (0.0, 1.0), SURF_LEFT: (1.0, 0.0), SURF_RIGHT: (-1.0, 0.0)}


@pytest.mark.parametrize("sides", [3, 4, 5, 6, 8, 20])
@pytest.mark.parametrize("model", ["paper", "rigid"])
@pytest.mark.parametrize("surface", [SURF_TABLE, SURF_LEFT, SURF_RIGHT])
@pytest.mark.parametrize("friction", [0.0, 0.4, math.inf])
def test_flat_impact_without_spin_or_slip_leaves_without_spin(sides, model, surface, friction):
    params = make_params(sides=sides, model=model, beta_n=0.5, beta_t=-0.35, friction=friction, separation=0.2)
    side = sides // 3
    phi = flat_angle(sides, side, surface)
    normal = NORMALS[surface]
    speed = 1.3  # m/s, towards the surface
    state = [0.0, 0.05, phi, -speed * normal[0], -speed * normal[1], 0.0]
    after, _ = impact(params, state, ((surface, side), (surface, (side + 1) % sides)))
    assert abs(after[5]) <= 1e-12 * speed / R
    # the centre leaves along the normal at beta_normal times its approach speed
    assert after[3] * normal[0] + after[4] * normal[1] == pytest.approx(0.5 * speed, rel=1e-12)
    assert abs(after[3] * normal[1] - after[4] * normal[0]) <= 1e-12 * speed


@settings(max_examples=200, deadline=None)
@given(
    sides=st.integers(3, 12),
    side=st.integers(0, 11),
    surface=st.sampled_from([SURF_TABLE, SURF_LEFT, SURF_RIGHT]),
    model=st.sampled_from(["paper", "rigid"]),
    friction=st.sampled_from([0.0, 0.1, 0.5, 2.0, math.inf]),
    beta_t=st.floats(-1.0, 1.0),
    v_t=st.floats(-2.0, 2.0),
    omega=st.floats(-30.0, 30.0),
)
def test_flat_impacts_are_exact_mirror_images(sides, side, surface, model, friction, beta_t, v_t, omega):
    """x -> -x, vx -> -vx, omega -> -omega, phi -> pi - phi: corner k -> corner -k, side k ->
    side n-1-k, the left wall -> the right wall. The impact of the mirror is the mirror of the
    impact to round-off."""
    side %= sides
    params = make_params(sides=sides, model=model, beta_n=0.4, beta_t=beta_t, friction=friction, separation=0.2)
    phi = flat_angle(sides, side, surface)
    normal = NORMALS[surface]
    tangent = (normal[1], -normal[0])
    speed = 1.0 + R * abs(omega)  # both corners approach
    v = [-speed * normal[0] + v_t * tangent[0], -speed * normal[1] + v_t * tangent[1]]
    state = [0.0, 0.05, phi, v[0], v[1], omega]
    mirror = [0.0, 0.05, math.pi - phi, -v[0], v[1], -omega]
    mirror_surface = {SURF_TABLE: SURF_TABLE, SURF_LEFT: SURF_RIGHT, SURF_RIGHT: SURF_LEFT}[surface]
    a, b = side, (side + 1) % sides
    after, _ = impact(params, state, ((surface, a), (surface, b)))
    after_m, _ = impact(params, mirror, ((mirror_surface, (-b) % sides), (mirror_surface, (-a) % sides)))
    scale = speed + R * abs(omega)
    assert after_m[3] == pytest.approx(-after[3], abs=1e-12 * scale)
    assert after_m[4] == pytest.approx(after[4], abs=1e-12 * scale)
    assert R * after_m[5] == pytest.approx(-R * after[5], abs=1e-12 * scale)


def _two_contact_state(draw_phi, sides, com, kind, vx, vy, omega):
    """A COM state with two contacts: a flat side (tilted by up to 1e-6 rad) on the table, or
    the lowest corner on the table and the leftmost on the left wall. Returns (state,
    contacts, separation)."""
    if kind == "flat":
        phi = flat_angle(sides, 0, SURF_TABLE) + draw_phi * 1e-6
        corners = corner_vectors(sides, phi, com)
        y = -min(corners[0, 1], corners[1, 1])
        return [0.0, y, phi, vx, vy, omega], ((SURF_TABLE, 0), (SURF_TABLE, 1)), 0.5
    phi = draw_phi * math.pi
    corners = corner_vectors(sides, phi, com)
    low = int(np.argmin(corners[:, 1]))
    left = int(np.argmin(corners[:, 0]))
    if low == left:
        return None
    half_width = -corners[left, 0]  # the centre at x = 0, the wall through the leftmost corner
    return [0.0, -corners[low, 1], phi, vx, vy, omega], ((SURF_TABLE, low), (SURF_LEFT, left)), 2 * half_width


@settings(max_examples=300, deadline=None)
@given(
    sides=st.integers(3, 10),
    kind=st.sampled_from(["flat", "corner"]),
    draw_phi=st.floats(-1.0, 1.0),
    model=st.sampled_from(["paper", "rigid"]),
    beta_n=st.floats(0.0, 1.0),
    beta_t=st.floats(-1.0, 1.0),
    friction=st.sampled_from([0.0, 0.05, 0.3, 1.0, 2.0, math.inf]),
    com=st.tuples(st.floats(-0.3, 0.3), st.floats(-0.3, 0.3)),
    vx=st.floats(-3.0, 0.0),
    vy=st.floats(-3.0, -0.05),
    omega=st.floats(-40.0, 40.0),
)
def test_no_two_contact_impact_gains_energy_or_leaves_a_contact_approaching(sides, kind, draw_phi, model, beta_n, beta_t, friction, com, vx, vy, omega):
    com = (com[0] * R * math.cos(math.pi / sides), com[1] * R * math.cos(math.pi / sides))
    built = _two_contact_state(draw_phi, sides, com, kind, vx, vy, omega)
    if built is None:
        return
    state, contacts, separation = built
    params = make_params(sides=sides, model=model, beta_n=beta_n, beta_t=beta_t, friction=friction, separation=separation, com_offset=com)
    fpar, _ = params
    inertia = fpar[FP_INERTIA]  # I / M about the centre of mass
    corners = corner_vectors(sides, state[2], com)
    before = [normal_velocity(np.array(state), corners[k], NORMALS[surf]) for surf, k in contacts]
    if max(before) >= 0.0:
        return  # the law is for approaching contacts
    after, _ = impact(params, state, contacts)
    energy = lambda s: 0.5 * (s[3] ** 2 + s[4] ** 2 + inertia * s[5] ** 2)  # noqa: E731
    scale = energy(np.array(state))
    assert energy(after) <= scale * (1 + 1e-12)
    for surf, k in contacts:
        assert normal_velocity(after, corners[k], NORMALS[surf]) >= -1e-9 * math.sqrt(2 * scale)


@settings(max_examples=100, deadline=None)
@given(
    sides=st.integers(3, 10),
    kind=st.sampled_from(["flat", "corner"]),
    draw_phi=st.floats(-1.0, 1.0),
    beta_n=st.floats(0.0, 1.0),
    vx=st.floats(-3.0, 0.0),
    vy=st.floats(-3.0, -0.05),
    omega=st.floats(-40.0, 40.0),
)
def test_frictionless_impact_equals_an_independent_quadratic_programme(sides, kind, draw_phi, beta_n, vx, vy, omega):
    """Without friction, Newton's law at two contacts is the linear complementarity problem
    p >= 0, w = u + K p + beta u >= 0, p . w = 0 (u the approach velocities, K the contact
    mass matrix), i.e. min p.K p / 2 + (1 + beta) u . p over p >= 0, solved here by scipy."""
    built = _two_contact_state(draw_phi, sides, (0.0, 0.0), kind, vx, vy, omega)
    if built is None:
        return
    state, contacts, separation = built
    params = make_params(sides=sides, model="rigid", beta_n=beta_n, beta_t=0.0, friction=0.0, separation=separation)
    inertia = params[0][FP_INERTIA]
    corners = corner_vectors(sides, state[2], (0.0, 0.0))
    jac = np.array([[*NORMALS[surf], -corners[k, 1] * NORMALS[surf][0] + corners[k, 0] * NORMALS[surf][1]] for surf, k in contacts])
    u = jac @ np.array(state[3:])
    if u.max() >= 0.0:
        return
    mass_inv = np.diag([1.0, 1.0, 1.0 / inertia])
    k_mat = jac @ mass_inv @ jac.T
    q = (1 + beta_n) * u
    best = minimize(lambda p: 0.5 * p @ k_mat @ p + q @ p, np.zeros(2), jac=lambda p: k_mat @ p + q,
                    bounds=[(0, None)] * 2, method="L-BFGS-B", options={"ftol": 1e-15, "gtol": 1e-13})
    expected = np.array(state[3:]) + mass_inv @ jac.T @ best.x
    after, _ = impact(params, state, contacts)
    scale = math.hypot(vx, vy) + R * abs(omega)
    assert np.allclose(after[3:5], expected[:2], atol=1e-7 * scale)
    assert R * after[5] == pytest.approx(R * expected[2], abs=1e-7 * scale)


def test_second_contact_is_found_within_the_window_only():
    """A square landing at 1 m/s tilted by theta: its second corner arrives after about
    S theta / (1 m/s), S = sqrt(2) R the side; the default 1e-6 s window takes it up to
    theta = 1e-6 / S = 5.3e-5 rad."""
    sides = 4
    fpar, ipar = make_params(sides=sides)
    side_length = math.sqrt(2) * R
    for tilt, joins in [(0.0, True), (1e-9, True), (-1e-9, True), (3e-5, True), (8e-5, False)]:
        phi = flat_angle(sides, 0, SURF_TABLE) + tilt
        corners = corner_vectors(sides, phi)
        first = int(np.argmin(corners[:, 1]))
        state = np.array([0.0, -corners[first, 1], phi, 0.0, -1.0, 0.0])
        surf, corner, _ = second_contact(state, fpar, sides, 1, SURF_TABLE, first, 1e-6, 1e-12 * R, 1e-9)
        assert (corner >= 0) == joins, (tilt, side_length * abs(tilt))
        if joins:
            assert (surf, corner) == (SURF_TABLE, 1 - first)


FLAT_SIDE = 0


@pytest.mark.parametrize("sides", [3, 4, 5, 6, 8, 12, 20])
@pytest.mark.parametrize("model", ["paper", "rigid"])
def test_flat_drop_lands_on_the_side_that_was_down(sides, model):
    """Dropped exactly flat, without spin or horizontal speed, from 5 cm, and tilted by tilts
    inside the window: it bounces flat and stays on that side (issue 15: a rigid hexagon
    used to end on side 5 after 20 impacts; pymunk says side 0). With walls too."""
    for separation in (None, 0.2):
        params = make_params(sides=sides, model=model, beta_n=0.5, beta_t=-0.35, friction=0.8, separation=separation)
        tilts = [0.0, 1e-9, -1e-9, 1e-8, -1e-8]
        states = np.zeros((len(tilts), 6))
        states[:, 1] = 0.05
        states[:, 2] = [flat_angle(sides, FLAT_SIDE, SURF_TABLE) + t for t in tilts]
        outcome, status, counts, _ = run_batch(params, states)
        assert (status == 0).all()
        assert (outcome == FLAT_SIDE).all(), (separation, outcome)
        assert (counts[:, 5] >= 1).all()  # multi_contacts
        # after the first impact the die has no spin
        _, _, _, _, rec, _ = run_one(params, states[0])
        assert abs(rec[1, 2 + 5]) <= 1e-9 * 1.0 / R


def _wall_map(params, tilt, mirrored=False, num=16):
    """The issue's flat wall hit: a pentagon with side 2 vertical (phi0 = 0) thrown sideways
    between walls 0.2 m apart, y0 in [0.02, 0.10] m against vx0 in [-1, 1] m/s."""
    ys, vxs = np.meshgrid(np.linspace(0.02, 0.10, num), np.linspace(-1.0, 1.0, num), indexing="ij")
    states = np.zeros((num * num, 6))
    states[:, 1] = ys.ravel()
    states[:, 3] = -vxs.ravel() if mirrored else vxs.ravel()
    states[:, 2] = math.pi - tilt if mirrored else tilt
    return run_batch(params, states)


@pytest.mark.parametrize("model", ["paper", "rigid"])
def test_flat_wall_hits_are_continuous_in_tilt_and_mirror_symmetric(model):
    """Outcomes at phi0 = 0 and +-1e-9 used to differ in 11 of 12 rows; now none does, and
    the mirror-image throws land on the mirror-image sides."""
    params = make_params(sides=5, model=model, beta_n=0.3, beta_t=0.0, friction=0.4, separation=0.2)
    flat, status, counts, _ = _wall_map(params, 0.0)
    assert (status == 0).all()
    assert (counts[:, 5] > 0).sum() >= 15  # the map is full of flat wall hits (20 of 256)
    for tilt in (1e-9, -1e-9):
        assert np.array_equal(_wall_map(params, tilt)[0], flat), tilt
    mirrored = _wall_map(params, 0.0, mirrored=True)[0]
    assert np.array_equal(mirrored, 4 - flat)


def _after_first_impact(**kwargs):
    """COM state just after the first impact of a square landing tilted by 1e-3 rad at
    about 1 m/s (the second corner arrives about S * 1e-3 / (1 m/s) = 1.9e-5 s later)."""
    params = make_params(sides=4, model="rigid", beta_n=0.4, beta_t=0.0, friction=0.5, **kwargs)
    state = [0.0, 0.06, flat_angle(4, 0, SURF_TABLE) + 1e-3, 0.2, 0.0, 0.0]
    _, _, _, _, rec, counts = run_one(params, state)
    return rec[1, 2:8], counts


def test_flat_landing_effect_shares_the_impact_linearly_in_the_delay():
    """The flat_landing effect: a second corner arriving a delay d after the first, with
    d inside the contact time T, gives the two-contact impulse the share 1 - d/T. Checked
    between the single-contact impact (T = 0) and the whole two-contact one (a window that
    takes the delay): the share measured at one T predicts the share at another, and the
    delay it implies is the geometric one."""
    single, counts_single = _after_first_impact()
    both, counts_both = _after_first_impact(window=1e-3)
    assert counts_single[5] == 0 and counts_both[5] >= 1
    assert abs(both[5] - single[5]) > 1.0  # rad/s: the two laws differ
    shares = {}
    for contact_time in (4e-5, 1e-4):
        blended, _ = _after_first_impact(contact_time=contact_time)
        share = (blended[5] - single[5]) / (both[5] - single[5])
        # all three velocities are the same blend
        assert np.allclose(blended[3:5], single[3:5] + share * (both[3:5] - single[3:5]), atol=1e-12)
        shares[contact_time] = share
    delay = 4e-5 * (1 - shares[4e-5])
    assert shares[1e-4] == pytest.approx(1 - delay / 1e-4, abs=1e-9)
    side, speed = math.sqrt(2) * R, math.sqrt(2 * 9.81 * (0.06 - R / math.sqrt(2)))
    assert delay == pytest.approx(side * math.sin(1e-3) / speed, rel=0.05)
    # no effect when the contact time is shorter than the delay
    short, _ = _after_first_impact(contact_time=0.5 * delay)
    assert np.array_equal(short, single)
