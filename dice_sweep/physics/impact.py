"""Impact laws at a corner, per unit mass (results do not depend on M).

Each surface has a normal n (into the free region) and a tangent t = (n_y, -n_x); for the
table t = +x, for the right wall t = +y, for the left wall t = -y. In that frame the paper's
law (Smith 2014, eqs 9-13) takes the same form on every surface, which is what makes the two
walls mirror images of each other (the paper's literal "replace vx by vy" is the right wall's
frame only; tests/physics/test_impact.py::test_walls_are_mirror_images caught it).

``corner_impulse`` is the impulse P at the actual corner r (from the centre of mass) through
the contact mass matrix K = 1 + r_perp r_perp^T / I (per unit mass): Newton restitution on the
corner's normal velocity, u_n' = -beta_n u_n, the tangential target u_t' = -beta_t u_t, and a
Coulomb cap |P_t| <= mu P_n (Stronge 2000; Brach 1991). When the target impulse leaves the
friction cone, the impulse is taken on the cone's edge on the side of the target,
P_t = sign(P_t target) mu P_n, with P_n from the normal condition. The textbook sliding branch
P_t = -sign(u_t) mu P_n disagrees with that when the normal impulse, by spinning the die, throws
the corner back: then the impulse that would stop the slip points along the incoming slip, and
-sign(u_t) makes friction push the corner along its slip for most of the impact. The pymunk
comparison (docs/validation.md) found that; Chipmunk clamps to the cone edge the same way. Such laws can create kinetic energy at an
off-centre corner (Kane's and Stronge's examples). The energy change of an impulse is exactly
dT = P . u + P^T K P / 2, so the law checks it and, when it is positive or the normal impulse
would pull, moves the impulse towards the frictionless one (a purely normal impulse meeting
the same normal condition, which never gains energy) just as far as needed: an "energy clip".
Every impulse on that segment meets the normal condition and lies inside the friction cone.

``[contact] friction_rule`` (ipar[IP_FRICTION_RULE]) picks the rule: "aimed" (the above),
"sliding" (the textbook branch P_t = -sign(u_t) mu P_n, same jam rule and clip) or "exact"
(the integrated Coulomb impact, physics/exact_impact.py, with ``[contact] restitution``).

Rounded corners (fpar[FP_CORNER_RADIUS] = r > 0): the impulse acts at the contact point, the arc
centre less r times the surface normal (:func:`contact_lever`), not at the arc centre. Its normal
velocity equals the arc centre's (omega x (-r n) is tangential), so the tests on the corner's
normal velocity (the paper law's "left approaching" among them) read the same either way; its
tangential velocity and the contact mass matrix change. The paper's law itself (lever R below
the centre) is left as it is.
"""

import math

import numba

from dice_sweep.physics.flight import corner_offset, surface_frame
from dice_sweep.physics.params import (
    FP_ALPHA,
    FP_BN,
    FP_BT,
    FP_CORNER_RADIUS,
    FP_G,
    FP_INERTIA,
    FP_KSR,
    FP_MU,
    FP_R,
    FP_WALL,
    IP_FRICTION_RULE,
    IP_MODEL,
    IP_RESTITUTION,
)
from dice_sweep.physics.exact_impact import exact_impulse
from dice_sweep.physics.layout import (
    C_CLIPS,
    C_FALLBACK,
    FRICTION_RULE_EXACT,
    FRICTION_RULE_SLIDING,
    MODEL_PAPER,
    RESTITUTION_ENERGETIC,
)


@numba.njit(cache=True)
def specific_energy(s, fpar):
    """Mechanical energy per unit mass (J/kg) of COM state s, the table at y = 0."""
    return 0.5 * (s[3] * s[3] + s[4] * s[4]) + 0.5 * fpar[FP_INERTIA] * s[5] * s[5] + fpar[FP_G] * s[1]


@numba.njit(cache=True)
def corner_vector(s, fpar, corner):
    """Vector (m) from the centre of mass to ``corner`` in state s."""
    return corner_offset(fpar, corner, math.cos(s[2]), math.sin(s[2]))


