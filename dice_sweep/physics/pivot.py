"""Pivot phase: the die turns about a corner resting on the table (Housner's rocking block).

With the corner fixed at (px, 0), rho its distance from the centre of mass (R for a fair die),
alpha = I / (M rho^2) and chi the angle of the centre of mass seen from the corner, the die is a
pendulum: chi'' = -g cos(chi) / (rho (1 + alpha)). Its specific energy
e = rho^2 (1 + alpha) omega^2 / 2 + g rho sin(chi) is conserved, so everything but the elapsed
time is known in closed form along the path (written below with R for rho):

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
* the next corner reaches the table when its side is flat: chi = pi/2 -+ pi/n for a fair die,
  in general the angles of ``flat_angles``.

The pivot is entered only while the side is undecided, e >= g R, so omega never vanishes on
the way: the path in chi is monotone and the time is the integral of dchi / |omega|.
"""

import math

import numba

import numpy as np

from dice_sweep.physics.flight import SURF_LEFT, SURF_RIGHT, SURF_TABLE, corner_offset
from dice_sweep.physics.outcome import corner_geometry, decided_side
from dice_sweep.physics.params import (
    FP_COM_X,
    FP_COM_Y,
    FP_CORNER_RADIUS,
    FP_DRAG,
    FP_G,
    FP_INERTIA,
    FP_MU,
    FP_RHO_MAX,
    FP_WALL,
)

PIVOT_LIFTOFF = 0
PIVOT_FLAT = 1  # the next corner reached the table
PIVOT_WALL = 2  # a corner reached a wall
PIVOT_BALANCED = 3  # resting on the corner at the top: unstable equilibrium
PIVOT_DECIDED = 4  # friction or drag took the energy below the barrier during the pivot
PIVOT_TIMEOUT = 5  # the time allowed ran out during the pivot

# Sliding or drag-damped pivots (pivot_ode): adaptive Dormand-Prince steps.
ODE_TOL = 1e-14  # local error per step, relative to 1 rad, sqrt(g/rho), rho and sqrt(g rho)
ODE_FIRST_STEP = 1e-2  # x sqrt(rho/g): trial first step (the error control adapts it)
ODE_MAX_STEP = 5e-2  # x sqrt(rho/g): longest step, so that a brief event is still seen
ODE_MIN_STEP = 1e-13  # x sqrt(rho/g): a step this short is taken whatever its error
EVENT_SAMPLES = 4  # an accepted step's dense output is tested at 1/4, 1/2, 3/4 for events
EVENT_TIME_TOL = 1e-13  # x sqrt(rho/g): width of the bracket of an event time (Illinois, safeguarded)
STICK_SAMPLE = 1e-2  # rad: spacing of the tests for lift-off and slip on a closed-form sticking path
STICK_TURN_MARGIN = 1e-9  # x g rho: least energy over the top for a closed-form sticking path
# x sqrt(g rho): a slip this slow at the start of a pivot is round-off of a corner brought to
# rest, and the pivot starts sticking. A 3e-17 m/s slip left by the impact once started a
# mu = 1e6 slide whose normal force came out negative (the slide is inconsistent at such mu),
# a lift-off at the first instant (test_sticking_pivot_ode_matches_the_closed_form).
SLIP_TOL = 1e-12

BALANCE_TOL = 1e-12  # relative kinetic energy at the top below which the die is balanced
WALL_SAMPLES = 64


@numba.njit(cache=True)
def pivot_energy(chi, omega, radius, g, alpha):
    """Specific energy (J/kg) of a die pivoting on a table corner."""
    return 0.5 * radius * radius * (1.0 + alpha) * omega * omega + g * radius * math.sin(chi)


@numba.njit(cache=True)
def pivot_omega_squared(e, sin_chi, radius, g, alpha):
    """omega^2 (1/s^2) of a die pivoting without loss at specific energy ``e`` (J/kg) and
    angle chi (its sine ``sin_chi``): :func:`pivot_energy` solved for omega^2."""
    return 2.0 * (e - g * radius * sin_chi) / (radius * radius * (1.0 + alpha))


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
def half_angle_integral(v, delta, b):
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
    ga = half_angle_integral(0.5 * (chi_a - 0.5 * math.pi), delta, 2.0 * big_b)
    gb = half_angle_integral(0.5 * (chi_b - 0.5 * math.pi), delta, 2.0 * big_b)
    return 2.0 * abs(gb - ga)


@numba.njit(cache=True)
def _wrap(angle):
    return angle % (2.0 * math.pi)


@numba.njit(cache=True)
def flat_angles(fpar, n, corner):
    """(chi_right, chi_left): chi at which the side to the right (to corner k+1) or to the
    left (to corner k-1) of the pivot corner k lies flat on the table."""
    rho, ang = corner_geometry(fpar, corner)
    bx = rho * math.cos(ang)
    by = rho * math.sin(ang)
    com_angle = math.atan2(-by, -bx)  # centre of mass seen from the corner, body frame
    rho_r, ang_r = corner_geometry(fpar, (corner + 1) % n)
    rho_l, ang_l = corner_geometry(fpar, (corner - 1) % n)
    right = math.atan2(rho_r * math.sin(ang_r) - by, rho_r * math.cos(ang_r) - bx)
    left = math.atan2(rho_l * math.sin(ang_l) - by, rho_l * math.cos(ang_l) - bx)
    # the side to the right lies along +x when flat, the side to the left along -x
    return _wrap(com_angle - right), _wrap(com_angle + math.pi - left)


@numba.njit(cache=True)
def wall_gap(fpar, chi, com_angle, px, rho, j, half_width, surf):
    """Gap (m) between a wall and corner j while pivoting at (px, 0)."""
    phi = chi - com_angle
    rx, _ = corner_offset(fpar, j, math.cos(phi), math.sin(phi))
    x = px + rho * math.cos(chi) + rx
    if surf == SURF_LEFT:
        return x + half_width
    return half_width - x


@numba.njit(cache=True)
def first_wall_contact(fpar, n, corner, px, chi0, chi1, hit):
    """First chi on the path chi0 -> chi1 where a corner reaches a wall, or NaN.

    Only called when a wall is within reach of the die (|px| + rho + rho_max >= L). The gaps are
    smooth with at most a few extrema on a short path, so sampling then bisection is enough.
    """
    half_width = fpar[FP_WALL]
    rho, ang = corner_geometry(fpar, corner)
    com_angle = math.atan2(-math.sin(ang), -math.cos(ang))
    best = math.nan
    best_frac = 2.0
    for j in range(n):
        if j == corner:
            continue
        for surf in (SURF_LEFT, SURF_RIGHT):
            prev = wall_gap(fpar, chi0, com_angle, px, rho, j, half_width, surf)
            for i in range(1, WALL_SAMPLES + 1):
                frac = i / WALL_SAMPLES
                if frac >= best_frac:
                    break
                chi = chi0 + (chi1 - chi0) * frac
                gap = wall_gap(fpar, chi, com_angle, px, rho, j, half_width, surf)
                if gap <= 0.0 and prev > 0.0:
                    a = chi0 + (chi1 - chi0) * (i - 1) / WALL_SAMPLES
                    b = chi
                    for _ in range(100):
                        mid = 0.5 * (a + b)
                        if wall_gap(fpar, mid, com_angle, px, rho, j, half_width, surf) > 0.0:
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
def below_the_top(fpar, corner, chi0, omega0):
    """True when a pivot has less energy than it takes to pass over the top of its corner.

    A fair die never has while its side is undecided (e >= g R); a loaded die can: pivoting on
    a corner far from the centre of mass it may hold more than the barrier of its side yet
    less than g rho of that corner, and then turns back or never reaches the top. The
    closed-form time (an elliptic integral written for omega^2 > 0 at the top) does not apply;
    such pivots are followed by :func:`pivot_ode` (test_loaded_die_prefers_the_heavy_side).
    """
    g = fpar[FP_G]
    rho, _ = corner_geometry(fpar, corner)
    alpha = fpar[FP_INERTIA] / (rho * rho)
    return pivot_energy(chi0, omega0, rho, g, alpha) < g * rho * (1.0 - BALANCE_TOL)


