"""Tests of the independent drop generator (tests/measured/independent.py).

The generator must not use the project's simulation code; only the agreement tests here call
the kernel, to check that both implement the same documented physics (docs/physics.md).
"""

import ast
import csv
import dataclasses
import math
from pathlib import Path as FsPath

import numpy as np
import pytest

from tests.measured import independent as ind
from tests.measured.independent import Truth, energy, impact, simulate_drops, simulate_path, simulate_track, write_csv

R = 0.06 / math.sqrt(2)  # m, the default square
ALPHA = 1.0 / 3.0  # I / (M R^2) of a square
G = 9.81


def release_states(count, seed):
    """Release states like simulate_drops draws (m, rad, m/s, rad/s)."""
    rng = np.random.default_rng(seed)
    return np.column_stack([
        rng.uniform(-0.05, 0.05, count), rng.uniform(0.12, 0.17, count), rng.uniform(-np.pi, np.pi, count),
        rng.uniform(-0.8, -0.4, count), rng.uniform(-2.1, -1.7, count), rng.uniform(-8.0, 8.0, count),
    ])


def test_generator_imports_nothing_from_the_project():
    tree = ast.parse(FsPath(ind.__file__).read_text())
    names = [a.name for n in ast.walk(tree) if isinstance(n, ast.Import) for a in n.names]
    names += [n.module or "" for n in ast.walk(tree) if isinstance(n, ast.ImportFrom)]
    assert all(name.split(".")[0] in {"csv", "math", "dataclasses", "numpy", "scipy"} for name in names), names


# ----------------------------------------------------------------------------------- energy


@pytest.mark.parametrize("truth", [
    Truth(contact="rigid", beta_normal=0.4, beta_tangential=-0.2),
    Truth(contact="paper", beta_normal=0.4, beta_tangential=-0.2, com_offset=(0.005, 0.004)),
])
def test_free_flight_conserves_energy(truth):
    path = simulate_path(truth, (0.0, 0.15, 0.3, -0.5, -1.9, 6.0), 0.5)
    assert len(path.impacts) >= 3
    for t0, t1, flight in path.flights:
        e = [energy(truth, flight.state(t)) for t in np.linspace(t0, t1, 7)]
        assert np.ptp(e) < 1e-12 * abs(e[0])


def test_air_drag_removes_energy_in_flight():
    truth = Truth(air_drag=0.8)
    path = simulate_path(truth, (0.0, 0.15, 0.3, -0.5, -1.9, 6.0), 0.5)
    assert len(path.impacts) >= 3
    for t0, t1, flight in path.flights:
        e = np.array([energy(truth, flight.state(t)) for t in np.linspace(t0, t1, 9)])
        assert np.all(np.diff(e) < 0.0)
    # a vertical fall against the closed form y0 - (v_t^2/g) ln cosh(g t / v_t)
    vt = math.sqrt(G / truth.air_drag)
    fall = simulate_path(truth, (0.0, 0.5, 0.3, 0.0, 0.0, 0.0), 0.2)
    assert not fall.impacts
    assert fall.com_state(0.15)[1] == pytest.approx(0.5 - vt**2 / G * math.log(math.cosh(G * 0.15 / vt)), abs=1e-12)


@pytest.mark.parametrize("contact", ["rigid", "paper"])
def test_no_impact_gains_energy(contact):
    rng = np.random.default_rng(7)
    impacts = clipped = 0
    for state in release_states(40, 3):
        truth = Truth(contact=contact, beta_normal=rng.uniform(0.0, 1.0), beta_tangential=rng.uniform(-1.0, 1.0),
                      friction=[math.inf, rng.uniform(0.0, 1.0)][rng.integers(2)],
                      com_offset=tuple(rng.uniform(-0.01, 0.01, 2)), speed_restitution=rng.uniform(0.0, 1.0))
        for hit in simulate_path(truth, state, 0.5).impacts:
            impacts += 1
            clipped += hit["clipped"]
            gain = energy(truth, hit["after"]) - energy(truth, hit["before"])
            assert gain <= 1e-12 * energy(truth, hit["before"])
            assert hit["dT"] <= 1e-12
    assert impacts > 100
    if contact == "rigid":
        assert clipped > 0  # the energy rule was exercised


# ----------------------------------------------------------------------------------- single impacts


def corner_down(tilt, vx, vy, omega):
    """COM state of the default square with corner 0 at the table, ``tilt`` rad from straight
    below the centre (counterclockwise), and its offset r from the centre."""
    phi = -math.pi / 2 + tilt
    r = np.array([R * math.cos(phi), R * math.sin(phi)])
    return np.array([0.0, -r[1], phi, vx, vy, omega]), r


@pytest.mark.parametrize("contact", ["rigid", "paper"])
def test_square_falling_corner_first_bounces_straight_up(contact):
    # released with corner 0 straight down, no spin: Newton restitution at the corner is also
    # eq 9, and neither law can create spin or drift (no lever, no slip)
    h0, e = 0.1, 0.4
    truth = Truth(contact=contact, beta_normal=e, beta_tangential=-0.35)
    path = simulate_path(truth, (0.02, R + h0, -math.pi / 2, 0.0, 0.0, 0.0), 0.5)
    first = path.impacts[0]
    tc = math.sqrt(2.0 * h0 / G)
    assert first["t"] == pytest.approx(tc, abs=1e-12)
    assert first["corner"] == 0
    assert first["after"][3:] == pytest.approx([0.0, e * G * tc, 0.0], abs=1e-12)
    second = path.impacts[1]
    assert second["t"] == pytest.approx(tc + 2.0 * e * tc, abs=1e-12)
    assert path.end == "slow_impact" and -path.impacts[-1]["after"][4] < 0.05 / e + 1e-12


def test_paper_law_matches_eqs_12_and_13_for_a_corner_below_the_centre():
    # beta_t = 0: vx' = (vx - alpha R w)/(1 + alpha), R w' = -vx', by eqs 12-13 with alpha = 1/3
    truth = Truth(contact="paper", beta_normal=0.5, beta_tangential=0.0)
    s, _ = corner_down(0.0, 0.4, -1.0, 0.3 / R)
    after, info = impact(truth, s, 0)
    assert info["law"] == "paper"
    assert after[3] == pytest.approx(0.225, abs=1e-14)
    assert after[4] == pytest.approx(0.5, abs=1e-14)
    assert after[5] * R == pytest.approx(-0.225, abs=1e-14)
    # beta_t = -0.35: the same equations, evaluated by hand
    truth = Truth(contact="paper", beta_normal=0.2, beta_tangential=-0.35)
    after, _ = impact(truth, s, 0)
    a, b, vx, rw = ALPHA, -0.35, 0.4, 0.3
    assert after[3] == pytest.approx(-((a * b - 1) * vx + a * (b + 1) * rw) / (a + 1), abs=1e-14)
    assert after[5] * R == pytest.approx(-((b + 1) * vx - rw * (a - b)) / (a + 1), abs=1e-14)


def test_paper_law_ignores_the_lever_of_a_tilted_corner():
    # the paper's lever is R straight below the centre: a tilted corner gets no spin
    truth = Truth(contact="paper", beta_normal=0.4, beta_tangential=-0.35)
    s, _ = corner_down(0.3, 0.0, -2.0, 0.0)
    after, info = impact(truth, s, 0)
    assert info["law"] == "paper"
    assert after[3:] == pytest.approx([0.0, 0.8, 0.0], abs=1e-14)


@pytest.mark.parametrize("contact", ["rigid", "paper"])
def test_paper_fallback_and_rigid_law_use_the_corner_impulse(contact):
    # centre moving up while the spin drives the corner in: the paper law's undefined case 1
    e = 0.4
    truth = Truth(contact=contact, beta_normal=e, beta_tangential=0.0)
    s, r = corner_down(0.4, 0.1, 0.2, -30.0)
    after, info = impact(truth, s, 0)
    assert info["law"] == ("rigid" if contact == "rigid" else "fallback")
    i = ALPHA * R**2
    u = np.array([0.1 - s[5] * r[1], 0.2 + s[5] * r[0]])
    assert u[1] < 0.0
    # K = 1 + r_perp r_perp^T / I, inverse by hand: K^-1 = (1 + r r^T / I) / (1 + R^2 / I)
    kinv = (np.eye(2) + np.outer(r, r) / i) / (1.0 + R**2 / i)
    P = kinv @ np.array([-u[0], -(1 + e) * u[1]])
    assert not info["clipped"]
    assert after[3] == pytest.approx(0.1 + P[0], abs=1e-14)
    assert after[4] == pytest.approx(0.2 + P[1], abs=1e-14)
    assert after[5] == pytest.approx(-30.0 + (r[0] * P[1] - r[1] * P[0]) / i, abs=1e-11)
    # the corner leaves with the targets: no slip, Newton restitution
    assert after[3] - after[5] * r[1] == pytest.approx(0.0, abs=1e-14)
    assert info["u_n_after"] == pytest.approx(-e * u[1], abs=1e-14)


