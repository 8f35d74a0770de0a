"""The ideal rigid-body bound (dice_sweep/measured/impact_bound.py) against impacts written out by
hand here: Newton-Euler impulses at a corner of a square plate, brute-force grids over the
impulses, and the real drops (skipped when ../shared/data is absent)."""

import dataclasses
import math
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from dice_sweep.config import load_config
from dice_sweep.measured.impact_bound import (
    CONTACT_TIME_SCAN,
    best_contact_time,
    first_impact_bounds,
    flat_landing_after,
    flat_landing_errors,
    impact_bound,
    law_after,
    second_corner_delay,
    summarise_bounds,
    two_contact_after,
)
from tests.measured.test_tracks import real_tracks

SIDES = 4
R = 0.06 / math.sqrt(2.0)  # m, the shared data's plate
INERTIA = R * R / 3.0  # I/M of a uniform square, m^2: (side^2 + side^2) / 12 with side = R sqrt(2)
CONFIG = Path(__file__).resolve().parents[2] / "configs" / "square_drops.toml"
EXACT = 1e-9  # m/s: an impact made by an admissible impulse is at this distance (rounding only)
GRID = 2e-3  # m/s: a two-stage grid over the impulses finds the minimum to this much
PHI = -0.5 * math.pi + 0.35  # corner 0 lowest, 20 deg from straight down (a side 25 deg off flat)
BEFORE = np.array([-0.5, -2.2, 4.0])  # vx, vy (m/s), omega (rad/s) before
RIGID = {"beta_normal": 0.4535, "beta_tangential": 0.1895, "friction": 0.08813}  # the loop's fit (docs/measured.md)
PAPER = {"beta_normal": 0.397, "beta_tangential": -0.792}
FLAT = -0.25 * math.pi  # corners 0 (at -45 deg) and 3 (at -135 deg) on the table: side 3 flat


def state_of(velocity, phi=PHI):
    return np.r_[0.01, 0.05, phi, velocity]


def corner(phi, k):
    return R * np.array([math.cos(phi + 0.5 * math.pi * k), math.sin(phi + 0.5 * math.pi * k)])


def push(velocity, r, p_t, p_n):
    """Newton-Euler, per unit mass: the impulse (p_t, p_n) along (+x, +y) at r from the centre."""
    vx, vy, omega = velocity
    return np.array([vx + p_t, vy + p_n, omega + (r[0] * p_n - r[1] * p_t) / INERTIA])


def energy(v):
    return 0.5 * (v[..., 0] ** 2 + v[..., 1] ** 2 + INERTIA * v[..., 2] ** 2)


def distance(v, w):
    d = v - w
    return np.sqrt(d[..., 0] ** 2 + d[..., 1] ** 2 + INERTIA * d[..., 2] ** 2)


def normal_restitution(before, r, e):
    """After a purely normal impulse at r that sends the corner's normal velocity to -e times itself."""
    u_n = before[1] + before[2] * r[0]
    p_n = -(1.0 + e) * u_n / (1.0 + r[0] ** 2 / INERTIA)
    return push(before, r, 0.0, p_n), p_n


def grid_minimum(before, after, points, mu=math.inf, cells=(81, 41), zooms=3):
    """Smallest distance over a grid of impulses (p_t, p_n >= 0) at each point with no energy gain
    (and |p_t| <= mu p_n), zoomed in around the best cell ``zooms`` times."""
    scale = 4.0 * math.sqrt(2.0 * energy(before))
    count = len(points)
    lows = np.array([-scale, 0.0] * count)
    highs = np.array([scale, scale] * count)
    best = math.inf
    for _ in range(zooms + 1):
        axes = [np.linspace(lo, hi, cells[0] if j % 2 == 0 else cells[1]) for j, (lo, hi) in enumerate(zip(lows, highs))]
        mesh = np.meshgrid(*axes, indexing="ij")
        v = np.broadcast_to(before, mesh[0].shape + (3,)).copy()
        for i, r in enumerate(points):
            p_t, p_n = mesh[2 * i], mesh[2 * i + 1]
            v[..., 0] += p_t
            v[..., 1] += p_n
            v[..., 2] += (r[0] * p_n - r[1] * p_t) / INERTIA
        ok = energy(v) <= energy(before)
        for i in range(count):
            ok &= np.abs(mesh[2 * i]) <= mu * mesh[2 * i + 1] if math.isfinite(mu) else True
        dist = np.where(ok, distance(v, after), np.inf)
        at = np.unravel_index(np.argmin(dist), dist.shape)
        best = min(best, float(dist[at]))
        centre = np.array([axes[j][at[j]] for j in range(2 * count)])
        step = np.array([axes[j][1] - axes[j][0] for j in range(2 * count)])
        lows = np.maximum(centre - 2 * step, [-np.inf, 0.0] * count)
        highs = centre + 2 * step
    return best


