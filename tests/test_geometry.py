"""Tests of dice_sweep.geometry: inertia (paper eq. 25), lengths, corners, side numbering."""

import math

import numpy as np
import pytest

from dice_sweep import geometry

R = 0.019 / math.sqrt(2.0)  # Table I circumradius, m


@pytest.mark.parametrize(("sides", "expected"), [(3, 0.25), (4, 1.0 / 3.0), (6, 5.0 / 12.0)])
def test_inertia_ratio_known_polygons(sides, expected):
    assert geometry.inertia_ratio(sides) == pytest.approx(expected, rel=1e-14)


def test_inertia_ratio_tends_to_disc_and_grows_with_sides():
    sides = np.arange(3, 2000)
    alpha = geometry.inertia_ratio(sides)
    assert np.all(np.diff(alpha) > 0)
    assert alpha[-1] == pytest.approx(0.5, abs=1e-6)
    assert alpha[-1] < 0.5


def test_moment_of_inertia_square():
    mass = 0.02  # kg
    assert geometry.moment_of_inertia(4, R, mass) == pytest.approx(mass * R**2 / 3.0, rel=1e-14)


@pytest.mark.parametrize("sides", [3, 4, 5, 20, 1000])
def test_apothem_and_side_form_a_right_triangle_with_the_circumradius(sides):
    apothem = geometry.apothem(sides, R)
    half_side = 0.5 * geometry.side_length(sides, R)
    assert apothem**2 + half_side**2 == pytest.approx(R**2, rel=1e-13)
    # the perimeter approaches the circumference from below
    assert sides * 2 * half_side < 2 * math.pi * R


def test_square_lengths():
    assert geometry.apothem(4, 1.0) == pytest.approx(math.sqrt(0.5), rel=1e-15)
    assert geometry.side_length(4, 1.0) == pytest.approx(math.sqrt(2.0), rel=1e-15)


@pytest.mark.parametrize("sides", [3, 4, 7])
def test_corners_lie_on_the_circumcircle_counterclockwise(sides):
    x, y, phi = 0.3, -0.2, 0.4
    points = geometry.corners(sides, R, x, y, phi)
    assert points.shape == (sides, 2)
    np.testing.assert_allclose(np.hypot(points[:, 0] - x, points[:, 1] - y), R, rtol=1e-14)
    np.testing.assert_allclose(points[0], [x + R * math.cos(phi), y + R * math.sin(phi)])
    # counterclockwise: the cross product of consecutive corner offsets is positive
    offsets = points - [x, y]
    cross = offsets[:, 0] * np.roll(offsets[:, 1], -1) - offsets[:, 1] * np.roll(offsets[:, 0], -1)
    assert np.all(cross > 0)
    # neighbouring corners are one side length apart
    np.testing.assert_allclose(
        np.linalg.norm(np.roll(points, -1, axis=0) - points, axis=1),
        geometry.side_length(sides, R),
        rtol=1e-13,
    )


def test_corner_angles():
    np.testing.assert_allclose(geometry.corner_angles(4, 0.1), 0.1 + np.array([0, 0.5, 1, 1.5]) * np.pi)


@pytest.mark.parametrize("sides", [3, 4, 5, 20])
def test_lowest_corner_height_matches_brute_force(sides):
    rng = np.random.default_rng(sides)
    y = rng.uniform(-0.1, 0.1, 200)
    phi = rng.uniform(-20.0, 20.0, 200)
    brute = np.array([geometry.corners(sides, R, 0.0, yi, p)[:, 1].min() for yi, p in zip(y, phi)])
    np.testing.assert_allclose(geometry.lowest_corner_height(sides, R, y, phi), brute, atol=1e-15)


def test_lowest_corner_height_of_square_flat_and_on_a_corner():
    assert geometry.lowest_corner_height(4, R, 0.1, math.pi / 4) == pytest.approx(0.1 - R / math.sqrt(2))
    assert geometry.lowest_corner_height(4, R, 0.1, 0.0) == pytest.approx(0.1 - R)


def test_lowest_corner_height_broadcasts():
    heights = geometry.lowest_corner_height(4, R, np.array([[0.1], [0.2]]), np.array([0.0, 0.3, 0.6]))
    assert heights.shape == (2, 3)


