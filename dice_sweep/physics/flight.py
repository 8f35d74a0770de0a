"""Free flight (Smith 2014, eqs 6-8), flight with air drag, and exact contact detection.

Without drag, flight is evaluated in closed form from the state at the start of the flight
segment, never accumulated step by step. With quadratic drag (a = -c |v| v on the centre of
mass) there is no closed form: the translation is integrated by classical Runge-Kutta steps
with step-doubling error control (position error below fpar[FP_DRAG_TOL] rho_max per step, steps
at most fpar[FP_DRAG_MAX_STEP]); the rotation
stays exact (drag exerts no torque about the centre of mass).

Contacts are found by conservative advancement: for every corner and surface the gap obeys a
quadratic lower bound

    gap(t + s) >= gap(t) + gap'(t) s - M2 s^2 / 2,   M2 = max |n . a_com| + rho_k omega^2,

so stepping to the first root of that bound can never pass a contact. Near a root the step is
a Newton step taken from the safe side, which converges quadratically; a corner is never
inside a surface by more than round-off. With drag the steps are also the integration steps,
so the contact is located to the same precision as without it.

Rounded corners (fpar[FP_CORNER_RADIUS] = r > 0): the corner block holds the arc centres, and a
corner's gap is its arc centre's distance from the surface less r, so the search runs on the
centres against each surface moved r towards the die (the same bound holds: the gap and the
centre's distance differ by a constant). FP_RHO_MAX is the die's reach, max rho_k + r, so the
"no corner within reach" shortcut is unchanged. At r = 0 the subtraction of +0.0 is exact.

Surfaces: 0 = table (y = 0, normal +y), 1 = left wall (x = -L, normal +x), 2 = right wall
(x = +L, normal -x), with L half the wall separation (inf: no walls).
"""

import math

import numba
import numpy as np

from dice_sweep.physics.params import (
    CORNER_STRIDE,
    FP_COM_X,
    FP_COM_Y,
    FP_CORNER_RADIUS,
    FP_CORNERS,
    FP_DRAG,
    FP_DRAG_MAX_STEP,
    FP_DRAG_TOL,
    FP_G,
    FP_RHO_MAX,
    FP_WALL,
    IP_N,
)

SURF_TABLE = 0
SURF_LEFT = 1
SURF_RIGHT = 2

NO_CONTACT = -1.0  # no contact before the horizon
STALLED = -2.0  # the search did not converge within MAX_SEARCH_STEPS

MAX_SEARCH_STEPS = 200000
DRAG_MIN_STEP = 1e-8  # x sqrt(R/g): shortest; below it the step is taken whatever its error
REACH_MARGIN = 1e-6  # x rho_max: a surface farther than the die's reach by this cannot be touched
# A fair die with this many sides or more: the drag-free search visits, on the table, the
# NEAR_CORNERS corners either side of the lowest and bounds the rest (issue 33: n = 20 spent
# most of a roll on the corner loop). REST_MARGIN (relative) covers round-off in that bound.
NEAR_MIN_SIDES = 12
NEAR_CORNERS = 1
REST_MARGIN = 1e-9
# That search also bounds each corner's curvature over a turn of at most NEAR_TURN (rad)
# instead of by rho omega^2 (see _corner_motion): fig09's flights took 3.15 steps instead of
# 4.74 (0.02: 3.12, 0.1: 3.25, 0.2: 3.43), to the same contact tolerance.
NEAR_TURN = 0.05
# And the corner that limits a step is stepped, if it can be shown safe, to where its gap is
# HOP_AIM tol (accepted within HOP_AIM +- HOP_BAND tol) by Newton steps on its exact gap in
# flight (hop_step): a hop of the corner that just hit took 3 search steps, now 2 (issue 33).
# HOP_TURN (rad) bounds the turn over which its series are used (error < 1e-20 rho).
HOP_AIM = 0.5
HOP_BAND = 0.25
HOP_TURN = 0.05
HOP_NEWTON = 4
HOP_SURE = 0.5  # a Newton step's end is taken unevaluated if its bound is within this share of the band
HOP_CONCAVE = 1e-6  # relative margin of rho omega^2 < g: every corner's gap concave in time