def test_rigid_law_for_a_tilted_corner_falling_straight_down():
    # u = (0, -v), target (0, e v): P = (1+e) v (r_x r_y, I + r_y^2) / (I + R^2)
    e, v, tilt = 0.4, 2.0, 0.3
    s, r = corner_down(tilt, 0.0, -v, 0.0)
    i = ALPHA * R**2
    after, _ = impact(Truth(beta_normal=e, beta_tangential=0.0), s, 0)
    pt = (1 + e) * v * r[0] * r[1] / (i + R**2)
    pn = (1 + e) * v * (i + r[1] ** 2) / (i + R**2)
    assert after[3:] == pytest.approx([pt, -v + pn, (r[0] * pn - r[1] * pt) / i], abs=1e-13)
    # frictionless: P = (0, (1+e) v / (1 + r_x^2 / I))
    after, _ = impact(Truth(beta_normal=e, beta_tangential=0.0, friction=0.0), s, 0)
    pn = (1 + e) * v / (1 + r[0] ** 2 / i)
    assert after[3:] == pytest.approx([0.0, -v + pn, r[0] * pn / i], abs=1e-13)


def test_coulomb_cap_puts_the_impulse_on_the_cone_edge_on_the_targets_side():
    e, mu = 0.4, 0.1
    s, r = corner_down(0.3, 1.0, -2.0, 0.0)  # sliding in +x: the target impulse points to -x
    i = ALPHA * R**2
    after, info = impact(Truth(beta_normal=e, beta_tangential=0.0, friction=mu), s, 0)
    assert info["capped"]
    knn, ktn = 1 + r[0] ** 2 / i, -r[0] * r[1] / i
    pn = (1 + e) * 2.0 / (knn - mu * ktn)
    assert after[3] == pytest.approx(1.0 - mu * pn, abs=1e-13)
    assert info["u_n_after"] == pytest.approx(e * 2.0, abs=1e-13)


def test_speed_restitution_divides_beta_normal():
    k, e, v = 0.5, 0.6, 2.0
    s, _ = corner_down(0.0, 0.0, -v, 0.0)
    for contact in ("rigid", "paper"):
        after, info = impact(Truth(contact=contact, beta_normal=e, speed_restitution=k), s, 0)
        assert after[4] == pytest.approx(e / (1 + k * v) * v, abs=1e-14)


def test_loaded_die_is_reported_at_its_geometric_centre():
    truth = Truth(com_offset=(0.01, 0.0))
    state0 = (0.0, 0.2, 0.0, 0.0, 0.0, 10.0)
    track = simulate_track(truth, state0, 0.05, 1000.0)
    # in flight the COM follows a parabola and the centre circles around it at 1 cm; the
    # centre starts at rest, so the COM starts at x = 1 cm moving up at omega * 1 cm
    com_x = track["x"] + 0.01 * np.cos(track["phi"])
    com_y = track["y"] + 0.01 * np.sin(track["phi"])
    t = track["t"]
    assert com_x == pytest.approx(0.01 * np.ones_like(t), abs=1e-14)
    assert com_y == pytest.approx(0.2 + 0.1 * t - 0.5 * G * t**2, abs=1e-14)
    assert track["phi"] == pytest.approx(10.0 * t, abs=1e-14)
    assert track["vx"][0] == 0.0 and track["vy"][0] == 0.0


# ----------------------------------------------------------------------------------- contact search


def test_no_corner_goes_below_the_table_and_impacts_are_at_contact():
    truth = Truth(contact="rigid", beta_normal=0.5, beta_tangential=-0.3, air_drag=0.3)
    for state in release_states(5, 11):
        path = simulate_path(truth, state, 0.5)
        for hit in path.impacts:
            s = hit["before"]
            k = hit["corner"]
            corner_y = s[1] + path.die.rho[k] * math.sin(s[2] + path.die.gamma[k])
            assert abs(corner_y) < 1e-12 * R
        for t0, t1, flight in path.flights:
            for t in np.linspace(t0, t1, 400):
                s = flight.state(t)
                assert np.min(s[1] + path.die.rho * np.sin(s[2] + path.die.gamma)) > -1e-12 * R


def test_tracks_end_before_sustained_contact():
    truth = Truth(beta_normal=0.4)
    for state in release_states(10, 5):
        track = simulate_track(truth, state, 2.0, 500.0)
        assert track["end"] in {"slow_impact", "second_corner", "no_rebound"}
        assert track["t"][-1] <= track["t_stop"] < track["t"][-1] + 1 / 500.0 + 1e-12
        last = track["path"].impacts[-1]
        assert -last["u_n"] >= 0.05


def test_a_flat_landing_bounces_and_a_dead_impact_ends_the_track():
    # a square released flat lands on two corners at once: one impact of both, straight up
    path = simulate_path(Truth(), (0.0, 0.1, math.pi / 4, 0.0, 0.0, 0.0), 0.5)
    first = path.impacts[0]
    tc = math.sqrt(2 * (0.1 - R / math.sqrt(2)) / G)
    assert first["t"] == pytest.approx(tc, abs=1e-12)
    assert first["contacts"] == 2 and first["share"] == 1.0
    assert first["after"][3:] == pytest.approx([0.0, 0.4 * G * tc, 0.0], abs=1e-12)
    assert path.end == "slow_impact" and all(hit["contacts"] == 2 for hit in path.impacts)
    # beta_normal = 0: the corner stays on the table, which is sustained contact
    path = simulate_path(Truth(beta_normal=0.0), (0.0, 0.1, 0.3, 0.0, 0.0, 1.0), 0.5)
    assert path.end == "no_rebound" and len(path.impacts) == 1
    # ... and so does a flat landing with beta_normal = 0: the die lies flat
    path = simulate_path(Truth(beta_normal=0.0), (0.0, 0.1, math.pi / 4, 0.3, 0.0, 0.0), 0.5)
    assert path.end == "no_rebound" and len(path.impacts) == 1 and path.impacts[0]["contacts"] == 2


def test_out_of_library_effects_act_in_flight():
    state0 = (0.0, 0.5, 0.0, 1.0, 0.0, 10.0)
    damped = simulate_path(Truth(spin_damping=2.0), state0, 0.2)
    s = damped.com_state(0.2)
    assert s[5] == pytest.approx(10.0 * math.exp(-0.4), rel=1e-14)
    assert s[2] == pytest.approx(10.0 * (1 - math.exp(-0.4)) / 2.0, rel=1e-14)
    assert s[1] == pytest.approx(0.5 - 0.5 * G * 0.04, abs=1e-14)  # translation untouched
    lifted = simulate_path(Truth(magnus=0.05), state0, 0.2).com_state(0.2)
    plain = simulate_path(Truth(), state0, 0.2).com_state(0.2)
    assert lifted[1] > plain[1] + 1e-3  # omega > 0 and vx > 0: the Magnus force lifts
    # the Magnus force is perpendicular to v: it does no work
    assert energy(Truth(), lifted) == pytest.approx(energy(Truth(), plain), rel=1e-10)


# ----------------------------------------------------------------------------------- physics outside the library (issue 30)


