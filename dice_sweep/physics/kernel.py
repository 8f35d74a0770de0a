"""One roll and a batch of rolls: the event-driven and the fixed-step integrators.

A roll ends as soon as its side is decided (the exact rule of docs/physics.md: once the
energy per unit mass is below g rho, rho the smaller distance from the centre of mass to the
two corners of the side below it (R for a fair die), no corner can pass under the centre of
mass again, so the side crossed by the vertical ray down from it is the answer), or with
outcome -1 and a status saying why not.

With rounded corners (fpar[FP_CORNER_RADIUS] = r > 0) the corner geometry is that of the arc
centres, gaps are their distances less r, impulses act at the contact point r below the arc
centre, and a pivot rolls on the arc (pivot.pivot_ode; docs/physics.md, "Rounded corners").

Initial states and sampled paths are those of the geometric centre (where a tracker sees a
die's centre mark); inside, the kernels follow the centre of mass.
"""

import math

import numba
import numpy as np

from dice_sweep.physics.flight import (
    NEAR_MIN_SIDES,
    NO_CONTACT,
    STALLED,
    SURF_TABLE,
    advance_flight,
    corner_offset,
    next_contact,
    search_free,
    surface_frame,
)
from dice_sweep.physics.impact import (
    contact_lever,
    corner_normal_velocity,
    corner_vector,
    resolve_impact,
    specific_energy,
    stick_corner,
    stop_corner_normal,
)
from dice_sweep.physics.params import (
    CORNER_STRIDE,
    FP_COM_X,
    FP_CORNERS,
    FP_COM_Y,
    FP_CORNER_RADIUS,
    FP_DRAG,
    FP_DT,
    FP_G,
    FP_INERTIA,
    FP_MU,
    FP_RHO_MAX,
    FP_STREAM_DRAW,
    FP_STREAM_PIXEL,
    FP_TMAX,
    FP_CONTACT_TIME,
    FP_WALL,
    FP_WINDOW,
    IP_CONTINUE,
    IP_MAX_EVENTS,
    IP_METHOD,
    IP_N,
)
from dice_sweep.physics.layout import (  # noqa: F401  (STATE_COLUMNS ... re-exported: the kernel's API)
    C_IMPACTS,
    C_MULTI,
    C_PIVOTS,
    C_WALL,
    COUNT_COLUMNS,
    EVENT_IMPACT,
    EVENT_LIFTOFF,
    EVENT_START,
    METHOD_FIXED_STEP,
    PATH_CUT,
    REC_CHI,
    REC_CHI_END,
    REC_CORNER,
    REC_ENERGY,
    REC_EVENT,
    REC_KIND,
    REC_PX,
    REC_STATE,
    REC_T,
    REC_WIDTH,
    SAMPLE_RECORDS,
    SEG_END,
    SEG_FLIGHT,
    SEG_LADDER,
    SEG_PIVOT,
    SEG_PIVOT_ODE,
    SEG_SLIDE,
    STATE_COLUMNS,
    STATUS_BALANCED,
    STATUS_DECIDED,
    STATUS_EVENT_BUDGET,
    STATUS_NAMES,
    STATUS_PROPPED,
    STATUS_STALLED,
    STATUS_T_MAX,
)
from dice_sweep.physics.ladder import (LADDER_AT_REST, LADDER_DECIDED, LADDER_OFF_WALL, LADDER_REFUSED, LADDER_TIMEOUT, ladder, ladder_at,
                                      ladder_spin, ladder_state)
from dice_sweep.physics.multi_contact import resolve_two_contacts, second_contact
from dice_sweep.physics.scatter import scatter_impact, scatter_on
from dice_sweep.physics.outcome import DECISION_MARGIN, barrier_height, decided_side, decision_bound, rest_height, side_below  # noqa: F401
from dice_sweep.physics.pivot import (
    PIVOT_BALANCED,
    PIVOT_DECIDED,
    PIVOT_LIFTOFF,
    PIVOT_TIMEOUT,
    corner_geometry,
    pivot_angle_at,
    pivot_energy,
    pivot_omega_squared,
    flat_angles,
    pivot_next_flat,
    pivot_ode,
    pivot_ode_flat,
    below_the_top,
)

# Tolerances, relative to the die's own scales R and sqrt(R/g) (see docs/physics.md).
GAP_TOL = 1e-12  # x R: an approaching corner this close counts as touching
MIN_STEP = 1e-9  # x sqrt(R/g): smallest step away from a touching, separating corner
CONTACT_SPEED = 1e-9  # x sqrt(g R): slower approach than this is round-off, not an impact
STICK_HEIGHT = 1e-8  # x R: a corner bouncing lower than this has come to rest (pivot)
# Consecutive table impacts of one corner after which the contact counts as sustained even
# if the rebound stays above STICK_HEIGHT: the paper's law on a loaded die can chatter at a
# constant tiny amplitude (test_loaded_die_prefers_the_heavy_side ran out of events on it).
CHATTER_LIMIT = 1000
REST_ENERGY = 1e-9  # x g rho_max: a decided die this close to lying still is at rest
# Wall impacts in a row of a die on a table corner, leaning into the wall with less kinetic
# energy than REST_ENERGY, after which it is at rest there (propped): without it such a die
# traded pivots and wall impacts at ~1e-9 m/s until the event budget (issue 33).
PROPPED_CYCLES = 16
# Pivots on one table corner in a row, each ended by the same corner hitting a wall, after which
# that wall contact counts as sustained (a ladder) even if it rebounds faster than the stick speed:
# a loaded die sliding down a wall in hops took 10^5 events for 4 s (issue 33, seed 3).
WALL_CHATTER_LIMIT = 16
RESTING_GAP = 1e-9  # x rho_max: a corner this close above the table rests on it (a flat die)
LONE_MARGIN = 1e-9  # relative, x rho_max: round-off allowed for in _far_gap and _lone_contact
DECIDED_SPEED_MARGIN = 1e-9  # relative: a sliding die counts as decided just below the barrier's speed
SLIDE_STOP = 1e-15  # x sqrt(g rho_max): a slide this slow has stopped (round-off of the deceleration)
SAMPLE_PAST = 1e-9  # x sqrt(rho_max/g): sample_batch runs a roll this far past its last sample time


@numba.njit(cache=True)
def _com_offset_world(fpar, phi):
    """Vector (m) from the geometric centre to the centre of mass at body angle phi."""
    c = math.cos(phi)
    sn = math.sin(phi)
    dx = fpar[FP_COM_X]
    dy = fpar[FP_COM_Y]
    return c * dx - sn * dy, sn * dx + c * dy


@numba.njit(cache=True)
def shift_reference(s, fpar, sign, out):
    """Move state s between the geometric centre (sign +1: centre -> COM) and the COM (-1)."""
    ox, oy = _com_offset_world(fpar, s[2])
    out[0] = s[0] + sign * ox
    out[1] = s[1] + sign * oy
    out[2] = s[2]
    out[3] = s[3] - sign * s[5] * oy
    out[4] = s[4] + sign * s[5] * ox
    out[5] = s[5]