@numba.njit(cache=True)
def surface_frame(surf, half_width):
    """Normal (nx, ny) pointing into the free region and offset d: gap = d + n . p."""
    if surf == SURF_TABLE:
        return 0.0, 1.0, 0.0
    if surf == SURF_LEFT:
        return 1.0, 0.0, half_width
    return -1.0, 0.0, half_width


@numba.njit(cache=True)
def corner_offset(fpar, corner, cos_phi, sin_phi):
    """Vector (m) from the centre of mass to ``corner`` at body angle phi."""
    base = FP_CORNERS + CORNER_STRIDE * corner
    rho = fpar[base]
    cg = fpar[base + 1]
    sg = fpar[base + 2]
    return rho * (cos_phi * cg - sin_phi * sg), rho * (sin_phi * cg + cos_phi * sg)


@numba.njit(cache=True)
def flight_state(s0, tau, g, out):
    """State after a drag-free flight of ``tau`` seconds from ``s0`` = (x, y, phi, vx, vy, omega)."""
    out[0] = s0[0] + s0[3] * tau
    out[1] = s0[1] + s0[4] * tau - 0.5 * g * tau * tau
    out[2] = s0[2] + s0[5] * tau
    out[3] = s0[3]
    out[4] = s0[4] - g * tau
    out[5] = s0[5]


@numba.njit(cache=True)
def _rk4_drag(s, h, g, c, out):
    """One classical Runge-Kutta step of the translation with drag; rotation exact."""
    x, y, vx, vy = s[0], s[1], s[3], s[4]
    sp = math.sqrt(vx * vx + vy * vy)
    k1x, k1y, k1u, k1v = vx, vy, -c * sp * vx, -g - c * sp * vy
    ux, uy = vx + 0.5 * h * k1u, vy + 0.5 * h * k1v
    sp = math.sqrt(ux * ux + uy * uy)
    k2x, k2y, k2u, k2v = ux, uy, -c * sp * ux, -g - c * sp * uy
    ux, uy = vx + 0.5 * h * k2u, vy + 0.5 * h * k2v
    sp = math.sqrt(ux * ux + uy * uy)
    k3x, k3y, k3u, k3v = ux, uy, -c * sp * ux, -g - c * sp * uy
    ux, uy = vx + h * k3u, vy + h * k3v
    sp = math.sqrt(ux * ux + uy * uy)
    k4x, k4y, k4u, k4v = ux, uy, -c * sp * ux, -g - c * sp * uy
    out[0] = x + h * (k1x + 2.0 * k2x + 2.0 * k3x + k4x) / 6.0
    out[1] = y + h * (k1y + 2.0 * k2y + 2.0 * k3y + k4y) / 6.0
    out[2] = s[2] + s[5] * h
    out[3] = vx + h * (k1u + 2.0 * k2u + 2.0 * k3u + k4u) / 6.0
    out[4] = vy + h * (k1v + 2.0 * k2v + 2.0 * k3v + k4v) / 6.0
    out[5] = s[5]


@numba.njit(cache=True)
def drag_step(s, h, g, c, out, work):
    """Step of length h with error control by step doubling; returns the error estimate (m).

    ``out`` gets the two-half-steps result improved by Richardson extrapolation.
    """
    _rk4_drag(s, h, g, c, work[0])
    _rk4_drag(s, 0.5 * h, g, c, work[1])
    _rk4_drag(work[1], 0.5 * h, g, c, out)
    err = max(abs(out[0] - work[0, 0]), abs(out[1] - work[0, 1])) / 15.0
    for i in (0, 1, 3, 4):
        out[i] += (out[i] - work[0, i]) / 15.0
    return err


@numba.njit(cache=True)
def drag_step_limits(fpar):
    """(longest step s, error allowed per step m, shortest step s) of a flight with drag."""
    return (fpar[FP_DRAG_MAX_STEP], fpar[FP_DRAG_TOL] * fpar[FP_RHO_MAX],
            DRAG_MIN_STEP * math.sqrt(fpar[FP_RHO_MAX] / fpar[FP_G]))