@pytest.mark.parametrize("w0", [10.0, -7.0])
def test_spin_drag_follows_its_closed_form(w0):
    """d omega/dt = -k |omega| omega: omega(t) = omega0 / (1 + k |omega0| t) and
    phi(t) = phi0 + sign(omega0) ln(1 + k |omega0| t) / k; the translation is untouched."""
    k, t = 0.05, 0.2
    s = simulate_path(Truth(spin_drag=k), (0.0, 0.5, 0.3, 1.0, 0.0, w0), t).com_state(t)
    assert s[5] == pytest.approx(w0 / (1.0 + k * abs(w0) * t), rel=1e-14)
    assert s[2] == pytest.approx(0.3 + math.copysign(1.0, w0) * math.log(1.0 + k * abs(w0) * t) / k, rel=1e-14)
    assert s[:2] == pytest.approx([t, 0.5 - 0.5 * G * t * t], abs=1e-14)
    # the angular acceleration is -k |omega| omega, by a central difference of the path
    path = simulate_path(Truth(spin_drag=k), (0.0, 0.5, 0.3, 1.0, 0.0, w0), t)
    h = 1e-4
    acc = (path.com_state(0.1 + h)[5] - path.com_state(0.1 - h)[5]) / (2 * h)
    w = path.com_state(0.1)[5]
    assert acc == pytest.approx(-k * abs(w) * w, rel=1e-6)
    # with the Magnus force the integrated translation sees the decaying spin
    lifted = simulate_path(Truth(magnus=0.05, spin_drag=k), (0.0, 0.5, 0.3, 1.0, 0.0, w0), t).com_state(t)
    assert lifted[5] == pytest.approx(s[5], rel=1e-14)


def test_a_tilted_table_gives_a_parabola_along_it():
    """In the table's frame gravity is (g sin(tilt), -g cos(tilt)): x and y are parabolas in
    flight, and energy with the potential g (cos(tilt) y - sin(tilt) x) is conserved."""
    tilt, t = math.radians(3.0), 0.2
    truth = Truth(table_tilt=tilt)
    s = simulate_path(truth, (0.01, 0.5, 0.3, 0.7, 0.4, 5.0), t).com_state(t)
    assert s[0] == pytest.approx(0.01 + 0.7 * t + 0.5 * G * math.sin(tilt) * t * t, abs=1e-14)
    assert s[1] == pytest.approx(0.5 + 0.4 * t - 0.5 * G * math.cos(tilt) * t * t, abs=1e-14)
    assert s[3:] == pytest.approx([0.7 + G * math.sin(tilt) * t, 0.4 - G * math.cos(tilt) * t, 5.0], abs=1e-14)
    # with drag, numerically: the same parabola as drag goes to zero
    dragged = simulate_path(Truth(table_tilt=tilt, air_drag=1e-9), (0.01, 0.5, 0.3, 0.7, 0.4, 5.0), t).com_state(t)
    assert dragged[:2] == pytest.approx(s[:2], abs=1e-9)
    path = simulate_path(truth, (0.0, 0.15, 0.3, -0.5, -1.9, 6.0), 0.5)
    assert len(path.impacts) >= 3
    for t0, t1, flight in path.flights:
        e = [energy(truth, flight.state(tt)) for tt in np.linspace(t0, t1, 7)]
        assert np.ptp(e) < 1e-12 * abs(e[0]) + 1e-15


@pytest.mark.parametrize("contact", ["rigid", "paper"])
def test_restitution_by_corner_acts_at_the_touching_corner(contact):
    """Each corner k falling straight down (no spin, no slip) leaves at beta_k times its speed;
    a path records each impact's own beta."""
    betas = (0.2, 0.5, 0.35, 0.6)
    truth = Truth(contact=contact, corner_beta_normal=betas, beta_normal=0.4)
    for k, beta in enumerate(betas):
        phi = -math.pi / 2 - 2 * math.pi * k / 4  # corner k straight down
        new, info = impact(truth, (0.0, R, phi, 0.0, -2.0, 0.0), k)
        assert new[3:] == pytest.approx([0.0, 2.0 * beta, 0.0], abs=1e-12), k
        assert info["beta_n"] == pytest.approx(beta)
    path = simulate_path(truth, (0.0, 0.15, 0.3, -0.5, -1.9, 6.0), 0.5)
    assert len(path.impacts) >= 3
    assert all(h["beta_n"] == pytest.approx(betas[h["corner"]]) for h in path.impacts if h["contacts"] == 1)
    for bad in ((0.4, 0.4, 0.4), (0.4, 0.4, 0.4, 1.2)):
        with pytest.raises(ValueError):
            simulate_path(Truth(corner_beta_normal=bad), (0.0, 0.15, 0.3, -0.5, -1.9, 6.0), 0.1)


@pytest.mark.parametrize("beta", [0.2, 0.4, 1 / math.e, 0.9])
def test_compliant_contact_of_a_point_mass_has_its_restitution_and_duration(beta):
    """A corner straight down under the centre is a point mass for the normal force (no lever):
    without gravity it leaves at beta times its speed after exactly the contact time, whatever
    the speed; the constants follow the closed form of compliant_constants."""
    duration = 4e-4
    truth = Truth(compliant_time=duration, beta_normal=beta, friction=0.3, g=0.0)
    die = ind._Die(truth)
    for speed in (0.5, 2.0):
        contact = ind._Contact(truth, die, 0.0, (0.0, R, -math.pi / 2, 0.0, -speed, 0.0))
        assert contact.ended
        assert contact.after[3:] == pytest.approx([0.0, beta * speed, 0.0], rel=1e-7, abs=1e-12)
        assert contact.t1 == pytest.approx(duration, rel=1e-6)
    stiff, damp = ind.compliant_constants(beta, duration)
    zeta = damp / (2 * math.sqrt(stiff))
    f = ind._loading_decay(zeta)
    assert math.exp(-zeta * f) == pytest.approx(beta, rel=1e-12)
    assert (f + math.pi / 2) / math.sqrt(stiff) == pytest.approx(duration, rel=1e-12)


def test_compliant_contact_sliding_throughout_is_the_coulomb_impulse():
    """A short compliant contact (1e-5 s: the die turns by 2e-4 rad in it) of a corner straight
    down that slides all the way: the tangential impulse is -mu times the normal one,
    (1 + beta) v_n, and it spins the die by R P_t / I about its centre."""
    mu, beta, vn, vx = 0.1, 0.4, 2.0, 2.0
    truth = Truth(compliant_time=1e-5, beta_normal=beta, friction=mu, g=0.0)
    die = ind._Die(truth)
    contact = ind._Contact(truth, die, 0.0, (0.0, R, -math.pi / 2, vx, -vn, 0.0))
    pn = (1 + beta) * vn
    pt = -mu * pn
    assert contact.after[3:] == pytest.approx([vx + pt, beta * vn, R * pt / (ALPHA * R * R)], rel=2e-3)


def test_compliant_tracks_bounce_for_a_while_and_gain_no_energy():
    truth = Truth(compliant_time=5e-4, beta_normal=0.4, friction=0.3)
    for state in release_states(6, 3):
        path = simulate_path(truth, state, 0.5)
        assert path.impacts and all(h["law"] == "compliant" for h in path.impacts)
        for h in path.impacts:
            assert 0.3 * 5e-4 < h["duration"] < 3 * 5e-4
            assert energy(truth, h["after"]) <= energy(truth, h["before"]) + 1e-12
        # the frames sample the contact too: never deeper than a millimetre below the table
        die = ind._Die(truth)
        for h in path.impacts:
            for tt in np.linspace(h["t"], h["t"] + h["duration"], 9):
                assert die.heights(path.com_state(tt)).min() > -1e-3
    for bad in (dict(compliant_time=2e-3), dict(compliant_time=1e-4), dict(compliant_time=1e-4, friction=0.3, contact_time=1e-4),
                dict(spin_drag=0.1, spin_damping=1.0), dict(spin_drag=-0.1), dict(table_tilt=2.0)):
        with pytest.raises(ValueError):
            simulate_path(Truth(**bad), (0.0, 0.15, 0.3, -0.5, -1.9, 6.0), 0.1)


# ----------------------------------------------------------------------------------- inertia, friction rules, rounded corners


RULES = [("aimed", "newton"), ("sliding", "newton"), ("exact", "newton"), ("exact", "energetic")]