@numba.njit(cache=True)
def pivot_next(fpar, n, corner, px, chi0, omega0, out, hit):
    """Follow a sticking pivot on ``corner`` from (chi0, omega0) to its next event.

    Parameters
    ----------
    fpar : parameter vector (dice_sweep.physics.params).
    n, corner : int
        Number of sides; the pivot corner.
    px : float
        Position (m) of the pivot corner on the table.
    chi0, omega0 : float
        Start angle of the centre of mass seen from the corner (rad) and angular velocity
        (rad/s).
    out : float64[3]
        Output: chi at the event (rad), omega there (rad/s), duration (s).
    hit : int64[2]
        Output for PIVOT_FLAT and PIVOT_WALL: surface and corner that arrives.

    Returns
    -------
    int
        PIVOT_LIFTOFF, PIVOT_FLAT, PIVOT_WALL or PIVOT_BALANCED.
    """
    chi_right, chi_left = flat_angles(fpar, n, corner)
    return pivot_next_flat(fpar, n, corner, px, chi0, omega0, chi_right, chi_left, out, hit)


@numba.njit(cache=True)
def pivot_next_flat(fpar, n, corner, px, chi0, omega0, chi_right, chi_left, out, hit):
    """:func:`pivot_next` given the corner's ``flat_angles(fpar, n, corner)``: the roll loop
    keeps them per corner for the batch, as they depend on the die alone."""
    g = fpar[FP_G]
    rho, _ = corner_geometry(fpar, corner)
    alpha = fpar[FP_INERTIA] / (rho * rho)
    chi0 = min(max(chi0, chi_right), chi_left)
    e = pivot_energy(chi0, omega0, rho, g, alpha)
    if omega0 > 0.0:
        direction = 1.0
    elif omega0 < 0.0:
        direction = -1.0
    else:
        c = math.cos(chi0)
        if c == 0.0:
            return PIVOT_BALANCED
        direction = -1.0 if c > 0.0 else 1.0
    chi_flat = chi_left if direction > 0.0 else chi_right
    # At the top with round-off-sized motion, or creeping up to it with no energy to spare:
    # the die stays balanced on the corner, and which way it would fall is round-off.
    crosses_top = direction * (0.5 * math.pi - chi0) > 0.0 and direction * (chi_flat - 0.5 * math.pi) > 0.0
    spare = BALANCE_TOL * g * rho
    at_top = 1.0 - math.sin(chi0) <= BALANCE_TOL and e - g * rho * math.sin(chi0) <= spare
    if at_top or (crosses_top and e - g * rho <= spare):
        return PIVOT_BALANCED
    kind = PIVOT_FLAT
    chi_end = chi_flat
    # lift-off: the first chi on the path where q(sin chi) < 0
    if liftoff_factor(math.sin(chi0), e, rho, g, alpha) < 0.0:
        kind = PIVOT_LIFTOFF
        chi_end = chi0
    else:
        b = 2.0 * e / rho
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
                    if liftoff_factor(probe, e, rho, g, alpha) < 0.0:
                        kind = PIVOT_LIFTOFF
                        chi_end = chi_c
    half_width = fpar[FP_WALL]
    # another corner is at most rho + rho_max from the pivot: 2 rho for a fair die; a loaded
    # die's far corner (2 rho missed it) went 1e-2 R into a wall (issue 33, fuzz throw 70227)
    if not math.isinf(half_width) and abs(px) + rho + fpar[FP_RHO_MAX] >= half_width and chi_end != chi0:
        chi_wall = first_wall_contact(fpar, n, corner, px, chi0, chi_end, hit)
        if not math.isnan(chi_wall):
            kind = PIVOT_WALL
            chi_end = chi_wall
    if kind == PIVOT_FLAT:
        hit[0] = SURF_TABLE
        hit[1] = (corner + 1) % n if direction < 0.0 else (corner - 1) % n
    out[0] = chi_end
    out[1] = direction * math.sqrt(max(omega_squared(chi_end, e, rho, g, alpha), 0.0))
    out[2] = pivot_time(chi0, chi_end, e, rho, g, alpha)
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


# ---- pivots that are not conservative: Coulomb slip and/or air drag (ODE) -------------------
# Variables: chi, omega, xp (how far the corner has slid, m), up (its slip velocity, m/s).
# Sticking (up = 0): the die turns about the corner. Sliding with slip direction s: the
# friction force is -s mu N, and N follows from the corner staying on the table,
#   N = (g - D_y - rho omega^2 sin chi) / (1 + (rho^2/I) cos chi (cos chi + s mu sin chi)),
#   omega' = -(rho/I) N (cos chi + s mu sin chi),
# with D the drag acceleration of the centre of mass (per unit mass throughout).
MODE_STICK = 0


@numba.njit(cache=True)
def _com_velocity(chi, omega, up, rho, arc):
    """COM velocity of a die on a corner (its arc, radius ``arc``) with slip velocity up."""
    if arc == 0.0:
        return up - omega * rho * math.sin(chi), omega * rho * math.cos(chi)
    return up - omega * (rho * math.sin(chi) + arc), omega * rho * math.cos(chi)


@numba.njit(cache=True)
def _rolling_rates(chi, omega, up, mode, rho, arc, inertia, g, mu, c):
    """:func:`_contact_rates` of a die on a rounded corner (arc radius ``arc`` > 0).

    The arc centre C stays at height r; the COM is at C + rho (cos chi, sin chi) and the
    contact point P = C - r y is at l = (-rho cos chi, -(rho sin chi + r)) from the COM. With N
    and F the normal and friction forces at P (per unit mass) and D the drag acceleration:
    X'' = F + D_x, Y'' = N - g + D_y, I omega' = -rho cos chi N + (rho sin chi + r) F, and
    Y = r + rho sin chi. Sticking (rolling without slip: P at rest, X' = -omega (rho sin chi +
    r)) gives, with J = I + rho^2 + r^2 + 2 r rho sin chi (I plus the squared distance from the
    COM to P),
      J omega' = rho cos chi (D_y - g) - (rho sin chi + r) D_x - r rho cos chi omega^2,
    the Lagrangian equation of the rolling die without drag. Sliding with slip direction s
    (F = -s mu N):
      N = (g - D_y - rho omega^2 sin chi) / (1 + rho cos chi L / I),
      omega' = -N L / I,  L = rho cos chi + s mu (rho sin chi + r).
    The arc centre moves at xp' = up - r omega (rolling: -r omega); up is P's slip velocity.
    """
    sc = math.sin(chi)
    cc = math.cos(chi)
    vx, vy = _com_velocity(chi, omega, up, rho, arc)
    speed = math.sqrt(vx * vx + vy * vy)
    drag_x = -c * speed * vx
    drag_y = -c * speed * vy
    w2 = omega * omega
    arm = rho * sc + arc  # height of the COM above the contact point
    if mode == MODE_STICK:
        domega = (rho * cc * (drag_y - g) - arm * drag_x - arc * rho * cc * w2) / (inertia + rho * rho + arc * arc + 2.0 * arc * rho * sc)
        ddx = -arm * domega - rho * cc * w2
        ddy = rho * (cc * domega - sc * w2)
        return omega, domega, up - arc * omega, 0.0, ddy + g - drag_y, ddx - drag_x
    lever = rho * cc + mode * mu * arm
    normal = (g - drag_y - rho * w2 * sc) / (1.0 + rho * cc * lever / inertia)
    domega = -normal * lever / inertia
    friction = -mode * mu * normal
    return omega, domega, up - arc * omega, friction + drag_x + arm * domega + rho * cc * w2, normal, friction