@numba.njit(cache=True)
def advance_flight(s0, tau, fpar, out):
    """State after a flight of ``tau`` seconds (with drag if any); for sampling paths."""
    g = fpar[FP_G]
    c = fpar[FP_DRAG]
    if c == 0.0:
        flight_state(s0, tau, g, out)
        return
    work = np.empty((2, 6))
    cur = s0.copy()
    done = 0.0
    max_step, tol, h_min = drag_step_limits(fpar)
    h = max_step
    while done < tau:
        h = min(h, tau - done)
        if drag_step(cur, h, g, c, out, work) > tol and h > h_min:
            h *= 0.5
            continue
        cur[:] = out
        done += h
        h = min(2.0 * h, max_step)
    out[:] = cur


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
def _touching_step(f, fp, m2, tol):
    """Step for a corner within tol of a surface that does not approach faster than
    contact_speed.

    Separating (fp > 0): the time for the bound to come back to the surface, 2 fp / m2
    (never with m2 = 0, a corner of a die without spin against a wall).
    Otherwise the corner may graze the surface for a long time: a corner at the bottom of
    a die spinning at omega with rho omega^2 close to g barely accelerates. It used to step
    by min_step there, and one such fig11 flight took 162,122 steps (42 % of all the search
    steps of fig11 at 64 x 64; tests/physics/test_flight.py, grazing). Instead step
    to where the bound could reach -tol / 2: within the tolerance with room for round-off
    (to -tol itself, a resting corner ended 3e-5 tol deeper: test_flight.py, the exact gap).
    With m2 = 0 and fp = 0 (a corner of a die without spin resting against a wall) that is
    never: min_step there made the search stall after MAX_SEARCH_STEPS while the die fell
    (test_flight.py, random flights, hypothesis seed 25); so is a corner of such a die that
    creeps into the wall slower than contact_speed, once past -tol / 2.
    """
    if fp > 0.0:
        if m2 <= 0.0:
            return math.inf
        # A corner leaving a sliding pivot separates at third order (zero normal speed and
        # acceleration at lift-off), so 2 fp / m2 is round-off sized and the search stalled
        # after MAX_SEARCH_STEPS (652 of 1000 flat, sliding hexagons, friction 1.2;
        # tests/physics/test_stalls.py). Stepping until the bound could fall tol / 2 below
        # where it starts, as if the corner were not separating, is as safe as the branch below
        # and changes nothing when the corner leaves at any real speed.
        if f + 0.5 * tol > 0.0:
            return max(2.0 * fp / m2, math.sqrt(2.0 * (f + 0.5 * tol) / m2))
        return 2.0 * fp / m2
    if f + 0.5 * tol > 0.0:
        return safe_step(f + 0.5 * tol, fp, m2)
    if m2 <= 0.0:
        # no spin against a wall: the gap falls at the constant, round-off rate fp for ever,
        # which is no impact; min_step here stalled the search (issue 33, a creeping corner)
        return math.inf
    return 0.0


@numba.njit(inline="always")
def _corner_motion(fpar, k, cos_phi, sin_phi, h, hv, nx, ny, omega, accel, turn):
    """Corner k against a surface (normal nx, ny; the centre of mass ``h`` from it, moving at
    ``hv``): its gap f (m), the gap's rate fp (m/s), the bound m2 (m/s^2) on the gap's
    curvature, and a tighter bound that holds while the die turns by at most ``turn`` (rad).
    One piece for :func:`_scan` and :func:`search_free`.

    The gap's curvature is n . a - omega^2 (n . r), r the corner from the centre of mass. Turned
    by u (|u| <= turn), n . r becomes (n . r) cos u + (n . r_perp) sin u, at most
    n . r + |n . r_perp| turn + rho turn^2 / 2 (and at most rho): for the corner at the bottom,
    curving towards the surface at g - rho omega^2, far less than the g + rho omega^2 of m2.
    """
    base = FP_CORNERS + CORNER_STRIDE * k
    rho = fpar[base]
    rx = rho * (cos_phi * fpar[base + 1] - sin_phi * fpar[base + 2])
    ry = rho * (sin_phi * fpar[base + 1] + cos_phi * fpar[base + 2])
    along = nx * rx + ny * ry
    across = ny * rx - nx * ry
    reach = min(rho, along + abs(across) * turn + 0.5 * rho * turn * turn)
    return h + nx * rx + ny * ry, hv + omega * across, accel + rho * omega * omega, accel + omega * omega * reach