@numba.njit(cache=True)
def _record(rec, nrec, t, kind, s, corner, px, chi, energy, event):
    if nrec >= rec.shape[0]:
        return nrec
    rec[nrec, REC_T] = t
    rec[nrec, REC_KIND] = kind
    for i in range(6):
        rec[nrec, REC_STATE + i] = s[i]
    rec[nrec, REC_CORNER] = corner
    rec[nrec, REC_PX] = px
    rec[nrec, REC_CHI] = chi
    rec[nrec, REC_CHI_END] = chi
    rec[nrec, REC_ENERGY] = energy
    rec[nrec, REC_EVENT] = event
    return nrec + 1


@numba.njit(cache=True)
def _flat_table(ipar):
    """An empty :func:`_flat_pair` table for the die of ipar: float64[n, 3] of NaN (the third
    column: the corner's body angle, for :func:`_set_pivot_state`)."""
    return np.full((ipar[IP_N], 3), math.nan)


@numba.njit(cache=True)
def _flat_pair(fpar, n, corner, flats):
    """``flat_angles(fpar, n, corner)``, computed on the corner's first pivot and then read
    from ``flats``: 20-sided rolls spent 119 of the 359 ns of a pivot on it (issue 33)."""
    if math.isnan(flats[corner, 0]):
        flats[corner, 0], flats[corner, 1] = flat_angles(fpar, n, corner)
        flats[corner, 2] = corner_geometry(fpar, corner)[1]  # an atan2 a pivot (issue 33)
    return flats[corner, 0], flats[corner, 1]


@numba.njit(cache=True)
def _set_pivot_state(s, fpar, px, chi, omega, corner, angle):
    """Full COM state of a die pivoting on ``corner`` at (px, 0), keeping phi unwrapped; with
    rounded corners px is the arc centre's x (the centre at height r) and the die rolls
    (the contact point at rest). ``angle``: the corner's body angle (``corner_geometry``; the
    roll loop keeps it in its :func:`_flat_pair` table). Returns the cosine and sine of the
    body angle s[2], from chi's and the corner's direction (within a few ulp of libm's; issue
    33: the impact that ends a 20-sided die's pivot, its outcome check and what follows took
    them again)."""
    base = FP_CORNERS + CORNER_STRIDE * corner
    rho = fpar[base]
    arc = fpar[FP_CORNER_RADIUS]
    c = math.cos(chi)
    sn = math.sin(chi)
    s[0] = px + rho * c
    s[1] = rho * sn
    phi = chi - angle - math.pi  # chi is the body angle of (COM - corner) turned by phi
    s[2] = phi + 2.0 * math.pi * round((s[2] - phi) / (2.0 * math.pi))
    s[3] = -omega * rho * sn
    s[4] = omega * rho * c
    s[5] = omega
    if arc != 0.0:
        s[1] += arc
        s[3] -= omega * arc
    # cos and sin of chi - angle - pi, (cos angle, sin angle) the corner's direction
    return -(c * fpar[base + 1] + sn * fpar[base + 2]), fpar[base + 2] * c - fpar[base + 1] * sn


@numba.njit(inline="always")  # inlined: a call (four array arguments) per impact costs refcounts
def _impact(s, fpar, ipar, surf, corner, counts, cos_phi, sin_phi):
    """Resolve one impact and tally it; returns the corner's normal velocity after (m/s).
    ``cos_phi``, ``sin_phi``: of s[2], or NaN (see resolve_impact)."""
    if scatter_on(fpar):
        return _scattered_impact(s, fpar, ipar, surf, corner, counts)
    u_n = resolve_impact(s, fpar, ipar, surf, corner, counts, cos_phi, sin_phi)
    counts[C_IMPACTS] += 1
    if surf != SURF_TABLE:
        counts[C_WALL] += 1
    return u_n


@numba.njit(cache=True)
def _add_scatter(s, fpar, ipar, surf, corner, vx0, vy0, w0, index, two_contacts):
    """The stochastic law's jump (physics/scatter.py) on impact ``index`` of ``corner`` on
    ``surf``, the velocity before it (vx0, vy0, w0); returns the corner's normal velocity
    after (m/s)."""
    nx, ny, _ = surface_frame(surf, fpar[FP_WALL])
    rx, ry = corner_vector(s, fpar, corner)
    lx, ly = contact_lever(fpar, rx, ry, nx, ny)
    approach = -(nx * (vx0 - w0 * ly) + ny * (vy0 + w0 * lx))
    scatter_impact(s, fpar, ipar, lx, ly, nx, ny, corner, vx0, vy0, w0, approach, index, two_contacts)
    return corner_normal_velocity(s, lx, ly, nx, ny)


@numba.njit(cache=True)
def _scattered_impact(s, fpar, ipar, surf, corner, counts):
    """:func:`_impact` with the stochastic law: the deterministic impact, then its jump."""
    vx0, vy0, w0 = s[3], s[4], s[5]
    index = counts[C_IMPACTS]
    u_n = resolve_impact(s, fpar, ipar, surf, corner, counts)
    counts[C_IMPACTS] += 1
    if surf != SURF_TABLE:
        counts[C_WALL] += 1
    return _add_scatter(s, fpar, ipar, surf, corner, vx0, vy0, w0, index, False)


@numba.njit(cache=True)
def _far_gap(fpar, n, tol):
    """Gap (m) below which no corner of a fair die can be, other than a corner touching the table
    (within tol) and its two neighbours: the nearest other corner is 2 rho sin(pi/n) sin(2 pi/n)
    above the line of a side (rho the corners' distance from the centre of mass)."""
    rho = fpar[FP_CORNERS]
    return 2.0 * rho * math.sin(math.pi / n) * math.sin(2.0 * math.pi / n) * (1.0 - LONE_MARGIN) - 2.0 * tol


@numba.njit(inline="always")
def _lone_contact(s, fpar, n, corner, cos_phi, sin_phi, tol, far_gap):
    """True if, on a fair die with the table alone (``far_gap`` from :func:`_far_gap`), no corner
    but ``corner``, touching the table, can arrive within the contact window: second_contact
    would find none. It looks at the two neighbours only (cos_phi, sin_phi: of the die's angle)."""
    speed = math.sqrt(s[3] * s[3] + s[4] * s[4]) + abs(s[5]) * fpar[FP_RHO_MAX]
    reach = tol + speed * max(fpar[FP_WINDOW], fpar[FP_CONTACT_TIME])  # second_contact's
    if not reach < far_gap:
        return False
    h = s[1] - fpar[FP_CORNER_RADIUS] - LONE_MARGIN * fpar[FP_RHO_MAX]  # round-off of the gaps
    below = corner - 1 + (n if corner == 0 else 0)
    above = corner + 1 - (n if corner == n - 1 else 0)
    return h + corner_offset(fpar, below, cos_phi, sin_phi)[1] > reach and h + corner_offset(fpar, above, cos_phi, sin_phi)[1] > reach


