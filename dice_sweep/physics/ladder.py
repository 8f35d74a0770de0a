"""A die sliding on a table corner and a wall corner at once (a ladder sliding down a wall).

Both contacts held leave one degree of freedom, the body angle phi: the arc centre of the
table corner a stays at height r, that of the wall corner b at r from the wall, so

    y = r - r_a,y(phi),  x = w_s (W - r) - r_b,x(phi),  vy = -omega r_a,x,  vx = omega r_b,y,

with r_k the arc centre of corner k from the centre of mass and w_s = +1 (right wall) or -1.
Each contact pushes along its normal (N_a up, N_b away from the wall, per unit mass) and
slides under Coulomb friction mu N against its slip; the two normal forces are those that
keep both constraints (a 2x2 linear system), and the angle moves by RK4 steps of LADDER_STEP.
The phase ends when a normal force would pull, when the die stops (a slip at either contact is
zero only when omega is: then it stays at rest unless gravity turns it on against friction),
when another corner reaches the table or the wall, or when the side is decided
(docs/physics.md, "Outcome rule"). Without this phase the event kernel traded a pivot on the
table corner for a wall impact every 1e-8 s of simulated time, until its event budget.

A hinge is the case a = b of a sharp corner: one corner lodged in the corner of table and wall.
Neither contact slips (the corner cannot move into either surface, and moving out of one is
moving along the other, which the other's friction or normal force stops), so the die turns
about the corner like a pendulum, (k^2 + rho^2) omega' = r_x (g - D_y) + r_y D_x, and the
reaction R = a - (0, -g) - D at the corner is whatever keeps it there. It holds while R lies
in the sum of the two friction cones, capped at the half-plane facing out of the corner
(friction up to 1: a larger mu would let the two frictions wedge the corner in with a reaction
that pulls, which the rigid model cannot decide). It ends, besides the common ends, when R
leaves that cone on the table's side (the corner slides away from the wall: a pivot on the
table) or on the wall's side (it would slide up the wall: flight). Without it a corner in the
table-wall corner traded a sliding pivot into the wall for a wall impact until the budget.
"""

import math

import numba

from dice_sweep.physics.flight import corner_offset
from dice_sweep.physics.outcome import decided_side, decision_bound
from dice_sweep.physics.params import FP_CORNER_RADIUS, FP_DRAG, FP_G, FP_INERTIA, FP_MU, FP_RHO_MAX, FP_WALL

LADDER_STEP = 1e-3  # x sqrt(rho_max/g): RK4 step of the angle
LADDER_TIME_TOL = 1e-12  # x sqrt(rho_max/g): an end is located (bisection) to this
LADDER_RESTARTS = 100  # stops in a row without moving on: at rest (gravity and friction balance)
LADDER_SLIP = 1e-9  # x sqrt(g rho_max): slower slip than this at entry is a contact at rest

# how the phase ended
LADDER_REFUSED = 0  # the two contacts cannot both be held (a normal force would pull): no phase
LADDER_OFF_WALL = 1  # the wall contact lets go: the die pivots on its table corner
LADDER_OFF_TABLE = 2  # the table contact lets go: flight
LADDER_AT_REST = 3  # stopped, and friction holds it: at rest leaning on the wall
LADDER_CONTACT = 4  # another corner reaches the table or the wall: an impact follows
LADDER_DECIDED = 5
LADDER_TIMEOUT = 6


@numba.njit(cache=True)
def ladder_state(fpar, a, b, wall, phi, omega, s):
    """The centre-of-mass state (into s) of a die at angle phi turning at omega on table corner
    a and wall corner b of the wall on side ``wall`` (+1 right, -1 left)."""
    c = math.cos(phi)
    sn = math.sin(phi)
    arc = fpar[FP_CORNER_RADIUS]
    rax, ray = corner_offset(fpar, a, c, sn)
    rbx, rby = corner_offset(fpar, b, c, sn)
    s[0] = wall * (fpar[FP_WALL] - arc) - rbx
    s[1] = arc - ray
    s[2] = phi
    s[3] = omega * rby
    s[4] = -omega * rax
    s[5] = omega