@numba.njit(inline="always")
def _corner_step(f, fp, m2, tol, min_step):
    """Safe step (s) for a corner that does not touch now: touching within tol (no faster than
    contact_speed), or clear of the surface."""
    if f <= tol:
        return max(_touching_step(f, fp, m2, tol), min_step)
    return safe_step(f, fp, m2)


@numba.njit(inline="always")
def _turn_step(f, fp, m2, m2_turn, tol, min_step, turn_time, step):
    """``step`` shortened by a corner's safe step by the tighter bound m2_turn (safe up to
    turn_time) or, if that is longer, the longer of turn_time and the wide bound's step (both
    safe); the wide one is only computed while it could shorten ``step``."""
    corner_step = _corner_step(f, fp, m2_turn, tol, min_step)
    if corner_step > turn_time and step > turn_time:
        corner_step = max(turn_time, _corner_step(f, fp, m2, tol, min_step))
    return min(step, corner_step)


@numba.njit(inline="always")
def turn_series(d):
    """(cos d - 1, sin d - d) for |d| <= HOP_TURN (rad): the series stop at their 8th and 9th
    powers, off by less than 3e-20 at 0.05 rad."""
    u = d * d
    cos_m1 = u * (-0.5 + u * (1.0 / 24.0 + u * (-1.0 / 720.0 + u * (1.0 / 40320.0))))
    sin_m = d * u * (-1.0 / 6.0 + u * (1.0 / 120.0 + u * (-1.0 / 5040.0 + u * (1.0 / 362880.0))))
    return cos_m1, sin_m


@numba.njit(inline="always")
def turned_trig(phi, anchor_phi, anchor_cos, anchor_sin):
    """(cos phi, sin phi, anchor_phi, anchor_cos, anchor_sin): within HOP_TURN of the anchor
    (an angle whose cosine and sine came from libm, or from a pivot's end within a few ulp;
    NaN: none) by the angle-addition identity and :func:`turn_series`, else from libm, phi then
    being the new anchor. Never from a value so derived, so errors do not pile up from step to
    step (issue 33: a 20-sided roll's flights turn about 1e-3 rad each; the series take half a
    libm call's time)."""
    d = phi - anchor_phi
    if abs(d) <= HOP_TURN:
        cos_m1, sin_m = turn_series(d)
        sin_d = d + sin_m
        return (anchor_cos + (anchor_cos * cos_m1 - anchor_sin * sin_d),
                anchor_sin + (anchor_sin * cos_m1 + anchor_cos * sin_d), anchor_phi, anchor_cos, anchor_sin)
    c = math.cos(phi)
    sn = math.sin(phi)
    return c, sn, phi, c, sn


@numba.njit(inline="always")
def hop_gap(f, fp, rx, ry, omega, g, s):
    """Gap (m) and its rate (m/s) of a corner ``s`` seconds into a drag-free flight, from its gap
    f, rate fp and offset (rx, ry) from the centre of mass now (table; the die turns by omega s
    with |omega s| <= HOP_TURN, :func:`turn_series`)."""
    d = omega * s
    cos_m1, sin_m = turn_series(d)
    gap = f + fp * s - 0.5 * g * s * s + ry * cos_m1 + rx * sin_m
    rate = fp - g * s - omega * ry * (d + sin_m) + omega * rx * cos_m1
    return gap, rate