@numba.njit(inline="always")  # as a call (four array arguments) it cost 8 % of fig08's rolls
def _impact_event(s, fpar, ipar, n_surf, surf, corner, tol, contact_speed, lone, counts, cos_phi, sin_phi):
    """Resolve the impact of ``corner`` on ``surf`` together with a second contact arriving
    within the contact window, if any (physics/multi_contact.py), or, with the flat_landing
    effect, within the contact time, sharing the impact. ``lone``: none can (see
    :func:`_lone_contact`). ``cos_phi``, ``sin_phi``: of s[2], or NaN.

    Returns the normal velocity after (m/s), surface and corner of the contact that decides
    what follows: of two arriving within the window, the table contact left slowest (a pivot
    candidate), else the first.
    """
    window = fpar[FP_WINDOW]
    contact_time = fpar[FP_CONTACT_TIME]  # the flat_landing effect (0: off)
    if lone:
        surf_b, corner_b, arrival = np.int64(-1), np.int64(-1), math.inf
    else:
        surf_b, corner_b, arrival = second_contact(s, fpar, ipar[IP_N], n_surf, surf, corner, max(window, contact_time), tol, contact_speed)
    share = 1.0 if arrival <= window else 1.0 - arrival / max(contact_time, window)  # < 1: found by contact_time
    vx0, vy0, w0 = s[3], s[4], s[5]  # the stochastic law scales its jump by the approach
    if corner_b < 0 or not resolve_two_contacts(s, fpar, ipar, surf, corner, surf_b, corner_b, share, counts):
        return _impact(s, fpar, ipar, surf, corner, counts, cos_phi, sin_phi), surf, corner
    if scatter_on(fpar):
        _add_scatter(s, fpar, ipar, surf, corner, vx0, vy0, w0, counts[C_IMPACTS], True)
    counts[C_IMPACTS] += 1
    counts[C_MULTI] += 1
    if surf != SURF_TABLE or surf_b != SURF_TABLE:
        counts[C_WALL] += 1
    nx, ny, _ = surface_frame(surf, fpar[FP_WALL])
    rx, ry = corner_vector(s, fpar, corner)
    u_n = corner_normal_velocity(s, rx, ry, nx, ny)
    if surf_b == SURF_TABLE and share >= 1.0:  # with a share below 1 the second corner has not arrived
        rx, ry = corner_vector(s, fpar, corner_b)
        u_b = s[4] + s[5] * rx
        if surf != SURF_TABLE or u_b < u_n:
            return u_b, surf_b, corner_b
    return u_n, surf, corner


# A plain call, not inline="always": inlined into _flat_side as numba IR it made the outcome
# checks about 25 % slower (scripts/profile_kernel.py, outcome checks, 270 against 210 ns).
@numba.njit(cache=True)
def _corner_resting(s, fpar, corner, c, sn, speed):
    """True if ``corner`` (body angle with cosine c, sine sn) is on the table and moves in or
    out no faster than ``speed``."""
    rx, ry = corner_offset(fpar, corner, c, sn)
    # rounded corners: the arc's gap is its centre's height less r (exact at r = 0)
    return not (s[1] + ry - fpar[FP_CORNER_RADIUS] > RESTING_GAP * fpar[FP_RHO_MAX] or abs(s[4] + s[5] * rx) > speed)


@numba.njit(cache=True)
def _flat_side(s, fpar, n, speed, near, cos_phi, sin_phi):
    """The side the die lies flat on (both its corners on the table, neither moving in or out
    faster than ``speed``), or -1. ``cos_phi``, ``sin_phi``: those of s[2] if known, else NaN.

    ``near``: a corner touching the table (within the gap tolerance), or -1 (unknown). No three
    corners of a regular polygon (arc centres too, loaded or not) lie within a tolerance of one
    line: the nearest corner off a side is 2 R sin(pi/n) sin(2 pi/n) from its line (2.5e-3 R at
    n = 127) against RESTING_GAP 1e-9. So a side lying flat has ``near`` as one of its two
    corners, and only it and its two neighbours need counting: the same answer (n = 20 counted
    20 corners on every table impact, issue 33).
    """
    c, sn = cos_phi, sin_phi
    if c != c:
        c = math.cos(s[2])
        sn = math.sin(s[2])
    # Both corners of the side must be resting; after a bounce only the corner that hit is,
    # if any. Counting the resting corners first skips side_below (a float modulo) on almost
    # every call, and changes no answer.
    passing = 0
    first = 0 if near < 0 else near - 1 + (n if near == 0 else 0)
    for j in range(n if near < 0 else 3):
        corner = first + j
        corner -= n if corner >= n else 0
        if _corner_resting(s, fpar, corner, c, sn, speed):
            passing += 1
    if passing < 2:
        return -1
    side = side_below(s[2], fpar, n)
    for corner in (side, (side + 1) % n):
        if not _corner_resting(s, fpar, corner, c, sn, speed):
            return -1
    return side


@numba.njit(cache=True)
def _slide_time(speed, fpar, side, n, to_rest):
    """Time (s) a die lying flat on ``side`` and sliding at ``speed`` (m/s) takes, under
    Coulomb friction, to stop (``to_rest``) or to fall below the decision barrier."""
    decel = fpar[FP_MU] * fpar[FP_G]
    if math.isinf(decel) or speed == 0.0:
        return 0.0
    if decel == 0.0:  # frictionless: it slides for ever, on a side it can no longer leave
        return math.inf if to_rest else 0.0
    if to_rest:
        return speed / decel
    spare = fpar[FP_G] * (barrier_height(fpar, n, side) * (1.0 - DECISION_MARGIN) - rest_height(fpar, n, side))
    decided_speed = math.sqrt(max(2.0 * spare, 0.0)) * (1.0 - DECIDED_SPEED_MARGIN)
    return max(speed - decided_speed, 0.0) / decel


@numba.njit(cache=True)
def _time_to_wall(s, fpar, n):
    """Time (s) until a flat die sliding under friction reaches a wall (inf: never)."""
    half_width = fpar[FP_WALL]
    decel = fpar[FP_MU] * fpar[FP_G]
    if math.isinf(half_width) or s[3] == 0.0 or math.isinf(decel):
        return math.inf
    c = math.cos(s[2])
    sn = math.sin(s[2])
    reach = 0.0
    for corner in range(n):
        rx, _ = corner_offset(fpar, corner, c, sn)
        reach = max(reach, rx if s[3] > 0.0 else -rx)
    gap = half_width - reach - fpar[FP_CORNER_RADIUS] - (s[0] if s[3] > 0.0 else -s[0])
    speed = abs(s[3])
    if decel == 0.0:
        return max(gap, 0.0) / speed
    disc = speed * speed - 2.0 * decel * gap
    if disc < 0.0:
        return math.inf
    return (speed - math.sqrt(disc)) / decel


@numba.njit(cache=True)
def _slide(s, fpar, tau):
    """Advance a flat, sliding die by tau seconds of friction-limited deceleration."""
    decel = fpar[FP_MU] * fpar[FP_G]
    if math.isinf(decel):
        s[3] = 0.0
        return
    sign = 1.0 if s[3] > 0.0 else -1.0
    if decel > 0.0:
        tau = min(tau, abs(s[3]) / decel)
    s[0] += s[3] * tau - 0.5 * sign * decel * tau * tau
    s[3] -= sign * decel * tau
    if abs(s[3]) < SLIDE_STOP * math.sqrt(fpar[FP_G] * fpar[FP_RHO_MAX]):
        s[3] = 0.0


