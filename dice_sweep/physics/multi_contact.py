"""One impact with two contacts: a side landing flat, a side hitting a wall flat, or a corner on
the table and another on a wall at once (docs/physics.md, "Two contacts at once").

Contacts whose arrival times lie within the contact window ``[contact] window`` (s) of the
first are one impact. Resolving them one after the other (two single-corner impulses at one
instant) breaks the mirror symmetry of a flat landing and makes the outcome jump with a tilt
of 1e-9 rad (issue 15).

Rigid law. Each contact i has Newton restitution on its corner's normal velocity,
u_n' = -beta_normal u_n, unless it separates with no impulse (u_n' >= -beta_normal u_n). The
tangential target is u_t' = -beta_tangential u_t, with a Coulomb cap. Two corners on one
surface share one tangential impulse at the midpoint of the side, capped by friction times
their summed normal impulses. Both corners sit at the same distance from the surface, so the
split of a tangential impulse between them moves neither the die nor its spin; asking each
corner for its own target makes the problem singular (four conditions, three velocities).
Corners on two surfaces each have their own tangential impulse and cone.

With at most two contacts the cases can be enumerated: each normal on or off; each tangential
impulse on its target, or on either edge of its cone. Every case is a small linear system.
A case is admissible when its normal impulses push, its targets lie in their cones, an edge
impulse falls short of its target, and a contact without impulse does not approach faster than
restitution allows. Of the admissible cases the one that leaves the least kinetic energy is
taken (maximal dissipation). With one contact this is the single-corner law of impact.py. The
frictionless case always has a solution (its matrix is positive definite) and never gains
energy. When the chosen impulse would gain energy it is moved towards the frictionless one, as
far as needed (an energy clip, as for one contact).

Friction rules (``[contact] friction_rule``). "aimed": the edges as above. "sliding": the
textbook sliding branch; the enumeration chooses the case as above, and a tangential row it put
on an edge is moved to the edge opposing that row's incoming tangential velocity and the case
solved again (with one contact this is impact.corner_impulse's sliding branch); if that case
pulls or leaves a contact approaching it is a jam and the frictionless impulse is used.
"exact": the compliant two-contact Coulomb impact (physics/two_contact_exact.py: equal normal
springs at the two contacts, Coulomb friction with stick and slip, per-contact energetic
restitution; one contact's closed-form exact impact when the other is never compressed). If its
integration does not end, the enumeration with the sliding rule and the sticking target
u_t' = 0 in place of -beta_tangential u_t is used (docs/physics.md, "Friction rules").

Rounded corners: each contact's lever is its contact point (impact.contact_lever), the arc
centre less r times the surface normal.

Paper law. Eqs 9-13 depend only on the surface, not on the corner, so two corners on one
surface get one application of the law. It stands when the centre approaches the surface
and neither corner is left approaching; otherwise, and for contacts on two surfaces, the rigid
two-contact impulse with the same coefficients is used (a fallback, as for one contact).
"""

import math

import numba
import numpy as np

from dice_sweep.physics.flight import corner_offset, surface_frame
from dice_sweep.physics.impact import (
    C_CLIPS, C_FALLBACK, beta_normal_at, contact_lever, corner_normal_velocity, paper_law, resolve_impact,
)
from dice_sweep.physics.params import (
    FP_ALPHA,
    FP_BT,
    FP_CORNER_RADIUS,
    FP_INERTIA,
    FP_MU,
    FP_R,
    FP_RHO_MAX,
    FP_WALL,
    IP_FRICTION_RULE,
    IP_MODEL,
    IP_RESTITUTION,
)
from dice_sweep.physics.two_contact_exact import exact_two_contacts
from dice_sweep.physics.layout import FRICTION_RULE_AIMED, FRICTION_RULE_EXACT, MODEL_PAPER, RESTITUTION_ENERGETIC