# Scalars in and out, no arrays: an array argument costs a reference count up and down per
# call, and the ODE calls this seven times a step (with arrays the rigid law's roll took 8.4
# instead of 7.1 us of CPU; scripts/bench_kernel.py). Results bit for bit as before.
@numba.njit(cache=True)
def _contact_rates(chi, omega, up, mode, rho, arc, inertia, g, mu, c):
    """Time derivatives (chi', omega', xp', up') of y = (chi, omega, xp, up), then (N, F_needed)
    per unit mass: six numbers.

    For a sticking corner N and F are the forces sticking needs; for a sliding one N is the
    normal force and F the friction applied. ``arc`` > 0: the corner is an arc of that radius,
    chi is the angle of the COM seen from the arc centre and xp the arc centre's displacement
    (:func:`_rolling_rates`).
    """
    if arc != 0.0:
        return _rolling_rates(chi, omega, up, mode, rho, arc, inertia, g, mu, c)
    sc = math.sin(chi)
    cc = math.cos(chi)
    drag_x = 0.0
    drag_y = 0.0
    if c != 0.0:  # without drag the zero terms below add nothing: skip the square root
        vx, vy = _com_velocity(chi, omega, up, rho, 0.0)
        speed = math.sqrt(vx * vx + vy * vy)
        drag_x = -c * speed * vx
        drag_y = -c * speed * vy
    if mode == MODE_STICK:
        torque = rho * cc * (drag_y - g) - rho * sc * drag_x  # about the corner
        domega = torque / (inertia + rho * rho)
        ddx = -rho * (sc * domega + cc * omega * omega)
        ddy = rho * (cc * domega - sc * omega * omega)
        return omega, domega, up, 0.0, ddy + g - drag_y, ddx - drag_x
    lever = cc + mode * mu * sc
    normal = (g - drag_y - rho * omega * omega * sc) / (1.0 + rho * rho / inertia * cc * lever)
    domega = -rho / inertia * normal * lever
    friction = -mode * mu * normal
    return omega, domega, up, friction + drag_x + rho * (sc * domega + cc * omega * omega), normal, friction


@numba.njit(inline="always")
def _rates_into(k, row, y, mode, rho, arc, inertia, g, mu, c):
    """k[row] = the rates at y (float64[4]); returns (N, F) as :func:`_contact_rates`."""
    r0, r1, r2, r3, normal, friction = _contact_rates(y[0], y[1], y[3], mode, rho, arc, inertia, g, mu, c)
    k[row, 0] = r0
    k[row, 1] = r1
    k[row, 2] = r2
    k[row, 3] = r3
    return normal, friction


# Dormand-Prince 5(4) (Dormand & Prince 1980), first same as last, with Shampine's quartic
# dense output: the coefficients of scipy.integrate.RK45.
DP_A21 = 1.0 / 5.0
DP_A31, DP_A32 = 3.0 / 40.0, 9.0 / 40.0
DP_A41, DP_A42, DP_A43 = 44.0 / 45.0, -56.0 / 15.0, 32.0 / 9.0
DP_A51, DP_A52, DP_A53, DP_A54 = 19372.0 / 6561.0, -25360.0 / 2187.0, 64448.0 / 6561.0, -212.0 / 729.0
DP_A61, DP_A62, DP_A63, DP_A64, DP_A65 = (9017.0 / 3168.0, -355.0 / 33.0, 46732.0 / 5247.0, 49.0 / 176.0,
                                          -5103.0 / 18656.0)
DP_B1, DP_B3, DP_B4, DP_B5, DP_B6 = 35.0 / 384.0, 500.0 / 1113.0, 125.0 / 192.0, -2187.0 / 6784.0, 11.0 / 84.0
DP_E1, DP_E3, DP_E4, DP_E5, DP_E6, DP_E7 = (-71.0 / 57600.0, 71.0 / 16695.0, -71.0 / 1920.0, 17253.0 / 339200.0,
                                            -22.0 / 525.0, 1.0 / 40.0)
DP_P0 = (-8048581381.0 / 2820520608.0, 8663915743.0 / 2820520608.0, -12715105075.0 / 11282082432.0)
DP_P2 = (131558114200.0 / 32700410799.0, -68118460800.0 / 10900136933.0, 87487479700.0 / 32700410799.0)
DP_P3 = (-1754552775.0 / 470086768.0, 14199869525.0 / 1410260304.0, -10690763975.0 / 1880347072.0)
DP_P4 = (127303824393.0 / 49829197408.0, -318862633887.0 / 49829197408.0, 701980252875.0 / 199316789632.0)
DP_P5 = (-282668133.0 / 205662961.0, 2019193451.0 / 616988883.0, -1453857185.0 / 822651844.0)
DP_P6 = (40617522.0 / 29380423.0, -110615467.0 / 29380423.0, 69997945.0 / 29380423.0)


@numba.njit(cache=True)
def _dp5_contact(y, h, mode, rho, arc, inertia, g, mu, c, scale, k, tmp, out):
    """One Dormand-Prince step of length h from y; k[0] must hold the rates at y.

    Writes the fifth-order solution to ``out`` and its rates to k[6] (the next step's k[0]);
    returns the embedded error estimate in units of the tolerance, max over i of
    |error_i| / scale[i].
    """
    for i in range(4):
        tmp[i] = y[i] + h * DP_A21 * k[0, i]
    _rates_into(k, 1, tmp, mode, rho, arc, inertia, g, mu, c)
    for i in range(4):
        tmp[i] = y[i] + h * (DP_A31 * k[0, i] + DP_A32 * k[1, i])
    _rates_into(k, 2, tmp, mode, rho, arc, inertia, g, mu, c)
    for i in range(4):
        tmp[i] = y[i] + h * (DP_A41 * k[0, i] + DP_A42 * k[1, i] + DP_A43 * k[2, i])
    _rates_into(k, 3, tmp, mode, rho, arc, inertia, g, mu, c)
    for i in range(4):
        tmp[i] = y[i] + h * (DP_A51 * k[0, i] + DP_A52 * k[1, i] + DP_A53 * k[2, i] + DP_A54 * k[3, i])
    _rates_into(k, 4, tmp, mode, rho, arc, inertia, g, mu, c)
    for i in range(4):
        tmp[i] = y[i] + h * (DP_A61 * k[0, i] + DP_A62 * k[1, i] + DP_A63 * k[2, i] + DP_A64 * k[3, i]
                             + DP_A65 * k[4, i])
    _rates_into(k, 5, tmp, mode, rho, arc, inertia, g, mu, c)
    for i in range(4):
        out[i] = y[i] + h * (DP_B1 * k[0, i] + DP_B3 * k[2, i] + DP_B4 * k[3, i] + DP_B5 * k[4, i]
                             + DP_B6 * k[5, i])
    _rates_into(k, 6, out, mode, rho, arc, inertia, g, mu, c)
    err = 0.0
    for i in range(4):
        e = h * (DP_E1 * k[0, i] + DP_E3 * k[2, i] + DP_E4 * k[3, i] + DP_E5 * k[4, i] + DP_E6 * k[5, i]
                 + DP_E7 * k[6, i])
        err = max(err, abs(e) / scale[i])
    if math.isnan(err):
        return math.inf
    return err