@numba.njit(cache=True)
def _corner_down(s, fpar, corner):
    """x (m) of ``corner`` (its arc centre) if it is on the table (within RESTING_GAP rho_max),
    else nan: a corner that lifted off a pivot by round-off still stands there."""
    rx, ry = corner_vector(s, fpar, corner)
    if s[1] + ry - fpar[FP_CORNER_RADIUS] > RESTING_GAP * fpar[FP_RHO_MAX]:
        return math.nan
    return s[0] + rx


@numba.njit(cache=True)
def _held_flat(s, fpar, n, speed):
    """A loaded die on two table corners of one side whose centre of mass is past that side
    (gravity alone would tip it over the nearer corner) but which friction holds flat while it
    slides: the friction force mu g at the table, below the centre of mass at height h, shifts
    the centre of pressure by mu h forwards, to x_c + mu h sign(vx), and while that point lies
    between the two corners both normal forces are positive (docs/physics.md, "Outcome rule").
    Returns the corner it tips over once the slide stops, or -1 if it is not so held."""
    if math.isinf(fpar[FP_MU]) or s[3] == 0.0:
        return -1  # no slide: nothing holds it, the pivot tips it
    c = math.cos(s[2])
    sn = math.sin(s[2])
    pressure = s[0] + fpar[FP_MU] * s[1] * (1.0 if s[3] > 0.0 else -1.0)
    for a in range(n):
        b = (a + 1) % n
        if not (_corner_resting(s, fpar, a, c, sn, speed) and _corner_resting(s, fpar, b, c, sn, speed)):
            continue
        xa = s[0] + corner_offset(fpar, a, c, sn)[0]
        xb = s[0] + corner_offset(fpar, b, c, sn)[0]
        lo = min(xa, xb)
        hi = max(xa, xb)
        if lo <= s[0] <= hi or not lo <= pressure <= hi:
            return -1
        near = xa if abs(xa - s[0]) < abs(xb - s[0]) else xb
        return a if near == xa else b
    return -1


@numba.njit(cache=True)
def _flat_on_wall(s, fpar, n, surf, corner, speed):
    """True if the die, clear of the table, has a side on wall ``surf``: ``corner`` (which has
    just hit it) and a neighbour within RESTING_GAP rho_max of the wall, the neighbour moving in
    or out no faster than ``speed``. Such a side rocked on the wall corner by corner, every
    rebound smaller (a Zeno run in the air, no gravity to end it in a pivot), until the contact
    search stalled (issue 33: 14 of 10^5 walled fuzz throws, all triangles)."""
    touch = RESTING_GAP * fpar[FP_RHO_MAX]
    arc = fpar[FP_CORNER_RADIUS]
    nx, _, d = surface_frame(surf, fpar[FP_WALL])
    c = math.cos(s[2])
    sn = math.sin(s[2])
    for k in range(n):
        _, ry = corner_offset(fpar, k, c, sn)
        if s[1] + ry - arc <= touch:
            return False
    for k in ((corner + 1) % n, (corner + n - 1) % n):
        rx, ry = corner_offset(fpar, k, c, sn)
        if abs(d + nx * (s[0] + rx) - arc) <= touch and abs(nx * (s[3] - s[5] * ry)) <= speed:
            return True
    return False


@numba.njit(cache=True)
def _sliding_jams(s, fpar, lx, ly, ry, slip):
    """True if a corner on the table (contact point (lx, ly) and arc centre height ry from the
    centre of mass) cannot slide at ``slip`` (m/s): Painleve's case. Friction against the slip
    turns the die so that a normal force pushing it would press the corner in faster
    (k^2 + lx^2 + sign(slip) mu lx ly < 0), while gravity, drag and spin press it in
    (g - D_y + omega^2 ry > 0): sliding would need the table to pull, and a released corner
    falls back in at once. The pivot lifted off at its first instant, the corner hit again at
    ~1e-7 m/s, and so on until the event budget (issue 33). The slip then stops in an impact
    without collision (Genot and Brogliato 1999), whose impulse, the plastic one that brings the
    contact point to rest, pushes (p_n > 0) and lies inside the friction cone there."""
    sign = 1.0 if slip > 0.0 else -1.0
    if fpar[FP_INERTIA] + lx * lx + sign * fpar[FP_MU] * lx * ly >= 0.0:
        return False
    drag_y = -fpar[FP_DRAG] * math.sqrt(s[3] * s[3] + s[4] * s[4]) * s[4]
    return fpar[FP_G] - drag_y + s[5] * s[5] * ry > 0.0


@numba.njit(cache=True)
def _leaning_still(s, fpar, px):
    """True if a die on a table corner at x = ``px`` that just hit a wall (the nearer one) is at
    rest there: gravity turns it into that wall (its centre of mass between the corner and the
    wall) and its kinetic energy is below REST_ENERGY g rho_max."""
    kinetic = specific_energy(s, fpar) - fpar[FP_G] * s[1]
    into = s[0] > px if s[0] > 0.0 else s[0] < px
    return into and kinetic < REST_ENERGY * fpar[FP_G] * fpar[FP_RHO_MAX]


@numba.njit(cache=True)
def _stopped(decided, status, t_decided, t, nrec):
    """Result of a roll that stopped for ``status``: decided earlier (continuing) or not."""
    if decided >= 0:
        return decided, STATUS_DECIDED, t_decided, t, nrec
    return -1, status, math.nan, t, nrec


# Inlined (numba IR) into its only caller, like _roll_event: the same code as a call.
@numba.njit(inline="always")
def _lie_flat(s, fpar, n, flat, rec, nrec, t, t_max, keep_going, decided, t_decided):
    """The end of a roll that lands flat on side ``flat`` (both its corners down): the die
    slides under Coulomb friction (or stops at once with unlimited friction, or against a
    wall) and is decided on that side. Without this phase the two corners traded pivots at
    one instant until the event budget ran out (docs/dev/validation_history.md).

    Returns the roll's (outcome, status, t_decided, t_end, n_records), as _roll_event does.
    """
    s[1] = rest_height(fpar, n, flat)
    s[4] = 0.0
    s[5] = 0.0
    if math.isinf(fpar[FP_MU]):
        s[3] = 0.0
    nrec = _record(rec, nrec, t, SEG_SLIDE, s, flat, 0.0, 0.0, specific_energy(s, fpar), EVENT_IMPACT)
    to_decision = _slide_time(abs(s[3]), fpar, flat, n, False)
    tau = _slide_time(abs(s[3]), fpar, flat, n, True) if keep_going else to_decision
    to_wall = _time_to_wall(s, fpar, n)
    tau = min(tau, t_max - t, to_wall)
    _slide(s, fpar, tau)
    if tau == to_wall:
        s[3] = 0.0  # a plastic stop against the wall
    if decided < 0:
        decided = flat
        t_decided = t + min(to_decision, tau)
    t += tau
    if keep_going and fpar[FP_MU] > 0.0:
        s[3] = 0.0
    nrec = _record(rec, nrec, t, SEG_END, s, -1, 0.0, 0.0, specific_energy(s, fpar), EVENT_IMPACT)
    return decided, STATUS_DECIDED, t_decided, t, nrec


