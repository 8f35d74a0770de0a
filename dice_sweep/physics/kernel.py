"""One roll and a batch of rolls: the event-driven and the fixed-step integrators.

A roll ends as soon as its side is decided (the exact rule of docs/physics.md: once the
energy per unit mass is below g R no corner can pass under the centre again, so the side
crossed by the vertical ray down from the centre is the answer), or with outcome -1 and a
status saying why not.
"""

import math

import numba
import numpy as np

from dice_sweep.physics.flight import (
    NO_CONTACT,
    STALLED,
    SURF_TABLE,
    flight_state,
    next_contact,
    surface_frame,
)
from dice_sweep.physics.impact import (
    corner_vector,
    resolve_impact,
    specific_energy,
    stick_corner,
)
from dice_sweep.physics.params import (
    FP_ALPHA,
    FP_BN,
    FP_BT,
    FP_DT,
    FP_G,
    FP_R,
    FP_TMAX,
    FP_WALL,
    IP_MAX_EVENTS,
    IP_METHOD,
    IP_N,
    METHOD_FIXED_STEP,
)
from dice_sweep.physics.pivot import (
    PIVOT_BALANCED,
    PIVOT_LIFTOFF,
    pivot_angle_at,
    pivot_next,
)

STATE_COLUMNS = ("x0", "y0", "phi0", "vx0", "vy0", "omega0")

STATUS_DECIDED = 0
STATUS_T_MAX = 1
STATUS_EVENT_BUDGET = 2
STATUS_BALANCED = 3
STATUS_STALLED = 4
STATUS_NAMES = ("decided", "t_max", "event_budget", "balanced", "stalled")

COUNT_COLUMNS = ("impacts", "wall_impacts", "corner_fallbacks", "pivots", "energy_clips")
C_IMPACTS = 0
C_WALL = 1
C_FALLBACK = 2
C_PIVOTS = 3
C_CLIPS = 4

# Segment records: one row per stretch of motion, enough to re-create the path at any time.
SEG_FLIGHT = 0
SEG_PIVOT = 1
SEG_END = 2
EVENT_START = 0
EVENT_IMPACT = 1
EVENT_LIFTOFF = 2
REC_T = 0
REC_KIND = 1
REC_STATE = 2  # six columns: x, y, phi, vx, vy, omega at the start of the segment
REC_CORNER = 8
REC_PX = 9
REC_CHI = 10
REC_CHI_END = 11
REC_ENERGY = 12
REC_EVENT = 13
REC_WIDTH = 14

# Tolerances, relative to the die's own scales R and sqrt(R/g) (see docs/physics.md).
GAP_TOL = 1e-12  # x R: an approaching corner this close counts as touching
MIN_STEP = 1e-9  # x sqrt(R/g): smallest step away from a touching, separating corner
CONTACT_SPEED = 1e-9  # x sqrt(g R): slower approach than this is round-off, not an impact
STICK_HEIGHT = 1e-8  # x R: a corner bouncing lower than this has come to rest (pivot)
# E < g R decides the side; a die balanced on a corner sits at E = g R up to round-off, which
# must not decide it (test_balanced_on_a_corner_is_reported_not_guessed caught that).
DECISION_MARGIN = 1e-12


@numba.njit(cache=True)
def side_below(phi, n):
    """Side crossed by the vertical ray down from the centre (side k: corners k and k+1)."""
    rel = (-0.5 * math.pi - phi) % (2.0 * math.pi)
    return int(rel / (2.0 * math.pi / n)) % n


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
def _set_pivot_state(s, px, chi, omega, corner, n, radius):
    """Full state of a die pivoting on ``corner`` at (px, 0), keeping phi unwrapped."""
    s[0] = px + radius * math.cos(chi)
    s[1] = radius * math.sin(chi)
    phi = chi + math.pi - 2.0 * math.pi * corner / n
    s[2] = phi + 2.0 * math.pi * round((s[2] - phi) / (2.0 * math.pi))
    s[3] = -omega * radius * math.sin(chi)
    s[4] = omega * radius * math.cos(chi)
    s[5] = omega


@numba.njit(cache=True)
def _unpack(fpar, ipar):
    """(n, R, g, beta_n, beta_t, half_width, t_max, alpha, decision barrier) of a roll."""
    g = fpar[FP_G]
    radius = fpar[FP_R]
    barrier = g * radius * (1.0 - DECISION_MARGIN)
    return (ipar[IP_N], radius, g, fpar[FP_BN], fpar[FP_BT], fpar[FP_WALL], fpar[FP_TMAX],
            fpar[FP_ALPHA], barrier)


