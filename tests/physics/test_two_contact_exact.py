"""The exact Coulomb impact with two contacts at once (physics/two_contact_exact.py).

Checked against calculations written here, not the kernel's:

* one contact: Routh's closed form of the energetic impact (physics/exact_impact.py, itself
  checked against scipy in test_exact_impact.py) is what a compliant contact with Walton's
  unloading line gives (the work of N dd is minus the work of u_n dp_n), so the integration
  with the other contact out of reach must land on it;
* two contacts: a plain-Python integrator of the same contact model with a different scheme
  (first-order semi-implicit Euler, 40 times smaller steps, friction by enumerating the stick
  and slide cases instead of Gauss-Seidel);
* symmetry: a square landing flat and square-on bounces straight up at e times its speed, and
  a mirrored landing gives the mirrored result.

Then the invariants over random landings: never an energy gain, never a contact left
approaching, friction never pushing the slip along.
"""

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from dice_sweep.physics.exact_impact import exact_impulse
from dice_sweep.physics.flight import SURF_RIGHT, SURF_TABLE, surface_frame
from dice_sweep.physics.impact import corner_normal_velocity, corner_vector
from dice_sweep.physics.multi_contact import resolve_two_contacts
from dice_sweep.physics.params import FP_INERTIA, FP_WALL
from dice_sweep.physics.two_contact_exact import compliant_two_contacts, exact_two_contacts
from tests.physics.conftest import TABLE1_RADIUS, make_params

R = TABLE1_RADIUS
N_COUNTS = 6
HALF_SIDE = 0.01  # m: a square plate of side 2 cm in the unit tests below
SQUARE_INERTIA = (2 * HALF_SIDE) ** 2 / 6  # I/M of a uniform square plate (eq. 25, n = 4)


def flat_contacts(half=HALF_SIDE):
    """A square's bottom side on the table: normals up, levers to the two bottom corners."""
    return np.array([[0.0, 1.0, -half, -half], [0.0, 1.0, half, -half]])


def integrate(v, contacts, e, mu, same_surface=True, inertia=SQUARE_INERTIA):
    v = np.array(v, float)
    loaded = np.zeros(2, np.bool_)
    assert compliant_two_contacts(v, inertia, mu, np.asarray(contacts, float), np.array(e, float), same_surface, loaded)
    return v, loaded