@pytest.mark.parametrize("direction", [0.0, 0.5 * math.pi, math.pi, 2.0])
def test_support_matches_brute_force(direction):
    rng = np.random.default_rng(7)
    for phi in rng.uniform(-7.0, 7.0, 50):
        offsets = geometry.corners(5, R, 0.0, 0.0, phi)
        brute = (offsets @ [math.cos(direction), math.sin(direction)]).max()
        assert geometry.support(5, R, phi, direction) == pytest.approx(brute, abs=1e-16)


def test_square_side_below_just_before_flat():
    # corners at pi/4 - eps + k pi/2: the ray at -pi/2 = 3 pi/2 falls between corners 2 and 3
    assert geometry.side_below(4, math.pi / 4 - 1e-9) == 2
    assert geometry.side_below(4, math.pi / 4 + 1e-9) == 2
    # turned just past the corner straight below: corner 3 is at -pi/2 + eps, side 2 is below
    assert geometry.side_below(4, 1e-9) == 2
    # turned just short of it: corner 3 is at -pi/2 - eps, side 3 (corners 3 -> 0) is below
    assert geometry.side_below(4, -1e-9) == 3


def test_side_below_triangle_resting_on_side_zero():
    # side 0 of a triangle is flat at the bottom when its corners are at -pi/2 -+ pi/3
    assert geometry.side_below(3, -0.5 * math.pi - math.pi / 3) == 0


@pytest.mark.parametrize("sides", [3, 4, 5, 20])
def test_side_below_turning_by_one_corner_lowers_the_index_by_one(sides):
    phi = np.linspace(-10.0, 10.0, 997)
    below = geometry.side_below(sides, phi)
    turned = geometry.side_below(sides, phi + 2 * math.pi / sides)
    np.testing.assert_array_equal(turned, (below - 1) % sides)
    assert below.min() == 0 and below.max() == sides - 1


@pytest.mark.parametrize("sides", [3, 4, 5, 20])
def test_side_below_is_the_side_whose_corners_straddle_the_ray(sides):
    rng = np.random.default_rng(sides)
    for phi in rng.uniform(-10.0, 10.0, 100):
        k = geometry.side_below(sides, phi)
        points = geometry.corners(sides, R, 0.0, 0.0, phi)
        start, end = points[k], points[(k + 1) % sides]
        # the ray x = 0, y < 0 crosses the segment from corner k to corner k+1
        assert start[0] * end[0] <= 0
        assert min(start[1], end[1]) < 0


def test_side_below_wraps_to_side_zero_at_the_last_corner():
    # (-pi/2 - phi) mod 2 pi rounds to 2 pi here; the index must still be in range
    phi = np.nextafter(-0.5 * np.pi, 0.0)
    assert 0 <= geometry.side_below(4, phi) < 4
    assert isinstance(geometry.side_below(4, 0.3), int)


# ---- rounded corners: outline and reach --------------------------------------------------


def _core(sides, r):
    """Arc centres' distance from the centre, by hand: the apothem less r over cos(pi/n)."""
    return (R * math.cos(math.pi / sides) - r) / math.cos(math.pi / sides)


@pytest.mark.parametrize("sides", [3, 4, 7])
def test_outline_of_a_sharp_die_is_its_corners(sides):
    arcs = geometry.outline(sides, R, 0.3, -0.2, 0.4)
    assert arcs.shape == (sides, 1, 2)
    np.testing.assert_array_equal(arcs[:, 0], geometry.corners(sides, R, 0.3, -0.2, 0.4))


@pytest.mark.parametrize(("sides", "share"), [(3, 0.5), (4, 0.2), (4, 0.99), (7, 0.3)])
def test_rounded_outline_lies_in_the_circumcircle_on_arcs_and_keeps_the_apothem(sides, share):
    x, y, phi = 0.3, -0.2, 0.4
    apothem = R * math.cos(math.pi / sides)
    r = share * apothem
    arcs = geometry.outline(sides, R, x, y, phi, r)
    assert np.hypot(arcs[..., 0] - x, arcs[..., 1] - y).max() <= R * (1 + 1e-15)
    # every arc point is r from its centre, the core corner at phi + 2 pi k / n
    angles = phi + 2 * math.pi * np.arange(sides) / sides
    centres = np.column_stack((x + _core(sides, r) * np.cos(angles), y + _core(sides, r) * np.sin(angles)))
    np.testing.assert_allclose(np.linalg.norm(arcs - centres[:, None], axis=-1), r, rtol=1e-12)
    # each side's straight part lies at the apothem, along the side's outward normal
    for k in range(sides):
        normal = np.array([math.cos(angles[k] + math.pi / sides), math.sin(angles[k] + math.pi / sides)])
        ends = np.array([arcs[k, -1], arcs[(k + 1) % sides, 0]]) - [x, y]
        np.testing.assert_allclose(ends @ normal, apothem, rtol=1e-12)