# A call, not inlined (scalars only, so no reference counts): at most once a search step, and
# inlined into search_free and _scan it lengthened the cold compile.
@numba.njit(cache=True)
def hop_step(f, fp, rx, ry, omega, g, tol, s, s_max):
    """A step (s) putting a corner's gap above the table (f, its rate fp, its offset (rx, ry)
    from the centre of mass) within HOP_AIM +- HOP_BAND tol, by Newton steps from ``s`` (the
    corner's safe step) or, for a corner leaving the table, from the time a parabola of its
    curvature now would take to come back; 0 if none is found within s_max (<= HOP_TURN /
    |omega|).

    Only for a die whose corners' gaps are all concave in time (g > rho omega^2: the gap's
    curvature is -g - omega^2 (n . r) <= -g + rho omega^2). Then the gap stays above the
    smaller of its values at 0 and at the step, so a step ending with the gap above 0 passed
    no contact of this corner (a corner that starts touching, leaving, may dip only where it
    started). Newton steps on a concave gap falling past its root come back from beyond it, and
    end below their tangent's aim by at most half the curvature's bound times the step squared:
    a step whose bound is well inside the band is taken without evaluating the gap there
    (tests/physics/test_flight.py checks every hop against the exact gap)."""
    curve = g + omega * omega * ry  # the gap's curvature now, less sign
    if f <= tol and fp > 0.0 and curve > 0.0:
        # leaving the table: back at about 2 fp / curve, closer than the bound's safe step
        # (fig09: 2.75 -> 2.0 gap evaluations a hop); Newton steps go on from either side
        s = 2.0 * fp / curve
    # |the gap's curvature| <= g + omega^2 |r|, and |r| <= |rx| + |ry|
    m2 = g + omega * omega * (abs(rx) + abs(ry))
    for i in range(HOP_NEWTON):
        if not (s > 0.0 and s <= s_max):  # the series hold up to s_max
            return 0.0
        gap, rate = hop_gap(f, fp, rx, ry, omega, g, s)
        if abs(gap - HOP_AIM * tol) <= HOP_BAND * tol:
            return s
        if not rate < 0.0:
            return 0.0
        ds = (HOP_AIM * tol - gap) / rate
        s += ds
        # The concave gap ends this Newton step below its tangent's HOP_AIM tol by at most
        # m2 ds^2 / 2: well inside the band, it needs no evaluation to be accepted (fig09: 1.98
        # evaluations a hop). Not on the last pass, which returns 0 as before.
        if 0.5 * m2 * ds * ds <= HOP_SURE * HOP_BAND * tol and s > 0.0 and s <= s_max and i < HOP_NEWTON - 1:
            return s
    return 0.0


@numba.njit(inline="always")
def _near_step(f, fp, m2, m2_turn, tol, min_step, turn_time, step, second, limit, k):
    """After corner k (its step by :func:`_turn_step`): the shortest corner step so far, the
    second shortest and the corner of the shortest (for :func:`_hop_limit`)."""
    corner_step = _turn_step(f, fp, m2, m2_turn, tol, min_step, turn_time, second)
    if corner_step < step:
        return corner_step, step, k
    return step, corner_step, limit


@numba.njit(inline="always")
def _hop_limit(fpar, limit, cos_phi, sin_phi, h, hv, omega, g, tol, step, second, hop_time):
    """``step``, set by corner ``limit`` alone (``second``: the next shortest corner step),
    lengthened to that corner's :func:`hop_step` if it is longer, up to ``second``."""
    if limit < 0 or not step < second:
        return step
    rx, ry = corner_offset(fpar, limit, cos_phi, sin_phi)
    return min(second, max(step, hop_step(h + ry, hv + omega * rx, rx, ry, omega, g, tol, step, hop_time)))


