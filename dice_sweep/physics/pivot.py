"""Pivot phase: the die turns about a corner resting on the table (Housner's rocking block).

With the corner fixed at (px, 0) and chi the angle of the centre seen from the corner, the die
is a pendulum: chi'' = -g cos(chi) / (R (1 + alpha)). Its specific energy
e = R^2 (1 + alpha) omega^2 / 2 + g R sin(chi) is conserved, so everything but the elapsed time
is known in closed form along the path:

* omega(chi)^2 = 2 (e - g R sin chi) / (R^2 (1 + alpha));
* lift-off is where the corner, released, would accelerate away from the table:
  omega^2 R sin(chi) >= g, i.e. q(sin chi) <= 0 with q(s) = 2 g s^2 - (2 e / R) s + g (1 + alpha).
  That is where the normal force of the (normal-only) contact turns negative. The sticking
  pivot's own normal force, (g (alpha + sin^2 chi) - R omega^2 sin chi) / (1 + alpha), turns
  negative a little earlier when the corner is off the top: in that band the paper model's
  unlimited friction would have to pull, while a released corner would still fall back in, so
  neither sticking nor flight is consistent. The kernel keeps the pivot through the band (a
  lift-off there would be followed by a re-contact at the same instant, forever;
  tests/physics/test_kernel.py::test_rolling_polygon_loses_energy_by_the_plastic_factor
  caught that loop). Coulomb friction with a slip phase resolves the band physically;
* the next corner reaches the table when the side is flat, chi = pi/2 -+ pi/n.

The pivot is entered only while the side is undecided, e >= g R, so omega never vanishes on
the way: the path in chi is monotone and the time is the integral of dchi / |omega|.
"""

import math

import numba

from dice_sweep.physics.flight import SURF_LEFT, SURF_RIGHT, SURF_TABLE

PIVOT_LIFTOFF = 0
PIVOT_FLAT = 1  # the next corner reached the table
PIVOT_WALL = 2  # a corner reached a wall
PIVOT_BALANCED = 3  # resting on the corner at the top: unstable equilibrium

BALANCE_TOL = 1e-12  # relative kinetic energy at the top below which the die is balanced
WALL_SAMPLES = 64


@numba.njit(cache=True)
def pivot_energy(chi, omega, radius, g, alpha):
    """Specific energy (J/kg) of a die pivoting on a table corner."""
    return 0.5 * radius * radius * (1.0 + alpha) * omega * omega + g * radius * math.sin(chi)


@numba.njit(cache=True)
def liftoff_factor(sin_chi, e, radius, g, alpha):
    """q(s) = (1 + alpha) (g - R omega^2 s); the corner lifts off where it is negative."""
    return 2.0 * g * sin_chi * sin_chi - (2.0 * e / radius) * sin_chi + g * (1.0 + alpha)


@numba.njit(cache=True)
def omega_squared(chi, e, radius, g, alpha):
    return 2.0 * (e - g * radius * math.sin(chi)) / (radius * radius * (1.0 + alpha))


@numba.njit(cache=True)
def carlson_rf(x, y, z):
    """Carlson's symmetric elliptic integral R_F(x, y, z) by duplication (Carlson 1995).

    At most one argument may be zero. The relative error of the fifth-order series after
    the loop is about ERRTOL^6, below round-off for ERRTOL = 1e-3.
    """
    for _ in range(200):
        sx = math.sqrt(x)
        sy = math.sqrt(y)
        sz = math.sqrt(z)
        lam = sx * sy + sy * sz + sz * sx
        x = 0.25 * (x + lam)
        y = 0.25 * (y + lam)
        z = 0.25 * (z + lam)
        mu = (x + y + z) / 3.0
        dx = 1.0 - x / mu
        dy = 1.0 - y / mu
        dz = 1.0 - z / mu
        if max(abs(dx), abs(dy), abs(dz)) < 1e-3:
            break
    e2 = dx * dy - dz * dz
    e3 = dx * dy * dz
    return (1.0 + (e2 / 24.0 - 0.1 - 3.0 * e3 / 44.0) * e2 + e3 / 14.0) / math.sqrt(mu)