@numba.njit(cache=True)
def contact_lever(fpar, rx, ry, nx, ny):
    """Vector (m) from the centre of mass to the contact point of the corner whose arc centre is
    at (rx, ry), on a surface of normal (nx, ny): the arc centre less r n (the corner itself
    when r = 0, returned untouched so that a sharp die's arithmetic is unchanged)."""
    arc = fpar[FP_CORNER_RADIUS]
    if arc == 0.0:
        return rx, ry
    return rx - arc * nx, ry - arc * ny


@numba.njit(cache=True)
def normal_velocity(vx, vy, w, rx, ry, nx, ny):
    """Normal velocity (m/s) of the point (rx, ry) from the centre of mass, for the centre's
    velocity (vx, vy) and angular velocity w."""
    return nx * (vx - w * ry) + ny * (vy + w * rx)


@numba.njit(cache=True)
def corner_normal_velocity(s, rx, ry, nx, ny):
    """Normal velocity (m/s) of the corner at (rx, ry) from the centre of mass."""
    return normal_velocity(s[3], s[4], s[5], rx, ry, nx, ny)


@numba.njit(cache=True)
def beta_normal_at(fpar, speed):
    """beta_normal at a normal impact speed (m/s): beta_normal / (1 + k speed), the
    speed_restitution effect (k = 0: constant)."""
    return fpar[FP_BN] / (1.0 + fpar[FP_KSR] * speed)


@numba.njit(cache=True)
def paper_law(s, alpha, radius, beta_n, beta_t, nx, ny):
    """Apply eqs 9, 12 and 13 in the surface frame (n, t); modifies s in place."""
    s[3], s[4], s[5] = paper_law_velocity(s, alpha, radius, beta_n, beta_t, nx, ny)


@numba.njit(cache=True)
def paper_law_velocity(s, alpha, radius, beta_n, beta_t, nx, ny):
    """(vx, vy, omega) after eqs 9, 12 and 13 in the surface frame (n, t); s is only read."""
    tx = ny
    ty = -nx
    v_n = nx * s[3] + ny * s[4]
    v_t = tx * s[3] + ty * s[4]
    w = s[5]
    v_n_new = -beta_n * v_n
    v_t_new = -((alpha * beta_t - 1.0) * v_t + alpha * (beta_t + 1.0) * radius * w) / (alpha + 1.0)
    w_new = -((beta_t + 1.0) * v_t - radius * w * (alpha - beta_t)) / (radius * (alpha + 1.0))
    return v_n_new * nx + v_t_new * tx, v_n_new * ny + v_t_new * ty, w_new


@numba.njit(cache=True)
def apply_impulse(s, inertia, rx, ry, p_t, p_n, nx, ny):
    """Add the impulse (p_t t + p_n n) per unit mass at the corner (rx, ry)."""
    px = p_t * ny + p_n * nx
    py = -p_t * nx + p_n * ny
    s[3] += px
    s[4] += py
    s[5] += (rx * py - ry * px) / inertia


@numba.njit(cache=True)
def contact_frame(s, inertia, rx, ry, nx, ny):
    """The contact point (rx, ry) from the centre of mass in the surface frame (t = (n_y, -n_x),
    n): its tangential and normal velocity (m/s) and the contact mass matrix per unit mass,
    K = 1 + r_perp r_perp^T / I, as (u_t, u_n, K_tt, K_tn, K_nn). Every single-contact law
    starts here."""
    tx = ny
    ty = -nx
    # r_perp = z x r: the corner velocity is v + omega r_perp
    a_t = tx * (-ry) + ty * rx
    a_n = nx * (-ry) + ny * rx
    u_t = tx * (s[3] - s[5] * ry) + ty * (s[4] + s[5] * rx)
    u_n = nx * (s[3] - s[5] * ry) + ny * (s[4] + s[5] * rx)
    return u_t, u_n, 1.0 + a_t * a_t / inertia, a_t * a_n / inertia, 1.0 + a_n * a_n / inertia