def test_new_truth_fields_are_validated():
    for bad in (dict(friction_rule="kinetic"), dict(restitution="poisson"), dict(restitution="energetic"),
                dict(inertia=0.0), dict(inertia=-1.0), dict(inertia=3.01), dict(inertia=0.01, com_offset=(0.02, 0.0)),
                dict(corner_radius=-1e-4), dict(corner_radius=R * math.cos(math.pi / 4)), dict(corner_radius=math.nan)):
        with pytest.raises(ValueError):
            simulate_path(Truth(**bad), (0.0, 0.15, 0.3, -0.5, -1.9, 6.0), 0.1)
    simulate_path(Truth(friction_rule="exact", restitution="energetic", inertia=3.0, corner_radius=0.02), (0.0, 0.15, 0.3, -0.5, -1.9, 6.0), 0.1)


@pytest.mark.parametrize("rule,restitution", RULES)
def test_no_impact_gains_energy_for_any_friction_rule(rule, restitution):
    rng = np.random.default_rng(17)
    impacts = clipped = 0
    seen = {"capped": 0, "stick": 0, "reversal": 0}
    for state in release_states(30, 23):
        truth = Truth(contact=["rigid", "paper"][rng.integers(2)], beta_normal=rng.uniform(0.0, 1.0),
                      beta_tangential=rng.uniform(-1.0, 1.0), friction=[math.inf, rng.uniform(0.0, 1.0)][rng.integers(2)],
                      com_offset=tuple(rng.uniform(-0.008, 0.008, 2)), speed_restitution=rng.uniform(0.0, 1.0),
                      inertia=rng.uniform(0.5, 1.5), corner_radius=[0.0, rng.uniform(0.0, 0.006)][rng.integers(2)],
                      friction_rule=rule, restitution=restitution)
        for hit in simulate_path(truth, state, 0.5).impacts:
            impacts += 1
            clipped += hit["clipped"]
            for key in seen:
                seen[key] += bool(hit.get(key, False))
            scale = ind.kinetic_energy(truth, hit["before"])
            assert energy(truth, hit["after"]) - energy(truth, hit["before"]) <= 1e-12 * scale
            assert hit["dT"] <= 1e-12 * scale
    assert impacts > 80
    assert seen["capped"] > 0
    if rule == "exact":
        assert seen["stick"] > 0 and seen["reversal"] > 0, seen
    elif rule == "sliding":
        assert clipped > 0  # the energy rule was exercised


def _corner_velocity(s, r):
    """(u_t, u_n) of the contact point at ``r`` from the COM for a COM state."""
    return np.array([s[3] - s[5] * r[1], s[4] + s[5] * r[0]])


def _k_matrix(r, i):
    return np.array([[1 + r[1] ** 2 / i, -r[0] * r[1] / i], [-r[0] * r[1] / i, 1 + r[0] ** 2 / i]])


@pytest.mark.parametrize("restitution", ["newton", "energetic"])
def test_exact_rule_without_friction_is_the_frictionless_impulse(restitution):
    # without friction the normal work in compression is -u_n0^2/(2 K_nn) and in restitution
    # u_n'^2/(2 K_nn): both restitution laws give u_n' = -beta_n u_n0, the frictionless impulse
    for tilt, vx, vy, w in ((0.3, 0.5, -2.0, 0.0), (-0.7, -1.0, -1.5, 12.0), (1.1, 0.2, 0.3, -30.0)):
        s, r = corner_down(tilt, vx, vy, w)
        if _corner_velocity(s, r)[1] >= 0.0:
            continue
        free, _ = impact(Truth(beta_normal=0.6, friction=0.0), s, 0)
        exact, info = impact(Truth(beta_normal=0.6, friction=0.0, friction_rule="exact", restitution=restitution), s, 0)
        assert not info["stick"] and not info["clipped"]
        assert exact[3:] == pytest.approx(free[3:], abs=1e-12 * (1 + abs(w)))


@pytest.mark.parametrize("restitution", ["newton", "energetic"])
def test_exact_rule_with_huge_friction_sticks(restitution):
    e, mu = 0.5, 1e6
    s, r = corner_down(0.3, 0.3, -2.0, 0.0)
    i = ALPHA * R**2
    K = _k_matrix(r, i)
    assert abs(K[0, 1] / K[0, 0]) <= mu
    after, info = impact(Truth(beta_normal=e, friction=mu, friction_rule="exact", restitution=restitution), s, 0)
    assert info["stick"] and not info["reversal"]
    u = _corner_velocity(after, r)
    assert u[0] == pytest.approx(0.0, abs=1e-12)
    if restitution == "newton":
        # stuck with Newton restitution: u' = (0, -e u_n), the rigid law's target with
        # beta_t = 0 and no cap
        rigid, rinfo = impact(Truth(beta_normal=e, beta_tangential=0.0), s, 0)
        assert not rinfo["clipped"]
        assert after[3:] == pytest.approx(rigid[3:], abs=1e-9)
    else:
        assert u[1] > 0.0 and u[1] != pytest.approx(e * 2.0, abs=1e-3)  # Stronge's law differs from Newton's here


@pytest.mark.parametrize("mu,reverses", [(0.2, True), (0.5, False)])
def test_exact_rule_reverses_the_slip_when_friction_cannot_hold_it(mu, reverses):
    # tilt 0.5 on the square: K_tn / K_tt = 0.381; a slow slip to -x is stopped during the impact
    e, tilt = 0.4, 0.5
    s, r = corner_down(tilt, -0.1, -2.0, 0.0)
    i = ALPHA * R**2
    K = _k_matrix(r, i)
    assert (abs(K[0, 1] / K[0, 0]) > mu) == reverses
    u0 = _corner_velocity(s, r)
    assert u0[0] == pytest.approx(-0.1, abs=1e-15)
    after, info = impact(Truth(beta_normal=e, friction=mu, friction_rule="exact"), s, 0)
    assert info["reversal"] == reverses and info["stick"] == (not reverses) and not info["clipped"]
    u = _corner_velocity(after, r)
    assert u[1] == pytest.approx(-e * u0[1], abs=1e-12)
    # by hand: slide to -x (f = +mu) until u_t = 0 at p1, then
    ktt, ktn, knn = K[0, 0], K[0, 1], K[1, 1]
    p1 = -u0[0] / (ktn + mu * ktt)
    un1 = u0[1] + (knn + mu * ktn) * p1
    assert un1 < -e * u0[1]
    if reverses:  # slide to +x (f = -mu) to the end
        pf = p1 + (-e * u0[1] - un1) / (knn - mu * ktn)
        assert u[0] == pytest.approx((ktn - mu * ktt) * (pf - p1), abs=1e-12)
        assert u[0] > 0.0
    else:  # stuck (f = -K_tn / K_tt)
        pf = p1 + (-e * u0[1] - un1) / (knn - ktn**2 / ktt)
        assert u[0] == pytest.approx(0.0, abs=1e-12)
    assert after[4] - s[4] == pytest.approx(pf, abs=1e-12)  # P_n: the normal impulse per unit mass


def test_exact_energetic_restitution_balances_the_normal_work():
    # Stronge: work of the normal force in restitution = beta_n^2 (- work in compression),
    # integrated here by hand over the piecewise-linear u_n(p) of a slip reversal
    e, mu, tilt = 0.6, 0.2, 0.5
    s, r = corner_down(tilt, -0.1, -2.0, 0.0)
    K = _k_matrix(r, ALPHA * R**2)
    after, info = impact(Truth(beta_normal=e, friction=mu, friction_rule="exact", restitution="energetic"), s, 0)
    assert info["reversal"]
    u0 = _corner_velocity(s, r)
    ktt, ktn, knn = K[0, 0], K[0, 1], K[1, 1]
    p1 = -u0[0] / (ktn + mu * ktt)
    un1 = u0[1] + (knn + mu * ktn) * p1
    slope = knn - mu * ktn  # after the reversal
    assert un1 < 0.0  # the reversal is in compression
    pc = p1 - un1 / slope
    w_c = 0.5 * (u0[1] + un1) * p1 + 0.5 * un1 * (pc - p1)
    pf = after[4] - s[4]
    w_r = 0.5 * slope * (pf - pc) ** 2
    assert w_r == pytest.approx(-e**2 * w_c, rel=1e-10)
    assert _corner_velocity(after, r)[1] == pytest.approx(slope * (pf - pc), abs=1e-12)


