"""Free flight (Smith 2014, eqs 6-8) and exact contact detection.

Flight is evaluated in closed form from the state at the start of the flight segment, never
accumulated step by step, so a long flight has no drift. Contacts are found by conservative
advancement: for every corner and surface the gap obeys an exact quadratic lower bound

    gap(t + s) >= gap(t) + gap'(t) s - M2 s^2 / 2,   M2 = |n . a_centre| + R omega^2,

so stepping to the first root of that bound can never pass a contact. Near a root the step
is a Newton step taken from the safe side, which converges quadratically; a corner is never
inside a surface by more than round-off.

Surfaces: 0 = table (y = 0, normal +y), 1 = left wall (x = -L, normal +x), 2 = right wall
(x = +L, normal -x), with L half the wall separation (inf: no walls).
"""

import math

import numba

SURF_TABLE = 0
SURF_LEFT = 1
SURF_RIGHT = 2

NO_CONTACT = -1.0  # no contact before the horizon
STALLED = -2.0  # the search did not converge within MAX_SEARCH_STEPS

MAX_SEARCH_STEPS = 20000


@numba.njit(cache=True)
def surface_frame(surf, half_width):
    """Normal (nx, ny) pointing into the free region and offset d: gap = d + n . p."""
    if surf == SURF_TABLE:
        return 0.0, 1.0, 0.0
    if surf == SURF_LEFT:
        return 1.0, 0.0, half_width
    return -1.0, 0.0, half_width


@numba.njit(cache=True)
def flight_state(s0, tau, g, out):
    """State after a free flight of ``tau`` seconds from ``s0`` = (x, y, phi, vx, vy, omega)."""
    out[0] = s0[0] + s0[3] * tau
    out[1] = s0[1] + s0[4] * tau - 0.5 * g * tau * tau
    out[2] = s0[2] + s0[5] * tau
    out[3] = s0[3]
    out[4] = s0[4] - g * tau
    out[5] = s0[5]


@numba.njit(cache=True)
def safe_step(f, fp, m2):
    """First positive root of f + fp s - m2 s^2 / 2 (f >= 0): a step that cannot pass a root.

    The fp < 0 branch uses the cancellation-free form, which is what makes the last steps
    before a contact Newton steps accurate to round-off.
    """
    if m2 <= 0.0:
        if fp < 0.0:
            return f / (-fp)
        return math.inf
    sq = math.sqrt(fp * fp + 2.0 * m2 * f)
    if fp < 0.0:
        return 2.0 * f / (sq - fp)
    return (fp + sq) / m2


@numba.njit(cache=True)
def next_contact(s0, n, radius, g, half_width, tau_max, tol, min_step, contact_speed, hit):
    """Time of the next corner contact in free flight from state ``s0``.

    Parameters
    ----------
    s0 : float64[6]
        State (x, y, phi, vx, vy, omega) at the start of the flight, SI.
    n : int
        Number of sides.
    radius, g, half_width : float
        Circumradius (m), gravity (m/s^2), half the wall separation (m, inf: no walls).
    tau_max : float
        Horizon (s).
    tol : float
        Gap (m) below which an approaching corner counts as touching.
    min_step : float
        Smallest step (s) taken while a touching corner is separating (avoids a zero step
        when a corner leaves with zero normal velocity, as at a pivot lift-off).
    contact_speed : float
        A touching corner approaching slower than this (m/s) is round-off of a corner at
        rest, not an impact (a corner just released by a pivot must not re-hit at once).
    hit : int64[2]
        Output: surface and corner of the contact.

    Returns
    -------
    float
        Contact time (s) from the start, ``NO_CONTACT`` if none before ``tau_max``,
        ``STALLED`` if the search did not converge.
    """
    n_surf = 1 if math.isinf(half_width) else 3
    dtheta = 2.0 * math.pi / n
    cos_dt = math.cos(dtheta)
    sin_dt = math.sin(dtheta)
    omega = s0[5]
    rot_m2 = radius * omega * omega
    tau = 0.0
    for _ in range(MAX_SEARCH_STEPS):
        x = s0[0] + s0[3] * tau
        y = s0[1] + s0[4] * tau - 0.5 * g * tau * tau
        phi = s0[2] + omega * tau
        vx = s0[3]
        vy = s0[4] - g * tau
        step = math.inf
        best_surf = -1
        best_corner = -1
        best_rate = 0.0
        for surf in range(n_surf):
            nx, ny, d = surface_frame(surf, half_width)
            h = d + nx * x + ny * y  # distance of the centre from the surface
            hv = nx * vx + ny * vy
            ha = abs(ny) * g
            if h - radius > 1e-6 * radius:
                # No corner reaches the surface before the centre is within R of it. (The
                # margin keeps this shortcut from taking round-off-sized steps near h = R.)
                step = min(step, safe_step(h - radius, hv, ha))
                continue
            m2 = ha + rot_m2
            ck = math.cos(phi)
            sk = math.sin(phi)
            for k in range(n):
                f = h + radius * (nx * ck + ny * sk)
                fp = hv + radius * omega * (ny * ck - nx * sk)
                if f <= tol:
                    if fp < -contact_speed:
                        if best_corner < 0 or fp < best_rate:
                            best_surf = surf
                            best_corner = k
                            best_rate = fp
                    elif m2 > 0.0:
                        step = min(step, max(2.0 * max(fp, 0.0) / m2, min_step))
                    else:
                        step = min(step, math.inf if fp > 0.0 else min_step)
                else:
                    step = min(step, safe_step(f, fp, m2))
                # rotate the corner direction by 2 pi / n instead of calling cos/sin again
                ck, sk = ck * cos_dt - sk * sin_dt, sk * cos_dt + ck * sin_dt
        if best_corner >= 0:
            hit[0] = best_surf
            hit[1] = best_corner
            return tau
        if tau + step > tau_max:
            return NO_CONTACT
        tau += step
    return STALLED