def test_admissible_impact_gives_zero():
    """(a) A purely normal impulse with restitution 0.5 at the touching corner (corner 0)."""
    r = corner(PHI, 0)
    after, p_n = normal_restitution(BEFORE, r, 0.5)
    assert energy(after) < energy(BEFORE)
    one = impact_bound(state_of(BEFORE), after, sides=SIDES, circumradius=R, contacts="corner")
    two = impact_bound(state_of(BEFORE), after, sides=SIDES, circumradius=R, contacts="side")
    assert one.error < EXACT and two.error < EXACT
    assert one.impulses[0] == pytest.approx([0.0, p_n], abs=1e-9)
    assert not one.energy_active
    # the project's rigid law with no friction is this impulse too
    cfg = load_config(CONFIG)
    law = law_after(state_of(BEFORE), cfg, model="rigid", beta_normal=0.5, beta_tangential=0.0, friction=0.0)
    assert law == pytest.approx(after, abs=1e-9)


def test_energy_gain_gives_the_grid_minimum():
    """(b) Post-impact velocities that gain energy: scaled up by 1.5, and a restitution of 1.6."""
    r = corner(PHI, 0)
    elastic, _ = normal_restitution(BEFORE, r, 0.9)
    scaled = 1.5 * elastic
    superelastic, _ = normal_restitution(BEFORE, r, 1.6)
    for after in (scaled, superelastic):
        assert energy(after) > energy(BEFORE)
        bound = impact_bound(state_of(BEFORE), after, sides=SIDES, circumradius=R)
        assert bound.error > 0.05
        grid = grid_minimum(BEFORE, after, [r])
        assert grid - GRID <= bound.error <= grid + EXACT
    # the super-elastic one lies in the plane of impulses at the corner: only the energy binds
    bound = impact_bound(state_of(BEFORE), superelastic, sides=SIDES, circumradius=R)
    assert bound.energy_active and bound.energy_ratio == pytest.approx(1.0, abs=1e-9)


def test_pulling_impulse_gives_a_positive_bound():
    """(c) A corner leaving the table, pulled back by a negative normal impulse (energy lost)."""
    before = np.array([0.3, 1.0, 6.0])
    r = corner(PHI, 0)
    u_n = before[1] + before[2] * r[0]
    assert u_n > 0.5
    after = push(before, r, 0.0, -0.5 * u_n / (1.0 + r[0] ** 2 / INERTIA))
    assert energy(after) < energy(before)
    bound = impact_bound(state_of(before), after, sides=SIDES, circumradius=R)
    assert bound.error > 0.05 and not bound.energy_active
    grid = grid_minimum(before, after, [r])
    assert grid - GRID <= bound.error <= grid + EXACT
    # the table's push is switched off at the optimum, a tangential impulse does what it can
    assert bound.impulses[0, 1] == pytest.approx(0.0, abs=1e-9) and bound.error < float(distance(before, after))


def test_two_contacts_and_friction_cone_against_grids():
    """Two contacts (corners 0 and 3: the lower side), and a friction cone at one, on grids."""
    r0, r3 = corner(PHI, 0), corner(PHI, 3)
    assert r3[1] < corner(PHI, 1)[1]  # corner 3 is the lower neighbour
    after = np.array([-0.2, -2.5, -10.0])  # comes down faster: needs a pull
    bound = impact_bound(state_of(BEFORE), after, sides=SIDES, circumradius=R, contacts="side")
    assert bound.error > 0.05
    grid = grid_minimum(BEFORE, after, [r0, r3], cells=(21, 11), zooms=4)
    assert grid - 3 * GRID <= bound.error <= grid + EXACT
    # a cone |p_t| <= 0.1 p_n at the corner, and a measured impulse outside it
    sliding = push(BEFORE, r0, 1.0, 2.0)
    coned = impact_bound(state_of(BEFORE), sliding, sides=SIDES, circumradius=R, friction=0.1)
    assert coned.error > 0.05 and abs(coned.impulses[0, 0]) <= 0.1 * coned.impulses[0, 1] + 1e-9
    grid = grid_minimum(BEFORE, sliding, [r0], mu=0.1)
    assert grid - GRID <= coned.error <= grid + EXACT