# Inlined (numba IR) into its only caller, _roll_into, itself inlined into roll_one, roll_batch
# and sample_batch: as a call it took eight array arguments, a reference count up and down for
# each on every roll. The fixed overhead of a roll fell by about 40 % (docs/dev/profile.md, change
# 5); results bit for bit the same.
@numba.njit(inline="always")
def _roll_event(fpar, ipar, s, rec, counts, after, out, hit, flats):
    """One roll by events (docs/physics.md): from the state ``s`` (centre of mass, changed in
    place) to a decided side, or to a stop with a status.

    Each pass of the loop finds the next event and acts on it:

    - in flight: the next contact of a corner with the table or a wall (exact without drag,
      by the flight search), then the impact it makes (with a second contact arriving within
      the contact window: physics/multi_contact.py);
    - pivoting on a corner (a bounce too low to leave the table: the limit of its Zeno run):
      the pivot ends by lift-off, by a second corner landing, or by the decision (closed form
      when it sticks without drag, else the pivot ODE);
    - a landing flat on a side ends the roll by sliding (:func:`_lie_flat`).

    The side is decided once the energy is below the barrier of the side below the centre of
    mass (outcome.decided_side); with ``ipar[IP_CONTINUE]`` the roll goes on to rest.
    ``rec`` receives one record per segment (layout.REC_*); ``counts`` the event tallies;
    ``after``, ``out`` and ``hit`` are scratch arrays (float64[6], float64[5], int64[2]);
    ``flats`` (float64[n, 3], NaN where not yet known) the die's :func:`_flat_pair` table.

    Returns (outcome, status, t_decided, t_end, n_records).
    """
    n = ipar[IP_N]
    g = fpar[FP_G]
    t_max = fpar[FP_TMAX]
    scale = fpar[FP_RHO_MAX]
    tol = GAP_TOL * scale
    min_step = MIN_STEP * math.sqrt(scale / g)
    contact_speed = CONTACT_SPEED * math.sqrt(g * scale)
    stick_speed = math.sqrt(2.0 * g * scale * STICK_HEIGHT)
    # the closed-form pivot: sticking, without drag, on a sharp corner (a rounded one rolls: ODE)
    smooth_pivot = math.isinf(fpar[FP_MU]) and fpar[FP_DRAG] == 0.0 and fpar[FP_CORNER_RADIUS] == 0.0
    drag_free = fpar[FP_DRAG] == 0.0
    decide_bound = decision_bound(fpar)
    n_surf = 1 if math.isinf(fpar[FP_WALL]) else 3
    for i in range(out.shape[0]):
        out[i] = 0.0
    hit[0] = 0
    hit[1] = 0
    keep_going = ipar[IP_CONTINUE] == 1
    t = 0.0
    energy = specific_energy(s, fpar)
    nrec = _record(rec, 0, t, SEG_FLIGHT, s, -1, 0.0, 0.0, energy, EVENT_START)
    decided = decided_side(s, fpar, n)
    t_decided = 0.0 if decided >= 0 else math.nan
    if decided >= 0 and not keep_going:
        return decided, STATUS_DECIDED, t, t, nrec
    pivoting = False
    # np.int64(-1), not -1: while typing the loop numba first sees the literal alone and
    # compiled the pivot and impact code a second time for corner = Literal[int](-1), about
    # 5 s of a cold start with the other literals below (scripts/bench.py, cold rows)
    corner = np.int64(-1)
    px = 0.0
    chi = 0.0
    slip = 0.0
    closed_form = True
    chatter = 0
    propped = 0
    wall_chatter = 0  # pivots on table_corner in a row ended by wall corner wall_corner
    wall_corner = np.int64(-1)
    table_corner = np.int64(0)  # the corner of the last pivot
    sliding_walls = n_surf == 3 and not math.isinf(fpar[FP_MU])  # a ladder needs walls and sliding friction
    loaded = fpar[FP_COM_X] != 0.0 or fpar[FP_COM_Y] != 0.0  # a fair die lying flat is never past its side
    last_was_flight_impact = False
    # the angle whose cosine and sine the last search left: the next flight's start, after an impact
    trig_phi = math.nan
    trig_cos = 0.0
    trig_sin = 0.0
    # the search's last libm cosine and sine, or a pivot's end's (flight.turned_trig): most
    # others come from them
    anchor_phi = math.nan
    anchor_cos = 0.0
    anchor_sin = 0.0
    # a fair many-sided die with the table alone: at a flight's contact only the contact corner's
    # neighbours can be near the table (issue 33: second_contact looked at all 20 on every impact)
    far_gap = _far_gap(fpar, n, tol) if n >= NEAR_MIN_SIDES and not loaded and n_surf == 1 else -1.0
    for _ in range(ipar[IP_MAX_EVENTS]):
        came_from_pivot = pivoting
        if not pivoting:
            if drag_free:
                # next_contact's own drag-free search, called with the state as scalars
                (tau, surf, corner_hit, x, y, phi, vy, trig_phi, trig_cos, trig_sin,
                 anchor_phi, anchor_cos, anchor_sin) = search_free(
                    fpar, n, n_surf, t_max - t, tol, min_step, contact_speed, s[0], s[1], s[2], s[3], s[4], s[5],
                    trig_phi, trig_cos, trig_sin, anchor_phi, anchor_cos, anchor_sin
                )
            else:
                tau = next_contact(s, fpar, ipar, t_max - t, tol, min_step, contact_speed, hit, after)
            if tau == NO_CONTACT:
                return _stopped(decided, STATUS_T_MAX, t_decided, t_max, nrec)
            if tau == STALLED:
                return _stopped(decided, STATUS_STALLED, t_decided, t, nrec)
            if drag_free:
                hit[0] = surf
                hit[1] = corner_hit
                s[0] = x
                s[1] = y
                s[2] = phi
                s[4] = vy
            else:
                for i in range(6):
                    s[i] = after[i]
            t += tau
        else:
            out[3] = 0.0
            out[4] = 0.0
            chi_right, chi_left = _flat_pair(fpar, n, corner, flats)
            if closed_form:
                kind = pivot_next_flat(fpar, n, corner, px, chi, s[5], chi_right, chi_left, out, hit)
            else:
                kind = pivot_ode_flat(fpar, n, corner, px, chi, s[5], slip, t_max - t, not keep_going, chi_right, chi_left,
                                      out, hit)
            if kind == PIVOT_BALANCED:
                return _stopped(decided, STATUS_BALANCED, t_decided, t, nrec)
            if kind == PIVOT_TIMEOUT or t + out[2] > t_max:
                return _stopped(decided, STATUS_T_MAX, t_decided, t, nrec)
            if nrec > 0:
                rec[nrec - 1, REC_CHI_END] = out[0]
            t += out[2]
            trig_cos, trig_sin = _set_pivot_state(s, fpar, px + out[3], out[0], out[1], corner, flats[corner, 2])
            trig_phi = s[2]
            # and the anchor of the next search's series: a pivot turns a 20-sided die by 0.3 rad
            anchor_phi, anchor_cos, anchor_sin = trig_phi, trig_cos, trig_sin
            s[3] += out[4]  # a sliding corner carries its slip velocity into what follows
            pivoting = False
            if kind == PIVOT_DECIDED:
                nrec = _record(rec, nrec, t, SEG_END, s, -1, 0.0, 0.0, specific_energy(s, fpar), EVENT_LIFTOFF)
                return decided_side(s, fpar, n), STATUS_DECIDED, t, t, nrec
            if kind == PIVOT_LIFTOFF:
                nrec = _record(rec, nrec, t, SEG_FLIGHT, s, -1, 0.0, 0.0, specific_energy(s, fpar), EVENT_LIFTOFF)
                continue
        surf = hit[0]
        same_corner = surf == SURF_TABLE and hit[1] == corner and last_was_flight_impact
        chatter = chatter + 1 if same_corner else 0
        if surf != SURF_TABLE:
            wall_chatter = wall_chatter + 1 if came_from_pivot and hit[1] == wall_corner else int(came_from_pivot)
            wall_corner = hit[1]
        elif hit[1] != table_corner:
            wall_chatter = 0
        corner = hit[1]
        last_was_flight_impact = not came_from_pivot
        walls_before = counts[C_WALL]  # a wall in this impact, alone or shared with the table
        contact = corner if surf == SURF_TABLE else np.int64(-1)  # a table corner within the gap tolerance
        known = s[2] == trig_phi  # the search left the cosine and sine of this angle
        lone = far_gap > 0.0 and contact >= 0 and known and _lone_contact(s, fpar, n, corner, trig_cos, trig_sin, tol, far_gap)
        u_n, surf, corner = _impact_event(s, fpar, ipar, n_surf, surf, corner, tol, contact_speed, lone, counts,
                                          trig_cos if known else math.nan, trig_sin)
        flat = -1
        if surf == SURF_TABLE and not (corner == contact and abs(u_n) > stick_speed):
            # u_n is the corner's normal velocity after the impact, the one _corner_resting
            # tests: a contact corner leaving faster is not resting, and no side lies flat
            # without it (_flat_side). Most impacts of a many-sided die end so.
            # the search's cosine and sine if the angle is theirs (an impact moves no angle; 28 calls a 20-sided roll)
            flat = _flat_side(s, fpar, n, stick_speed, corner if corner == contact else np.int64(-1),
                              trig_cos if known else math.nan, trig_sin)
        if flat >= 0:
            return _lie_flat(s, fpar, n, flat, rec, nrec, t, t_max, keep_going, decided, t_decided)
        tip = _held_flat(s, fpar, n, stick_speed) if surf == SURF_TABLE and loaded else -1
        if tip >= 0:
            # it slides flat to a stop, then tips over the corner: the two corners used to
            # trade pivots at one instant until the event budget (issue 33)
            s[4] = 0.0
            s[5] = 0.0
            nrec = _record(rec, nrec, t, SEG_SLIDE, s, -1, 0.0, 0.0, specific_energy(s, fpar), EVENT_IMPACT)
            tau = min(abs(s[3]) / (fpar[FP_MU] * g), _time_to_wall(s, fpar, n))
            if t + tau > t_max:
                return _stopped(decided, STATUS_T_MAX, t_decided, t_max, nrec)
            _slide(s, fpar, tau)
            s[3] = 0.0
            t += tau
            corner = np.int64(tip)
            u_n = 0.0
        if surf != SURF_TABLE and abs(u_n) < stick_speed:
            # a slow wall contact found inside the wall by more than the gap tolerance: put it
            # back on, or a pivot takes it for an impact at once, again and again (issue 33)
            nx, _, d = surface_frame(surf, fpar[FP_WALL])
            rx, _ = corner_vector(s, fpar, corner)
            gap = d + nx * (s[0] + rx) - fpar[FP_CORNER_RADIUS]
            if gap < -tol:
                s[0] += nx * (tol - gap)
        ladder_end = LADDER_REFUSED
        if surf != SURF_TABLE and sliding_walls and (abs(u_n) < stick_speed or wall_chatter >= WALL_CHATTER_LIMIT):
            # a wall contact that stays, on a table corner that stays: slide on both (physics/ladder.py)
            on_corner = px if came_from_pivot else _corner_down(s, fpar, table_corner)
            rx, _ = corner_vector(s, fpar, table_corner)
            kinetic = specific_energy(s, fpar) - g * s[1]
            if on_corner == on_corner and abs(s[4] + s[5] * rx) < stick_speed and kinetic >= REST_ENERGY * g * scale:
                wall_side = -surface_frame(surf, fpar[FP_WALL])[0]
                # chattering faster than the stick speed: the limit of the hops, a plastic stop of both contacts
                spin = s[5] if abs(u_n) < stick_speed else ladder_spin(fpar, table_corner, corner, s)
                ladder_end, tau = ladder(fpar, n, table_corner, corner, wall_side, s[2], spin, t_max - t, after)
                if ladder_end != LADDER_REFUSED:
                    ladder_state(fpar, table_corner, corner, wall_side, s[2], spin, s)
                    nrec = _record(rec, nrec, t, SEG_LADDER, s, table_corner, float(corner), wall_side, specific_energy(s, fpar), EVENT_IMPACT)
                    for i in range(6):
                        s[i] = after[i]
                    t += tau
                    if ladder_end == LADDER_TIMEOUT:
                        return _stopped(decided, STATUS_T_MAX, t_decided, t_max, nrec)
                    if ladder_end == LADDER_DECIDED and not keep_going:
                        nrec = _record(rec, nrec, t, SEG_END, s, -1, 0.0, 0.0, specific_energy(s, fpar), EVENT_LIFTOFF)
                        return decided_side(s, fpar, n), STATUS_DECIDED, t, t, nrec
                    if ladder_end == LADDER_OFF_WALL:  # it pivots on its table corner
                        # clear of the wall by the gap tolerance: the pivot takes a corner at the
                        # wall for an impact, and the two phases traded places in no time
                        s[0] -= wall_side * tol
                        surf = SURF_TABLE
                        corner = table_corner
                        u_n = 0.0
        if surf != SURF_TABLE and ladder_end == LADDER_REFUSED and abs(u_n) < stick_speed and _flat_on_wall(s, fpar, n, surf, corner, stick_speed):
            # a side rocking on a wall in the air: the limit of the Zeno run, the side at rest on
            # the wall (its normal speed and the spin gone); it falls along the wall from there
            s[3] = 0.0
            s[5] = 0.0
        pivoting = surf == SURF_TABLE and (u_n < stick_speed or chatter >= CHATTER_LIMIT)
        if pivoting:
            # The bounces that would follow shrink geometrically (a Zeno run): take their
            # limit, the corner at rest on the table, and turn about it.
            if s[2] == trig_phi:  # tested again, not `known`: a ladder above can turn the die
                rx, ry = corner_offset(fpar, corner, trig_cos, trig_sin)
            else:
                rx, ry = corner_vector(s, fpar, corner)
            lx, ly = contact_lever(fpar, rx, ry, 0.0, 1.0)  # rounded corners: the contact point
            if math.isinf(fpar[FP_MU]):
                stick_corner(s, fpar[FP_INERTIA], lx, ly)
                slip = 0.0
            else:
                slip = stop_corner_normal(s, fpar[FP_INERTIA], lx, ly)
                if slip != 0.0 and _sliding_jams(s, fpar, lx, ly, ry, slip):
                    # an impact without collision stops the slip (docs/physics.md, "Outcome rule")
                    stick_corner(s, fpar[FP_INERTIA], lx, ly)
                    slip = 0.0
            px = s[0] + rx  # the corner's (arc centre's) x
            table_corner = corner
            chi = math.atan2(-ry, -rx)
            counts[C_PIVOTS] += 1
        if counts[C_WALL] > walls_before:
            # on a table corner (the pivot just ended, or one begun by this shared impact)
            # or on the last pivot's corner, lifted off by round-off only
            on_corner = px if came_from_pivot or pivoting else _corner_down(s, fpar, table_corner)
            propped = propped + 1 if on_corner == on_corner and _leaning_still(s, fpar, on_corner) else 0
        if ladder_end == LADDER_AT_REST:  # stopped on both, friction holding it
            propped = PROPPED_CYCLES
        energy = specific_energy(s, fpar)
        if decided < 0:
            # decided_side's own first test, made here: most impacts leave the die above it,
            # and the call (two array arguments) is then skipped
            decided = decided_side(s, fpar, n) if energy < decide_bound else -1
            t_decided = t if decided >= 0 else math.nan
        if decided >= 0 and (not keep_going or energy - fpar[FP_G] * rest_height(fpar, n, decided) < REST_ENERGY * fpar[FP_G] * fpar[FP_RHO_MAX]):
            if keep_going:
                s[3:] = 0.0  # at rest: what motion is left is below REST_ENERGY
            nrec = _record(rec, nrec, t, SEG_END, s, -1, 0.0, 0.0, energy, EVENT_IMPACT)
            return decided, STATUS_DECIDED, t_decided, t, nrec
        if propped >= PROPPED_CYCLES:  # at rest leaning on a wall (docs/physics.md, "Outcome rule")
            if keep_going:
                s[3:] = 0.0
            nrec = _record(rec, nrec, t, SEG_END, s, -1, 0.0, 0.0, energy, EVENT_IMPACT)
            return _stopped(decided, STATUS_PROPPED, t_decided, t, nrec)
        if pivoting:
            closed_form = smooth_pivot and not below_the_top(fpar, corner, chi, s[5])
            kind_rec = SEG_PIVOT if closed_form else SEG_PIVOT_ODE
            nrec = _record(rec, nrec, t, kind_rec, s, corner, px, chi, energy, EVENT_IMPACT)
        else:
            nrec = _record(rec, nrec, t, SEG_FLIGHT, s, -1, 0.0, 0.0, energy, EVENT_IMPACT)
    return _stopped(decided, STATUS_EVENT_BUDGET, t_decided, t, nrec)