@numba.njit(inline="always")  # in pivot_ode: as a call (three array arguments) it cost reference counts per bisection step
def _dp5_dense(y, h, k, theta, out):
    """State a fraction ``theta`` into the last Dormand-Prince step from y (quartic, error
    of the order of the step's own)."""
    t2 = theta * theta
    t3 = t2 * theta
    t4 = t3 * theta
    w0 = theta + DP_P0[0] * t2 + DP_P0[1] * t3 + DP_P0[2] * t4
    w2 = DP_P2[0] * t2 + DP_P2[1] * t3 + DP_P2[2] * t4
    w3 = DP_P3[0] * t2 + DP_P3[1] * t3 + DP_P3[2] * t4
    w4 = DP_P4[0] * t2 + DP_P4[1] * t3 + DP_P4[2] * t4
    w5 = DP_P5[0] * t2 + DP_P5[1] * t3 + DP_P5[2] * t4
    w6 = DP_P6[0] * t2 + DP_P6[1] * t3 + DP_P6[2] * t4
    for i in range(4):
        out[i] = y[i] + h * (w0 * k[0, i] + w2 * k[2, i] + w3 * k[3, i] + w4 * k[4, i] + w5 * k[5, i]
                             + w6 * k[6, i])


@numba.njit(cache=True)
def _sticking_event(chi, omega, rho, g, mu, normal, friction, drag_accel):
    """Lift-off (3) or slip (4) of a sticking corner, else 0; ``drag_accel`` is the drag's
    downward acceleration of the centre of mass, c |v| v_y (m/s^2)."""
    if -g - drag_accel + omega * omega * rho * math.sin(chi) >= 0.0:
        return 3  # a released corner would leave the table (see the module docstring)
    if not math.isinf(mu) and abs(friction) > mu * normal:
        return 4  # friction cannot hold the corner: it starts to slide
    return 0


@numba.njit(inline="always")  # in pivot_ode: as a call (four array arguments) it cost reference counts per test
def _contact_event(fpar, n, corner, px, y, mode, rho, arc, inertia, g, mu, c, chi_right, chi_left, state, hit):
    """The event that holds in contact state y (0: none), with ``hit`` for impacts.

    Order matters only for simultaneous events: impacts, then lift-off, then friction
    transitions, then the decision.
    """
    chi, omega = y[0], y[1]
    if (chi <= chi_right and omega < 0.0) or (chi >= chi_left and omega > 0.0):
        hit[0] = SURF_TABLE
        hit[1] = (corner + 1) % n if chi <= chi_right else (corner - 1) % n
        return 1
    _, _, _, _, normal, friction = _contact_rates(y[0], y[1], y[3], mode, rho, arc, inertia, g, mu, c)
    vx, vy = _com_velocity(chi, omega, y[3], rho, arc)
    height = rho * math.sin(chi) if arc == 0.0 else rho * math.sin(chi) + arc
    energy = 0.5 * (vx * vx + vy * vy) + 0.5 * inertia * omega * omega + g * height
    half_width = fpar[FP_WALL]
    walls = not math.isinf(half_width)
    # the full state (an atan2 and some trigonometry) only when walls or the outcome rule need
    # it: the die can be decided only below g rho_max (this check made sliding pivots 1.4 x
    # faster with bitwise equal results)
    may_decide = energy < g * fpar[FP_RHO_MAX]
    if walls or may_decide:
        _, angle = corner_geometry(fpar, corner)
        state[0] = px + y[2] + rho * math.cos(chi)
        state[1] = height
        state[2] = chi - angle - math.pi
        state[3] = vx
        state[4] = vy
        state[5] = omega
    if walls:
        cphi = math.cos(state[2])
        sphi = math.sin(state[2])
        for j in range(n):
            rx, _ = corner_offset(fpar, j, cphi, sphi)
            if state[0] + rx + arc >= half_width or state[0] + rx - arc <= -half_width:
                hit[0] = SURF_RIGHT if state[0] + rx + arc >= half_width else SURF_LEFT
                hit[1] = j
                return 2
    if mode == MODE_STICK:
        speed = math.sqrt(vx * vx + vy * vy)
        found = _sticking_event(chi, omega, rho, g, mu, normal, friction, c * speed * vy)
        if found != 0:
            return found
    else:
        if normal < 0.0:
            return 3
        if mode * y[3] < 0.0:
            return 4  # the slip stopped: stick again, or slide the other way
    if may_decide and decided_side(state, fpar, n) >= 0:
        return 5
    return 0


@numba.njit(cache=True)  # a call, not inlined: five inlined copies cost compile time for ~10 calls a pivot
def _event_margin(code, y, mode, rho, arc, inertia, g, mu, c, chi_right, chi_left):
    """A continuous function of contact state y that is >= 0 where event ``code`` of
    :func:`_contact_event` holds (the same formulas), to steer the search for its time; NaN
    for the events without one here (walls, the decision: those are bisected)."""
    chi, omega = y[0], y[1]
    if code == 1:
        return chi_right - chi if omega < 0.0 else chi - chi_left
    if code != 3 and code != 4:
        return math.nan
    _, _, _, _, normal, friction = _contact_rates(chi, omega, y[3], mode, rho, arc, inertia, g, mu, c)
    if mode != MODE_STICK:
        return -normal if code == 3 else -mode * y[3]
    if code == 4:
        return abs(friction) - mu * normal
    vx, vy = _com_velocity(chi, omega, y[3], rho, arc)
    return -g - c * math.sqrt(vx * vx + vy * vy) * vy + omega * omega * rho * math.sin(chi)


@numba.njit(cache=True)
def _stick_event(y, rho, inertia, g, mu):
    """Lift-off (3) or slip (4) of a sticking corner without drag in state y, else 0: the
    test :func:`_contact_event` makes (the same function)."""
    _, _, _, _, normal, friction = _contact_rates(y[0], y[1], y[3], MODE_STICK, rho, 0.0, inertia, g, mu, 0.0)
    return _sticking_event(y[0], y[1], rho, g, mu, normal, friction, 0.0)


@numba.njit(cache=True)
def _stick_margin(sin_chi, cos_chi, e, rho, g, alpha, mu):
    """max(released-corner lift, |F| - mu N) (m/s^2) of a sticking corner without drag at
    energy e: the event of :func:`_stick_event` is due where it is >= 0.

    With omega^2 = 2 (e - g rho s) / (rho^2 (1 + alpha)), s = sin chi, the forces per unit
    mass are F = cos chi P(s) and N = g alpha / (1 + alpha) + s P(s), with
    P(s) = 3 g s / (1 + alpha) - 2 e / (rho (1 + alpha)).
    """
    w2 = pivot_omega_squared(e, sin_chi, rho, g, alpha)
    lift = w2 * rho * sin_chi - g
    if math.isinf(mu):
        return lift
    p = (3.0 * g * sin_chi - 2.0 * e / rho) / (1.0 + alpha)
    normal = g * alpha / (1.0 + alpha) + sin_chi * p
    return max(lift, abs(cos_chi * p) - mu * normal)