def test_exact_newton_impact_that_would_gain_energy_takes_the_energetic_terminal():
    # sticking with Newton restitution near 1 at a tilted corner: Newton's terminal gains energy
    e, mu = 0.997, 1.02
    s, r = corner_down(-0.63, 0.61, -1.0, 0.0)
    K = _k_matrix(r, ALPHA * R**2)
    u0 = _corner_velocity(s, r)
    P, raw = ind._exact_impulse(K, u0, e, mu, "newton")
    assert raw["stick"] and raw["dT"] > 0.01  # the configuration: Newton alone gains energy
    after, info = impact(Truth(beta_normal=e, friction=mu, friction_rule="exact"), s, 0)
    energetic, _ = impact(Truth(beta_normal=e, friction=mu, friction_rule="exact", restitution="energetic"), s, 0)
    assert info["clipped"] and info["energetic_terminal"] and info["dT"] <= 0.0
    assert np.array_equal(after, energetic)


def test_sliding_rule_opposes_the_slip_where_the_normal_impulse_throws_the_corner_back():
    e, mu, tilt = 0.4, 0.1, 0.3
    i = ALPHA * R**2
    # slow slip to -x: the normal impulse (K_tn > 0) alone would throw the corner to +x, so the
    # impulse aimed at stopping the slip points along the slip, to -x
    s, r = corner_down(tilt, -0.05, -2.0, 0.0)
    K = _k_matrix(r, i)
    u0 = _corner_velocity(s, r)
    aimed_t = np.linalg.solve(K, np.array([0.0, -e * u0[1]]) - u0)
    assert aimed_t[0] < 0.0 and abs(aimed_t[0]) > mu * aimed_t[1]
    aimed, a_info = impact(Truth(beta_normal=e, friction=mu), s, 0)
    sliding, s_info = impact(Truth(beta_normal=e, friction=mu, friction_rule="sliding"), s, 0)
    assert a_info["capped"] and s_info["capped"] and not s_info["clipped"]
    assert aimed[3] - s[3] < 0.0  # the cone edge on the target's side: along the slip
    pn = (1 + e) * -u0[1] / (K[1, 1] + mu * K[0, 1])  # the textbook branch: P_t = +mu P_n
    assert sliding[3] - s[3] == pytest.approx(mu * pn, abs=1e-13)
    assert sliding[4] - s[4] == pytest.approx(pn, abs=1e-13)
    assert abs(sliding[5] - aimed[5]) > 1.0
    # a slip to +x (the normal impulse throws the corner along it) or a fast slip to -x: the
    # target impulse opposes the slip, both rules take the same edge
    for slip in (0.5, -3.0):
        s, r = corner_down(tilt, slip, -2.0, 0.0)
        aimed, a_info = impact(Truth(beta_normal=e, friction=mu), s, 0)
        sliding, s_info = impact(Truth(beta_normal=e, friction=mu, friction_rule="sliding"), s, 0)
        assert a_info["capped"] and s_info["capped"] and (aimed[3] - s[3]) * slip < 0.0
        assert np.array_equal(aimed, sliding)


def test_sliding_rule_for_two_contacts_opposes_the_rows_slip():
    rng = np.random.default_rng(31)
    edges = 0
    for _ in range(300):
        truth = Truth(sides=4, circumradius=0.03, beta_normal=rng.uniform(0.0, 1.0), beta_tangential=rng.uniform(-1.0, 1.0),
                      friction=rng.uniform(0.05, 0.6), friction_rule="sliding")
        speed = rng.uniform(0.3, 2.0)
        state = landing(4, 0.03, 0.0, rng.uniform(-2.0, 2.0), speed, rng.uniform(-0.95, 0.95) * 2 * speed / (2 * 0.03 * math.sin(math.pi / 4)), 0.0)
        die = ind._Die(truth)
        com = die.to_com(state)
        com[1] -= min(die.heights(com))
        k, j = (int(c) for c in np.argsort(die.heights(com))[:2])
        after, info = impact(truth, com, k, j)
        scale = ind.kinetic_energy(truth, com)
        assert ind.kinetic_energy(truth, after) - scale <= 1e-12 * scale
        case = info.get("case")
        if isinstance(case, tuple) and case[2].endswith("edge") and not info["clipped"]:
            edges += 1
            pressing = [r for r, on in zip(die.corners(com)[[k, j]], case[:2]) if on]
            mid = sum(pressing) / len(pressing)
            u_t_in = com[3] - com[5] * mid[1]
            assert math.copysign(1.0, after[3] - com[3]) == -math.copysign(1.0, u_t_in)
    assert edges > 10


def test_exact_rule_ends_the_track_at_a_two_contact_impact():
    truth = Truth(friction=0.3, friction_rule="exact")
    path = simulate_path(truth, (0.0, 0.1, math.pi / 4, 0.0, 0.0, 0.0), 0.5)
    assert path.end == "exact_two_contacts" and not path.impacts
    s, _ = corner_down(0.0, 0.0, -1.0, 0.0)
    with pytest.raises(NotImplementedError):
        impact(truth, s, 0, 1)


@pytest.mark.parametrize("com_offset", [(0.0, 0.0), (0.004, -0.002)])
def test_inertia_factor_sets_the_spin_after_a_corner_falls_straight_down(com_offset):
    # a tilted die falling straight down onto corner 0, frictionless: P_n = (1+e) v / (1 + r_x^2/I),
    # omega' = r_x P_n / I with I = factor * eq. 25 - |d|^2 about the COM
    e, v, tilt, factor = 0.4, 2.0, 0.3, 0.85
    d = np.array(com_offset)
    truth = Truth(beta_normal=e, friction=0.0, inertia=factor, com_offset=com_offset)
    die = ind._Die(truth)
    i = factor * ALPHA * R**2 - d @ d
    assert die.inertia == pytest.approx(i, rel=1e-15)
    phi = -math.pi / 2 + tilt
    corner = R * np.array([math.cos(phi), math.sin(phi)])
    com_from_centre = np.array([[math.cos(phi), -math.sin(phi)], [math.sin(phi), math.cos(phi)]]) @ d
    r = corner - com_from_centre
    s = np.array([0.0, -r[1], phi, 0.0, -v, 0.0])
    after, _ = impact(truth, s, 0)
    pn = (1 + e) * v / (1 + r[0] ** 2 / i)
    assert after[5] == pytest.approx(r[0] * pn / i, abs=1e-12)
    assert after[4] == pytest.approx(-v + pn, abs=1e-13)
    # and it differs from the uniform plate's spin by more than round-off
    plain, _ = impact(Truth(beta_normal=e, friction=0.0, com_offset=com_offset), s, 0)
    assert abs(plain[5] - after[5]) > 0.1


@pytest.mark.parametrize("tilt", [0.0, 0.3])
def test_rounded_corner_touches_when_its_arc_centre_is_at_height_r(tilt):
    # released at rest with corner 0 at tilt from straight down: the arc centre (the core's
    # corner, circumradius (a - r)/cos(pi/4)) reaches height r at sqrt(2 (y0 - Rc cos(tilt) - r) / g)
    r_c, y0, e = 0.004, 0.12, 0.4
    core = (R * math.cos(math.pi / 4) - r_c) / math.cos(math.pi / 4)
    truth = Truth(corner_radius=r_c, beta_normal=e, friction=0.0)
    path = simulate_path(truth, (0.0, y0, -math.pi / 2 + tilt, 0.0, 0.0, 0.0), 0.5)
    first = path.impacts[0]
    assert first["corner"] == 0
    assert first["t"] == pytest.approx(math.sqrt(2 * (y0 - core * math.cos(tilt) - r_c) / G), abs=1e-12)
    # the impulse acts at the contact point below the arc centre: lever x Rc sin(tilt), y -(Rc cos(tilt) + r)
    lever = np.array([core * math.sin(tilt), -(core * math.cos(tilt) + r_c)])
    assert path.die.corners(first["before"])[0] == pytest.approx(lever, abs=1e-15)
    i = ALPHA * R**2
    v = -first["before"][4]
    pn = (1 + e) * v / (1 + lever[0] ** 2 / i)
    assert first["after"][3:] == pytest.approx([0.0, -v + pn, lever[0] * pn / i], abs=1e-12)
    # with friction the tangential lever is the contact point's depth below the COM
    rigid, _ = impact(Truth(corner_radius=r_c, beta_normal=e, beta_tangential=0.0), first["before"], 0)
    pt = (1 + e) * v * lever[0] * lever[1] / (i + lever @ lever)
    assert rigid[3] == pytest.approx(pt, abs=1e-12)