@numba.njit(cache=True)
def _scan(s, fpar, n, n_surf, accel_table, accel_wall, tol, min_step, contact_speed, turn, hit):
    """Safe step (s) from state s, or -1 with ``hit`` set when a corner touches now; with
    ``turn`` >= 0 (rad) each corner also takes the tighter curvature bound (as
    :func:`search_free` on a many-sided die)."""
    half_width = fpar[FP_WALL]
    rho_max = fpar[FP_RHO_MAX]
    arc = fpar[FP_CORNER_RADIUS]
    omega = s[5]
    turn_time = turn / abs(omega) if turn >= 0.0 and omega != 0.0 else math.inf
    hop = turn >= 0.0 and omega * omega * fpar[FP_CORNERS] < accel_table * (1.0 - HOP_CONCAVE)
    hop_time = HOP_TURN / abs(omega) if omega != 0.0 else math.inf
    cphi = math.cos(s[2])
    sphi = math.sin(s[2])
    step = math.inf
    best_corner = -1
    best_rate = 0.0
    for surf in range(n_surf):
        nx, ny, d = surface_frame(surf, half_width)
        h = d + nx * s[0] + ny * s[1]  # distance of the centre of mass from the surface
        hv = nx * s[3] + ny * s[4]
        accel = accel_table if surf == SURF_TABLE else accel_wall
        if h - rho_max > REACH_MARGIN * rho_max:
            # No corner reaches the surface before the COM is within rho_max of it. (The
            # margin keeps this shortcut from taking round-off-sized steps near h = rho_max.)
            step = min(step, safe_step(h - rho_max, hv, accel))
            continue
        h -= arc  # rounded corners: the arc centres against the surface moved by r (exact at 0)
        second = math.inf
        limit = -1
        for k in range(n):
            f, fp, m2, m2_turn = _corner_motion(fpar, k, cphi, sphi, h, hv, nx, ny, omega, accel, max(turn, 0.0))
            if f <= tol and fp < -contact_speed:
                if best_corner < 0 or fp < best_rate:
                    hit[0] = surf
                    hit[1] = k
                    best_corner = k
                    best_rate = fp
            elif turn >= 0.0:
                step, second, limit = _near_step(f, fp, m2, m2_turn, tol, min_step, turn_time, step, second, limit, k)
            else:
                step = min(step, _corner_step(f, fp, m2, tol, min_step))
        if hop and surf == SURF_TABLE and best_corner < 0:
            step = _hop_limit(fpar, limit, cphi, sphi, h, hv, omega, accel, tol, step, second, hop_time)
    if best_corner >= 0:
        return -1.0
    return step


@numba.njit(inline="always")
def _table_gap(fpar, k, cos_phi, sin_phi, h):
    """Gap (m) of corner k above the table with the centre of mass ``h`` above it."""
    base = FP_CORNERS + CORNER_STRIDE * k
    return h + fpar[base] * (sin_phi * fpar[base + 1] + cos_phi * fpar[base + 2])


