"""Impact laws at a corner, per unit mass (results do not depend on M).

Each surface has a normal n (into the free region) and a tangent t = (n_y, -n_x); for the
table t = +x, for the right wall t = +y, for the left wall t = -y. In that frame the paper's
law (Smith 2014, eqs 9-13) takes the same form on every surface, which is what makes the two
walls mirror images of each other (the paper's literal "replace vx by vy" is the right wall's
frame only; tests/physics/test_impact.py::test_walls_are_mirror_images caught it).

``corner_impulse`` is the impulse at the actual corner (Newton restitution on the corner's
normal velocity, a tangential target -beta_t u_t) through the 2 x 2 contact mass matrix
K = 1 + r_perp r_perp^T / I. A tangential target at an off-centre corner can create kinetic
energy (Kane's and Stronge's examples); the energy change of an impulse is exactly
dT = (u'^T K^-1 u' - u^T K^-1 u) / 2, so the law checks it and, when it is positive or the
normal impulse would pull, moves the tangential target towards the frictionless one just as
far as needed (an "energy clip").
"""

import math

import numba

from dice_sweep.physics.flight import surface_frame

IMPACT_PAPER = 0  # the paper's law was used
IMPACT_CORNER = 1  # the paper's law was undefined here: impulse at the corner


@numba.njit(cache=True)
def specific_energy(s, alpha, radius, g):
    """Mechanical energy per unit mass (J/kg) of state s, the table at y = 0."""
    return 0.5 * (s[3] * s[3] + s[4] * s[4]) + 0.5 * alpha * radius * radius * s[5] * s[5] + g * s[1]


@numba.njit(cache=True)
def corner_vector(s, n, radius, corner):
    """Vector (m) from the centre to ``corner``."""
    psi = s[2] + 2.0 * math.pi * corner / n
    return radius * math.cos(psi), radius * math.sin(psi)


@numba.njit(cache=True)
def corner_normal_velocity(s, rx, ry, nx, ny):
    """Normal velocity (m/s) of the corner at (rx, ry) from the centre."""
    return nx * (s[3] - s[5] * ry) + ny * (s[4] + s[5] * rx)


@numba.njit(cache=True)
def paper_law(s, alpha, radius, beta_n, beta_t, nx, ny):
    """Apply eqs 9, 12 and 13 in the surface frame (n, t); modifies s in place."""
    tx = ny
    ty = -nx
    v_n = nx * s[3] + ny * s[4]
    v_t = tx * s[3] + ty * s[4]
    w = s[5]
    v_n_new = -beta_n * v_n
    v_t_new = -((alpha * beta_t - 1.0) * v_t + alpha * (beta_t + 1.0) * radius * w) / (alpha + 1.0)
    w_new = -((beta_t + 1.0) * v_t - radius * w * (alpha - beta_t)) / (radius * (alpha + 1.0))
    s[3] = v_n_new * nx + v_t_new * tx
    s[4] = v_n_new * ny + v_t_new * ty
    s[5] = w_new


@numba.njit(cache=True)
def apply_impulse(s, inertia, rx, ry, p_t, p_n, nx, ny):
    """Add the impulse (p_t t + p_n n) per unit mass at the corner (rx, ry)."""
    px = p_t * ny + p_n * nx
    py = -p_t * nx + p_n * ny
    s[3] += px
    s[4] += py
    s[5] += (rx * py - ry * px) / inertia