def test_rounded_corners_never_go_below_the_table():
    truth = Truth(corner_radius=0.005, beta_normal=0.5, beta_tangential=-0.3, friction=0.3, air_drag=0.3)
    for state in release_states(5, 11):
        path = simulate_path(truth, state, 0.5)
        assert len(path.impacts) >= 2
        for hit in path.impacts:
            assert abs(path.die.heights(hit["before"])[hit["corner"]]) < 1e-12 * R
        for t0, t1, flight in path.flights:
            for t in np.linspace(t0, t1, 200):
                assert path.die.heights(flight.state(t)).min() > -1e-12 * R


# the generator before rounded corners, inertia and friction rules (commit c762595): first four
# impact times and the centre's state at 0.3 s of two drops of a loaded die with friction
BEFORE = [
    ((0.0, 0.15, 0.3, -0.5, -1.9, 6.0), [0.0534827151576931, 0.05871770422217851, 0.2672533273998198, 0.2876813439020144],
     [-0.21926914369418435, 0.03924795670579716, 4.109973904139344, -0.746937046374308, 0.35813383098553503, 2.859730487827278]),
    ((0.01, 0.13, -2.0, -0.7, -1.8, -5.0), [0.04749555186450018, 0.05058872338261388, 0.19907868658432648, 0.2625631630561265],
     [-0.1048059861799084, 0.031621162252388126, -2.300896901999563, -0.16754930597642442, 0.020043353355384763, 0.06329532715139252]),
]


@pytest.mark.parametrize("state,times,pose", BEFORE)
def test_defaults_give_the_tracks_of_before(state, times, pose):
    truth = Truth(contact="rigid", beta_normal=0.4, beta_tangential=-0.2, friction=0.3, com_offset=(0.003, 0.002),
                  inertia=1.0, friction_rule="aimed", restitution="newton", corner_radius=0.0)
    path = simulate_path(truth, state, 0.5)
    assert [h["t"] for h in path.impacts[:4]] == pytest.approx(times, abs=1e-12)
    assert path.centre_state(0.3) == pytest.approx(pose, abs=1e-12)
    # a vanishing corner radius is continuous with none
    tiny = simulate_path(dataclasses.replace(truth, corner_radius=1e-14), state, 0.5)
    assert tiny.centre_state(0.3) == pytest.approx(pose, abs=1e-9)


# ----------------------------------------------------------------------------------- the kernel


def kernel_poses(truth, states, times):
    """The project's kernel, sampled at ``times`` for each state (geometric centre poses)."""
    from dice_sweep.config import parse_config
    from dice_sweep.physics import pack_params
    from dice_sweep.physics.kernel import sample_batch
    from dice_sweep.physics.params import IP_CONTINUE

    cfg = parse_config(
        f"[die]\nsides = {truth.sides}\ncircumradius = {truth.circumradius!r}\n"
        f'[contact]\nmodel = "{truth.contact}"\nbeta_normal = {truth.beta_normal!r}\n'
        f"beta_tangential = {truth.beta_tangential!r}\nfriction = {truth.friction!r}\nwindow = {truth.window!r}\n"
        f'friction_rule = "{truth.friction_rule}"\nrestitution = "{truth.restitution}"\n'
        f"[world]\ng = {truth.g!r}\n"
        f"[effects]\nair_drag = {truth.air_drag!r}\ncom_offset = [{truth.com_offset[0]!r}, {truth.com_offset[1]!r}]\n"
        f"speed_restitution = {truth.speed_restitution!r}\ncontact_time = {truth.contact_time!r}\n"
        f"inertia = {truth.inertia!r}\ncorner_radius = {truth.corner_radius!r}\n"
        f"[integrator]\nt_max = {float(max(t[-1] for t in times if len(t))) + 0.01!r}\n"
    )
    fpar, ipar = pack_params(cfg)
    ipar[IP_CONTINUE] = 1
    all_t = np.concatenate(times)
    starts = np.concatenate([[0], np.cumsum([len(t) for t in times])])
    out = np.zeros((all_t.size, 6))
    sample_batch(fpar, ipar, np.asarray(states, float), all_t, starts, out, np.zeros(len(states), np.int8))
    return [out[starts[i]:starts[i + 1]] for i in range(len(states))]


def _t(contact, **kw):
    """A Truth at the test's base coefficients (beta_normal 0.4, beta_tangential -0.2)."""
    return Truth(contact=contact, **{"beta_normal": 0.4, "beta_tangential": -0.2, **kw})


KERNEL_CASES = {
    # name: (truth, the impact law or branch the case must exercise)
    "paper": (_t("paper"), "fallback"),
    "paper+friction": (_t("paper", friction=0.3), "capped"),
    "rigid": (_t("rigid"), "rigid"),
    "rigid+friction": (_t("rigid", friction=0.3), "capped"),
    "rigid, energy rule": (_t("rigid", beta_normal=0.5, beta_tangential=-0.9, friction=0.5), "clipped"),
    "drag": (_t("rigid", air_drag=0.5), "rigid"),
    "com_offset rigid": (_t("rigid", com_offset=(0.006, -0.004)), "rigid"),
    "com_offset paper": (_t("paper", com_offset=(0.006, -0.004)), "fallback"),
    "speed_restitution rigid": (_t("rigid", beta_normal=0.6, speed_restitution=0.5), "rigid"),
    "speed_restitution paper": (_t("paper", beta_normal=0.6, speed_restitution=0.5), "fallback"),
    "hexagon, everything": (_t("rigid", sides=6, circumradius=0.03, beta_tangential=-0.3, friction=0.4, air_drag=0.2,
                               com_offset=(0.003, 0.002), speed_restitution=0.3), "capped"),
    "inertia": (_t("rigid", inertia=0.85), "rigid"),
    "inertia, loaded paper": (_t("paper", inertia=0.85, com_offset=(0.004, -0.002)), "fallback"),
    "sliding friction": (_t("rigid", friction=0.2, friction_rule="sliding"), "capped"),
    "exact newton": (_t("rigid", friction=0.3, friction_rule="exact"), "reversal"),
    "exact energetic": (_t("rigid", friction=0.3, friction_rule="exact", restitution="energetic"), "stick"),
    "rounded corners": (_t("rigid", corner_radius=0.003), "rigid"),
}
KERNEL_TOL = (1e-8, 1e-7)  # m, rad; measured: at most 2e-12 m and 4e-11 rad (300 drops per case)


@pytest.mark.parametrize("name", list(KERNEL_CASES))
def test_agrees_with_the_kernel_over_the_first_three_impacts(name):
    truth, exercised = KERNEL_CASES[name]
    states = release_states(20, 1)
    tracks = [simulate_track(truth, s, 0.5, 2000.0) for s in states]
    times, used = [], 0
    for tr in tracks:
        hits = tr["path"].impacts[:3]
        assert len(hits) == 3  # generic drops bounce at least three times
        times.append(tr["t"][tr["t"] <= hits[-1]["t"]])
        used += sum(bool(h[exercised]) if exercised in h else h["law"] == exercised for h in hits)
    assert used > 0, f"no impact of this case exercised {exercised!r}"
    for tr, t, ref in zip(tracks, times, kernel_poses(truth, states, times)):
        n = t.size
        assert np.abs(ref[:, :2] - np.column_stack([tr["x"][:n], tr["y"][:n]])).max() < KERNEL_TOL[0]
        assert np.abs(ref[:, 2] - tr["phi"][:n]).max() < KERNEL_TOL[1]


# ----------------------------------------------------------------------------------- two contacts at once


def flat_phi(n):
    """phi at which side 0 (corners 0 and 1) lies flat below the centre (rad)."""
    return -math.pi / 2 - math.pi / n