MAX_ROWS = 4  # two normal rows and at most two tangential rows
# Relative slack of the admissibility tests: round-off of the 4 x 4 solves, not physics.
ADMISSIBLE_SLACK = 1e-12
# A pivot below this share of the matrix's largest entry: the case's conditions are dependent
# (e.g. both corners of a side sticking on a wall and on the table at once) and it is skipped.
SINGULAR_PIVOT = 1e-12


@numba.njit(inline="always")  # inlined into the kernel's impact: as a call it cost ~8 % (bench_kernel)
def second_contact(s, fpar, n, n_surf, surf0, corner0, window, tol, contact_speed):
    """The contact, other than (surf0, corner0), that arrives first within ``window`` seconds.

    A corner joins when it approaches its surface faster than ``contact_speed`` (m/s) and its
    gap would close, at its present normal speed, within ``window`` (or is within ``tol``,
    m). Returns (surface, corner, arrival time in s), (-1, -1, inf) when none does. With
    rounded corners the gap is the arc centre's distance less r, and the normal speed is the
    arc centre's (the contact point's is the same).
    """
    c = math.cos(s[2])
    sn = math.sin(s[2])
    speed = math.sqrt(s[3] * s[3] + s[4] * s[4]) + abs(s[5]) * fpar[FP_RHO_MAX]
    best_time = math.inf
    best_surf = np.int64(-1)  # not literals: see corner in kernel._roll_event
    best_corner = np.int64(-1)
    reach = tol + speed * window  # no corner farther than this can arrive within the window
    arc = fpar[FP_CORNER_RADIUS]
    for surf in range(n_surf):
        nx, ny, d = surface_frame(surf, fpar[FP_WALL])
        h = d + nx * s[0] + ny * s[1]
        if h - fpar[FP_RHO_MAX] > reach:
            continue
        h -= arc  # rounded corners: an arc's gap is its centre's distance less r (exact at 0)
        for k in range(n):
            if surf == surf0 and k == corner0:
                continue
            rx, ry = corner_offset(fpar, k, c, sn)
            gap = h + nx * rx + ny * ry
            if gap > reach:
                continue  # most corners: rejected before their speed is computed
            u = corner_normal_velocity(s, rx, ry, nx, ny)
            if u >= -contact_speed or gap > tol - u * window:
                continue
            arrival = max(gap, 0.0) / (-u)
            if arrival < best_time:
                best_time = arrival
                best_surf = surf
                best_corner = k
    return best_surf, best_corner, best_time


@numba.njit(cache=True)
def _row(jac, i, nx, ny, rx, ry, tangential):
    """Row i of the contact Jacobian: the velocity (n or t component) of the point (rx, ry)
    from the centre of mass is jac[i] . (vx, vy, omega)."""
    ex = ny if tangential else nx
    ey = -nx if tangential else ny
    jac[i, 0] = ex
    jac[i, 1] = ey
    jac[i, 2] = -ry * ex + rx * ey  # r_perp . e, r_perp = z x r


@numba.njit(cache=True)
def _solve_in_place(a, b, m):
    """Gaussian elimination with partial pivoting on the leading m x m block; b gets x.
    Returns False when a pivot is negligible (dependent conditions)."""
    scale = 0.0
    for i in range(m):
        for j in range(m):
            scale = max(scale, abs(a[i, j]))
    if scale == 0.0:
        return False
    for col in range(m):
        piv = col
        for i in range(col + 1, m):
            if abs(a[i, col]) > abs(a[piv, col]):
                piv = i
        if abs(a[piv, col]) <= SINGULAR_PIVOT * scale:
            return False
        if piv != col:
            for j in range(m):
                a[col, j], a[piv, j] = a[piv, j], a[col, j]
            b[col], b[piv] = b[piv], b[col]
        for i in range(col + 1, m):
            f = a[i, col] / a[col, col]
            for j in range(col, m):
                a[i, j] -= f * a[col, j]
            b[i] -= f * b[col]
    for i in range(m - 1, -1, -1):
        acc = b[i]
        for j in range(i + 1, m):
            acc -= a[i, j] * b[j]
        b[i] = acc / a[i, i]
    return True


