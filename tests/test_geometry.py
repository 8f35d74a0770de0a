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