@numba.njit(cache=True)
def _stick_closed_form(fpar, px, y, rho, inertia, g, mu, chi_right, chi_left, t_room, probe):
    """Move a sticking pivot without drag along its exact path to its next event.

    Without drag a sticking pivot keeps its energy, so omega and the contact forces are
    known functions of chi (the closed form of :func:`pivot_next`). Lift-off and slip are
    tested on a grid of chi spaced at most STICK_SAMPLE, the first sign change of
    :func:`_stick_margin` is located by the Illinois method, and the time is the elliptic
    integral :func:`pivot_time`. Returns that time (s) with y moved to the event, or -1 with
    y untouched when the closed form does not apply: omega = 0, energy less than
    STICK_TURN_MARGIN over the top of the corner (turning points, and pivot_time's domain),
    a wall within reach, a loaded die that may be
    decided on the way (its barrier changes with the side below), or more time than
    ``t_room``, or rounded corners (a rolling pivot: its time is no longer this elliptic
    integral). The event itself is left to :func:`_contact_event` in the caller.
    """
    omega = y[1]
    if omega == 0.0 or fpar[FP_CORNER_RADIUS] != 0.0:  # a rolling pivot: the ODE (docs/physics.md)
        return -1.0
    half_width = fpar[FP_WALL]
    if not math.isinf(half_width) and abs(px + y[2]) + 2.0 * fpar[FP_RHO_MAX] >= half_width:
        return -1.0
    alpha = inertia / (rho * rho)
    chi0 = y[0]
    e = pivot_energy(chi0, omega, rho, g, alpha)
    fair = fpar[FP_COM_X] == 0.0 and fpar[FP_COM_Y] == 0.0
    if not fair and e < g * fpar[FP_RHO_MAX]:
        return -1.0
    # pivot_time is written for omega^2 > 0 at the top, even where the path stays below it:
    # a rocking die going down with e < g rho once got a time of 0
    # (tests/measured/test_tracks.py::test_convention_glitches_and_missing_frames_are_recovered)
    if e - g * rho <= STICK_TURN_MARGIN * g * rho:
        return -1.0
    chi_end = chi_left if omega > 0.0 else chi_right
    direction = 1.0 if omega > 0.0 else -1.0
    # Grid up to the flat angle included (a lift-off or slip just before it comes first; at
    # the flat angle itself _contact_event reports the flat side). sin and cos of the grid
    # points by rotation: a few ulp of drift, enough to bracket.
    samples = max(int(abs(chi_end - chi0) / STICK_SAMPLE) + 1, 4)
    step = (chi_end - chi0) / samples
    cs = math.cos(step)
    ss = math.sin(step)
    sin_chi = math.sin(chi0)
    cos_chi = math.cos(chi0)
    lo = chi0
    hi = chi_end
    # the caller found no event at chi0; should round-off make the margin say otherwise,
    # the event is located right after chi0
    f_lo = min(_stick_margin(sin_chi, cos_chi, e, rho, g, alpha, mu), -1e-300)
    f_hi = 0.0
    for j in range(1, samples + 1):
        sin_chi, cos_chi = sin_chi * cs + cos_chi * ss, cos_chi * cs - sin_chi * ss
        chi = chi_end if j == samples else chi0 + step * j
        f = _stick_margin(sin_chi, cos_chi, e, rho, g, alpha, mu)
        if f >= 0.0:
            hi = chi
            f_hi = f
            break
        lo = chi
        f_lo = f
    if lo != chi_end:
        # Illinois (regula falsi, halving the weight of a retained end) on the margin with
        # exact sin and cos, then the caller's own test: where round-off makes it disagree,
        # the first bracket end on which it holds
        side = 0
        for _ in range(100):
            if abs(hi - lo) <= 4e-16 * abs(hi) or f_hi == f_lo:
                break
            mid = (lo * f_hi - hi * f_lo) / (f_hi - f_lo)
            if not (min(lo, hi) < mid < max(lo, hi)):
                mid = 0.5 * (lo + hi)
            f = _stick_margin(math.sin(mid), math.cos(mid), e, rho, g, alpha, mu)
            if f >= 0.0:
                hi = mid
                f_hi = f
                if side == 1:
                    f_lo *= 0.5
                side = 1
            else:
                lo = mid
                f_lo = f
                if side == -1:
                    f_hi *= 0.5
                side = -1
        probe[2] = y[2]
        probe[3] = y[3]
        nudge = 4e-16 * abs(hi)
        for _ in range(40):
            probe[0] = hi
            probe[1] = direction * math.sqrt(max(omega_squared(hi, e, rho, g, alpha), 0.0))
            if _stick_event(probe, rho, inertia, g, mu) != 0 or hi == chi_end:
                break
            hi = hi + direction * nudge if direction * (chi_end - hi) > nudge else chi_end
            nudge *= 2.0
    tau = pivot_time(chi0, hi, e, rho, g, alpha)
    if tau > t_room:
        return -1.0
    y[0] = hi
    y[1] = direction * math.sqrt(max(omega_squared(hi, e, rho, g, alpha), 0.0))
    return tau


# ---- sliding without drag on a sharp corner: the exact path, panel by panel in chi -----------
# With s the slip direction, k = rho^2 / I, L = cos chi + s mu sin chi and D = 1 + k cos chi L,
# W = omega^2 obeys the linear equation dW/dchi = 2 omega' = (k s mu - D') W / D - 2 rho g L / (I D),
# so W(chi) = (D_a / D) exp(k s mu Phi) (W_a - 2 rho g / (I D_a) int_a^chi L exp(-k s mu Phi)),
# Phi = int_a^chi dchi / D; t = int dchi / |omega|. The contact force is the only horizontal
# force and N = vy' + g, so the centre of mass moves as vx = vx_a - s mu (vy - vy_a + g t):
# the slip velocity and the slid distance follow from (chi, omega, t) with no integral.
# The integrals are spectral: values at Chebyshev points to values of the integral, one matrix.
# Panel lengths and points: the last two Chebyshev coefficients of 1/D (poles where D = 0, about
# 0.5 rad off the real axis at mu = 0.5) stay below 1e-15 at 24 points over 0.4 rad and at 10
# points over 0.02 rad and at 6 over 1e-4 rad (a numpy check of fig08's square at mu = 0.5 and 1,
# both slip directions). Most slides of the rigid law are the slip a pivot starts with, which
# stops within 1e-4 rad.
SLIDE_NODES = 24  # Chebyshev points of a panel
SLIDE_PANEL = 0.4  # rad: longest panel
SLIDE_SHORT_NODES = 10  # Chebyshev points of a short first panel (a slip about to stop)
SLIDE_SHORT_PANEL = 0.02  # rad: longest short panel
SLIDE_TINY_NODES = 6  # Chebyshev points of a tiny first panel
SLIDE_TINY_PANEL = 1e-4  # rad: longest tiny panel
SLIDE_STOP_REACH = 2.0  # a first panel spans this many times the estimated turn to a slip stop
# Last two Chebyshev coefficients of 1/D and 1/omega, relative, on a panel of SLIDE_PANEL rad;
# on a shorter panel the bound grows as its length falls (the error of the integrals is per
# radian, and a tiny panel's values are flat to round-off): larger halves the panel.
SLIDE_TAIL = 1e-15
SLIDE_HALVINGS = 4  # a panel halved this often without converging (a turning point near) leaves the slide to the ODE
PIVOT_SCRATCH_ROWS = 22  # pivot_ode_flat's scratch: scale, y, trial, tmp, state, 7 stages, 10 rows of a slide


def _chebyshev_tables(m):
    """Chebyshev-Lobatto points on [-1, 1] (increasing), the matrix taking values there to the
    values of the interpolant's integral from -1 (stored transposed: row j holds what value j
    adds to each point), the rows giving its last two Chebyshev coefficients, and the
    barycentric weights."""
    x = -np.cos(np.pi * np.arange(m) / (m - 1))
    cheb = np.polynomial.chebyshev
    to_coef = np.linalg.solve(cheb.chebvander(x, m - 1), np.eye(m))
    integral = np.empty((m, m))
    for k in range(m):
        unit = np.zeros(m)
        unit[k] = 1.0
        integral[:, k] = cheb.chebval(x, cheb.chebint(unit, lbnd=-1.0))
    weights = (-1.0) ** np.arange(m)
    weights[[0, -1]] *= 0.5
    return x, np.ascontiguousarray((integral @ to_coef).T), np.ascontiguousarray(to_coef[-2:]), weights


SLIDE_TABLES = _chebyshev_tables(SLIDE_NODES)
SLIDE_SHORT_TABLES = _chebyshev_tables(SLIDE_SHORT_NODES)
SLIDE_TINY_TABLES = _chebyshev_tables(SLIDE_TINY_NODES)


@numba.njit(cache=True)
def _panel_integral(q_t, work, src, m, scale, dst):
    """work[dst] = scale times the integral from the panel's start of the interpolant of the
    first m values of work[src] at the Chebyshev points, at the same points (q_t: the table's
    matrix, transposed). Rows by index, not as views: a view costs a reference count up and
    down.

    Each point's sum runs over the values in order, as a dot product would, but all points
    advance together: the points are independent, so the loop over them vectorizes, where a dot
    product per point is a chain of dependent additions. The same sums, bit for bit.
    """
    for i in range(m):
        work[dst, i] = 0.0
    for j in range(m):
        v = work[src, j]
        for i in range(1, m):
            work[dst, i] += q_t[j, i] * v
    for i in range(1, m):
        work[dst, i] *= scale