@numba.njit(cache=True)
def ladder_spin(fpar, a, b, s):
    """The spin (rad/s) of the motion on table corner a and wall corner b nearest to the
    centre-of-mass state s in the kinetic-energy metric: the velocity a plastic, frictionless
    impulse at both contacts leaves (their normal velocities zero). A projection, so the kinetic
    energy never rises; it ends a wall contact chattering above the stick speed (kernel)."""
    c = math.cos(s[2])
    sn = math.sin(s[2])
    rax, _ = corner_offset(fpar, a, c, sn)
    _, rby = corner_offset(fpar, b, c, sn)
    k2 = fpar[FP_INERTIA]
    # ladder_state's velocity is omega (rby, -rax, 1)
    return (s[3] * rby - s[4] * rax + k2 * s[5]) / (rby * rby + rax * rax + k2)


@numba.njit(cache=True)
def is_hinge(fpar, a, b):
    """True if the phase on table corner a and wall corner b is a hinge: one sharp corner."""
    return a == b and fpar[FP_CORNER_RADIUS] == 0.0


@numba.njit(cache=True)
def hinge_reaction(fpar, rx, ry, omega, dx, dy):
    """(angular acceleration rad/s^2, Rx, Ry m/s^2) of a die turning at omega about its corner
    held at rest, r = (rx, ry) from the centre of mass, drag acceleration (dx, dy): the reaction
    R (per unit mass) is what the two contacts must push at the corner."""
    alpha = (rx * (fpar[FP_G] - dy) + ry * dx) / (fpar[FP_INERTIA] + rx * rx + ry * ry)
    w2 = omega * omega
    return alpha, alpha * ry + w2 * rx - dx, -alpha * rx + w2 * ry + fpar[FP_G] - dy


@numba.njit(cache=True)
def hinge_margins(fpar, wall, rx_reaction, ry_reaction):
    """The reaction's margins (m/s^2, >= 0 inside) to the edges of the cone the two contacts can
    push in, wall ``wall`` (+1 right, -1 left): (wall side, table side). The cone spans the
    table's and the wall's friction cones, at most the half-plane out of the corner."""
    half = min(math.atan(fpar[FP_MU]), 0.25 * math.pi)
    c = math.cos(half)
    sn = math.sin(half)
    toward = wall * rx_reaction  # the reaction's component towards the wall (the wall pushes away)
    return -toward * sn + ry_reaction * c, -toward * c + ry_reaction * sn


@numba.njit(cache=True)
def _hinge(fpar, wall, rx, ry, omega, dx, dy):
    """:func:`_forces` of a hinge: (angular acceleration, wall-side margin, table-side margin)."""
    alpha, reaction_x, reaction_y = hinge_reaction(fpar, rx, ry, omega, dx, dy)
    on_wall, on_table = hinge_margins(fpar, wall, reaction_x, reaction_y)
    return alpha, on_wall, on_table


@numba.njit(cache=True)
def _forces(fpar, a, b, wall, phi, omega, sa, sb):
    """(angular acceleration rad/s^2, N_a, N_b in m/s^2) with the slips' signs sa, sb; for a
    hinge (:func:`is_hinge`) N_a and N_b are the reaction's margins to the wall's and the
    table's edge of the cone (>= 0 inside; :func:`_hinge`)."""
    c = math.cos(phi)
    sn = math.sin(phi)
    arc = fpar[FP_CORNER_RADIUS]
    mu = fpar[FP_MU]
    k2 = fpar[FP_INERTIA]
    rax, ray = corner_offset(fpar, a, c, sn)
    rbx, rby = corner_offset(fpar, b, c, sn)
    vx = omega * rby
    vy = -omega * rax
    speed = math.sqrt(vx * vx + vy * vy)
    dx = -fpar[FP_DRAG] * speed * vx
    dy = -fpar[FP_DRAG] * speed * vy
    if is_hinge(fpar, a, b):
        return _hinge(fpar, wall, rax, ray, omega, dx, dy)
    # torque per unit normal force of each contact, at its contact point (arc centre less r n)
    ca = rax + mu * sa * (ray - arc)
    cb = wall * rby - mu * sb * (rbx + wall * arc)
    # the arc centres' accelerations normal to their surfaces vanish
    m11 = 1.0 + rax * ca / k2
    m12 = -mu * sb + rax * cb / k2
    m21 = -mu * sa - rby * ca / k2
    m22 = -wall - rby * cb / k2
    r1 = fpar[FP_G] - dy + omega * omega * ray
    r2 = -dx + omega * omega * rbx
    det = m11 * m22 - m12 * m21
    if det == 0.0:
        return 0.0, -1.0, -1.0
    na = (r1 * m22 - m12 * r2) / det
    nb = (m11 * r2 - m21 * r1) / det
    return (na * ca + nb * cb) / k2, na, nb


