"""A die sliding on a table corner and a wall corner at once: energy is kept without friction and
only taken with it, the path sampled is the path rolled, and friction can hold it still. A hinge
(one corner held in the corner of table and wall) turns as a pendulum about that corner, its
reaction pushing within the two friction cones."""

import math

import numpy as np
import pytest

from dice_sweep.physics.flight import corner_offset
from dice_sweep.physics.impact import specific_energy
from dice_sweep.physics.ladder import (LADDER_AT_REST, LADDER_CONTACT, LADDER_DECIDED, LADDER_OFF_TABLE, LADDER_OFF_WALL,
                                       LADDER_REFUSED, hinge_margins, hinge_reaction, is_hinge, ladder, ladder_at,
                                       ladder_spin, ladder_state)
from dice_sweep.physics.outcome import corner_geometry
from dice_sweep.physics.params import FP_G, FP_INERTIA, FP_WALL
from tests.physics.conftest import make_params

RADIUS = 0.01
# A pentagon turned 1 rad (0.989 rad): corner 3 on the table left of the centre of mass and
# corner 4 on the right wall above it, the side between them leaning on the wall like a ladder.
TABLE, WALL, RIGHT = 3, 4, 1.0


def pentagon(friction):
    return make_params(sides=5, radius=RADIUS, model="rigid", friction=friction, separation=0.05)[0]


def energies(fpar, phi, omega, tau, count=40):
    s = np.zeros(6)
    out = []
    for t in np.linspace(0.0, tau, count):
        ladder_at(fpar, 5, TABLE, WALL, RIGHT, phi, omega, t, s)
        out.append(specific_energy(s, fpar))
    return np.array(out)


@pytest.mark.parametrize("omega", [3.0, -3.0])
def test_a_frictionless_ladder_keeps_its_energy_until_it_leaves_the_wall(omega):
    """Without friction the contact forces do no work: the energy after 0.02-0.03 s of sliding
    (about 1000 steps) is the energy before to round-off, which a wrong normal force (the two
    contacts' 2x2 system) would break; then the wall lets go."""
    fpar = pentagon(0.0)
    start = np.zeros(6)
    ladder_state(fpar, TABLE, WALL, RIGHT, 1.0, omega, start)
    end = np.zeros(6)
    how, tau = ladder(fpar, 5, TABLE, WALL, RIGHT, 1.0, omega, 1.0, end)
    assert how == LADDER_OFF_WALL and 0.01 < tau < 0.05
    e0 = specific_energy(start, fpar)
    assert abs(specific_energy(end, fpar) - e0) < 1e-12 * e0
    assert np.all(np.abs(energies(fpar, 1.0, omega, tau) - e0) < 1e-12 * e0)
    sampled = np.zeros(6)
    ladder_at(fpar, 5, TABLE, WALL, RIGHT, 1.0, omega, tau, sampled)
    assert np.allclose(sampled, end, rtol=0.0, atol=1e-12)


def test_friction_only_takes_energy():
    """mu 0.3, turning at -10 rad/s: the energy falls at every sample until the side is decided."""
    fpar = pentagon(0.3)
    end = np.zeros(6)
    how, tau = ladder(fpar, 5, TABLE, WALL, RIGHT, 1.0, -10.0, 1.0, end)
    assert how == LADDER_DECIDED and tau > 0.005
    e = energies(fpar, 1.0, -10.0, tau)
    assert np.all(np.diff(e) < 0.0)
    assert e[-1] < 0.99 * e[0]


def test_friction_holds_a_slow_ladder_still_and_none_does_not():
    """Turning at 1e-3 rad/s at 0.989 rad: mu 1.5 stops it within microseconds and holds it
    (at rest leaning on the wall); without friction it slides on until its side is decided."""
    held = np.zeros(6)
    how, tau = ladder(pentagon(1.5), 5, TABLE, WALL, RIGHT, 0.989, -1e-3, 1.0, held)
    assert how == LADDER_AT_REST and tau < 1e-5 and held[5] == 0.0
    slid = np.zeros(6)
    how, tau = ladder(pentagon(0.0), 5, TABLE, WALL, RIGHT, 0.989, -1e-3, 1.0, slid)
    assert how == LADDER_DECIDED and slid[5] != 0.0


def plastic_two_contact_velocity(fpar, sides, radius, com, table, wall, s):
    """The velocity (vx, vy, omega) after the frictionless plastic impulse at table corner
    ``table`` and right-wall corner ``wall`` of the centre-of-mass state s, solved as an impulse:
    J M^-1 J^T p = -J v with M = diag(1, 1, k^2), for a die whose centre of mass sits ``com``
    (body frame) from its centre."""
    c, sn = math.cos(s[2]), math.sin(s[2])
    offset = np.array([c * com[0] - sn * com[1], sn * com[0] + c * com[1]])
    arms = [radius * np.array([math.cos(s[2] + 2 * math.pi * k / sides), math.sin(s[2] + 2 * math.pi * k / sides)]) - offset
            for k in (table, wall)]
    # rows: the table corner's upward velocity, the wall corner's velocity away from the right wall
    jac = np.array([[0.0, 1.0, arms[0][0]], [-1.0, 0.0, arms[1][1]]])
    inv_mass = np.diag([1.0, 1.0, 1.0 / fpar[FP_INERTIA]])
    v = np.asarray(s[3:6], float)
    impulse = np.linalg.solve(jac @ inv_mass @ jac.T, -jac @ v)
    return v + inv_mass @ jac.T @ impulse


