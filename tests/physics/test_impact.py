"""Impact laws: energy, mirror walls, the paper's equations."""

import math

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from dice_sweep.physics.flight import SURF_LEFT, SURF_RIGHT, SURF_TABLE, surface_frame
from dice_sweep.physics.impact import (
    corner_impulse,
    corner_vector,
    corner_normal_velocity,
    paper_law,
    resolve_impact,
    specific_energy,
    stick_corner,
)
from dice_sweep.geometry import inertia_ratio
from dice_sweep.physics.params import FP_INERTIA
from tests.physics.conftest import TABLE1_RADIUS, corner_impacts, make_params

RADIUS = 0.0134


def kinetic(s, inertia):
    """Kinetic energy per unit mass; ``inertia`` = I/M (m^2)."""
    return 0.5 * (s[3] ** 2 + s[4] ** 2) + 0.5 * inertia * s[5] ** 2


state_strategy = st.tuples(
    st.floats(-math.pi, math.pi),  # phi
    st.floats(-3.0, 3.0),  # vx
    st.floats(-3.0, 3.0),  # vy
    st.floats(-80.0, 80.0),  # omega
)


@settings(max_examples=600, deadline=None)
@given(
    state=state_strategy,
    sides=st.integers(3, 20),
    beta_n=st.floats(0.0, 1.0),
    beta_t=st.floats(-1.0, 1.0),
    surf=st.sampled_from([SURF_TABLE, SURF_LEFT, SURF_RIGHT]),
    corner=st.integers(0, 19),
    model=st.sampled_from(["paper", "rigid"]),
    friction=st.sampled_from([math.inf, 0.0, 0.1, 0.5, 2.0]),
    speed_k=st.sampled_from([0.0, 0.5]),
    offset=st.tuples(st.floats(-0.004, 0.004), st.floats(-0.004, 0.004)),
)
def test_no_impact_gains_energy(state, sides, beta_n, beta_t, surf, corner, model, friction, speed_k, offset):
    """Both models, every cap, speed-dependent restitution and a loaded die: no impact creates
    kinetic energy, and the touching corner never keeps going in."""
    corner %= sides
    fpar, ipar = make_params(sides=sides, radius=RADIUS, beta_n=beta_n, beta_t=beta_t, separation=0.2,
                             model=model, friction=friction, speed_restitution=speed_k, com_offset=offset)
    phi, vx, vy, omega = state
    s = np.array([0.0, 0.1, phi, vx, vy, omega])
    nx, ny, _ = surface_frame(surf, 0.1)
    rx, ry = corner_vector(s, fpar, corner)
    if corner_normal_velocity(s, rx, ry, nx, ny) >= 0.0:
        return  # not an impact: the corner is not approaching
    before = kinetic(s, fpar[FP_INERTIA])
    counts = np.zeros(5, np.int32)
    u_after = resolve_impact(s, fpar, ipar, surf, corner, counts)
    assert kinetic(s, fpar[FP_INERTIA]) <= before * (1 + 1e-12) + 1e-15
    assert u_after >= -1e-12 * (1 + abs(vx) + abs(vy) + RADIUS * abs(omega))


@settings(max_examples=300, deadline=None)
@given(state=state_strategy, beta_n=st.floats(0.0, 1.0), beta_t=st.floats(-1.0, 1.0),
       corner_angle=st.floats(-math.pi, 0.0))
def test_corner_impulse_energy_and_restitution(state, beta_n, beta_t, corner_angle):
    """Direct law: never gains energy; the normal restitution target is always met."""
    alpha = inertia_ratio(4)
    _, vx, vy, omega = state
    rx, ry = RADIUS * math.cos(corner_angle), RADIUS * math.sin(corner_angle)
    s = np.array([0.0, 0.1, 0.0, vx, vy, omega])
    u_n = corner_normal_velocity(s, rx, ry, 0.0, 1.0)
    if u_n >= 0.0:
        return
    inertia = alpha * RADIUS**2
    before = kinetic(s, inertia)
    corner_impulse(s, inertia, beta_n, beta_t, math.inf, rx, ry, 0.0, 1.0)
    assert kinetic(s, inertia) <= before * (1 + 1e-12) + 1e-15
    assert math.isclose(corner_normal_velocity(s, rx, ry, 0.0, 1.0), -beta_n * u_n, rel_tol=1e-9, abs_tol=1e-12)


def test_energy_clip_happens_and_is_counted():
    """An off-centre corner with a reversing tangential target (beta_t = -1 keeps u_t, +1
    reverses it) is the textbook energy-gain case: the clip must trigger for some states."""
    alpha = inertia_ratio(4)
    rng = np.random.default_rng(3)
    clipped = 0
    for _ in range(2000):
        ang = rng.uniform(-math.pi, 0.0)
        rx, ry = RADIUS * math.cos(ang), RADIUS * math.sin(ang)
        s = np.array([0.0, 0.1, 0.0, *rng.uniform(-2, 2, 2), rng.uniform(-100, 100)])
        if corner_normal_velocity(s, rx, ry, 0.0, 1.0) >= 0.0:
            continue
        clipped += corner_impulse(s, alpha * RADIUS**2, 0.9, 1.0, math.inf, rx, ry, 0.0, 1.0)
    assert clipped > 0