@numba.njit(cache=True)
def _slips(fpar, a, b, wall, phi, omega):
    """Slip velocities (m/s) of the table contact (along x) and the wall contact (along y)."""
    c = math.cos(phi)
    sn = math.sin(phi)
    arc = fpar[FP_CORNER_RADIUS]
    rax, ray = corner_offset(fpar, a, c, sn)
    rbx, rby = corner_offset(fpar, b, c, sn)
    return omega * (rby - ray + arc), omega * (rbx + wall * arc - rax)


@numba.njit(cache=True)
def _step(fpar, a, b, wall, phi, omega, sa, sb, h):
    """One RK4 step of (phi, omega) with fixed slip signs."""
    k1p, k1w = omega, _forces(fpar, a, b, wall, phi, omega, sa, sb)[0]
    k2p = omega + 0.5 * h * k1w
    k2w = _forces(fpar, a, b, wall, phi + 0.5 * h * k1p, k2p, sa, sb)[0]
    k3p = omega + 0.5 * h * k2w
    k3w = _forces(fpar, a, b, wall, phi + 0.5 * h * k2p, k3p, sa, sb)[0]
    k4p = omega + h * k3w
    k4w = _forces(fpar, a, b, wall, phi + h * k3p, k4p, sa, sb)[0]
    return phi + h * (k1p + 2.0 * k2p + 2.0 * k3p + k4p) / 6.0, omega + h * (k1w + 2.0 * k2w + 2.0 * k3w + k4w) / 6.0


@numba.njit(cache=True)
def _margin(fpar, n, a, b, wall, phi, omega, sa, sb, s):
    """Smallest of the phase's conditions, each scaled to the die (>= 0 while it holds): both
    normal forces, both slips in their direction, every other corner clear of table and wall."""
    g = fpar[FP_G]
    scale = fpar[FP_RHO_MAX]
    _, na, nb = _forces(fpar, a, b, wall, phi, omega, sa, sb)
    ua, ub = _slips(fpar, a, b, wall, phi, omega)
    speed = math.sqrt(g * scale)
    m = min(na / g, nb / g)
    if not is_hinge(fpar, a, b):  # a hinge does not slip
        m = min(m, sa * ua / speed, sb * ub / speed)
    ladder_state(fpar, a, b, wall, phi, omega, s)
    c = math.cos(phi)
    sn = math.sin(phi)
    arc = fpar[FP_CORNER_RADIUS]
    for k in range(n):
        rx, ry = corner_offset(fpar, k, c, sn)
        if k != a:
            m = min(m, (s[1] + ry - arc) / scale)
        if k != b:
            m = min(m, (fpar[FP_WALL] - wall * (s[0] + rx) - arc) / scale)
    return m


@numba.njit(cache=True)
def _signs(fpar, a, b, wall, phi, omega):
    """Slip signs (+-1) of a die turning at omega, or, at rest (omega 0), of the way gravity
    turns it against friction: (0, 0) if friction holds it either way."""
    if omega != 0.0:
        ua, ub = _slips(fpar, a, b, wall, phi, omega)
        return (1.0 if ua > 0.0 else -1.0), (1.0 if ub > 0.0 else -1.0)
    for d in (1.0, -1.0):
        ua, ub = _slips(fpar, a, b, wall, phi, d)
        sa = 1.0 if ua > 0.0 else -1.0
        sb = 1.0 if ub > 0.0 else -1.0
        alpha, na, nb = _forces(fpar, a, b, wall, phi, 0.0, sa, sb)
        if alpha * d > 0.0 and na >= 0.0 and nb >= 0.0:
            return sa, sb
    return 0.0, 0.0