@numba.njit(cache=True)
def corner_impulse(s, alpha, radius, beta_n, beta_t, rx, ry, nx, ny):
    """Impulse at the corner (rx, ry) with restitution targets; modifies s in place.

    Returns 1 when the tangential target had to be clipped to keep the impact from creating
    energy or pulling on the surface, else 0.
    """
    inertia = alpha * radius * radius
    tx = ny
    ty = -nx
    # r_perp = z x r: the corner velocity is v + omega r_perp
    a_t = tx * (-ry) + ty * rx
    a_n = nx * (-ry) + ny * rx
    u_t = tx * (s[3] - s[5] * ry) + ty * (s[4] + s[5] * rx)
    u_n = nx * (s[3] - s[5] * ry) + ny * (s[4] + s[5] * rx)
    det = 1.0 + radius * radius / inertia
    # inverse contact mass matrix, (t, n) components
    m_tt = (1.0 + a_n * a_n / inertia) / det
    m_tn = -a_t * a_n / inertia / det
    m_nn = (1.0 + a_t * a_t / inertia) / det
    u_n_new = -beta_n * u_n
    q_before = m_tt * u_t * u_t + 2.0 * m_tn * u_t * u_n + m_nn * u_n * u_n
    target = -beta_t * u_t
    # frictionless reference: a purely normal impulse; never gains energy, never pulls
    k_nn = 1.0 + a_n * a_n / inertia
    k_tn = a_t * a_n / inertia
    frictionless = u_t + k_tn * (u_n_new - u_n) / k_nn
    span = frictionless - target
    # energy: q(lam) = a lam^2 + b lam + c must be <= 0 (twice the energy change)
    qa = m_tt * span * span
    qb = 2.0 * span * (m_tt * target + m_tn * u_n_new)
    qc = m_tt * target * target + 2.0 * m_tn * target * u_n_new + m_nn * u_n_new * u_n_new - q_before
    lam = 0.0
    if qc > 0.0:
        disc = max(qb * qb - 4.0 * qa * qc, 0.0)
        denom = math.sqrt(disc) - qb
        lam = 2.0 * qc / denom if denom > 0.0 else 1.0
    # normal impulse must push: p_n(lam) is linear, positive at lam = 1
    p_n0 = m_tn * (target - u_t) + m_nn * (u_n_new - u_n)
    if p_n0 < 0.0:
        p_n1 = m_tn * (frictionless - u_t) + m_nn * (u_n_new - u_n)
        lam = max(lam, p_n0 / (p_n0 - p_n1))
    clipped = 0
    if lam > 0.0:
        clipped = 1
        lam = min(lam, 1.0)
    tau = target + lam * span
    p_t = m_tt * (tau - u_t) + m_tn * (u_n_new - u_n)
    p_n = m_tn * (tau - u_t) + m_nn * (u_n_new - u_n)
    apply_impulse(s, inertia, rx, ry, p_t, p_n, nx, ny)
    return clipped


@numba.njit(cache=True)
def resolve_impact(s, n, alpha, radius, beta_n, beta_t, surf, half_width, corner, counts):
    """Resolve an impact of ``corner`` on surface ``surf`` with the paper model.

    The paper's law is used when the centre approaches the surface and the law leaves the
    touching corner not approaching; otherwise the paper's case is undefined (a corner driven
    in by rotation while the centre moves away, or a law that would keep pushing the corner
    in) and the impulse at the corner is used instead. ``counts`` gets the fallback and clip
    tallies (columns 2 and 4). Returns the corner's normal velocity after the impact (m/s).
    """
    nx, ny, _ = surface_frame(surf, half_width)
    rx, ry = corner_vector(s, n, radius, corner)
    v_n = nx * s[3] + ny * s[4]
    if v_n < 0.0:
        saved3 = s[3]
        saved4 = s[4]
        saved5 = s[5]
        paper_law(s, alpha, radius, beta_n, beta_t, nx, ny)
        u_after = corner_normal_velocity(s, rx, ry, nx, ny)
        if u_after >= 0.0:
            return u_after
        s[3] = saved3
        s[4] = saved4
        s[5] = saved5
    counts[2] += 1
    counts[4] += corner_impulse(s, alpha, radius, beta_n, beta_t, rx, ry, nx, ny)
    return corner_normal_velocity(s, rx, ry, nx, ny)


@numba.njit(cache=True)
def stick_corner(s, alpha, radius, rx, ry):
    """Bring the corner (rx, ry) on the table to rest (plastic, sticking impulse).

    This is the limit of an endless run of ever smaller bounces; it only removes energy:
    dT = -u^T K^-1 u / 2.
    """
    inertia = alpha * radius * radius
    a_t = -ry
    a_n = rx
    u_t = s[3] - s[5] * ry
    u_n = s[4] + s[5] * rx
    det = 1.0 + radius * radius / inertia
    m_tt = (1.0 + a_n * a_n / inertia) / det
    m_tn = -a_t * a_n / inertia / det
    m_nn = (1.0 + a_t * a_t / inertia) / det
    p_t = -(m_tt * u_t + m_tn * u_n)
    p_n = -(m_tn * u_t + m_nn * u_n)
    apply_impulse(s, inertia, rx, ry, p_t, p_n, 0.0, 1.0)