@numba.njit(cache=True)
def _roll_fixed_step(fpar, ipar, s, rec, counts, start):
    """The paper's scheme: flight over steps of dt (exact without drag), a collision applied
    when a corner is found inside a surface and moving further in at the end of a step (no
    pivot phase)."""
    n = ipar[IP_N]
    half_width = fpar[FP_WALL]
    dt = fpar[FP_DT]
    n_surf = 1 if math.isinf(half_width) else 3
    t = 0.0
    nrec = _record(rec, 0, t, SEG_FLIGHT, s, -1, 0.0, 0.0, specific_energy(s, fpar), EVENT_START)
    side = decided_side(s, fpar, n)
    if side >= 0:
        return side, STATUS_DECIDED, t, t, nrec
    arc = fpar[FP_CORNER_RADIUS]
    n_steps = int(math.ceil(fpar[FP_TMAX] / dt))
    impacts = 0
    for step in range(1, n_steps + 1):
        for i in range(6):
            start[i] = s[i]
        advance_flight(start, dt, fpar, s)
        t = step * dt
        deepest = 0.0
        surf = np.int64(-1)  # not literals: see corner in _roll_event
        corner = np.int64(-1)
        for sf in range(n_surf):
            nx, ny, d = surface_frame(sf, half_width)
            for k in range(n):
                rx, ry = corner_vector(s, fpar, k)
                gap = d + nx * (s[0] + rx) + ny * (s[1] + ry) - arc  # rounded: arc centre less r
                if gap < deepest:
                    u_n = nx * (s[3] - s[5] * ry) + ny * (s[4] + s[5] * rx)
                    if u_n < 0.0:
                        deepest = gap
                        surf = sf
                        corner = k
        if corner < 0:
            continue
        _impact(s, fpar, ipar, surf, corner, counts, math.nan, 0.0)
        impacts += 1
        energy = specific_energy(s, fpar)
        side = decided_side(s, fpar, n)
        if side >= 0:
            nrec = _record(rec, nrec, t, SEG_END, s, -1, 0.0, 0.0, energy, EVENT_IMPACT)
            return side, STATUS_DECIDED, t, t, nrec
        nrec = _record(rec, nrec, t, SEG_FLIGHT, s, -1, 0.0, 0.0, energy, EVENT_IMPACT)
        if impacts >= ipar[IP_MAX_EVENTS]:
            return -1, STATUS_EVENT_BUDGET, math.nan, t, nrec
    return -1, STATUS_T_MAX, math.nan, t, nrec