@numba.njit(cache=True)
def _energy_change(s, inertia, dv):
    """Kinetic energy change per unit mass (J/kg) of the velocity change dv = (dvx, dvy, domega)."""
    return s[3] * dv[0] + s[4] * dv[1] + inertia * s[5] * dv[2] + 0.5 * (dv[0] * dv[0] + dv[1] * dv[1] + inertia * dv[2] * dv[2])


@numba.njit(cache=True)
def _velocity(jac, r, s, dv):
    """Velocity (m/s) along row r of the Jacobian after the velocity change dv."""
    return jac[r, 0] * (s[3] + dv[0]) + jac[r, 1] * (s[4] + dv[1]) + jac[r, 2] * (s[5] + dv[2])


@numba.njit(cache=True)
def _tangential_rows(jac, owner, contacts, normal_mask, same_surface):
    """Fill the tangential rows (from row 2 on) for the pressing corners; returns the row count.

    One surface: one row at the midpoint of the pressing corners, owned by both (-1). Two
    surfaces: one row per pressing corner, owned by it.
    """
    rows = 2
    if same_surface:
        rx = 0.0
        ry = 0.0
        count = 0
        for i in range(2):
            if normal_mask & (1 << i):
                rx += contacts[i, 2]
                ry += contacts[i, 3]
                count += 1
        _row(jac, 2, contacts[0, 0], contacts[0, 1], rx / count, ry / count, True)
        owner[2] = -1
        return 3
    for i in range(2):
        if normal_mask & (1 << i):
            _row(jac, rows, contacts[i, 0], contacts[i, 1], contacts[i, 2], contacts[i, 3], True)
            owner[rows] = i
            rows += 1
    return rows