@pytest.mark.parametrize(("sides", "share"), [(3, 0.5), (4, 0.2), (7, 0.3)])
def test_rounded_outline_reaches_as_far_as_the_support_function(sides, share):
    r = share * R * math.cos(math.pi / sides)
    rng = np.random.default_rng(sides)
    step = math.pi / 36  # outline's default largest angle between arc points
    for phi, direction in rng.uniform(-7.0, 7.0, (50, 2)):
        arcs = geometry.outline(sides, R, 0.0, 0.0, phi, r)
        extent = (arcs.reshape(-1, 2) @ [math.cos(direction), math.sin(direction)]).max()
        reach = geometry.support(sides, R, phi, direction, r)
        # the sampled arc falls short of the true one by at most its chords' sagitta
        assert reach - r * (1 - math.cos(step / 2)) - 1e-16 <= extent <= reach + 1e-16


def test_rounded_support_by_hand_and_against_the_kernels_arc_centres():
    from dice_sweep.config import parse_config
    from dice_sweep.physics.params import CORNER_STRIDE, FP_CORNERS, FP_RHO_MAX, pack_params

    r = 0.002
    # a square on a corner (phi = 0: corner 3 straight down) reaches its core corner plus r;
    # lying flat (phi = pi/4) it reaches the apothem, as the sharp die does
    assert geometry.support(4, R, 0.0, geometry.DOWN, r) == pytest.approx(_core(4, r) + r, rel=1e-14)
    assert geometry.support(4, R, math.pi / 4, geometry.DOWN, r) == pytest.approx(R / math.sqrt(2), rel=1e-14)
    for sides in (3, 4, 7):
        fpar, _ = pack_params(parse_config(f"[die]\nsides = {sides}\n[effects]\ncorner_radius = {r}"))
        block = fpar[FP_CORNERS:].reshape(sides, CORNER_STRIDE)
        centres = block[:, :1] * block[:, 1:]  # arc centres from the (fair die's) centre, body frame
        assert fpar[FP_RHO_MAX] == pytest.approx(geometry.support(sides, R, 0.0, 0.0, r), rel=1e-14)
        for phi, direction in np.random.default_rng(sides).uniform(-7.0, 7.0, (50, 2)):
            unit = [math.cos(direction - phi), math.sin(direction - phi)]  # in the body frame
            assert geometry.support(sides, R, phi, direction, r) == pytest.approx((centres @ unit).max() + r, rel=1e-14)


def test_support_at_zero_radius_is_the_sharp_one_bit_for_bit():
    phi = np.random.default_rng(3).uniform(-7.0, 7.0, 200)
    for sides in (3, 4, 9):
        spacing = 2 * np.pi / sides
        offset = np.mod(0.3 - phi, spacing)
        sharp = R * np.cos(np.minimum(offset, spacing - offset))  # R cos(angle to the nearest corner)
        np.testing.assert_array_equal(geometry.support(sides, R, phi, 0.3, 0.0), sharp)


def test_scattered_starts_are_cleared_at_the_rounded_reach():
    """A square with phi = 0 (a corner straight down) at height y: the sharp reach is R, the
    rounded one sqrt(2) (a - r) + r (a the apothem, the arc centre at Rc = sqrt(2)(a - r)), so
    a centre between the two heights is clear only for the rounded die."""
    radius, r = 0.01, 0.002
    a = radius * math.cos(math.pi / 4)
    rounded_reach = math.sqrt(2) * (a - r) + r
    y = 0.5 * (rounded_reach + radius)
    states = np.array([[0.0, y, 0.0, 0, 0, 0], [0.0, rounded_reach - 1e-9, 0.0, 0, 0, 0]])
    assert geometry.clear_of_surfaces(4, radius, None, states).tolist() == [False, False]
    assert geometry.clear_of_surfaces(4, radius, None, states, corner_radius=r).tolist() == [True, False]