def test_a_chattering_wall_contact_stops_plastically_on_both_contacts():
    """ladder_spin, the spin a ladder is entered with from a wall contact chattering above the
    stick speed, gives the velocity of the frictionless plastic impulse at both contacts (solved
    here as an impulse, for loaded hexagons with random velocities): both normal velocities
    zero and the kinetic energy never above the one before."""
    rng = np.random.default_rng(33)
    radius, com = 0.0197, (0.00285, -0.00526)
    fpar = make_params(sides=6, radius=radius, model="paper", friction=0.15, separation=0.047, com_offset=com)[0]
    for _ in range(50):
        s = np.array([0.0, 0.0, rng.uniform(0.3, 0.9), *rng.normal(0.0, 1e-3, 2), rng.normal(0.0, 0.05)])
        expected = plastic_two_contact_velocity(fpar, 6, radius, com, 4, 5, s)
        projected = np.zeros(6)
        ladder_state(fpar, 4, 5, RIGHT, s[2], ladder_spin(fpar, 4, 5, s), projected)
        assert np.allclose(projected[3:], expected, rtol=0.0, atol=1e-15)
        kinetic = 0.5 * (s[3] ** 2 + s[4] ** 2 + fpar[FP_INERTIA] * s[5] ** 2)
        after = 0.5 * (projected[3] ** 2 + projected[4] ** 2 + fpar[FP_INERTIA] * projected[5] ** 2)
        assert after <= kinetic
    # the spin kept as it is (the entry below the stick speed) is another velocity: the check can tell
    ladder_state(fpar, 4, 5, RIGHT, s[2], s[5], projected)
    assert not np.allclose(projected[3:], expected, rtol=0.0, atol=1e-9)


# --- a hinge: one sharp corner in the corner of table and right wall ----------------------------

HINGE = 0  # the corner held
# the held corner 50 degrees below the right of the centre of mass (the triangle's sides clear of
# table and wall), turning away from the wall at 22 rad/s: energy over the barrier, so it is not
# decided on the way, and it falls about the corner until its next corner lands
TOWARD, OMEGA0 = -math.radians(50.0), 22.0


def triangle(friction, air_drag=0.0):
    kw = dict(air_drag=air_drag) if air_drag else {}
    return make_params(sides=3, radius=RADIUS, model="rigid", friction=friction, separation=0.05, **kw)[0]


def hinge_phi(fpar, toward):
    """Body angle with corner HINGE at ``toward`` (rad, world) from the centre of mass."""
    return toward - corner_geometry(fpar, HINGE)[1]


def reference_hinge(fpar, phi0, omega0, times):
    """The centre of mass at ``times`` by scipy's DOP853 on the rigid pendulum about the fixed
    corner, written in the angle chi of the centre of mass seen from the corner:
    chi'' = -g rho cos(chi) / (k^2 + rho^2) (no drag)."""
    from scipy.integrate import solve_ivp

    rho, _ = corner_geometry(fpar, HINGE)
    g, k2 = fpar[FP_G], fpar[FP_INERTIA]
    corner = np.array([fpar[FP_WALL], 0.0])
    rx, ry = corner_offset(fpar, HINGE, math.cos(phi0), math.sin(phi0))
    chi0 = math.atan2(-ry, -rx)
    sol = solve_ivp(lambda _, y: [y[1], -g * rho * math.cos(y[0]) / (k2 + rho * rho)], (0.0, times[-1]), [chi0, omega0],
                    method="DOP853", rtol=1e-13, atol=1e-15, t_eval=times)
    return corner + rho * np.stack([np.cos(sol.y[0]), np.sin(sol.y[0])], axis=1)


def test_a_hinge_is_one_sharp_corner():
    assert is_hinge(triangle(0.5), HINGE, HINGE)
    assert not is_hinge(triangle(0.5), HINGE, 1)
    rounded = make_params(sides=3, radius=RADIUS, model="rigid", friction=0.5, separation=0.05, corner_radius=1e-3)[0]
    assert not is_hinge(rounded, HINGE, HINGE)  # its arc slips on both surfaces: a ladder