# --- the independent reference -------------------------------------------------------------
def reference(v, contacts, e, mu, same_surface, inertia, steps_per_period=16000):
    """The same contact model (module docstring of two_contact_exact) by semi-implicit Euler."""
    vx, vy, w = (float(x) for x in v)
    rows_n = [(c[0], c[1], -c[3] * c[0] + c[2] * c[1]) for c in contacts]
    if same_surface:
        mx, my = 0.5 * (contacts[0][2] + contacts[1][2]), 0.5 * (contacts[0][3] + contacts[1][3])
        tx, ty = contacts[0][1], -contacts[0][0]
        rows_t = [(tx, ty, -my * tx + mx * ty)]
    else:
        rows_t = [(c[1], -c[0], -c[3] * c[1] + c[2] * -c[0]) for c in contacts]
    dot = lambda a, b: a[0] * b[0] + a[1] * b[1] + a[2] * b[2] / inertia  # noqa: E731
    w_nn = np.array([[dot(a, b) for b in rows_n] for a in rows_n])
    dt = 2 * math.pi / (math.sqrt(np.linalg.eigvalsh(w_nn).max()) * steps_per_period)
    w_tt = np.array([[dot(a, b) for b in rows_t] for a in rows_t])
    d = [0.0, 0.0]
    d_max = [0.0, 0.0]
    e = [max(x, 0.01) for x in e]  # the model's least restitution (LEAST_RESTITUTION)

    def force(i):
        if d[i] >= d_max[i]:
            return max(d[i], 0.0)
        e2 = e[i] ** 2
        return max((d[i] - d_max[i] * (1 - e2)) / e2, 0.0)

    for _ in range(10_000_000):
        n = [force(0), force(1)]
        for i, row in enumerate(rows_n):
            vx, vy, w = vx + row[0] * n[i] * dt, vy + row[1] * n[i] * dt, w + row[2] * n[i] * dt / inertia
        u_t = np.array([row[0] * vx + row[1] * vy + row[2] * w for row in rows_t])
        caps = [mu * (n[0] + n[1]) * dt] if same_surface else [mu * n[0] * dt, mu * n[1] * dt]
        # enumerate: every row stuck, or on its cone's edge opposing the slip; the first case
        # that is consistent (stuck rows inside their cones, edge rows short of stopping)
        lam = None
        for case in range(3 ** len(rows_t)):
            modes = [(case // 3 ** k) % 3 for k in range(len(rows_t))]  # 0 stick, 1 +cap, 2 -cap
            fixed = {k: (caps[k] if m == 1 else -caps[k]) for k, m in enumerate(modes) if m}
            free = [k for k, m in enumerate(modes) if not m]
            trial = np.zeros(len(rows_t))
            for k, val in fixed.items():
                trial[k] = val
            if free:
                rhs = -u_t[free] - w_tt[np.ix_(free, list(fixed))] @ trial[list(fixed)]
                trial[free] = np.linalg.solve(w_tt[np.ix_(free, free)], rhs)
            after = u_t + w_tt @ trial
            if all(abs(trial[k]) <= caps[k] * (1 + 1e-9) + 1e-300 for k in free) and all(
                    after[k] * np.sign(val) <= 1e-15 for k, val in fixed.items()):
                lam = trial
                break
        for k, row in enumerate(rows_t):
            vx, vy, w = vx + row[0] * lam[k], vy + row[1] * lam[k], w + row[2] * lam[k] / inertia
        moving = False
        for i, row in enumerate(rows_n):
            u_n = row[0] * vx + row[1] * vy + row[2] * w
            d[i] -= u_n * dt
            d_max[i] = max(d_max[i], d[i])
            moving |= force(i) > 0 or u_n < 0
        if not moving:
            return np.array([vx, vy, w]), [m > 0 for m in d_max]
    raise AssertionError("the reference impact did not end")


# --- symmetry and the one-contact limit -----------------------------------------------------
@pytest.mark.parametrize("e", [0.0, 0.3, 1.0])
def test_a_square_landing_square_on_bounces_straight_up(e):
    v, loaded = integrate([0.0, -1.3, 0.0], flat_contacts(), [e, e], 0.5)
    assert loaded.all()
    assert v[1] == pytest.approx(1.3 * max(e, 0.01), abs=3e-5 * 1.3)  # e at least LEAST_RESTITUTION
    assert v[0] == pytest.approx(0.0, abs=1e-12) and v[2] == pytest.approx(0.0, abs=1e-9)


def test_a_mirrored_landing_gives_the_mirrored_result():
    v, _ = integrate([0.4, -1.0, 35.0], flat_contacts(), [0.5, 0.5], 0.3)
    mirrored, _ = integrate([-0.4, -1.0, -35.0], flat_contacts(), [0.5, 0.5], 0.3)
    assert np.allclose(mirrored, [-v[0], v[1], -v[2]], rtol=0, atol=1e-12)


@pytest.mark.parametrize("mu", [0.0, 0.1, 0.4, 3.0])
def test_one_contact_in_reach_is_rouths_energetic_impact(mu):
    """The other contact far above its surface's reach (receding fast): the integration's
    velocity equals Routh's closed form (energetic) to 1e-4 of the impact speed."""
    rng = np.random.default_rng(5)
    for _ in range(20):
        rx, ry = rng.uniform(-HALF_SIDE, HALF_SIDE), -rng.uniform(0.3, 1) * HALF_SIDE
        contacts = np.array([[0.0, 1.0, rx, ry], [1.0, 0.0, -HALF_SIDE, 0.0]])  # a wall contact receding
        v0 = np.array([rng.uniform(-1, 1), -rng.uniform(0.3, 2), rng.uniform(-40, 40)])
        if v0[1] + v0[2] * rx >= 0:
            continue
        v0[0] = abs(v0[0]) + 5.0  # the wall contact (normal +x at x = -HALF_SIDE) recedes fast
        e = 0.6
        v, loaded = integrate(v0, contacts, [e, e], mu, same_surface=False)
        assert loaded.tolist() == [True, False]
        a_t, a_n = -ry, rx  # r_perp . t and r_perp . n, t = +x, n = +y
        k = (1 + a_t * a_t / SQUARE_INERTIA, a_t * a_n / SQUARE_INERTIA, 1 + a_n * a_n / SQUARE_INERTIA)
        u_t, u_n = v0[0] + v0[2] * a_t, v0[1] + v0[2] * a_n
        p_t, p_n, _ = exact_impulse(u_t, u_n, *k, e, mu, True)
        expected = v0 + [p_t, p_n, (a_t * p_t + a_n * p_n) / SQUARE_INERTIA]
        scale = abs(u_n) + abs(u_t)
        assert abs(v[0] - expected[0]) < 1e-4 * scale and abs(v[1] - expected[1]) < 1e-4 * scale
        assert HALF_SIDE * abs(v[2] - expected[2]) < 1e-4 * scale


# --- two contacts against the plain reference -------------------------------------------------
LANDINGS = [
    # (v, mu, e, surfaces): sliding throughout, sticking, slip reversal by spin, plastic, a corner
    # on the table and another on a wall
    ([0.8, -1.0, 0.0], 0.2, (0.5, 0.5), "table"),
    ([0.3, -1.0, 0.0], 1.5, (0.5, 0.5), "table"),
    ([0.3, -1.0, 25.0], 0.5, (0.5, 0.5), "table"),
    ([-0.2, -1.2, -60.0], 0.3, (0.0, 0.0), "table"),
    ([0.0, -1.0, 70.0], 0.0, (0.7, 0.7), "table"),
    ([-0.6, -0.8, 10.0], 0.4, (0.5, 0.5), "corner"),
    ([-0.3, -0.5, -20.0], 0.8, (0.3, 0.3), "corner"),
]


def _contacts(surfaces):
    if surfaces == "table":
        return flat_contacts(), True
    # the square's bottom-left corner on the table and its top-left... on the left wall
    return np.array([[0.0, 1.0, HALF_SIDE, -HALF_SIDE], [1.0, 0.0, -HALF_SIDE, HALF_SIDE]]), False


@pytest.mark.parametrize("v0,mu,e,surfaces", LANDINGS)
def test_two_contacts_agree_with_a_plain_integrator(v0, mu, e, surfaces):
    contacts, same = _contacts(surfaces)
    v, loaded = integrate(v0, contacts, e, mu, same_surface=same)
    ref, ref_loaded = reference(v0, contacts, e, mu, same, SQUARE_INERTIA)
    scale = abs(v0[0]) + abs(v0[1]) + HALF_SIDE * abs(v0[2])
    assert loaded.tolist() == ref_loaded
    assert np.abs(v[:2] - ref[:2]).max() < 2e-3 * scale
    assert HALF_SIDE * abs(v[2] - ref[2]) < 2e-3 * scale


# --- invariants through the kernel's entry point -------------------------------------------
def flat_state(sides, v_t, v_n, omega, tilt=0.0):
    """Side 0 flat on the table (plus ``tilt``), centre at the apothem."""
    phi = -math.pi / 2 - math.pi / sides + tilt
    return np.array([0.0, R * math.cos(math.pi / sides), phi, v_t, v_n, omega])


@settings(max_examples=150, deadline=None)
@given(
    sides=st.integers(3, 12),
    restitution=st.sampled_from(["newton", "energetic"]),
    beta_n=st.floats(0.0, 1.0),
    friction=st.sampled_from([0.0, 0.1, 0.5, 2.0, math.inf]),
    v_t=st.floats(-2.0, 2.0),
    v_n=st.floats(-3.0, -0.05),
    omega=st.floats(-200.0, 200.0),
    tilt=st.floats(-1e-7, 1e-7),
)
def test_no_exact_two_contact_impact_gains_energy_or_leaves_a_contact_approaching(
        sides, restitution, beta_n, friction, v_t, v_n, omega, tilt):
    fpar, ipar = make_params(sides=sides, model="rigid", beta_n=beta_n, friction=friction,
                             friction_rule="exact", restitution=restitution)
    s = flat_state(sides, v_t, v_n, omega, tilt)
    levers = [corner_vector(s, fpar, c) for c in (0, 1)]
    if max(corner_normal_velocity(s, *r, 0.0, 1.0) for r in levers) >= 0:
        return
    before = s.copy()
    counts = np.zeros(N_COUNTS, np.int32)
    assert resolve_two_contacts(s, fpar, ipar, SURF_TABLE, 0, SURF_TABLE, 1, 1.0, counts)
    inertia = fpar[FP_INERTIA]
    kin = lambda v: 0.5 * (v[3] ** 2 + v[4] ** 2 + inertia * v[5] ** 2)  # noqa: E731
    assert kin(s) <= kin(before) * (1 + 1e-12)
    speed = abs(v_n) + abs(v_t) + R * abs(omega)
    for r in levers:
        assert corner_normal_velocity(s, *r, 0.0, 1.0) >= -1e-3 * speed


def test_friction_never_pushes_a_sliding_flat_landing_along():
    """With the table's two corners sliding together, the midpoint's slip after the impact is
    between zero and its incoming value (friction brakes it, never reverses it past stick
    when the landing has no spin)."""
    rng = np.random.default_rng(11)
    for _ in range(40):
        mu = rng.uniform(0.05, 2.0)
        v_t = rng.uniform(-1.5, 1.5)
        v, _ = integrate([v_t, -rng.uniform(0.2, 2.0), 0.0], flat_contacts(), [0.5, 0.5], mu)
        slip = v[0] - v[2] * (-HALF_SIDE)  # u_t at the midpoint (0, -HALF_SIDE)
        assert -1e-3 * abs(v_t) <= slip * np.sign(v_t) <= abs(v_t) * (1 + 1e-12)


def test_a_corner_on_a_wall_and_one_on_the_table_through_the_kernel_entry():
    """Two surfaces: the table and the right wall, each with its own cone; through
    resolve_two_contacts the answer is exact_two_contacts' on the same levers."""
    sides = 4
    fpar, ipar = make_params(sides=sides, model="rigid", beta_n=0.5, friction=0.4, friction_rule="exact",
                             restitution="energetic", separation=0.05)
    s = np.array([0.0, 0.0, 0.3, 0.4, -0.9, 12.0])
    r0 = corner_vector(s, fpar, 0)
    r1 = corner_vector(s, fpar, 1)
    nx, ny, _ = surface_frame(SURF_RIGHT, fpar[FP_WALL])
    contacts = np.array([[0.0, 1.0, r0[0], r0[1]], [nx, ny, r1[0], r1[1]]])
    if corner_normal_velocity(s, *r0, 0.0, 1.0) >= 0 or corner_normal_velocity(s, *r1, nx, ny) >= 0:
        pytest.skip("the constructed landing does not approach both surfaces")
    expected = s.copy()
    ok, _ = exact_two_contacts(expected, fpar[FP_INERTIA], 0.4, True, contacts, np.array([0.5, 0.5]), False)
    assert ok
    assert resolve_two_contacts(s, fpar, ipar, SURF_TABLE, 0, SURF_RIGHT, 1, 1.0, np.zeros(N_COUNTS, np.int32))
    assert np.array_equal(s, expected)