def landing(n, radius, tilt, vx, speed, omega, drop=None):
    """Geometric-centre state of a plate that, falling ``drop`` m (default: half the height
    that ``speed`` needs) with spin ``omega``, touches the table at ``speed`` (m/s, downwards)
    with side 0 at ``tilt`` rad from flat (the centre's height at the landing is the apothem,
    whatever the tilt: to first order)."""
    drop = speed**2 / (4.0 * G) if drop is None else drop
    vy0 = -math.sqrt(speed**2 - 2.0 * G * drop)
    t_fall = (-vy0 - speed) / -G  # vy0 - G t = -speed
    return (0.0, radius * math.cos(math.pi / n) + drop, flat_phi(n) + tilt - omega * t_fall, vx, vy0, omega)


@pytest.mark.parametrize("sides", [3, 4, 5, 6, 8])
@pytest.mark.parametrize("contact", ["rigid", "paper"])
@pytest.mark.parametrize("friction", [0.0, 0.4, math.inf])
def test_flat_impact_without_spin_or_slip_leaves_straight_up(sides, contact, friction):
    # docs/physics.md: a flat impact without spin or slip leaves without spin, along the
    # normal at beta_normal times its speed, every n, both laws, any friction
    truth = Truth(sides=sides, circumradius=0.03, contact=contact, beta_normal=0.4, beta_tangential=-0.2, friction=friction)
    path = simulate_path(truth, landing(sides, 0.03, 0.0, 0.0, 1.3, 0.0), 0.2)
    first = path.impacts[0]
    assert first["contacts"] == 2 and first["share"] == 1.0
    assert first["after"][3:] == pytest.approx([0.0, 0.4 * 1.3, 0.0], abs=1e-12)


def _frictionless_by_quadratic_programming(truth, com_state, k, j):
    """The frictionless two-contact impact as the quadratic programme equivalent to its linear
    complementarity problem (K positive definite): min 1/2 P.K P + P.(u - target), P >= 0;
    solved by scipy's L-BFGS-B."""
    from scipy.optimize import minimize

    die = ind._Die(truth)
    r = die.corners(com_state)[[k, j]]
    rows = np.array([[0.0, 1.0, r[0][0]], [0.0, 1.0, r[1][0]]])  # normal velocity of each corner
    w = np.diag([1.0, 1.0, 1.0 / die.inertia])
    K = rows @ w @ rows.T
    u = rows @ com_state[3:]
    target = -truth.beta_normal * np.minimum(u, 0.0)
    res = minimize(lambda p: (0.5 * p @ K @ p + p @ (u - target), K @ p + u - target), np.zeros(2), jac=True,
                   method="L-BFGS-B", bounds=[(0.0, None)] * 2, options={"ftol": 1e-15, "gtol": 1e-13})
    return com_state[3:] + w @ rows.T @ res.x


def test_two_contact_impacts_gain_no_energy_and_leave_no_corner_approaching():
    rng = np.random.default_rng(12)
    seen = set()
    for _ in range(800):
        n = int(rng.choice([3, 4, 5, 6, 8]))
        side = 2 * 0.03 * math.sin(math.pi / n)
        truth = Truth(sides=n, circumradius=0.03, contact=str(rng.choice(["rigid", "paper"])), beta_normal=rng.uniform(0.0, 1.0),
                      beta_tangential=rng.uniform(-1.0, 1.0), friction=[0.0, 0.2, 0.6, math.inf][rng.integers(4)],
                      com_offset=tuple(rng.uniform(-0.004, 0.004, 2)) if rng.random() < 0.3 else (0.0, 0.0))
        speed = rng.uniform(0.3, 2.0)
        state = landing(n, 0.03, rng.uniform(-1e-6, 1e-6), rng.uniform(-2.0, 2.0), speed, rng.uniform(-0.95, 0.95) * 2 * speed / side, 0.0)
        die = ind._Die(truth)
        com = die.to_com(state)
        com[1] -= min(com[1] + die.rho * np.sin(com[2] + die.gamma))  # the lower corner on the table
        heights = com[1] + die.rho * np.sin(com[2] + die.gamma)
        k, j = (int(c) for c in np.argsort(heights)[:2])
        share = [1.0, rng.uniform(0.0, 1.0)][rng.integers(2)]
        after, info = impact(truth, com, k, j, share)
        assert info["contacts"] == 2
        case = info.get("case")
        on, mode = (case[:2], case[2]) if isinstance(case, tuple) else (None, None)
        seen.add((info["law"], on, mode, info["clipped"]))
        scale = ind.kinetic_energy(truth, com)
        assert ind.kinetic_energy(truth, after) - scale <= 1e-12 * scale
        assert info["u_n_after"] >= -1e-12 * speed  # the first corner leaves, whatever the share
        if share == 1.0:
            assert info["u_n_second_after"] >= -1e-12 * speed
        if truth.friction == 0.0 and info["law"] != "paper" and share == 1.0:
            reference = _frictionless_by_quadratic_programming(truth, com, k, j)
            assert after[3:] == pytest.approx(reference, abs=1e-7 * speed / 0.03)
    # the cases exercised: one corner without impulse, cone edges, the energy rule, the paper law
    # and its fallback
    assert {law for law, *_ in seen} == {"rigid", "paper", "fallback"}
    assert {on for _, on, *_ in seen} >= {(True, True), (True, False), (False, True)}
    assert {mode for _, _, mode, _ in seen} >= {"target", "+edge", "-edge", "none"}
    assert any(clipped for *_, clipped in seen)


# first impacts of flat drops: (delay of the second corner, s) for a tilt, the geometric one
def _delay(sides, radius, tilt, speed):
    return 2 * radius * math.sin(math.pi / sides) * math.sin(abs(tilt)) / speed


FLAT_TILTS = (0.0, 1e-9, -1e-9, 1e-3, -1e-3)
FLAT_TOL = (1e-10, 1e-9)  # m, rad; measured: at most 3e-14 m and 8e-13 rad over whole paths


@pytest.mark.parametrize("sides,radius", [(4, R), (6, 0.03)])
@pytest.mark.parametrize("contact", ["rigid", "paper"])
def test_flat_drops_agree_with_the_kernel(sides, radius, contact):
    """Squares and hexagons dropped 12 cm with a side flat, tilted by 1e-9 and 1e-3 rad, at
    contact times 0, 1e-4 and 1e-3 s, with and without slip and a friction cap: whole paths
    (to the generator's end of track) against the kernel's."""
    for contact_time in (0.0, 1e-4, 1e-3):
        for friction in (math.inf, 0.3):
            truth = _t(contact, sides=sides, circumradius=radius, friction=friction, contact_time=contact_time)
            states = [(0.0, 0.12, flat_phi(sides) + tilt, vx, 0.0, 0.0) for tilt in FLAT_TILTS for vx in (0.0, 0.3)]
            tracks = [simulate_track(truth, s, 0.5, 2000.0) for s in states]
            for state, tr, ref in zip(states, tracks, kernel_poses(truth, states, [tr["t"] for tr in tracks])):
                first = tr["path"].impacts[0]
                tilt = state[2] - flat_phi(sides)
                delay = _delay(sides, radius, tilt, -first["before"][4])
                if abs(tilt) < 1e-6:  # within the window: one impact of both corners
                    assert first["contacts"] == 2 and first["share"] == 1.0
                elif contact_time == 0.0:
                    assert first["contacts"] == 1
                else:  # the flat_landing blend, at the geometric delay's share
                    assert first["contacts"] == 2
                    assert first["share"] == pytest.approx(1 - delay / contact_time, abs=0.02 * delay / contact_time)
                assert np.abs(ref[:, :2] - np.column_stack([tr["x"], tr["y"]])).max() < FLAT_TOL[0]
                assert np.abs(ref[:, 2] - tr["phi"]).max() < FLAT_TOL[1]


# landings near flat with spin and slip, by coefficients: (truth keywords, draws)
def spin_landings(rng, count):
    """Landing states of a square (R = 3 cm) near flat (FLAT_TILTS), with slip and a spin of up
    to 0.95 of the one that would stop a corner of the landing side at the given speed."""
    side = 2 * 0.03 * math.sin(math.pi / 4)
    states = []
    for _ in range(count):
        speed = rng.uniform(0.4, 2.0)
        states.append(landing(4, 0.03, FLAT_TILTS[rng.integers(5)], rng.uniform(-1.5, 1.5), speed,
                              rng.uniform(-0.95, 0.95) * 2 * speed / side))
    return states