@numba.njit(cache=True)
def ladder(fpar, n, a, b, wall, phi0, omega0, t_left, s):
    """Slide on table corner a and wall corner b from (phi0, omega0) for at most t_left seconds.

    Returns (how it ended: LADDER_*, its duration s); s gets the centre-of-mass state at the end
    (untouched when LADDER_REFUSED).
    """
    g = fpar[FP_G]
    unit = math.sqrt(fpar[FP_RHO_MAX] / g)
    h = LADDER_STEP * unit
    ua, ub = _slips(fpar, a, b, wall, phi0, omega0)
    slow = LADDER_SLIP * math.sqrt(g * fpar[FP_RHO_MAX])
    if not is_hinge(fpar, a, b) and (abs(ua) < slow or abs(ub) < slow):
        return LADDER_REFUSED, 0.0
    sa, sb = _signs(fpar, a, b, wall, phi0, omega0)
    if _margin(fpar, n, a, b, wall, phi0, omega0, sa, sb, s) < 0.0:
        return LADDER_REFUSED, 0.0
    bound = decision_bound(fpar)
    phi = phi0
    omega = omega0
    t = 0.0
    restarts = 0
    while True:
        step = min(h, t_left - t)
        if step <= 0.0:
            ladder_state(fpar, a, b, wall, phi, omega, s)
            return LADDER_TIMEOUT, t
        p1, w1 = _step(fpar, a, b, wall, phi, omega, sa, sb, step)
        if _margin(fpar, n, a, b, wall, p1, w1, sa, sb, s) < 0.0:
            # locate the end: the last state where the phase still holds
            lo = 0.0
            hi = step
            while hi - lo > LADDER_TIME_TOL * unit:
                mid = 0.5 * (lo + hi)
                pm, wm = _step(fpar, a, b, wall, phi, omega, sa, sb, mid)
                if _margin(fpar, n, a, b, wall, pm, wm, sa, sb, s) < 0.0:
                    hi = mid
                else:
                    lo = mid
            phi, omega = _step(fpar, a, b, wall, phi, omega, sa, sb, lo)
            t += lo
            _, na, nb = _forces(fpar, a, b, wall, phi, omega, sa, sb)
            ua, ub = _slips(fpar, a, b, wall, phi, omega)
            pm, wm = _step(fpar, a, b, wall, phi, omega, sa, sb, hi - lo)
            _, na1, nb1 = _forces(fpar, a, b, wall, pm, wm, sa, sb)
            ua1, ub1 = _slips(fpar, a, b, wall, pm, wm)
            if sa * ua1 < 0.0 or sb * ub1 < 0.0:  # it stops: at rest unless gravity turns it on
                omega = 0.0
                sa, sb = _signs(fpar, a, b, wall, phi, 0.0)
                restarts = restarts + 1 if lo == 0.0 else 0
                if sa == 0.0 or restarts > LADDER_RESTARTS:
                    ladder_state(fpar, a, b, wall, phi, 0.0, s)
                    return LADDER_AT_REST, t
                if _margin(fpar, n, a, b, wall, phi, omega, sa, sb, s) < 0.0:
                    ladder_state(fpar, a, b, wall, phi, 0.0, s)
                    return LADDER_CONTACT, t
                continue
            ladder_state(fpar, a, b, wall, phi, omega, s)
            if nb1 < 0.0:
                return LADDER_OFF_WALL, t
            if na1 < 0.0:
                return LADDER_OFF_TABLE, t
            return LADDER_CONTACT, t
        phi = p1
        omega = w1
        t += step
        ladder_state(fpar, a, b, wall, phi, omega, s)
        if 0.5 * (s[3] * s[3] + s[4] * s[4]) + 0.5 * fpar[FP_INERTIA] * omega * omega + g * s[1] < bound and decided_side(s, fpar, n) >= 0:
            return LADDER_DECIDED, t


@numba.njit(cache=True)
def ladder_at(fpar, n, a, b, wall, phi0, omega0, tau, s):
    """The state (into s) tau seconds into a ladder phase begun at (phi0, omega0): the same
    steps as :func:`ladder`, for sampling a path."""
    h = LADDER_STEP * math.sqrt(fpar[FP_RHO_MAX] / fpar[FP_G])
    phi = phi0
    omega = omega0
    sa, sb = _signs(fpar, a, b, wall, phi0, omega0)
    t = 0.0
    while t < tau:
        step = min(h, tau - t)
        p1, w1 = _step(fpar, a, b, wall, phi, omega, sa, sb, step)
        ua, ub = _slips(fpar, a, b, wall, p1, w1)
        if sa * ua < 0.0 or sb * ub < 0.0:  # stopped within the step: at rest, or turning on
            omega = 0.0
            sa, sb = _signs(fpar, a, b, wall, phi, 0.0)
            if sa == 0.0:
                break
            t += step
            continue
        phi = p1
        omega = w1
        t += step
    ladder_state(fpar, a, b, wall, phi, omega, s)