velocities = st.tuples(st.floats(-1.0, 1.0), st.floats(-3.0, 0.5), st.floats(-30.0, 30.0))


@settings(max_examples=150, deadline=None)
@given(phi=st.floats(0.0, 2.0 * math.pi), before=velocities, after=st.tuples(st.floats(-1.5, 1.5), st.floats(-3.0, 3.0), st.floats(-80.0, 80.0)))
def test_two_contacts_never_worse_than_one(phi, before, after):
    """(d) Impulses at the touching corner are among those at both corners of its side."""
    state = state_of(np.array(before), phi)
    one = impact_bound(state, after, sides=SIDES, circumradius=R, contacts="corner")
    two = impact_bound(state, after, sides=SIDES, circumradius=R, contacts="side")
    assert two.error <= one.error + EXACT
    for bound in (one, two):  # what the solver returns is admissible and as far as it says
        assert bound.energy_ratio <= 1.0 + 1e-9 and (bound.impulses[:, 1] >= -1e-9).all()
        assert bound.error == pytest.approx(float(distance(bound.velocity, np.array(after))), abs=EXACT)


@pytest.mark.parametrize("model, law", [("rigid", RIGID), ("paper", PAPER)])
def test_two_contact_law_on_a_flat_landing(model, law):
    """An exactly flat landing without spin or slip leaves without spin at beta_n |vy|, through
    the kernel's resolve_two_contacts and through two_contact_after (tolerance 1e-12, round-off)."""
    from dice_sweep.physics import COUNT_COLUMNS, pack_params
    from dice_sweep.physics.flight import SURF_TABLE
    from dice_sweep.physics.multi_contact import resolve_two_contacts

    cfg = load_config(CONFIG)
    vy = -2.3
    state = np.array([0.0, R * math.sqrt(0.5), FLAT, 0.0, vy, 0.0])
    contact = dataclasses.replace(cfg.contact, model=model, friction=law.get("friction", math.inf), **{k: law[k] for k in ("beta_normal", "beta_tangential")})
    fpar, ipar = pack_params(dataclasses.replace(cfg, contact=contact))
    s = state.copy()
    counts = np.zeros(len(COUNT_COLUMNS), np.int32)
    assert resolve_two_contacts(s, fpar, ipar, SURF_TABLE, 0, SURF_TABLE, 3, 1.0, counts)
    expected = np.array([0.0, law["beta_normal"] * abs(vy), 0.0])  # plain numpy: (vx, vy, omega) after
    assert np.abs(s[3:] - expected).max() < 1e-12
    # both corners leave at beta_n |vy| (Newton-Euler: u_n = vy + omega r_x)
    for k in (0, 3):
        rx = R * math.cos(FLAT + 0.5 * math.pi * k)
        assert abs(s[4] + s[5] * rx - law["beta_normal"] * abs(vy)) < 1e-12
    wrapped = two_contact_after(state, cfg, model=model, **law)
    assert np.abs(wrapped - expected).max() < 1e-12