@numba.njit(cache=True)
def best_impulse(s, inertia, mu, beta_t, contacts, same_surface, frictionless, best_dv, sliding=False):
    """Enumerate the cases of a two-contact impact (module docstring).

    Parameters
    ----------
    s : float64[6]
        State of the centre of mass before the impact (only the velocities are read).
    inertia : float
        I / M about the centre of mass (m^2).
    mu, beta_t : float
        Coulomb friction coefficient (inf: no cap) and tangential restitution.
    contacts : float64[2, 5]
        Per contact: nx, ny (surface normal), rx, ry (corner from the centre of mass, m) and
        the normal target velocity -beta_n u_n (m/s).
    same_surface : bool
        Both corners on one surface (they share a tangential impulse).
    frictionless : bool
        No tangential impulse (the reference of the energy clip).
    best_dv : float64[3]
        Output: (dvx, dvy, domega) of the chosen case.
    sliding : bool
        The textbook sliding branch (friction_rule "sliding"): in the chosen case, a tangential
        row on an edge of its cone is moved to the edge opposing that row's incoming tangential
        velocity and the case solved once more (the "forced" pass); if that case pulls or
        leaves a contact approaching, no case is admissible (a jam, as for one contact).

    Returns
    -------
    float
        The chosen case's kinetic energy change per unit mass (J/kg); inf when no case is
        admissible.
    """
    jac = np.empty((MAX_ROWS, 3))
    owner = np.empty(MAX_ROWS, np.int64)
    mode = np.empty(MAX_ROWS, np.int64)  # tangential rows: 0 on target, 1 +edge, 2 -edge
    var = np.empty(MAX_ROWS, np.int64)  # row -> its unknown, -1 for none
    coef = np.empty((MAX_ROWS, MAX_ROWS))  # impulse of row r = sum_v coef[r, v] x[v]
    target = np.empty(MAX_ROWS)
    a = np.empty((MAX_ROWS, MAX_ROWS))
    x = np.empty(MAX_ROWS)
    impulse = np.empty(MAX_ROWS)
    dv = np.zeros(3)
    zero = np.zeros(3)
    u_scale = 0.0
    for i in range(2):
        _row(jac, i, contacts[i, 0], contacts[i, 1], contacts[i, 2], contacts[i, 3], False)
        target[i] = contacts[i, 4]
        u_scale = max(u_scale, abs(_velocity(jac, i, s, zero)))
    slack = ADMISSIBLE_SLACK * u_scale
    # tangential cases: on target, on the + edge, on the - edge; only the target without a cap,
    # only a zero impulse (the "+ edge" of a zero cone) without friction
    first_mode = 1 if mu == 0.0 else 0
    last_mode = 0 if math.isinf(mu) else (1 if mu == 0.0 else 2)
    n_modes = last_mode - first_mode + 1
    best_energy = math.inf
    best_mask = 0
    best_case = 0
    # One loop, one copy of the case's solve (each copy is compiled anew: cold start): the
    # enumeration, normal_mask 1 to 3, then at most one forced pass of the sliding branch.
    normal_mask = 0
    rows = 2
    n_cases = 0
    case = 0
    forced = False
    while True:
        if case >= n_cases:  # the next normal mask, or the end of the enumeration
            normal_mask += 1
            if normal_mask == 4:
                if not sliding or frictionless or math.isinf(best_energy) or mu == 0.0 or math.isinf(mu):
                    return best_energy
                # the sliding branch: the chosen case, each edge row opposing its incoming slip
                normal_mask = best_mask
                case = best_case
                forced = True
            rows = 2 if frictionless else _tangential_rows(jac, owner, contacts, normal_mask, same_surface)
            for r in range(2, rows):
                target[r] = -beta_t * _velocity(jac, r, s, zero)
            n_cases = n_modes ** (rows - 2)
            if not forced:
                case = 0
        code = case
        flipped = False
        for r in range(2, rows):
            mode[r] = first_mode + code % n_modes
            code //= n_modes
            if forced and mode[r] != 0:
                u_row = _velocity(jac, r, s, zero)
                if u_row != 0.0:
                    opposing = 2 if u_row > 0.0 else 1
                    flipped = flipped or mode[r] != opposing
                    mode[r] = opposing
        case += 1
        if forced and not flipped:
            return best_energy  # the chosen edges already oppose the slip
        m = 0
        for r in range(rows):
            var[r] = -1
            if (r < 2 and normal_mask & (1 << r)) or (r >= 2 and mode[r] == 0):
                var[r] = m
                m += 1
        for r in range(rows):
            for v in range(m):
                coef[r, v] = 0.0
            if var[r] >= 0:
                coef[r, var[r]] = 1.0
            elif r >= 2:  # on an edge: +-mu times the normal impulses it belongs to
                sign = 1.0 if mode[r] == 1 else -1.0
                for i in range(2):
                    if var[i] >= 0 and (owner[r] == -1 or owner[r] == i):
                        coef[r, var[i]] = sign * mu
        # one equation per unknown: that row's velocity reaches its target
        eq = 0
        for r in range(rows):
            if var[r] < 0:
                continue
            for v in range(m):
                acc = 0.0
                for q in range(rows):
                    if coef[q, v] != 0.0:
                        k_rq = jac[r, 0] * jac[q, 0] + jac[r, 1] * jac[q, 1] + jac[r, 2] * jac[q, 2] / inertia
                        acc += k_rq * coef[q, v]
                a[eq, v] = acc
            x[eq] = target[r] - _velocity(jac, r, s, zero)
            eq += 1
        if not _solve_in_place(a, x, m):
            if forced:
                return math.inf
            continue
        dv[0] = 0.0
        dv[1] = 0.0
        dv[2] = 0.0
        for r in range(rows):
            acc = 0.0
            for v in range(m):
                acc += coef[r, v] * x[v]
            impulse[r] = acc
            dv[0] += acc * jac[r, 0]
            dv[1] += acc * jac[r, 1]
            dv[2] += acc * jac[r, 2] / inertia
        ok = True
        for i in range(2):
            if var[i] >= 0:
                ok = ok and impulse[i] >= -slack  # pushes
            else:
                ok = ok and _velocity(jac, i, s, dv) >= target[i] - slack  # leaves on its own
        if forced:  # the sliding branch's edges are not tested against the targets
            if not ok:
                return math.inf  # a jam: the caller takes the frictionless impulse
            best_dv[0] = dv[0]
            best_dv[1] = dv[1]
            best_dv[2] = dv[2]
            return _energy_change(s, inertia, dv)
        for r in range(2, rows):
            if mode[r] == 0:
                pressing = 0.0
                for i in range(2):
                    if var[i] >= 0 and (owner[r] == -1 or owner[r] == i):
                        pressing += impulse[i]
                ok = ok and (math.isinf(mu) or abs(impulse[r]) <= mu * pressing + slack)
            elif mode[r] == 1:  # the + edge falls short of the target
                ok = ok and _velocity(jac, r, s, dv) <= target[r] + slack
            else:
                ok = ok and _velocity(jac, r, s, dv) >= target[r] - slack
        if not ok:
            continue
        energy = _energy_change(s, inertia, dv)
        if energy < best_energy:
            best_energy = energy
            best_mask = normal_mask
            best_case = case - 1
            best_dv[0] = dv[0]
            best_dv[1] = dv[1]
            best_dv[2] = dv[2]