def through_three_impacts(tracks):
    """Each track's times up to its third impact (all of them with fewer impacts)."""
    times = []
    for tr in tracks:
        hits = tr["path"].impacts[:3]
        times.append(tr["t"][tr["t"] <= hits[-1]["t"]] if hits else tr["t"])
    return times


SPIN_LANDINGS = {
    "rigid": (dict(contact="rigid", friction=math.inf), 12),
    "rigid+friction": (dict(contact="rigid", friction=0.3), 12),
    "rigid, energy rule": (dict(contact="rigid", beta_normal=0.9, beta_tangential=-0.85, friction=0.5), 12),
    "paper": (dict(contact="paper", friction=math.inf), 12),
    "paper+friction": (dict(contact="paper", friction=0.3), 12),
}


def test_landings_near_flat_with_spin_agree_with_the_kernel():
    """Flat and near-flat landings (tilt 0, +-1e-9, +-1e-3 rad) at 0.4-2 m/s with spin up to
    95 % of what keeps both corners approaching, slip up to 1.5 m/s, contact times 0 and
    1e-3 s: the paths over the first three impacts against the kernel's (measured: at most
    7e-14 m and 2e-12 rad). The blend's share moves with where each code locates the contact
    (to 1e-12 R), so over whole paths with later blends up to 3e-9 rad was measured: hence
    KERNEL_TOL."""
    rng = np.random.default_rng(5)
    exercised = set()
    for name, (kw, count) in SPIN_LANDINGS.items():
        for contact_time in (0.0, 1e-3):
            truth = _t(**{"sides": 4, "circumradius": 0.03, **kw, "contact_time": contact_time})
            states = spin_landings(rng, count)
            tracks = [simulate_track(truth, s, 0.3, 2000.0) for s in states]
            times = through_three_impacts(tracks)
            for tr in tracks:
                for hit in tr["path"].impacts[:3]:
                    if hit["contacts"] == 2:
                        exercised.add((hit["law"], hit["share"] < 1.0, hit["clipped"], hit.get("case", ("", "", ""))[:2]))
            for tr, t, ref in zip(tracks, times, kernel_poses(truth, states, times)):
                n = t.size
                assert np.abs(ref[:, :2] - np.column_stack([tr["x"][:n], tr["y"][:n]])).max() < KERNEL_TOL[0]
                assert np.abs(ref[:, 2] - tr["phi"][:n]).max() < KERNEL_TOL[1]
    laws = {law for law, *_ in exercised}
    assert laws == {"rigid", "paper", "fallback"}, exercised
    assert any(blend for _, blend, *_ in exercised) and any(clipped for _, _, clipped, _ in exercised), exercised
    assert any(case in ((True, False), (False, True)) for *_, case in exercised), exercised


@pytest.mark.parametrize("kw", [dict(friction_rule="sliding"), dict(corner_radius=0.002)], ids=["sliding", "rounded"])
def test_landings_near_flat_with_the_new_physics_agree_with_the_kernel(kw):
    """Near-flat landings with spin and slip (as above, friction 0.3, contact times 0 and
    1e-3 s) under the sliding rule (the two-contact row's edge opposing its slip) or with
    rounded corners: the first three impacts against the kernel's."""
    rng = np.random.default_rng(6)
    two = 0
    for contact_time in (0.0, 1e-3):
        truth = _t("rigid", sides=4, circumradius=0.03, friction=0.3, contact_time=contact_time, **kw)
        states = spin_landings(rng, 12)
        tracks = [simulate_track(truth, s, 0.3, 2000.0) for s in states]
        times = through_three_impacts(tracks)
        for tr in tracks:
            hits = tr["path"].impacts[:3]
            two += sum(hit["contacts"] == 2 and hit["capped"] for hit in hits)
        for tr, t, ref in zip(tracks, times, kernel_poses(truth, states, times)):
            n = t.size
            assert np.abs(ref[:, :2] - np.column_stack([tr["x"][:n], tr["y"][:n]])).max() < KERNEL_TOL[0]
            assert np.abs(ref[:, 2] - tr["phi"][:n]).max() < KERNEL_TOL[1]
    assert two > 0  # capped two-contact impacts were exercised


# ----------------------------------------------------------------------------------- measurement


def test_measurement_effects_change_the_file_as_defined():
    base = Truth(contact="paper", beta_normal=0.4, beta_tangential=-0.2)
    seen = Truth(contact="paper", beta_normal=0.4, beta_tangential=-0.2, angle_offset=0.3, time_scale=1.02,
                 length_scale=0.97)
    clean = simulate_drops(base, 3, 4, noise=(0.0, 0.0))
    warped = simulate_drops(seen, 3, 4, noise=(0.0, 0.0))
    for a, b in zip(clean, warped):
        assert a["state0"] == b["state0"]
        assert b["t"] == pytest.approx(1.02 * a["t"], rel=1e-15)
        assert b["x"] == pytest.approx(0.97 * a["x"], rel=1e-15)
        assert b["y"] == pytest.approx(0.97 * a["y"], rel=1e-15)
        assert b["phi"] == pytest.approx(a["phi"] + 0.3, abs=1e-15)
    # the clean file is the true track, sampled at 500 Hz
    true = simulate_track(base, clean[0]["state0"], 0.5, 500.0)
    assert clean[0]["t"] == pytest.approx(np.arange(true["t"].size) / 500.0)
    assert clean[0]["x"] == pytest.approx(true["x"], abs=0.0)


def test_noise_has_the_requested_sigma():
    truth = Truth()
    clean = simulate_drops(truth, 10, 8, noise=(0.0, 0.0))
    noisy = simulate_drops(truth, 10, 8, noise=(2e-4, 4e-3))
    dx = np.concatenate([n["x"] - c["x"] for n, c in zip(noisy, clean)])
    dy = np.concatenate([n["y"] - c["y"] for n, c in zip(noisy, clean)])
    dp = np.concatenate([n["phi"] - c["phi"] for n, c in zip(noisy, clean)])
    assert dx.size > 1000
    for d, sigma in ((dx, 2e-4), (dy, 2e-4), (dp, 4e-3)):
        assert abs(d.mean()) < 4 * sigma / math.sqrt(d.size)
        assert d.std() == pytest.approx(sigma, rel=5 / math.sqrt(d.size))


def test_dropped_frames_and_glitches():
    truth = Truth()
    clean = simulate_drops(truth, 10, 9, noise=(0.0, 0.0))
    hit = simulate_drops(truth, 10, 9, noise=(0.0, 0.0), drop_prob=0.2, glitch_prob=0.05)
    total = kept = glitches = 0
    for c, h in zip(clean, hit):
        total += c["t"].size
        kept += h["t"].size
        index = np.searchsorted(c["t"], h["t"])
        assert np.array_equal(c["t"][index], h["t"])  # the remaining rows keep their own times
        jump = np.hypot(h["x"] - c["x"][index], h["y"] - c["y"][index])
        turn = np.abs(h["phi"] - c["phi"][index])
        bad = np.isin(h["t"], h["glitch_t"])
        glitches += bad.sum()
        assert np.all((jump[bad] >= 0.005 - 1e-12) & (jump[bad] <= 0.020 + 1e-12))
        assert np.all((turn[bad] >= 0.3 - 1e-12) & (turn[bad] <= 1.0 + 1e-12))
        assert np.all(jump[~bad] == 0.0) and np.all(turn[~bad] == 0.0)  # one frame only
    assert kept / total == pytest.approx(0.8, abs=4 * math.sqrt(0.16 / total))
    assert glitches / kept == pytest.approx(0.05, abs=4 * math.sqrt(0.05 * 0.95 / kept))


def test_write_csv(tmp_path):
    tracks = simulate_drops(Truth(), 2, 1, drop_prob=0.1)
    write_csv(tmp_path / "drops.csv", tracks)
    with open(tmp_path / "drops.csv") as fh:
        rows = list(csv.reader(fh))
    assert rows[0] == ["traj", "t", "x", "y", "phi"]
    assert len(rows) - 1 == sum(t["t"].size for t in tracks)
    back = np.array(rows[1:], float)
    first = back[back[:, 0] == 1]
    assert first[:, 1:] == pytest.approx(np.column_stack([tracks[0][k] for k in ("t", "x", "y", "phi")]), abs=0.0)