@numba.njit(cache=True)
def search_free(fpar, n, n_surf, tau_max, tol, min_step, contact_speed, x0, y0, phi0, vx0, vy0, omega,
                known_phi, known_cos, known_sin, anchor_phi, anchor_cos, anchor_sin):
    """Drag-free contact search from the state (x0, y0, phi0, vx0, vy0, omega): the steps of
    :func:`_scan` from the closed-form flight; a fair die of NEAR_MIN_SIDES or more without
    walls also takes each corner's tighter curvature bound (:func:`_corner_motion`, ``turn``).

    The same arithmetic as ``_scan`` on ``flight_state`` (so the same steps, bit for bit;
    tests/physics/test_flight.py checks it), written as one loop over local variables:
    no array traffic per step, and the sine and cosine of phi only on steps that visit the
    corners (not while the centre of mass is still far from every surface). The state comes
    in and goes out as scalars: every array argument of a numba function that calls others
    costs a reference count up and down per call. This loop is most of a roll's time
    (docs/dev/profile.md). Its corner loop repeats ``_scan``'s on purpose: the two as one
    ``inline="always"`` function made the paper kernel 10 to 20 % slower (bench_kernel.py,
    interleaved runs).

    ``known_cos`` and ``known_sin`` are the cosine and sine of the angle ``known_phi`` (NaN:
    none), taken instead of computing them again when phi is that angle: a flight that starts
    at an impact starts at the angle where the search that found it stopped (issue 33: a
    20-sided roll has about 100 flights). Other angles' cosine and sine come from
    :func:`turned_trig` and the anchor ``anchor_phi`` (NaN: none).

    Returns
    -------
    tau : float
        As :func:`next_contact`.
    surf, corner : int
        The contact (-1, -1 when none).
    x, y, phi, vy : float
        The state at the contact or where the search stopped (vx and omega do not change).
    trig_phi, cos_phi, sin_phi : float
        The cosine and sine of trig_phi, the last angle whose cosine and sine were computed
        (or known_phi and the known values).
    anchor_phi, anchor_cos, anchor_sin : float
        The anchor for the next search.
    """
    g = fpar[FP_G]
    half_width = fpar[FP_WALL]
    rho_max = fpar[FP_RHO_MAX]
    arc = fpar[FP_CORNER_RADIUS]
    x, y, phi, vy = x0, y0, phi0, vy0
    few_near = n >= NEAR_MIN_SIDES and fpar[FP_COM_X] == 0.0 and fpar[FP_COM_Y] == 0.0 and n_surf == 1
    # the tighter curvature bound holds for steps up to this; a longer one takes the wider bound's
    turn_time = NEAR_TURN / abs(omega) if omega != 0.0 else math.inf
    per_rad = n / (2.0 * math.pi)
    hop = few_near and omega * omega * fpar[FP_CORNERS] < g * (1.0 - HOP_CONCAVE)
    hop_time = HOP_TURN / abs(omega) if omega != 0.0 else math.inf
    tau = 0.0
    result = STALLED
    hit_surf = -1
    hit_corner = -1
    trig_phi, cphi, sphi = known_phi, known_cos, known_sin
    for _ in range(MAX_SEARCH_STEPS):
        step = math.inf
        best_corner = -1
        best_rate = 0.0
        trig = False
        for surf in range(n_surf):
            nx, ny, d = surface_frame(surf, half_width)
            h = d + nx * x + ny * y
            hv = nx * vx0 + ny * vy
            accel = g if surf == SURF_TABLE else 0.0
            if h - rho_max > REACH_MARGIN * rho_max:
                step = min(step, safe_step(h - rho_max, hv, accel))
                continue
            h -= arc  # rounded corners: arc centres against the surface moved by r
            if not trig:
                if phi != trig_phi:
                    cphi, sphi, anchor_phi, anchor_cos, anchor_sin = turned_trig(phi, anchor_phi, anchor_cos, anchor_sin)
                    trig_phi = phi
                trig = True
            first = 0
            count = n
            lowest_first = 0  # the lowest corner visited first (a contact is most often there)
            if few_near and surf == SURF_TABLE:
                # corner k of a fair die is at phi + 2 pi k / n: the lowest is the nearest to -pi/2
                first = int(math.floor((-0.5 * math.pi - phi) * per_rad + 0.5)) % n - NEAR_CORNERS
                first += n if first < 0 else 0
                count = 2 * NEAR_CORNERS + 1
                lowest_first = NEAR_CORNERS
            step_in = step
            while True:
                step = step_in
                second = math.inf  # the second shortest corner step, and the corner of the shortest
                limit = -1
                for j in range(count):
                    # the order changes no result: the step and the second are the two shortest
                    # corner steps (a tie leaves step == second: no hop), the contact by its rule
                    k = first + j + (lowest_first if j < count - lowest_first else lowest_first - count)
                    k -= n if k >= n else 0
                    f, fp, m2, m2_turn = _corner_motion(fpar, k, cphi, sphi, h, hv, nx, ny, omega, accel, NEAR_TURN)
                    if f <= tol and fp < -contact_speed:
                        # ties go to the lowest index, in whatever order the corners come
                        if best_corner < 0 or fp < best_rate or (fp == best_rate and surf == hit_surf and k < best_corner):
                            hit_surf = surf
                            best_corner = k
                            best_rate = fp
                    elif few_near:
                        if best_corner < 0:  # with a contact found the step is not used
                            step, second, limit = _near_step(f, fp, m2, m2_turn, tol, min_step, turn_time, step, second,
                                                             limit, k)
                    else:
                        step = min(step, _corner_step(f, fp, m2, tol, min_step))
                if hop and best_corner < 0:
                    step = _hop_limit(fpar, limit, cphi, sphi, h, hv, omega, accel, tol, step, second, hop_time)
                if count == n:
                    break
                # The corners not visited are a run of the cycle without the lowest: no lower
                # than the nearer of its two ends (a fair die's heights rise away from the
                # bottom), no faster than hv + |omega| rho. Unless that bound shows that none
                # can touch now nor shorten the step, every corner is visited, as without it:
                # the step and the contact are the full loop's, bit for bit. With a contact
                # found the step is not used: none of the others touching is enough (fig09:
                # the full loop ran at a fifth of the contacts).
                f_rest = min(_table_gap(fpar, first - 1 + (n if first == 0 else 0), cphi, sphi, h),
                             _table_gap(fpar, first + count - (n if first + count >= n else 0), cphi, sphi, h))
                f_rest -= REST_MARGIN * rho_max
                rho = fpar[FP_CORNERS]
                if f_rest > tol and (best_corner >= 0 or safe_step(f_rest, hv - abs(omega) * rho * (1.0 + REST_MARGIN), accel + rho * omega * omega) > step * (1.0 + REST_MARGIN)):
                    break
                first = 0
                count = n
                lowest_first = 0
        if best_corner >= 0:
            hit_corner = best_corner
            result = tau
            break
        if tau + step > tau_max:
            result = NO_CONTACT
            break
        tau += step
        # flight_state(s0, tau, g, out), term by term
        x = x0 + vx0 * tau
        y = y0 + vy0 * tau - 0.5 * g * tau * tau
        phi = phi0 + omega * tau
        vy = vy0 - g * tau
    return result, hit_surf, hit_corner, x, y, phi, vy, trig_phi, cphi, sphi, anchor_phi, anchor_cos, anchor_sin