def test_paper_law_matches_equations_12_13():
    """Table impact: eq 9 for vy, eqs 12-13 for (vx, omega) exactly as printed."""
    alpha, bn, bt = inertia_ratio(4), 0.2, -0.35
    vx, vy, w = 0.3, -1.5, 12.0
    s = np.array([0.0, 0.05, 0.0, vx, vy, w])
    paper_law(s, alpha, RADIUS, bn, bt, 0.0, 1.0)
    vx_new = -((alpha * bt - 1) * vx + alpha * (bt + 1) * RADIUS * w) / (alpha + 1)
    w_new = -((bt + 1) * vx - RADIUS * w * (alpha - bt)) / (RADIUS * (alpha + 1))
    assert np.allclose(s[3:], [vx_new, -bn * vy, w_new], rtol=1e-14)
    # eq 10 and eq 11 hold
    assert math.isclose(s[3] + RADIUS * s[5], -bt * (vx + RADIUS * w), rel_tol=1e-12)
    assert math.isclose(alpha * RADIUS * s[5] - s[3], alpha * RADIUS * w - vx, rel_tol=1e-12)


def test_walls_are_mirror_images():
    """A hit on the left wall is the mirror image (x -> -x, vx -> -vx, omega -> -omega,
    phi -> pi - phi) of the same hit on the right wall."""
    alpha, bn, bt = inertia_ratio(5), 0.2, -0.35
    right = np.array([0.09, 0.05, 0.3, 1.2, -0.4, 7.0])
    left = np.array([-0.09, 0.05, math.pi - 0.3, -1.2, -0.4, -7.0])
    nx, ny, _ = surface_frame(SURF_RIGHT, 0.1)
    paper_law(right, alpha, RADIUS, bn, bt, nx, ny)
    nx, ny, _ = surface_frame(SURF_LEFT, 0.1)
    paper_law(left, alpha, RADIUS, bn, bt, nx, ny)
    assert np.allclose([-left[3], left[4], -left[5]], right[3:], rtol=1e-13)
    # The paper's literal substitution (vx -> vy in eq 13 for any wall) is the right wall's law
    vy, w = -0.4, 7.0
    w_literal = -((bt + 1) * vy - RADIUS * w * (alpha - bt)) / (RADIUS * (alpha + 1))
    assert math.isclose(right[5], w_literal, rel_tol=1e-13)
    # ... and applied unchanged at the left wall it would not be the mirror image
    w_literal_left = -((bt + 1) * vy - RADIUS * (-w) * (alpha - bt)) / (RADIUS * (alpha + 1))
    assert not math.isclose(w_literal_left, -right[5], rel_tol=1e-3)


def test_stick_corner_stops_the_corner_and_only_removes_energy():
    fpar, _ = make_params(sides=6, radius=RADIUS)
    rx, ry = RADIUS * math.cos(-1.2), RADIUS * math.sin(-1.2)
    s = np.array([0.0, 0.02, 0.0, 0.4, -0.1, 9.0])
    before = specific_energy(s, fpar)
    stick_corner(s, fpar[FP_INERTIA], rx, ry)
    assert abs(s[3] - s[5] * ry) < 1e-14 and abs(s[4] + s[5] * rx) < 1e-14
    assert specific_energy(s, fpar) <= before


def test_capped_impulse_sits_on_the_cone_edge_on_the_targets_side():
    """When the target impulse leaves the friction cone, friction takes the cone's edge on
    the target's side (as Chipmunk does), even when the normal impulse throws the corner
    back against its incoming slip (the case docs/dev/validation_history.md traced)."""
    inertia = TABLE1_RADIUS * TABLE1_RADIUS / 3
    seen_against_slip = 0
    for s, rx, ry in corner_impacts(np.random.default_rng(11), 3000, TABLE1_RADIUS):
        target = s.copy()
        corner_impulse(target, inertia, 0.2, 0.0, math.inf, rx, ry, 0.0, 1.0)
        capped = s.copy()
        corner_impulse(capped, inertia, 0.2, 0.0, 0.3, rx, ry, 0.0, 1.0)
        p_target = target[3] - s[3]
        p_t, p_n = capped[3] - s[3], capped[4] - s[4]
        if abs(p_target) > 0.3 * (target[4] - s[4]) * 1.01 and p_n > 0:
            assert math.copysign(1, p_t) == math.copysign(1, p_target)
            u_t = s[3] - s[5] * ry
            seen_against_slip += math.copysign(1, p_target) == math.copysign(1, u_t)
    assert seen_against_slip > 0  # the case the textbook branch gets wrong did occur