@numba.njit(cache=True)
def roll_one(fpar, ipar, state0, rec, counts):
    """Simulate one roll.

    Parameters
    ----------
    fpar, ipar : parameter vectors from :func:`dice_sweep.physics.pack_params`.
    state0 : float64[6]
        Initial (x0, y0, phi0, vx0, vy0, omega0) of the geometric centre, SI.
    rec : float64[m, REC_WIDTH]
        Segment records, filled up to the returned count (m = 0 records nothing).
    counts : int32[len(COUNT_COLUMNS)]
        Event tallies, overwritten.

    Returns
    -------
    outcome : int
        Side 0..n-1, or -1.
    status : int
        Index into STATUS_NAMES.
    t_decided : float
        Time (s) of the decision, NaN when undecided.
    t_end : float
        Time (s) at which the simulation stopped.
    n_records : int
        Rows of ``rec`` written (the last may be cut off when rec is too small).
    """
    return _roll_into(fpar, ipar, state0, rec, counts, np.empty(6), np.empty(6), np.empty(5), np.empty(2, dtype=np.int64),
                      _flat_table(ipar))


@numba.njit(inline="always")
def _roll_into(fpar, ipar, state0, rec, counts, s, after, pivot_out, hit, flats):
    """:func:`roll_one` with its scratch arrays passed in (float64[6], float64[6],
    float64[5], int64[2], contents irrelevant), so that a batch allocates them once: four
    allocations per roll were 5-10 % of a roll's time (docs/dev/profile.md). ``flats``
    (:func:`_flat_table`) is kept across the batch's rolls: the same die."""
    shift_reference(state0, fpar, 1.0, s)
    for i in range(counts.shape[0]):
        counts[i] = 0
    if ipar[IP_METHOD] == METHOD_FIXED_STEP:
        return _roll_fixed_step(fpar, ipar, s, rec, counts, after)
    return _roll_event(fpar, ipar, s, rec, counts, after, pivot_out, hit, flats)