@numba.njit(cache=True)
def exact_corner_impulse(s, inertia, beta_n, mu, energetic, rx, ry, nx, ny):
    """Apply the exact Coulomb impact (physics/exact_impact.py) at the corner (rx, ry) on the
    surface of normal (nx, ny) to the centre-of-mass state s, in place.

    Returns 1 when the energetic or frictionless impulse replaced one that would have gained
    energy (an energy clip), else 0.
    """
    u_t, u_n, k_tt, k_tn, k_nn = contact_frame(s, inertia, rx, ry, nx, ny)
    p_t, p_n, clipped = exact_impulse(u_t, u_n, k_tt, k_tn, k_nn, beta_n, mu, energetic)
    apply_impulse(s, inertia, rx, ry, p_t, p_n, nx, ny)
    return clipped


@numba.njit(cache=True)
def corner_impulse(s, inertia, beta_n, beta_t, mu, rx, ry, nx, ny, sliding=False):
    """Impulse at the corner (rx, ry) with restitution targets and a Coulomb cap mu.

    ``sliding``: a capped impulse takes the textbook sliding branch, the cone's edge opposing the
    incoming slip (friction_rule "sliding"), instead of the edge on the target's side ("aimed").
    Modifies s in place. Returns 1 when the impulse had to be moved towards the frictionless
    one to keep the impact from creating energy or pulling on the surface, else 0.
    """
    u_t, u_n, k_tt, k_tn, k_nn = contact_frame(s, inertia, rx, ry, nx, ny)
    det = k_tt * k_nn - k_tn * k_tn
    du_t = -(1.0 + beta_t) * u_t
    du_n = -(1.0 + beta_n) * u_n
    # restitution target
    p_t = (k_nn * du_t - k_tn * du_n) / det
    p_n = (k_tt * du_n - k_tn * du_t) / det
    # frictionless reference: purely normal, same normal condition; never gains, never pulls
    f_n = du_n / k_nn
    if not math.isinf(mu) and (p_n <= 0.0 or abs(p_t) > mu * p_n):
        # on the cone's edge, on the side of the target impulse (see the module docstring)
        side = 1.0 if p_t > 0.0 else -1.0 if p_t < 0.0 else (-1.0 if u_t > 0.0 else 1.0)
        if sliding and u_t != 0.0:  # the textbook branch: opposing the incoming slip
            side = -1.0 if u_t > 0.0 else 1.0
        denom = k_nn + side * mu * k_tn
        if denom > 0.0:
            p_n = du_n / denom
            p_t = side * mu * p_n
        else:  # no sliding impulse meets the normal condition (a jam): frictionless
            p_n = f_n
            p_t = 0.0
    d_t = -p_t
    d_n = f_n - p_n
    # twice the energy change along P(lam) = P + lam D: q(lam) = a lam^2 + b lam + c
    qa = k_tt * d_t * d_t + 2.0 * k_tn * d_t * d_n + k_nn * d_n * d_n
    qb = 2.0 * (d_t * (u_t + k_tt * p_t + k_tn * p_n) + d_n * (u_n + k_tn * p_t + k_nn * p_n))
    qc = 2.0 * (p_t * u_t + p_n * u_n) + k_tt * p_t * p_t + 2.0 * k_tn * p_t * p_n + k_nn * p_n * p_n
    lam = 0.0
    if qc > 0.0:
        disc = max(qb * qb - 4.0 * qa * qc, 0.0)
        denom = math.sqrt(disc) - qb
        lam = 2.0 * qc / denom if denom > 0.0 else 1.0
    if p_n < 0.0:
        lam = max(lam, -p_n / d_n)
    clipped = 0
    if lam > 0.0:
        clipped = 1
        lam = min(lam, 1.0)
        p_t += lam * d_t
        p_n += lam * d_n
    apply_impulse(s, inertia, rx, ry, p_t, p_n, nx, ny)
    return clipped