@numba.njit(cache=True)
def _panel_tail(rows, work, src, m):
    """Size of the last two Chebyshev coefficients of the first m values of work[src] relative
    to their largest (rows: the table's)."""
    top = 0.0
    c1 = 0.0
    c2 = 0.0
    for j in range(m):
        value = work[src, j]
        top = max(top, abs(value))
        c1 += rows[0, j] * value
        c2 += rows[1, j] * value
    return (abs(c1) + abs(c2)) / top


@numba.njit(cache=True)
def _panel_values(x, xs, weights, work, a, b, m):
    """The interpolants of the first m values of work[a] and work[b] (at the Chebyshev points
    xs) at x in [-1, 1], by the barycentric formula."""
    num_a = 0.0
    num_b = 0.0
    den = 0.0
    for j in range(m):
        d = x - xs[j]
        if d == 0.0:
            return work[a, j], work[b, j]
        q = weights[j] / d
        num_a += q * work[a, j]
        num_b += q * work[b, j]
        den += q
    return num_a / den, num_b / den


@numba.njit(cache=True)
def _slide_state(sc, cc, w2, t, direction, s_mu, rho, g, vx_a, vy_a, x_a, y_a):
    """(omega, xp, up) of a slide at the angle of sine sc and cosine cc, omega^2 = w2, t
    seconds in (the comment above); x_a, y_a: the centre of mass at the start from the corner."""
    omega = direction * math.sqrt(w2)
    height = rho * sc
    up = vx_a - s_mu * (omega * rho * cc - vy_a + g * t) + omega * height
    xp = x_a + vx_a * t - s_mu * (height - y_a - vy_a * t + 0.5 * g * t * t) - rho * cc
    return omega, xp, up


@numba.njit(cache=True)
def _slide_margin(sc, w2, up, mode, rho, g):
    """> 0 where a slide's event holds: the slip stopped (mode up < 0) or the normal force
    is negative (rho omega^2 sin chi > g, D > 0); the larger of the two."""
    return max(-mode * up, rho * w2 * sc - g)


@numba.njit(cache=True)
def _slide_event(chi, omega, up, mode, rho, inertia, g, mu):
    """Lift-off (3) or slip stop (4) of a drag-free slide, else 0: the test
    :func:`_contact_event` makes (the same function)."""
    _, _, _, _, normal, _ = _contact_rates(chi, omega, up, mode, rho, 0.0, inertia, g, mu, 0.0)
    if normal < 0.0:
        return 3
    if mode * up < 0.0:
        return 4
    return 0


@numba.njit(cache=True)
def _slide_closed_form(fpar, px, y, mode, rho, inertia, g, mu, chi_right, chi_left, t_room, work):
    """Move a drag-free slide on a sharp corner along its exact path to its next event.

    The slide is followed in chi, panel by panel (SLIDE_NODES Chebyshev points over at most
    SLIDE_PANEL rad; a first panel around a slip estimated to stop soon takes the short or
    the tiny table), each panel halved until the last Chebyshev coefficients of 1/D and 1/omega fall
    below SLIDE_TAIL (scaled by the panel's length), with W = omega^2, the time, the slip velocity and the slid distance
    from the closed forms of the comment above. The first Chebyshev point where the slip has
    stopped or the normal force is negative brackets the event, which is located by the
    Illinois method on :func:`_slide_margin` of the interpolants and then moved on until
    :func:`_slide_event` holds. Without either, the slide reaches the flat angle. Returns the
    time (s) with y moved to the event, or -1 with y untouched when this does not apply:
    omega = 0, rounded corners, a wall within reach where the slide starts or ends, D <= 0 or omega = 0 on the way (a
    Painleve jam, a turning point), a panel that does not converge, an energy below g rho_max
    at the event (the side may be decided on the way: the ODE tests that), or more time than
    ``t_room``. ``work`` is scratch, float64[10, SLIDE_NODES].
    """
    omega_a = y[1]
    if omega_a == 0.0 or fpar[FP_CORNER_RADIUS] != 0.0:
        return -1.0
    half_width = fpar[FP_WALL]
    if not math.isinf(half_width) and abs(px + y[2]) + 2.0 * fpar[FP_RHO_MAX] >= half_width:
        return -1.0
    direction = 1.0 if omega_a > 0.0 else -1.0
    chi_end = chi_left if omega_a > 0.0 else chi_right
    k = rho * rho / inertia
    s_mu = mode * mu
    chi_a = y[0]
    sc = math.sin(chi_a)
    cc = math.cos(chi_a)
    vx_a = y[3] - omega_a * rho * sc
    vy_a = omega_a * rho * cc
    x_a = y[2] + rho * cc
    y_a = rho * sc
    # a slip being braked: the first panel reaches a little past where it would stop
    _, _, _, slip_rate, _, _ = _contact_rates(chi_a, omega_a, y[3], mode, rho, 0.0, inertia, g, mu, 0.0)
    panel = SLIDE_PANEL
    if mode * y[3] > 0.0 and mode * slip_rate < 0.0:
        panel = min(panel, SLIDE_STOP_REACH * abs(omega_a * y[3] / slip_rate))
    # the rows of work by index (a view costs a reference count up and down)
    chi_n, sin_n, cos_n, inv_d, phi, lever, integral, w2, inv_w, t_n = 0, 1, 2, 3, 4, 5, 6, 7, 8, 9
    lo = chi_a  # start of the current panel, W and the time there
    w_lo = omega_a * omega_a
    t_lo = 0.0
    halvings = 0
    found = -1  # the Chebyshev point where the event first holds
    while True:
        if direction * (chi_end - lo) <= 0.0:
            return -1.0
        if panel <= SLIDE_TINY_PANEL:
            xs, q, rows, weights = SLIDE_TINY_TABLES
            m = SLIDE_TINY_NODES
        elif panel <= SLIDE_SHORT_PANEL:
            xs, q, rows, weights = SLIDE_SHORT_TABLES
            m = SLIDE_SHORT_NODES
        else:
            xs, q, rows, weights = SLIDE_TABLES
            m = SLIDE_NODES
        hi = chi_end if direction * (chi_end - lo) <= panel else lo + direction * panel
        half = 0.5 * (hi - lo)
        if half == 0.0:
            return -1.0
        tail_tol = SLIDE_TAIL * max(1.0, 0.5 * SLIDE_PANEL / abs(half))
        ok = True
        for j in range(m):
            chi = hi if j == m - 1 else lo + half * (xs[j] + 1.0)
            sn = math.sin(chi)
            cs = math.cos(chi)
            lev = cs + s_mu * sn
            d = 1.0 + k * cs * lev
            if not d > 0.0:
                ok = False
                break
            work[chi_n, j] = chi
            work[sin_n, j] = sn
            work[cos_n, j] = cs
            work[inv_d, j] = 1.0 / d
            work[lever, j] = lev
        if ok and _panel_tail(rows, work, inv_d, m) > tail_tol:
            ok = False
        if ok:
            _panel_integral(q, work, inv_d, m, half, phi)
            for j in range(m):
                work[phi, j] = math.exp(k * s_mu * work[phi, j])  # now exp(k s mu Phi)
                work[lever, j] /= work[phi, j]
            _panel_integral(q, work, lever, m, half, integral)
            d_lo = 1.0 / work[inv_d, 0]
            pull = 2.0 * rho * g / (inertia * d_lo)
            for j in range(m):
                w = d_lo * work[inv_d, j] * work[phi, j] * (w_lo - pull * work[integral, j])
                if not w > 0.0:
                    ok = False
                    break
                work[w2, j] = w
                work[inv_w, j] = 1.0 / math.sqrt(w)
            if ok and _panel_tail(rows, work, inv_w, m) > tail_tol:
                ok = False
        if not ok:
            halvings += 1
            if halvings > SLIDE_HALVINGS:
                return -1.0
            panel *= 0.5
            continue
        _panel_integral(q, work, inv_w, m, abs(half), t_n)
        for j in range(m):
            work[t_n, j] += t_lo
        for j in range(1, m):
            _, _, up = _slide_state(work[sin_n, j], work[cos_n, j], work[w2, j], work[t_n, j], direction, s_mu, rho, g, vx_a, vy_a, x_a, y_a)
            if _slide_margin(work[sin_n, j], work[w2, j], up, mode, rho, g) > 0.0:
                found = j
                break
        if found >= 0 or hi == chi_end:
            break
        lo = hi
        w_lo = work[w2, m - 1]
        t_lo = work[t_n, m - 1]
        panel = SLIDE_PANEL
    if found < 0:
        chi = chi_end
        w_end = work[w2, m - 1]
        t_end = work[t_n, m - 1]
    else:
        # Illinois in x in [-1, 1] on the interpolants' margin, then on until the test holds
        x_lo = xs[found - 1]
        x_hi = 1.0 if found == m - 1 else xs[found]
        _, _, up = _slide_state(work[sin_n, found - 1], work[cos_n, found - 1], work[w2, found - 1], work[t_n, found - 1], direction, s_mu, rho, g, vx_a, vy_a, x_a, y_a)
        f_lo = min(_slide_margin(work[sin_n, found - 1], work[w2, found - 1], up, mode, rho, g), -1e-300)
        _, _, up = _slide_state(work[sin_n, found], work[cos_n, found], work[w2, found], work[t_n, found], direction, s_mu, rho, g, vx_a, vy_a, x_a, y_a)
        f_hi = _slide_margin(work[sin_n, found], work[w2, found], up, mode, rho, g)
        # the bracket is shrunk to the ODE's EVENT_TIME_TOL (as dx = dt |omega| / |half|):
        # below it the margin is round-off (the slip is a difference of m/s-sized terms)
        x_tol = EVENT_TIME_TOL * math.sqrt(rho / g) * math.sqrt(work[w2, found]) / abs(half)
        side = 0
        for _ in range(100):
            if x_hi - x_lo <= x_tol or f_hi == f_lo:
                break
            x = (x_lo * f_hi - x_hi * f_lo) / (f_hi - f_lo)
            if not x_lo < x < x_hi:
                x = 0.5 * (x_lo + x_hi)
            chi = lo + half * (x + 1.0)
            sn = math.sin(chi)
            w, t = _panel_values(x, xs, weights, work, w2, t_n, m)
            _, _, up = _slide_state(sn, math.cos(chi), w, t, direction, s_mu, rho, g, vx_a, vy_a, x_a, y_a)
            f = _slide_margin(sn, w, up, mode, rho, g)
            if f > 0.0:
                x_hi = x
                f_hi = f
                if side == 1:
                    f_lo *= 0.5
                side = 1
            else:
                x_lo = x
                f_lo = f
                if side == -1:
                    f_hi *= 0.5
                side = -1
        nudge = 4e-16
        for _ in range(60):
            chi = hi if x_hi >= 1.0 else lo + half * (x_hi + 1.0)
            w_end, t_end = _panel_values(x_hi, xs, weights, work, w2, t_n, m)
            omega, _, up = _slide_state(math.sin(chi), math.cos(chi), w_end, t_end, direction, s_mu, rho, g, vx_a, vy_a, x_a, y_a)
            if _slide_event(chi, omega, up, mode, rho, inertia, g, mu) != 0 or x_hi >= 1.0:
                break
            x_hi = min(x_hi + nudge, 1.0)
            nudge *= 2.0
    if t_end > t_room:
        return -1.0
    sc = math.sin(chi)
    cc = math.cos(chi)
    omega, xp, up = _slide_state(sc, cc, w_end, t_end, direction, s_mu, rho, g, vx_a, vy_a, x_a, y_a)
    # the corner slides one way (the slip keeps its sign up to the event), so the die stays
    # between where it started and where it ends: out of a wall's reach at both, never near one
    if not math.isinf(half_width) and abs(px + xp) + 2.0 * fpar[FP_RHO_MAX] >= half_width:
        return -1.0
    vx = up - omega * rho * sc
    vy = omega * rho * cc
    if 0.5 * (vx * vx + vy * vy + inertia * w_end) + g * rho * sc < g * fpar[FP_RHO_MAX] * (1.0 + 1e-9):
        return -1.0  # it may be decided on the way (energy falls while sliding): the ODE's tests
    y[0] = chi
    y[1] = omega
    y[2] = xp
    y[3] = up
    return t_end