@numba.njit(cache=True)
def _half_angle_integral(v, delta, b):
    """G(v) = integral from 0 to v of dv' / sqrt(delta + b sin^2 v'), for |v| < pi/2."""
    sv = math.sin(v)
    cv = math.cos(v)
    return sv * carlson_rf(delta * cv * cv, delta + b * sv * sv, delta)


@numba.njit(cache=True)
def pivot_time(chi_a, chi_b, e, radius, g, alpha):
    """Time (s) to turn from chi_a to chi_b, in closed form.

    With u = chi - pi/2, omega^2 = delta + 2 B sin^2(u/2) where B = 2 g / (R (1 + alpha)) and
    delta = omega^2 at the top (>= 0 while undecided), so the time is an incomplete elliptic
    integral of the first kind, 2 [G(u_b/2) - G(u_a/2)], evaluated with Carlson's R_F. (An
    adaptive quadrature first used here took seconds when delta was near 0;
    test_pivot_time_matches_quadrature_and_is_fast_near_the_top guards that.)
    """
    scale = radius * radius * (1.0 + alpha)
    big_b = 2.0 * g / (radius * (1.0 + alpha))
    delta = max(2.0 * e / scale - big_b, 0.0)
    ga = _half_angle_integral(0.5 * (chi_a - 0.5 * math.pi), delta, 2.0 * big_b)
    gb = _half_angle_integral(0.5 * (chi_b - 0.5 * math.pi), delta, 2.0 * big_b)
    return 2.0 * abs(gb - ga)


@numba.njit(cache=True)
def wall_gap(chi, j_offset, px, radius, half_width, surf):
    """Gap (m) between a wall and the corner j_offset steps from the pivot corner."""
    x = px + radius * math.cos(chi) - radius * math.cos(chi + j_offset)
    if surf == SURF_LEFT:
        return x + half_width
    return half_width - x


@numba.njit(cache=True)
def first_wall_contact(n, radius, half_width, px, chi0, chi1, hit):
    """First chi on the path chi0 -> chi1 where a corner reaches a wall, or NaN.

    Only called when a wall is within reach of the die (|px| + 2 R >= L). The gaps are smooth
    with at most a few extrema on a path shorter than 2 pi / n, so sampling then bisection is
    enough.
    """
    best = math.nan
    best_frac = 2.0
    for j in range(1, n):
        offset = 2.0 * math.pi * j / n
        for surf in (SURF_LEFT, SURF_RIGHT):
            prev = wall_gap(chi0, offset, px, radius, half_width, surf)
            for i in range(1, WALL_SAMPLES + 1):
                frac = i / WALL_SAMPLES
                if frac >= best_frac:
                    break
                chi = chi0 + (chi1 - chi0) * frac
                gap = wall_gap(chi, offset, px, radius, half_width, surf)
                if gap <= 0.0 and prev > 0.0:
                    a = chi0 + (chi1 - chi0) * (i - 1) / WALL_SAMPLES
                    b = chi
                    for _ in range(100):
                        mid = 0.5 * (a + b)
                        if wall_gap(mid, offset, px, radius, half_width, surf) > 0.0:
                            a = mid
                        else:
                            b = mid
                    best = a
                    best_frac = (a - chi0) / (chi1 - chi0)
                    hit[0] = surf
                    hit[1] = j
                    break
                prev = gap
    return best