@numba.njit(cache=True)
def roll_batch(fpar, ipar, states, out_outcome, out_status, out_counts, out_t):
    """Roll every row of ``states``; results go into the preallocated outputs (see
    docs/dev/architecture.md). A row's result depends on that row only."""
    rec = np.empty((0, REC_WIDTH))
    counts = np.zeros(out_counts.shape[1], dtype=np.int32)
    s, after, pivot_out, hit = np.empty(6), np.empty(6), np.empty(5), np.empty(2, dtype=np.int64)
    flats = _flat_table(ipar)
    for i in range(states.shape[0]):
        outcome, status, t_decided, _, _ = _roll_into(fpar, ipar, states[i], rec, counts, s, after, pivot_out, hit, flats)
        out_outcome[i] = outcome
        out_status[i] = status
        out_t[i] = t_decided
        for j in range(counts.shape[0]):
            out_counts[i, j] = counts[j]


@numba.njit(cache=True)
def roll_batch_streams(fpar, ipar, states, streams, out_outcome, out_status, out_counts, out_t):
    """:func:`roll_batch` with the stochastic impact law's stream of row i set to
    (seed, streams[i, 0], streams[i, 1]) = (seed, pixel, draw): integers below 2^53 as floats.
    A row's result depends on that row and its stream only."""
    own = fpar.copy()
    for i in range(states.shape[0]):
        own[FP_STREAM_PIXEL] = streams[i, 0]
        own[FP_STREAM_DRAW] = streams[i, 1]
        roll_batch(own, ipar, states[i:i + 1], out_outcome[i:i + 1], out_status[i:i + 1], out_counts[i:i + 1], out_t[i:i + 1])


@numba.njit(cache=True)
def sample_records(fpar, ipar, rec, n_rec, times, out):
    """State (x, y, phi, vx, vy, omega) of the geometric centre at each of ``times`` (s,
    ascending) from the records of a roll."""
    g = fpar[FP_G]
    pivot_out = np.zeros(5)
    pivot_hit = np.zeros(2, dtype=np.int64)
    seg = 0
    start = np.empty(6)
    com = np.empty(6)
    flight_seg = -1  # the flight segment last sampled, its time and state (drag)
    flight_tau = 0.0
    flight_state_at = np.empty(6)
    for i in range(times.shape[0]):
        t = times[i]
        while seg + 1 < n_rec and rec[seg + 1, REC_T] <= t:
            seg += 1
        for c in range(6):
            start[c] = rec[seg, REC_STATE + c]
        tau = t - rec[seg, REC_T]
        if rec[seg, REC_KIND] == SEG_PIVOT_ODE:
            # sliding or drag-damped pivot: integrate again up to the sample time
            corner = int(rec[seg, REC_CORNER])
            rx, ry = corner_vector(start, fpar, corner)
            _, ly = contact_lever(fpar, rx, ry, 0.0, 1.0)  # the contact point's slip
            slip = 0.0 if math.isinf(fpar[FP_MU]) else start[3] - start[5] * ly
            pivot_ode(fpar, ipar[IP_N], corner, rec[seg, REC_PX], rec[seg, REC_CHI], start[5], slip, tau, False, pivot_out, pivot_hit)
            com[:] = start
            _set_pivot_state(com, fpar, rec[seg, REC_PX] + pivot_out[3], pivot_out[0], pivot_out[1], corner,
                             corner_geometry(fpar, corner)[1])
            com[3] += pivot_out[4]
        elif rec[seg, REC_KIND] == SEG_PIVOT:
            corner = int(rec[seg, REC_CORNER])
            rho, _ = corner_geometry(fpar, corner)
            alpha = fpar[FP_INERTIA] / (rho * rho)
            chi0 = rec[seg, REC_CHI]
            chi = pivot_angle_at(chi0, start[5], tau, rho, g, alpha, rec[seg, REC_CHI_END])
            e = pivot_energy(chi0, start[5], rho, g, alpha)
            w2 = pivot_omega_squared(e, math.sin(chi), rho, g, alpha)
            omega = math.copysign(math.sqrt(max(w2, 0.0)), start[5] if start[5] != 0.0 else -math.cos(chi0))
            com[:] = start
            _set_pivot_state(com, fpar, rec[seg, REC_PX], chi, omega, corner, corner_geometry(fpar, corner)[1])
        elif rec[seg, REC_KIND] == SEG_LADDER:
            ladder_at(fpar, ipar[IP_N], int(rec[seg, REC_CORNER]), int(rec[seg, REC_PX]), rec[seg, REC_CHI], start[2], start[5], tau, com)
        elif rec[seg, REC_KIND] == SEG_SLIDE:
            com[:] = start
            _slide(com, fpar, tau)
        elif rec[seg, REC_KIND] == SEG_END:
            com[:] = start  # the simulation stopped here (decided, at rest, or out of time)
        elif fpar[FP_DRAG] > 0.0 and seg == flight_seg and tau >= flight_tau:
            # with drag a flight is integrated: go on from the previous sample of the same
            # flight instead of from its start (a fit samples ~50 frames per flight)
            advance_flight(flight_state_at, tau - flight_tau, fpar, com)
            flight_state_at[:] = com
            flight_tau = tau
        else:
            advance_flight(start, tau, fpar, com)
            flight_seg = seg
            flight_tau = tau
            flight_state_at[:] = com
        shift_reference(com, fpar, -1.0, out[i])


@numba.njit(cache=True)
def sample_batch(fpar, ipar, states, times, starts, out, out_outcome):
    """Simulate many rolls and sample each at its own times: the fitting workhorse.

    Roll i starts from ``states[i]`` (geometric centre) at time 0 and is sampled at
    ``times[starts[i]:starts[i+1]]`` (s, ascending); the geometric centre's (x, y, phi, vx, vy,
    omega) go to the same rows of ``out``. Set ipar[IP_CONTINUE] = 1 to follow dice past the
    decision. Each roll stops at its last sample time (or at t_max if that is earlier): a fit
    samples short pieces of track, and what follows the last sample is never read.

    A roll keeps SAMPLE_RECORDS segments. One that fills them before it stops has outcome
    PATH_CUT: its samples after the start of the last kept segment assume that segment goes on,
    which a caller must not trust (the fit refuses; simulate-drops cuts its track there).
    """
    rec = np.empty((SAMPLE_RECORDS, REC_WIDTH))
    counts = np.zeros(len(COUNT_COLUMNS), dtype=np.int32)
    s, after, roll_pivot_out, hit = np.empty(6), np.empty(6), np.empty(5), np.empty(2, dtype=np.int64)
    flats = _flat_table(ipar)  # t_max is all that changes between the rows: the same die
    own = fpar.copy()  # per-roll t_max without touching the caller's array
    past = SAMPLE_PAST * math.sqrt(fpar[FP_RHO_MAX] / fpar[FP_G])
    for i in range(states.shape[0]):
        if starts[i + 1] > starts[i]:
            # just past the last sample, so that it falls inside a simulated segment
            own[FP_TMAX] = min(fpar[FP_TMAX], times[starts[i + 1] - 1] + past)
        else:
            own[FP_TMAX] = fpar[FP_TMAX]
        outcome, _, _, _, n_rec = _roll_into(own, ipar, states[i], rec, counts, s, after, roll_pivot_out, hit, flats)
        out_outcome[i] = outcome
        lo = starts[i]
        hi = starts[i + 1]
        sample_records(own, ipar, rec, n_rec, times[lo:hi], out[lo:hi])
        if n_rec == SAMPLE_RECORDS and rec[n_rec - 1, REC_KIND] != SEG_END:
            out_outcome[i] = PATH_CUT  # the records ran out before the roll stopped