@numba.njit(cache=True)
def next_contact(s0, fpar, ipar, tau_max, tol, min_step, contact_speed, hit, out):
    """Time of the next corner contact in flight from state ``s0``.

    Parameters
    ----------
    s0 : float64[6]
        State (x, y, phi, vx, vy, omega) of the centre of mass at the start of the flight, SI.
    fpar, ipar : parameter vectors (dice_sweep.physics.params).
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
    out : float64[6]
        Output: the state at the contact (or where the search stopped).

    Returns
    -------
    float
        Contact time (s) from the start, ``NO_CONTACT`` if none before ``tau_max``,
        ``STALLED`` if the search did not converge.
    """
    n = ipar[IP_N]
    g = fpar[FP_G]
    c = fpar[FP_DRAG]
    n_surf = 1 if math.isinf(fpar[FP_WALL]) else 3
    if c == 0.0:
        tau, surf, corner, out[0], out[1], out[2], out[4], _, _, _, _, _, _ = search_free(
            fpar, n, n_surf, tau_max, tol, min_step, contact_speed, s0[0], s0[1], s0[2], s0[3], s0[4], s0[5],
            math.nan, 0.0, 0.0, math.nan, 0.0, 0.0
        )
        out[3] = s0[3]
        out[5] = s0[5]
        if corner >= 0:
            hit[0] = surf
            hit[1] = corner
        return tau
    for i in range(6):
        out[i] = s0[i]
    tau = 0.0
    work = np.empty((2, 6))
    trial = np.empty(6)
    max_step, ode_tol, h_min = drag_step_limits(fpar)
    h_ode = max_step
    for _ in range(MAX_SEARCH_STEPS):
        # bound |a| over the next h_ode: speed can grow by at most g h_ode meanwhile
        speed = math.sqrt(out[3] * out[3] + out[4] * out[4]) + g * h_ode  # not hypot: see outcome.rest_height
        drag_accel = c * speed * speed
        # towards a wall drag pulls at c |v| |vx| at most, and |vx| only falls (gravity is along
        # y): a die at rest on a wall, falling along it, stepped by sqrt(tol / (c v^2)) and stalled
        wall_accel = c * speed * abs(out[3])
        step = _scan(out, fpar, n, n_surf, g + drag_accel, wall_accel, tol, min_step, contact_speed, -1.0, hit)
        if step < 0.0:
            return tau
        h = min(step, h_ode)
        if tau + h > tau_max:
            return NO_CONTACT
        if drag_step(out, h, g, c, trial, work) > ode_tol and h > h_min:
            h_ode = 0.5 * h
            continue
        out[:] = trial
        tau += h
        if h == h_ode:
            h_ode = min(2.0 * h_ode, max_step)
    return STALLED