def test_flat_landing_blend_limits():
    """The flat_landing prediction: the single-corner rigid law at T -> 0, the two-contact law at
    T >> d (to (d/T) |two - single|), and the kernel's own blend at a share in between (1e-12)."""
    from dice_sweep.physics import COUNT_COLUMNS, pack_params
    from dice_sweep.physics.flight import SURF_TABLE
    from dice_sweep.physics.multi_contact import resolve_two_contacts

    cfg = load_config(CONFIG)
    phi = FLAT + math.radians(2.0)  # side 3 tilted 2 deg: corner 3 touches first, corner 0 follows
    state = np.array([0.0, 0.05, phi, 0.3, -2.0, 3.0])
    single = law_after(state, cfg, model="rigid", **RIGID)
    both = two_contact_after(state, cfg, model="rigid", **RIGID)
    delay = second_corner_delay(state, SIDES, R)
    # plain numpy: corner 0's height above corner 3 over its approach speed -(vy + omega r_x)
    r0, r3 = corner(phi, 0), corner(phi, 3)
    assert r3[1] < r0[1]
    assert delay == pytest.approx((r0[1] - r3[1]) / -(state[4] + state[5] * r0[0]), rel=1e-12)
    assert 1e-4 < delay < 1e-2
    gap = float(np.linalg.norm(both - single))
    assert gap > 0.1  # the two laws differ, so the limits say something
    blend = lambda contact_time: flat_landing_after(single[None], both[None], [delay], contact_time)[0]  # noqa: E731
    for contact_time in (0.0, 1e-12, 0.5 * delay):  # T <= d: share 0, the single law exactly
        assert np.array_equal(blend(contact_time), single)
    for factor in (1e3, 1e9):
        assert np.abs(blend(factor * delay) - both).max() <= gap / factor + 1e-12
    # at T = 3 d (share 2/3) the kernel's resolve_two_contacts blends the same way
    fpar, ipar = pack_params(dataclasses.replace(cfg, contact=dataclasses.replace(cfg.contact, model="rigid", **RIGID)))
    s = state.copy()
    counts = np.zeros(len(COUNT_COLUMNS), np.int32)
    assert resolve_two_contacts(s, fpar, ipar, SURF_TABLE, 3, SURF_TABLE, 0, 1.0 - 1.0 / 3.0, counts)
    assert np.abs(blend(3.0 * delay) - s[3:]).max() < 1e-12


def test_best_contact_time_finds_a_planted_one():
    """Measured velocities made by the flat_landing blend at T* = 2e-4 s: the scan's minimiser is
    within one scan step (a factor 10^(3/29)) of T*, inside its bootstrap interval."""
    rng = np.random.default_rng(3)
    count, planted = 90, 2e-4
    single = rng.normal(0.0, 1.0, (count, 3))
    both = single + rng.normal(0.0, 1.0, (count, 3))
    delay = 10.0 ** rng.uniform(-5.5, -3.0, count)
    after = flat_landing_after(single, both, delay, planted)
    rows = [
        {"traj": k // 3, "after": after[k], "rigid_after": single[k], "two_after": both[k], "delay": delay[k]} for k in range(count)
    ]
    assert np.abs(flat_landing_errors(rows, planted, INERTIA)[1]).max() < 1e-12
    scan = best_contact_time(rows, INERTIA, resamples=200)
    step = CONTACT_TIME_SCAN[1] / CONTACT_TIME_SCAN[0]
    assert planted / step <= scan["best"] <= planted * step
    assert scan["low"] <= scan["best"] <= scan["high"] and not scan["at_edge"]


def test_real_first_impacts():
    """Every impact law at the corner is admissible, so its error is at least the bound."""
    trackset = dataclasses.replace(real_tracks(), tracks=real_tracks().tracks[:60])
    cfg = load_config(CONFIG)
    rows, skipped = first_impact_bounds(
        trackset, cfg, rigid={"beta_normal": 0.449, "beta_tangential": 0.115, "friction": 0.0821}, paper={"beta_normal": 0.397, "beta_tangential": -0.792}
    )
    assert len(rows) >= 20 and sum(skipped.values()) + len(rows) == 60
    for row in rows:
        assert row["bound_side"] <= row["bound_corner"] + EXACT
        assert row["bound_corner"] <= row["rigid_error"] + EXACT
        assert row["bound_side"] <= row["rigid_side_error"] + EXACT
        assert row["bound_side"] <= row["two_error"] + EXACT  # the two-contact law pushes and loses energy
    # the flat_landing blend at T = 0 is the single-corner rigid law
    assert flat_landing_errors(rows, 0.0, INERTIA)[1] == pytest.approx([row["rigid_error"] for row in rows], abs=1e-12)
    summary = summarise_bounds(rows, resamples=200)
    assert summary[-1]["label"] == "all" and summary[-1]["impacts"] == len(rows)
    assert sum(entry["impacts"] for entry in summary[:-1]) == len(rows)
    for entry in summary:
        if entry["impacts"]:
            stats = entry["bound_corner"]
            assert stats["low"] <= stats["median"] <= stats["high"]
