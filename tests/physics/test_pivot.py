"""Pivot phase in closed form: time integral, lift-off, events."""

import math
import time

import numpy as np
import pytest

from tests.physics.conftest import make_params
from dice_sweep.physics.pivot import (
    PIVOT_FLAT,
    PIVOT_LIFTOFF,
    carlson_rf,
    liftoff_factor,
    omega_squared,
    pivot_angle_at,
    pivot_energy,
    pivot_next,
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
def test_pivot_time_matches_quadrature_and_is_fast_near_the_top(excess):
    """Closed form = Simpson on a fine grid, including energies just above the top (where an
    adaptive quadrature once took seconds per call)."""
    e = G * R * excess
    chi_a, chi_b = math.pi / 4, 3 * math.pi / 4 - 0.1
    t0 = time.perf_counter()
    exact = pivot_time(chi_a, chi_b, e, R, G, ALPHA)
    assert time.perf_counter() - t0 < 5.0  # compile included; the call itself is microseconds
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