def test_a_hinge_turns_as_a_pendulum_about_its_corner_and_keeps_its_energy():
    """Turning away from the wall (mu 0.3), it falls about the held corner for 5 ms: the sampled path is scipy's pendulum to 1e-9
    R, the corner stays at the table-wall corner, the energy is kept to 1e-12 (no slip, no
    drag: the reaction does no work), and the phase ends where the reaction leaves the cone."""
    fpar = triangle(0.3)
    phi0 = hinge_phi(fpar, TOWARD)
    start, end = np.zeros(6), np.zeros(6)
    ladder_state(fpar, HINGE, HINGE, RIGHT, phi0, OMEGA0, start)
    how, tau = ladder(fpar, 3, HINGE, HINGE, RIGHT, phi0, OMEGA0, 1.0, end)
    assert how == LADDER_OFF_WALL and 0.002 < tau < 0.1
    times = np.linspace(0.0, tau, 25)
    reference = reference_hinge(fpar, phi0, OMEGA0, times)
    e0 = specific_energy(start, fpar)
    s = np.zeros(6)
    for t, com in zip(times, reference):
        ladder_at(fpar, 3, HINGE, HINGE, RIGHT, phi0, OMEGA0, t, s)
        assert np.allclose(s[:2], com, rtol=0.0, atol=1e-9 * RADIUS)
        rx, ry = corner_offset(fpar, HINGE, math.cos(s[2]), math.sin(s[2]))
        assert abs(s[0] + rx - fpar[FP_WALL]) < 1e-15 and abs(s[1] + ry) < 1e-15  # the corner stays put
        assert abs(specific_energy(s, fpar) - e0) < 1e-12 * e0
    assert abs(specific_energy(end, fpar) - e0) < 1e-12 * e0
    # it ends where the reaction reaches the cone's edge on the table's side: the corner would
    # slide away from the wall (mu 0.3 cannot hold it there)
    rx, ry = corner_offset(fpar, HINGE, math.cos(end[2]), math.sin(end[2]))
    on_wall, on_table = hinge_margins(fpar, RIGHT, *hinge_reaction(fpar, rx, ry, end[5], 0.0, 0.0)[1:])
    assert on_wall > 0.1 * fpar[FP_G] and abs(on_table) < 1e-6 * fpar[FP_G]


def test_the_hinge_reaction_is_what_the_path_needs_and_lies_in_the_cone():
    """The reaction hinge_reaction gives equals, per unit mass, the centre of mass's acceleration
    (second differences of the sampled path) plus g up: the force the two contacts must push.
    Along the hinge it lies in the cone: both margins >= 0 and, split into a table force
    (N_t, F_t) and a wall force (N_w, F_w) with the friction in each as small as it can be,
    N_t >= 0, N_w >= 0 and |F| <= mu N at each."""
    mu = 0.3
    fpar = triangle(mu)
    phi0 = hinge_phi(fpar, TOWARD)
    end = np.zeros(6)
    _, tau = ladder(fpar, 3, HINGE, HINGE, RIGHT, phi0, OMEGA0, 1.0, end)
    h = 1e-5
    s, before, after = np.zeros(6), np.zeros(6), np.zeros(6)
    for t in np.linspace(2 * h, tau - 2 * h, 15):
        for at, out in ((t, s), (t - h, before), (t + h, after)):
            ladder_at(fpar, 3, HINGE, HINGE, RIGHT, phi0, OMEGA0, at, out)
        accel = (after[:2] - 2.0 * s[:2] + before[:2]) / (h * h)
        rx, ry = corner_offset(fpar, HINGE, math.cos(s[2]), math.sin(s[2]))
        _, reaction_x, reaction_y = hinge_reaction(fpar, rx, ry, s[5], 0.0, 0.0)
        assert np.allclose([reaction_x, reaction_y], accel + [0.0, fpar[FP_G]], rtol=0.0, atol=1e-5 * fpar[FP_G])
        assert min(hinge_margins(fpar, RIGHT, reaction_x, reaction_y)) >= -1e-12 * fpar[FP_G]
        # the wall pushes left (-x) only, the table up: N_w = -R_x (friction F_t = 0) unless the
        # reaction points right, then the table's friction carries R_x and the wall nothing
        n_wall = max(-reaction_x, 0.0)
        f_table = reaction_x + n_wall
        n_table = reaction_y  # with F_w = 0
        assert n_wall >= 0.0 and n_table >= 0.0 and abs(f_table) <= mu * n_table + 1e-12


def test_a_spinning_hinge_is_refused_and_drag_only_takes_energy():
    """Spinning at 100 rad/s the corner would need the contacts to pull it in (omega^2 rho is
    10 g): no hinge. Slowly, with drag 0.5 /m, the energy only falls."""
    fpar = triangle(0.5)
    phi0 = hinge_phi(fpar, TOWARD)
    assert ladder(fpar, 3, HINGE, HINGE, RIGHT, phi0, 100.0, 1.0, np.zeros(6))[0] == LADDER_REFUSED
    dragged = triangle(0.5, air_drag=0.5)
    end = np.zeros(6)
    how, tau = ladder(dragged, 3, HINGE, HINGE, RIGHT, phi0, OMEGA0, 1.0, end)
    assert how != LADDER_REFUSED and tau > 0.005
    s = np.zeros(6)
    energy = []
    for t in np.linspace(0.0, tau, 30):
        ladder_at(dragged, 3, HINGE, HINGE, RIGHT, phi0, OMEGA0, t, s)
        energy.append(specific_energy(s, dragged))
    assert np.all(np.diff(energy) < 0.0)