# inlined (numba IR): as a call with four array arguments, its reference counts made it
# 86 ns an impact against 70 inlined (a replay of fig09's impacts; issue 33)
@numba.njit(cache=True, inline="always")
def resolve_impact(s, fpar, ipar, surf, corner, counts, cos_phi=math.nan, sin_phi=0.0):
    """Resolve an impact of ``corner`` on surface ``surf`` with the config's contact model.

    Model "paper": the paper's law is used when the centre approaches the surface and the law
    leaves the touching corner not approaching; otherwise the paper's case is undefined (a
    corner driven in by rotation while the centre moves away, or a law that would keep
    pushing the corner in) and the impulse at the corner is used (counted). Model "rigid":
    always the impulse at the corner. The impulse at the corner follows ``[contact]
    friction_rule``: "aimed" and "sliding" are :func:`corner_impulse`'s two ways to meet the
    Coulomb cap, "exact" the integrated Coulomb impact of :mod:`exact_impact` (with ``[contact]
    restitution``; beta_tangential unused). beta_normal falls with the impact speed as
    beta_normal / (1 + k |u_n|) (k = 0: constant). Returns the corner's normal velocity
    after the impact (m/s). ``cos_phi`` and ``sin_phi``: those of s[2] if known (the contact
    search's; a 20-sided roll has 130 impacts), else NaN.
    """
    nx, ny, _ = surface_frame(surf, fpar[FP_WALL])
    if math.isnan(cos_phi):
        rx, ry = corner_vector(s, fpar, corner)
    else:
        rx, ry = corner_offset(fpar, corner, cos_phi, sin_phi)
    rx, ry = contact_lever(fpar, rx, ry, nx, ny)  # rounded corners: the contact point
    u_n = corner_normal_velocity(s, rx, ry, nx, ny)
    if u_n >= 0.0:
        return u_n  # touching but not approaching (e.g. a side landing flat at rest): no impact
    beta_n = beta_normal_at(fpar, abs(u_n))
    beta_t = fpar[FP_BT]
    if ipar[IP_MODEL] == MODEL_PAPER:
        if nx * s[3] + ny * s[4] < 0.0:
            # the law's outcome tested before it is written: most attempts fail (a 20-sided
            # die: 124 of 130 impacts), and then s is left as it was, with nothing to restore
            vx, vy, w = paper_law_velocity(s, fpar[FP_ALPHA], fpar[FP_R], beta_n, beta_t, nx, ny)
            u_after = normal_velocity(vx, vy, w, rx, ry, nx, ny)
            if u_after >= 0.0:
                s[3] = vx
                s[4] = vy
                s[5] = w
                return u_after
        counts[C_FALLBACK] += 1
    rule = ipar[IP_FRICTION_RULE]
    if rule == FRICTION_RULE_EXACT:
        energetic = ipar[IP_RESTITUTION] == RESTITUTION_ENERGETIC
        counts[C_CLIPS] += exact_corner_impulse(s, fpar[FP_INERTIA], beta_n, fpar[FP_MU], energetic, rx, ry, nx, ny)
    else:
        counts[C_CLIPS] += corner_impulse(s, fpar[FP_INERTIA], beta_n, beta_t, fpar[FP_MU], rx, ry, nx, ny,
                                          rule == FRICTION_RULE_SLIDING)
    return corner_normal_velocity(s, rx, ry, nx, ny)


@numba.njit(cache=True)
def stick_corner(s, inertia, rx, ry):
    """Bring the corner (rx, ry) on the table to rest (plastic, sticking impulse); with rounded
    corners (rx, ry) is the contact point (:func:`contact_lever`).

    This is the limit of an endless run of ever smaller bounces; it only removes energy:
    dT = -u^T K^-1 u / 2.
    """
    a_t = -ry
    a_n = rx
    u_t = s[3] - s[5] * ry
    u_n = s[4] + s[5] * rx
    k_tt = 1.0 + a_t * a_t / inertia
    k_tn = a_t * a_n / inertia
    k_nn = 1.0 + a_n * a_n / inertia
    det = k_tt * k_nn - k_tn * k_tn
    p_t = -(k_nn * u_t - k_tn * u_n) / det
    p_n = -(k_tt * u_n - k_tn * u_t) / det
    apply_impulse(s, inertia, rx, ry, p_t, p_n, 0.0, 1.0)


@numba.njit(cache=True)
def stop_corner_normal(s, inertia, rx, ry):
    """Stop only the normal motion of the table corner (rx, ry): the limit of a Zeno run of
    bounces under Coulomb friction, whose total normal impulse, and so the friction it can
    exert, vanishes; the corner keeps its slip. Returns the slip velocity (m/s)."""
    u_n = s[4] + s[5] * rx
    k_nn = 1.0 + rx * rx / inertia
    apply_impulse(s, inertia, rx, ry, 0.0, -u_n / k_nn, 0.0, 1.0)
    return s[3] - s[5] * ry