@numba.njit(cache=True)
def _fill_contact(contacts, i, s, fpar, surf, corner, c, sn):
    """Row i of ``contacts`` for ``corner`` on ``surf``; returns its normal velocity (m/s)."""
    nx, ny, _ = surface_frame(surf, fpar[FP_WALL])
    rx, ry = corner_offset(fpar, corner, c, sn)
    rx, ry = contact_lever(fpar, rx, ry, nx, ny)  # rounded corners: the contact point
    u_n = corner_normal_velocity(s, rx, ry, nx, ny)
    beta_n = beta_normal_at(fpar, abs(u_n))
    contacts[i, 0] = nx
    contacts[i, 1] = ny
    contacts[i, 2] = rx
    contacts[i, 3] = ry
    contacts[i, 4] = -beta_n * min(u_n, 0.0)
    return u_n


@numba.njit(cache=True)
def resolve_two_contacts(s, fpar, ipar, surf_a, corner_a, surf_b, corner_b, share, counts):
    """Resolve one impact of two contacts with the config's contact model (module docstring).

    ``share`` in (0, 1]: the flat_landing effect's share of the two-contact impulse; the rest
    is the first corner's single-contact impulse (docs/physics.md, "Flat landing"). Modifies s
    (centre-of-mass state) in place. Returns False, with s untouched, when no case is
    admissible (the caller then resolves the contacts one at a time).
    """
    both = s.copy()
    if not _two_contacts(both, fpar, ipar, surf_a, corner_a, surf_b, corner_b, counts):
        return False
    if share < 1.0:
        resolve_impact(s, fpar, ipar, surf_a, corner_a, counts)
    # kinetic energy is convex in the velocity change, so the blend of two changes that do
    # not gain energy does not either; the first corner leaves in both, so in the blend
    for i in range(3, 6):
        s[i] = both[i] if share >= 1.0 else share * both[i] + (1.0 - share) * s[i]
    return True


