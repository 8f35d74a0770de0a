"""The outcome rule: which side is below the centre of mass, and whether it is decided.

Rounded corners (fpar[FP_CORNER_RADIUS] = r > 0): the corner block holds the arc centres c_k.
Rolling over corner k lifts the centre of mass to |c_k - COM| + r at most (when it is straight
above c_k), so that is the barrier; the rays through the arc centres separate the sides (a die
on arc k tips towards the side its COM is over), so side_below reads the same block; a side
lying flat rests on both its arcs, with the COM at r above the line through their centres.
"""

import math

import numba

from dice_sweep.physics.impact import specific_energy
from dice_sweep.physics.params import CORNER_STRIDE, FP_COM_X, FP_COM_Y, FP_CORNER_RADIUS, FP_CORNERS, FP_G, FP_RHO_MAX

# E < g rho decides the side; a die balanced on a corner sits at E = g rho up to round-off,
# which must not decide it (test_balanced_on_a_corner_is_reported_not_guessed caught that).
DECISION_MARGIN = 1e-12


@numba.njit(cache=True)
def corner_geometry(fpar, corner):
    """(rho, angle) of ``corner`` seen from the centre of mass in the body frame."""
    base = FP_CORNERS + CORNER_STRIDE * corner
    return fpar[base], math.atan2(fpar[base + 2], fpar[base + 1])


@numba.njit(cache=True)
def side_below(phi, fpar, n):
    """Side crossed by the vertical ray down from the centre of mass (side k: corners k, k+1)."""
    ray = (-0.5 * math.pi - phi) % (2.0 * math.pi)  # the ray's angle in the body frame
    if fpar[FP_COM_X] == 0.0 and fpar[FP_COM_Y] == 0.0:
        return int(ray / (2.0 * math.pi / n)) % n
    _, start = corner_geometry(fpar, 0)
    for k in range(n):
        _, end = corner_geometry(fpar, (k + 1) % n)
        if (ray - start) % (2.0 * math.pi) < (end - start) % (2.0 * math.pi):
            return k
        start = end
    return n - 1


@numba.njit(cache=True)
def decision_bound(fpar):
    """Specific energy (J/kg) at or above which no side can be decided: g rho_max with the
    decision margin. Exact as a first test: min(rho_a, rho_b) <= rho_max and rounding is
    monotone, so it is never below the barrier of :func:`decided_side`. (With rounded corners
    rho_max is max rho_k + r, the largest barrier height.)"""
    return fpar[FP_G] * fpar[FP_RHO_MAX] * (1.0 - DECISION_MARGIN)


@numba.njit(cache=True)
def decided_side(s, fpar, n):
    """The side if it is decided in COM state s, else -1.

    To change the side below the centre of mass a corner of that side must pass under it,
    lifting it to that corner's distance rho from it: impossible once the energy per unit mass
    is below g min(rho_a, rho_b) (with a relative margin, so that a die balanced on a corner,
    at exactly that energy, is not decided by round-off). With rounded corners rho is the arc
    centre's distance plus r (exact: + 0.0 when r = 0).
    """
    energy = specific_energy(s, fpar)
    # Most calls come at energies above g rho_max, where no side can be decided: answer those
    # without the side (a float modulo) and its corners.
    if not energy < decision_bound(fpar):
        return -1
    k = side_below(s[2], fpar, n)
    barrier = fpar[FP_G] * barrier_height(fpar, n, k) * (1.0 - DECISION_MARGIN)
    return k if energy < barrier else -1


@numba.njit(cache=True)
def barrier_height(fpar, n, side):
    """Height (m) the centre of mass must reach to leave ``side``: over the nearer of its two
    corners, min(rho_a, rho_b), or over their arcs, plus r (exact: + 0.0 when r = 0)."""
    rho_a = fpar[FP_CORNERS + CORNER_STRIDE * side]
    rho_b = fpar[FP_CORNERS + CORNER_STRIDE * ((side + 1) % n)]
    return min(rho_a, rho_b) + fpar[FP_CORNER_RADIUS]


@numba.njit(cache=True)
def rest_height(fpar, n, side):
    """Height (m) of the centre of mass above the table when the die lies on ``side`` (with
    rounded corners its distance from the line through the two arc centres, plus r)."""
    rho_a, ang_a = corner_geometry(fpar, side)
    rho_b, ang_b = corner_geometry(fpar, (side + 1) % n)
    ax = rho_a * math.cos(ang_a)
    ay = rho_a * math.sin(ang_a)
    bx = rho_b * math.cos(ang_b)
    by = rho_b * math.sin(ang_b)
    # sqrt, not math.hypot: CPython's hypot and the compiled one differ in the last bit in about
    # 0.6 % of calls, and the plain engine must match the compiled kernel bit for bit
    # (tests/test_engine.py, a sliding die lying flat, caught it)
    dx = bx - ax
    dy = by - ay
    return abs(ax * by - ay * bx) / math.sqrt(dx * dx + dy * dy) + fpar[FP_CORNER_RADIUS]