@numba.njit(cache=True)
def _impact(s, n, alpha, radius, beta_n, beta_t, surf, half_width, corner, counts):
    """Resolve one impact and tally it; returns the corner's normal velocity after (m/s)."""
    u_n = resolve_impact(s, n, alpha, radius, beta_n, beta_t, surf, half_width, corner, counts)
    counts[C_IMPACTS] += 1
    if surf != SURF_TABLE:
        counts[C_WALL] += 1
    return u_n


@numba.njit(cache=True)
def _roll_event(fpar, ipar, s, rec, counts):
    n, radius, g, beta_n, beta_t, half_width, t_max, alpha, barrier = _unpack(fpar, ipar)
    tol = GAP_TOL * radius
    min_step = MIN_STEP * math.sqrt(radius / g)
    contact_speed = CONTACT_SPEED * math.sqrt(g * radius)
    stick_speed = math.sqrt(2.0 * g * radius * STICK_HEIGHT)
    start = np.empty(6)
    hit = np.zeros(2, dtype=np.int64)
    out = np.zeros(3)
    t = 0.0
    nrec = _record(rec, 0, t, SEG_FLIGHT, s, -1, 0.0, 0.0, specific_energy(s, alpha, radius, g), EVENT_START)
    if specific_energy(s, alpha, radius, g) < barrier:
        return side_below(s[2], n), STATUS_DECIDED, t, t, nrec
    pivoting = False
    corner = -1
    px = 0.0
    chi = 0.0
    for _ in range(ipar[IP_MAX_EVENTS]):
        if not pivoting:
            tau = next_contact(s, n, radius, g, half_width, t_max - t, tol, min_step, contact_speed, hit)
            if tau == NO_CONTACT:
                return -1, STATUS_T_MAX, math.nan, t, nrec
            if tau == STALLED:
                return -1, STATUS_STALLED, math.nan, t, nrec
            start[:] = s
            flight_state(start, tau, g, s)
            t += tau
            surf = hit[0]
            corner = hit[1]
        else:
            kind = pivot_next(n, radius, g, alpha, half_width, px, chi, s[5], out, hit)
            if kind == PIVOT_BALANCED:
                return -1, STATUS_BALANCED, math.nan, t, nrec
            if t + out[2] > t_max:
                return -1, STATUS_T_MAX, math.nan, t, nrec
            if nrec > 0:
                rec[nrec - 1, REC_CHI_END] = out[0]
            t += out[2]
            _set_pivot_state(s, px, out[0], out[1], corner, n, radius)
            pivoting = False
            if kind == PIVOT_LIFTOFF:
                nrec = _record(rec, nrec, t, SEG_FLIGHT, s, -1, 0.0, 0.0, specific_energy(s, alpha, radius, g), EVENT_LIFTOFF)
                continue
            surf = hit[0]
            corner = (corner + hit[1]) % n
        u_n = _impact(s, n, alpha, radius, beta_n, beta_t, surf, half_width, corner, counts)
        pivoting = surf == SURF_TABLE and u_n < stick_speed
        if pivoting:
            # The bounces that would follow shrink geometrically (a Zeno run): take their
            # limit, the corner at rest on the table, and turn about it.
            rx, ry = corner_vector(s, n, radius, corner)
            stick_corner(s, alpha, radius, rx, ry)
            px = s[0] + rx
            chi = math.atan2(-ry, -rx)
            counts[C_PIVOTS] += 1
        energy = specific_energy(s, alpha, radius, g)
        if energy < barrier:
            nrec = _record(rec, nrec, t, SEG_END, s, -1, 0.0, 0.0, energy, EVENT_IMPACT)
            return side_below(s[2], n), STATUS_DECIDED, t, t, nrec
        if pivoting:
            nrec = _record(rec, nrec, t, SEG_PIVOT, s, corner, px, chi, energy, EVENT_IMPACT)
        else:
            nrec = _record(rec, nrec, t, SEG_FLIGHT, s, -1, 0.0, 0.0, energy, EVENT_IMPACT)
    return -1, STATUS_EVENT_BUDGET, math.nan, t, nrec


