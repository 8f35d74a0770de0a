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
def _inverse_speed(chi, e, radius, g, alpha):
    return 1.0 / math.sqrt(max(omega_squared(chi, e, radius, g, alpha), 1e-300))


@numba.njit(cache=True)
def pivot_time(chi_a, chi_b, e, radius, g, alpha):
    """Time (s) to turn from chi_a to chi_b: adaptive Simpson on dchi / |omega(chi)|.

    The integrand is smooth but peaks at chi = pi/2 when e is close to g R; the adaptive
    refinement (explicit stack, numba has no cheap recursion) handles that.
    """
    lo = min(chi_a, chi_b)
    hi = max(chi_a, chi_b)
    if hi - lo <= 0.0:
        return 0.0
    depth_max = 48
    st_a = [lo]
    st_b = [hi]
    fa = _inverse_speed(lo, e, radius, g, alpha)
    fb = _inverse_speed(hi, e, radius, g, alpha)
    fm = _inverse_speed(0.5 * (lo + hi), e, radius, g, alpha)
    st_fa = [fa]
    st_fm = [fm]
    st_fb = [fb]
    st_whole = [(hi - lo) * (fa + 4.0 * fm + fb) / 6.0]
    st_tol = [1e-13 + 1e-12 * st_whole[0]]
    st_depth = [0]
    total = 0.0
    while len(st_a) > 0:
        a = st_a.pop()
        b = st_b.pop()
        fa = st_fa.pop()
        fm = st_fm.pop()
        fb = st_fb.pop()
        whole = st_whole.pop()
        tol = st_tol.pop()
        depth = st_depth.pop()
        m = 0.5 * (a + b)
        flm = _inverse_speed(0.5 * (a + m), e, radius, g, alpha)
        frm = _inverse_speed(0.5 * (m + b), e, radius, g, alpha)
        left = (m - a) * (fa + 4.0 * flm + fm) / 6.0
        right = (b - m) * (fm + 4.0 * frm + fb) / 6.0
        if depth >= depth_max or abs(left + right - whole) <= 15.0 * tol:
            total += left + right + (left + right - whole) / 15.0
        else:
            for a2, b2, fa2, fm2, fb2, w2 in ((a, m, fa, flm, fm, left), (m, b, fm, frm, fb, right)):
                st_a.append(a2)
                st_b.append(b2)
                st_fa.append(fa2)
                st_fm.append(fm2)
                st_fb.append(fb2)
                st_whole.append(w2)
                st_tol.append(0.5 * tol)
                st_depth.append(depth + 1)
    return total


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