# One call site per function below: numba links a callee's code into each caller and LLVM
# inlines it per call site, so two calls of best_impulse compiled it twice (a cold start
# 6 s longer; scripts/bench.py, cold).
@numba.njit(cache=True)
def _two_contacts(s, fpar, ipar, surf_a, corner_a, surf_b, corner_b, counts):
    """The whole two-contact impact (share 1) on s; False, s untouched, when no case is
    admissible."""
    c = math.cos(s[2])
    sn = math.sin(s[2])
    contacts = np.empty((2, 5))
    u_a = _fill_contact(contacts, 0, s, fpar, surf_a, corner_a, c, sn)
    u_b = _fill_contact(contacts, 1, s, fpar, surf_b, corner_b, c, sn)
    same_surface = surf_a == surf_b
    if ipar[IP_MODEL] == MODEL_PAPER:
        nx = contacts[0, 0]
        ny = contacts[0, 1]
        if same_surface and nx * s[3] + ny * s[4] < 0.0:
            saved3 = s[3]
            saved4 = s[4]
            saved5 = s[5]
            # the law does not depend on the corner; its beta_normal on the faster approach
            beta_n = beta_normal_at(fpar, max(abs(u_a), abs(u_b)))
            paper_law(s, fpar[FP_ALPHA], fpar[FP_R], beta_n, fpar[FP_BT], nx, ny)
            if min(
                corner_normal_velocity(s, contacts[0, 2], contacts[0, 3], nx, ny),
                corner_normal_velocity(s, contacts[1, 2], contacts[1, 3], nx, ny),
            ) >= 0.0:
                return True
            s[3] = saved3
            s[4] = saved4
            s[5] = saved5
    inertia = fpar[FP_INERTIA]
    changes = np.empty((2, 3))  # with friction, frictionless
    energies = np.empty(2)
    # friction rules (module docstring): "exact" integrates the compliant two-contact impact;
    # if that does not end, the sliding edge with the sticking target u_t' = 0
    rule = ipar[IP_FRICTION_RULE]
    if rule == FRICTION_RULE_EXACT:
        beta = np.empty(2)
        beta[0] = beta_normal_at(fpar, max(-u_a, 0.0))
        beta[1] = beta_normal_at(fpar, max(-u_b, 0.0))
        ok, clips = exact_two_contacts(s, inertia, fpar[FP_MU], ipar[IP_RESTITUTION] == RESTITUTION_ENERGETIC,
                                       contacts, beta, same_surface)
        if ok:
            counts[C_CLIPS] += clips
            if ipar[IP_MODEL] == MODEL_PAPER:
                counts[C_FALLBACK] += 1
            return True
    beta_t = 0.0 if rule == FRICTION_RULE_EXACT else fpar[FP_BT]
    sliding = rule != FRICTION_RULE_AIMED
    for k in range(2):
        energies[k] = best_impulse(s, inertia, fpar[FP_MU], beta_t, contacts, same_surface, k == 1, changes[k], sliding)
    energy = energies[0]
    dv = changes[0]
    free = changes[1]
    if math.isinf(energies[1]):
        return False
    if ipar[IP_MODEL] == MODEL_PAPER:
        counts[C_FALLBACK] += 1
    if math.isinf(energy):  # no admissible case with friction (a jam): frictionless
        dv[:] = free
    elif energy > 0.0:
        # move towards the frictionless impulse until no energy is gained:
        # dT(lam) = energy + qb lam + qa lam^2 along dv + lam (free - dv)
        d0 = free[0] - dv[0]
        d1 = free[1] - dv[1]
        d2 = free[2] - dv[2]
        qa = 0.5 * (d0 * d0 + d1 * d1 + inertia * d2 * d2)
        qb = (s[3] + dv[0]) * d0 + (s[4] + dv[1]) * d1 + inertia * (s[5] + dv[2]) * d2
        root = math.sqrt(max(qb * qb - 4.0 * qa * energy, 0.0)) - qb
        lam = min(2.0 * energy / root, 1.0) if root > 0.0 else 1.0
        dv[0] += lam * d0
        dv[1] += lam * d1
        dv[2] += lam * d2
        counts[C_CLIPS] += 1
    s[3] += dv[0]
    s[4] += dv[1]
    s[5] += dv[2]
    return True