@numba.njit(cache=True)
def _roll_fixed_step(fpar, ipar, s, rec, counts):
    """The paper's scheme: exact flight over steps of dt, a collision applied when a corner is
    found inside a surface and moving further in at the end of a step (no pivot phase)."""
    n, radius, g, beta_n, beta_t, half_width, t_max, alpha, barrier = _unpack(fpar, ipar)
    dt = fpar[FP_DT]
    n_surf = 1 if math.isinf(half_width) else 3
    start = np.empty(6)
    t = 0.0
    nrec = _record(rec, 0, t, SEG_FLIGHT, s, -1, 0.0, 0.0, specific_energy(s, alpha, radius, g), EVENT_START)
    if specific_energy(s, alpha, radius, g) < barrier:
        return side_below(s[2], n), STATUS_DECIDED, t, t, nrec
    n_steps = int(math.ceil(t_max / dt))
    impacts = 0
    for step in range(1, n_steps + 1):
        start[:] = s
        flight_state(start, dt, g, s)
        t = step * dt
        deepest = 0.0
        surf = -1
        corner = -1
        for sf in range(n_surf):
            nx, ny, d = surface_frame(sf, half_width)
            for k in range(n):
                rx, ry = corner_vector(s, n, radius, k)
                gap = d + nx * (s[0] + rx) + ny * (s[1] + ry)
                if gap < deepest:
                    u_n = nx * (s[3] - s[5] * ry) + ny * (s[4] + s[5] * rx)
                    if u_n < 0.0:
                        deepest = gap
                        surf = sf
                        corner = k
        if corner < 0:
            continue
        _impact(s, n, alpha, radius, beta_n, beta_t, surf, half_width, corner, counts)
        impacts += 1
        energy = specific_energy(s, alpha, radius, g)
        if energy < barrier:
            nrec = _record(rec, nrec, t, SEG_END, s, -1, 0.0, 0.0, energy, EVENT_IMPACT)
            return side_below(s[2], n), STATUS_DECIDED, t, t, nrec
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
        Initial (x0, y0, phi0, vx0, vy0, omega0), SI.
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
    s = state0.copy()
    for i in range(counts.shape[0]):
        counts[i] = 0
    if ipar[IP_METHOD] == METHOD_FIXED_STEP:
        return _roll_fixed_step(fpar, ipar, s, rec, counts)
    return _roll_event(fpar, ipar, s, rec, counts)


@numba.njit(cache=True)
def roll_batch(fpar, ipar, states, out_outcome, out_status, out_counts, out_t):
    """Roll every row of ``states``; results go into the preallocated outputs (see
    docs/architecture.md). A row's result depends on that row only."""
    rec = np.empty((0, REC_WIDTH))
    counts = np.zeros(out_counts.shape[1], dtype=np.int32)
    for i in range(states.shape[0]):
        outcome, status, t_decided, _, _ = roll_one(fpar, ipar, states[i], rec, counts)
        out_outcome[i] = outcome
        out_status[i] = status
        out_t[i] = t_decided
        for j in range(counts.shape[0]):
            out_counts[i, j] = counts[j]


@numba.njit(cache=True)
def sample_records(fpar, ipar, rec, n_rec, times, out):
    """State (x, y, phi, vx, vy, omega) at each of ``times`` (s, ascending) from records."""
    n = ipar[IP_N]
    radius = fpar[FP_R]
    g = fpar[FP_G]
    alpha = fpar[FP_ALPHA]
    seg = 0
    start = np.empty(6)
    for i in range(times.shape[0]):
        t = times[i]
        while seg + 1 < n_rec and rec[seg + 1, REC_T] <= t:
            seg += 1
        for c in range(6):
            start[c] = rec[seg, REC_STATE + c]
        tau = t - rec[seg, REC_T]
        if rec[seg, REC_KIND] == SEG_PIVOT:
            chi0 = rec[seg, REC_CHI]
            chi = pivot_angle_at(chi0, start[5], tau, radius, g, alpha, rec[seg, REC_CHI_END])
            e = 0.5 * radius * radius * (1.0 + alpha) * start[5] ** 2 + g * radius * math.sin(chi0)
            w2 = 2.0 * (e - g * radius * math.sin(chi)) / (radius * radius * (1.0 + alpha))
            omega = math.copysign(math.sqrt(max(w2, 0.0)), start[5] if start[5] != 0.0 else -math.cos(chi0))
            for c in range(6):
                out[i, c] = start[c]
            _set_pivot_state(out[i], rec[seg, REC_PX], chi, omega, int(rec[seg, REC_CORNER]), n, radius)
        else:
            flight_state(start, tau, g, out[i])