@numba.njit(cache=True)
def _event_holds(found, stop_at_decision):
    return found != 0 and (found != 5 or stop_at_decision)


@numba.njit(cache=True)
def pivot_ode(fpar, n, corner, px, chi0, omega0, slip0, t_left, stop_at_decision, out, hit):
    """Follow a pivot with Coulomb slip and/or air drag to its next event (ODE).

    ``slip0`` is the corner's slip velocity (m/s) at the start; ``stop_at_decision`` False
    ignores the decision event (for following a die to rest). Same contract as
    :func:`pivot_next`, plus out[3] = slid distance of the corner (m) and
    out[4] = its slip velocity (m/s) at the event, and two more results: PIVOT_DECIDED when
    friction or drag took the energy below the barrier, PIVOT_TIMEOUT when ``t_left`` (s) ran
    out (out then holds the state at exactly t_left: sample_records relies on that).

    A slip below SLIP_TOL sqrt(g rho) at the start counts as sticking. Sticking phases
    without drag take the exact path (:func:`_stick_closed_form`) where it applies, and so do
    sliding phases without drag on a sharp corner (:func:`_slide_closed_form`); the rest
    is integrated by adaptive Dormand-Prince 5(4) steps with a local error below ODE_TOL of
    the die's scales. After each accepted step the event predicate (:func:`_contact_event`) is tested at its end
    and, when it holds there, on the step's dense output at EVENT_SAMPLES points, then the
    bracket is shrunk to EVENT_TIME_TOL by Illinois steps on the event's margin
    (:func:`_event_margin`), the predicate deciding which end moves; the step is then taken again, for real, to the event, so that
    the event holds in the state returned (the loop's next pass acts on it).
    """
    chi_right, chi_left = flat_angles(fpar, n, corner)
    return pivot_ode_flat(fpar, n, corner, px, chi0, omega0, slip0, t_left, stop_at_decision, chi_right, chi_left, out, hit)