@numba.njit(cache=True)
def pivot_next(n, radius, g, alpha, half_width, px, chi0, omega0, out, hit):
    """Follow a pivot from (chi0, omega0) to its next event.

    Parameters
    ----------
    n, radius, g, alpha, half_width : die and world (SI).
    px : float
        Position (m) of the pivot corner on the table.
    chi0, omega0 : float
        Start angle of the centre seen from the corner (rad) and angular velocity (rad/s).
    out : float64[3]
        Output: chi at the event (rad), omega there (rad/s), duration (s).
    hit : int64[2]
        Output for PIVOT_FLAT and PIVOT_WALL: surface and corner offset (steps from the pivot
        corner, counterclockwise) of the corner that arrives.

    Returns
    -------
    int
        PIVOT_LIFTOFF, PIVOT_FLAT, PIVOT_WALL or PIVOT_BALANCED.
    """
    half_angle = math.pi / n
    chi0 = min(max(chi0, 0.5 * math.pi - half_angle), 0.5 * math.pi + half_angle)
    e = pivot_energy(chi0, omega0, radius, g, alpha)
    if omega0 > 0.0:
        direction = 1.0
    elif omega0 < 0.0:
        direction = -1.0
    else:
        c = math.cos(chi0)
        if c == 0.0:
            return PIVOT_BALANCED
        direction = -1.0 if c > 0.0 else 1.0
    chi_flat = 0.5 * math.pi + direction * half_angle
    # At the top with round-off-sized motion, or creeping up to it with no energy to spare:
    # the die stays balanced on the corner, and which way it would fall is round-off.
    crosses_top = direction * (0.5 * math.pi - chi0) > 0.0
    spare = BALANCE_TOL * g * radius
    at_top = 1.0 - math.sin(chi0) <= BALANCE_TOL and e - g * radius * math.sin(chi0) <= spare
    if at_top or (crosses_top and e - g * radius <= spare):
        return PIVOT_BALANCED
    kind = PIVOT_FLAT
    chi_end = chi_flat
    # lift-off: the first chi on the path where q(sin chi) < 0
    if liftoff_factor(math.sin(chi0), e, radius, g, alpha) < 0.0:
        kind = PIVOT_LIFTOFF
        chi_end = chi0
    else:
        b = 2.0 * e / radius
        disc = b * b - 8.0 * g * g * (1.0 + alpha)
        if disc > 0.0:
            sq = math.sqrt(disc)
            for s_root in ((b - sq) / (4.0 * g), (b + sq) / (4.0 * g)):
                if s_root <= 0.0 or s_root >= 1.0:
                    continue
                base = math.asin(s_root)
                for chi_c in (base, math.pi - base):
                    dist = direction * (chi_c - chi0)
                    if dist <= 0.0 or dist >= direction * (chi_end - chi0):
                        continue
                    probe = math.sin(chi_c + direction * 1e-9)
                    if liftoff_factor(probe, e, radius, g, alpha) < 0.0:
                        kind = PIVOT_LIFTOFF
                        chi_end = chi_c
    if not math.isinf(half_width) and abs(px) + 2.0 * radius >= half_width and chi_end != chi0:
        chi_wall = first_wall_contact(n, radius, half_width, px, chi0, chi_end, hit)
        if not math.isnan(chi_wall):
            kind = PIVOT_WALL
            chi_end = chi_wall
    if kind == PIVOT_FLAT:
        hit[0] = SURF_TABLE
        hit[1] = 1 if direction < 0.0 else n - 1
    out[0] = chi_end
    out[1] = direction * math.sqrt(max(omega_squared(chi_end, e, radius, g, alpha), 0.0))
    out[2] = pivot_time(chi0, chi_end, e, radius, g, alpha)
    return kind


@numba.njit(cache=True)
def pivot_angle_at(chi0, omega0, tau, radius, g, alpha, chi_end):
    """Angle chi (rad) reached ``tau`` seconds into a pivot that ends at ``chi_end``.

    Newton on T(chi0 -> chi) = tau with dT/dchi = 1 / |omega(chi)|, bracketed; used to sample
    paths for pictures and for fitting, not in sweeps.
    """
    e = pivot_energy(chi0, omega0, radius, g, alpha)
    lo = min(chi0, chi_end)
    hi = max(chi0, chi_end)
    sign = 1.0 if chi_end >= chi0 else -1.0
    chi = chi0 + sign * min(tau * abs(omega0), hi - lo)
    for _ in range(60):
        resid = pivot_time(chi0, chi, e, radius, g, alpha) - tau
        if abs(resid) < 1e-13:
            break
        step = resid * math.sqrt(max(omega_squared(chi, e, radius, g, alpha), 0.0))
        chi = min(max(chi - sign * step, lo), hi)
    return chi