@numba.njit(cache=True)
def pivot_ode_flat(fpar, n, corner, px, chi0, omega0, slip0, t_left, stop_at_decision, chi_right, chi_left, out, hit):
    """:func:`pivot_ode` given the corner's ``flat_angles(fpar, n, corner)`` (the roll loop keeps
    them per corner, as for :func:`pivot_next_flat`)."""
    g = fpar[FP_G]
    mu = fpar[FP_MU]
    c = fpar[FP_DRAG]
    inertia = fpar[FP_INERTIA]
    arc = fpar[FP_CORNER_RADIUS]
    rho, _ = corner_geometry(fpar, corner)
    time_unit = math.sqrt(rho / g)
    h_max = ODE_MAX_STEP * time_unit
    h_min = ODE_MIN_STEP * time_unit
    t_tol = EVENT_TIME_TOL * time_unit
    # one allocation for all the scratch (rows of SLIDE_NODES): seven were about 150 ns of a
    # rigid-law pivot's 2.7 us (issue 33)
    buf = np.empty((PIVOT_SCRATCH_ROWS, SLIDE_NODES))
    scale = buf[0, :4]
    scale[0] = ODE_TOL
    scale[1] = ODE_TOL / time_unit
    scale[2] = ODE_TOL * rho
    scale[3] = ODE_TOL * rho / time_unit
    y = buf[1, :4]
    trial = buf[2, :4]
    tmp = buf[3, :4]
    state = buf[4, :6]
    k = buf[5:12]  # rows 0-6 of the Dormand-Prince stages (the first 4 columns)
    work = buf[12:22]
    for i in range(4):
        y[i] = 0.0
        trial[i] = 0.0
        tmp[i] = 0.0
    for i in range(6):
        state[i] = 0.0
    y[0] = min(max(chi0, chi_right), chi_left)
    y[1] = omega0
    y[3] = slip0
    if abs(slip0) <= SLIP_TOL * math.sqrt(g * rho):
        y[3] = 0.0
    mode = MODE_STICK if y[3] == 0.0 else (1 if y[3] > 0.0 else -1)
    t = 0.0
    h = ODE_FIRST_STEP * time_unit
    kind = PIVOT_TIMEOUT
    event = -1  # the event at y, -1 when not known yet
    fresh = False  # k[0] holds the rates at y in the current mode
    closed_form_last = False  # the last move was a closed-form sticking path
    max_steps = int(t_left / h_max) + 2 * int(1e6)
    for _ in range(max_steps):
        if event < 0:
            event = _contact_event(fpar, n, corner, px, y, mode, rho, arc, inertia, g, mu, c, chi_right, chi_left, state, hit)
        if event == 4:
            # friction transition at this instant: slide (direction against the needed force)
            _, _, _, _, normal, friction = _contact_rates(y[0], y[1], y[3], MODE_STICK, rho, arc, inertia, g, mu, c)
            if mode != MODE_STICK and abs(friction) <= mu * normal:
                mode = MODE_STICK
                y[3] = 0.0
            elif y[3] != 0.0:
                mode = 1 if y[3] > 0.0 else -1
            else:
                mode = 1 if friction < 0.0 else -1  # slide against the force sticking needs
            fresh = False
            closed_form_last = False  # a new mode: its own closed form may follow one of the other
        elif event == 5 and not stop_at_decision:
            event = 0
        elif event != 0:
            kind = (PIVOT_FLAT, PIVOT_WALL, PIVOT_LIFTOFF, PIVOT_DECIDED)[event - 1 if event < 4 else 3]
            break
        if mode == MODE_STICK and abs(y[1]) < 1e-12 * math.sqrt(g / rho) and abs(math.cos(y[0])) < 1e-9:
            kind = PIVOT_BALANCED
            break
        if t_left - t <= 0.0:
            kind = PIVOT_TIMEOUT
            break
        if c == 0.0 and not closed_form_last:
            if mode == MODE_STICK:
                tau = _stick_closed_form(fpar, px, y, rho, inertia, g, mu, chi_right, chi_left, t_left - t, trial)
            else:
                tau = _slide_closed_form(fpar, px, y, mode, rho, inertia, g, mu, chi_right, chi_left, t_left - t, work)
            if tau >= 0.0:
                # the next pass finds the event at y; should round-off hide it there, take
                # an ODE step rather than the same closed form again
                t += tau
                event = -1
                fresh = False
                closed_form_last = True
                continue
        closed_form_last = False
        if not fresh:
            _rates_into(k, 0, y, mode, rho, arc, inertia, g, mu, c)
            fresh = True
        while True:
            step = min(h, t_left - t)
            err = _dp5_contact(y, step, mode, rho, arc, inertia, g, mu, c, scale, k, tmp, trial)
            if err <= 1.0 or step <= h_min:
                break
            h = step * max(0.2, 0.9 * err ** -0.2)
        # the usual controller: growth at most 5 x, at most h_max; a step cut short by t_left
        # leaves h as it was
        grow = 5.0 if err < 1e-4 else min(5.0, 0.9 * err ** -0.2)
        h = min(max(h if step < h else 0.0, step * grow), h_max)
        probe = _contact_event(fpar, n, corner, px, trial, mode, rho, arc, inertia, g, mu, c, chi_right, chi_left, state, hit)
        if _event_holds(probe, stop_at_decision):
            # first sample of the dense output where the event holds, then the bracket
            # [lo, hi] (no event at lo, the event at hi) shrunk to EVENT_TIME_TOL
            lo = 0.0
            hi = step
            code = probe
            for j in range(1, EVENT_SAMPLES):
                theta = j / EVENT_SAMPLES
                _dp5_dense(y, step, k, theta, tmp)
                found = _contact_event(fpar, n, corner, px, tmp, mode, rho, arc, inertia, g, mu, c, chi_right, chi_left, state, hit)
                if _event_holds(found, stop_at_decision):
                    hi = theta * step
                    code = found
                    break
                lo = theta * step
            _dp5_dense(y, step, k, hi / step, tmp)
            f_hi = _event_margin(code, tmp, mode, rho, arc, inertia, g, mu, c, chi_right, chi_left)
            _dp5_dense(y, step, k, lo / step, tmp)
            f_lo = _event_margin(code, tmp, mode, rho, arc, inertia, g, mu, c, chi_right, chi_left)
            # Illinois steps on the event's margin, safeguarded: the event predicate alone
            # decides which end moves, a trial is kept t_tol / 2 inside the bracket, and a
            # bracket that did not halve over two trials is bisected
            side = 0
            width_1 = math.inf  # bracket width one and two trials ago
            width_2 = math.inf
            while hi - lo > t_tol:
                width = hi - lo
                if f_lo < 0.0 <= f_hi and width <= 0.5 * width_2:
                    mid = (lo * f_hi - hi * f_lo) / (f_hi - f_lo)
                    mid = min(max(mid, lo + 0.5 * t_tol), hi - 0.5 * t_tol)
                else:
                    mid = 0.5 * (lo + hi)
                    side = 0
                width_2 = width_1
                width_1 = width
                _dp5_dense(y, step, k, mid / step, tmp)
                found = _contact_event(fpar, n, corner, px, tmp, mode, rho, arc, inertia, g, mu, c, chi_right, chi_left, state, hit)
                if _event_holds(found, stop_at_decision):
                    hi = mid
                    if found != code:
                        # another event comes first: steer by its margin from now on
                        code = found
                        f_hi = _event_margin(code, tmp, mode, rho, arc, inertia, g, mu, c, chi_right, chi_left)
                        _dp5_dense(y, step, k, lo / step, tmp)
                        f_lo = _event_margin(code, tmp, mode, rho, arc, inertia, g, mu, c, chi_right, chi_left)
                        side = 0
                        continue
                    f_hi = _event_margin(code, tmp, mode, rho, arc, inertia, g, mu, c, chi_right, chi_left)
                    if side == 1:
                        f_lo *= 0.5
                    side = 1
                else:
                    lo = mid
                    f_lo = _event_margin(code, tmp, mode, rho, arc, inertia, g, mu, c, chi_right, chi_left)
                    if side == -1:
                        f_hi *= 0.5
                    side = -1
            # a real step to hi; where the dense output was off by its own small error and the
            # event does not hold there yet, move on by doubling amounts (the full step has it)
            gap = t_tol
            while True:
                _dp5_contact(y, hi, mode, rho, arc, inertia, g, mu, c, scale, k, tmp, trial)
                probe = _contact_event(fpar, n, corner, px, trial, mode, rho, arc, inertia, g, mu, c, chi_right, chi_left, state, hit)
                if _event_holds(probe, stop_at_decision) or hi >= step:
                    break
                hi = min(hi + gap, step)
                gap *= 2.0
            step = hi
        for i in range(4):
            y[i] = trial[i]
            k[0, i] = k[6, i]  # first same as last: the rates at the new y
        t = t_left if step == t_left - t else t + step
        event = probe
    out[0] = y[0]
    out[1] = y[1]
    out[2] = t
    out[3] = y[2]
    out[4] = y[3]
    return kind
