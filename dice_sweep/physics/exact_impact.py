"""The exact Coulomb impact of a rigid body at one corner (``[contact] friction_rule = "exact"``).

Routh's method as in Stronge (*Impact Mechanics*, 2000, ch. 3-4) and Brach (1991): during the
impact the contact point's velocity u = (u_t, u_n) (surface frame, per unit mass) changes with
the normal impulse p_n as

    du/dp_n = K (f, 1),

K the 2 x 2 contact mass matrix (impact.py) and f = dp_t/dp_n the friction ratio:

* sliding (u_t != 0): f = -mu sign(u_t), friction opposes the slip;
* at u_t = 0 the contact sticks, f = -K_tn / K_tt (keeps u_t = 0), when that ratio is inside the
  cone, |K_tn / K_tt| <= mu (the stick ratio); otherwise it slides on in the direction
  sign(K_tn) (slip reversal), which then accelerates and never stops again.

Compression ends where u_n = 0 (impulse p_c); restitution continues to the terminal impulse:

* Newton (kinematic): u_n final = -beta_normal u_n initial;
* energetic (Stronge): the work of the normal impulse in restitution is -beta_normal^2 times its
  work in compression (the work is int u_n dp_n).

In 2-D with one contact every phase is linear in p_n, so the impact is closed form: at most
three phases (a slide in the incoming direction, then stick or reversed slide), each advanced
exactly to its end (slip stops, compression ends, terminal impulse). beta_tangential has no role
here: the tangential outcome follows from friction and the mass matrix alone.

Why the phases cannot jam: a slide whose u_n falls (K_nn - mu s K_tn <= 0) needs
mu |K_tn| >= K_nn, and a slide that never stops needs |K_tn| >= mu K_tt; both together would give
K_tn^2 >= K_tt K_nn, impossible as K is positive definite. So a falling-u_n slide always stops,
and the phases after it raise u_n.

mu = inf: a slip is stopped at once by a tangential impulse at zero normal impulse (the limit of
the slide phase as mu grows), then the contact sticks.

Energy: the energetic law never gains energy (the friction work is never positive and the
normal work is (1 - beta_normal^2) times the compression's, which is negative). Newton's law
with friction can gain it when the restitution phase raises u_n more slowly than the
compression did (e.g. slip stopping in restitution); the energy change of the total impulse is
checked exactly and, when positive, the energetic terminal impulse is used instead (counted as
an energy clip by the caller).
"""

import math

import numba

# at most: the mu = inf tangential jump, an incoming slide, and a stick or reversed slide; two
# spare passes in case round-off leaves u_t a hair from zero at a phase end
MAX_PHASES = 6


@numba.njit(cache=True)
def _phase(u_t, k_tt, k_tn, k_nn, det, mu):
    """Slopes of the phase starting at tangential velocity ``u_t``.

    Returns (f, a_t, a_n, length): dp_t/dp_n, du_t/dp_n, du_n/dp_n and the normal impulse after
    which the phase ends by the slip stopping (inf when it does not).
    """
    if u_t == 0.0:
        if abs(k_tn) <= mu * k_tt:  # stick: friction inside the cone keeps u_t = 0
            return -k_tn / k_tt, 0.0, det / k_tt, math.inf
        side = 1.0 if k_tn > 0.0 else -1.0  # slip reversal: slides off along sign(K_tn)
        f = -mu * side
        return f, k_tt * f + k_tn, k_tn * f + k_nn, math.inf
    side = 1.0 if u_t > 0.0 else -1.0
    f = -mu * side
    a_t = k_tt * f + k_tn
    length = -u_t / a_t if a_t * side < 0.0 else math.inf  # decelerating slip: stops at length
    return f, a_t, k_tn * f + k_nn, length


@numba.njit(cache=True)
def _integrate(u_t, u_n, k_tt, k_tn, k_nn, beta_n, mu, energetic):
    """Total impulse (p_t, p_n) of the exact impact (module docstring); p_n < 0 when the
    phases do not close (not expected, see the module docstring; the caller then falls back)."""
    det = k_tt * k_nn - k_tn * k_tn
    u_n0 = u_n
    p_t = 0.0
    p_n = 0.0
    work_c = 0.0  # int u_n dp_n over the compression (<= 0)
    compressing = True
    target = -beta_n * u_n0  # Newton: final u_n
    remaining = 0.0  # energetic: restitution work still to do
    if mu == 0.0:
        # frictionless: one phase, f = 0 (u_t may change but friction does nothing)
        a_n = k_nn
        p_c = -u_n0 / a_n
        if energetic:
            # work_c = -u_n0^2 / (2 a_n); restitution work beta^2 |work_c| gives u_n = beta |u_n0|
            return 0.0, p_c * (1.0 + beta_n)
        return 0.0, (target - u_n0) / a_n
    if math.isinf(mu) and u_t != 0.0:
        # the slip is stopped at p_n = 0 (the limit mu -> inf of the incoming slide)
        jump = -u_t / k_tt
        p_t += jump
        u_n += k_tn * jump
        u_t = 0.0
        if u_n >= 0.0:  # the jump alone ended the compression (no normal work done)
            compressing = False
            if energetic or u_n >= target:
                return p_t, p_n
    for _ in range(MAX_PHASES):
        f, a_t, a_n, length = _phase(u_t, k_tt, k_tn, k_nn, det, mu)
        if compressing:
            if a_n > 0.0 and (math.isinf(length) or u_n + a_n * length >= 0.0):
                d = -u_n / a_n  # compression ends inside this phase
                work_c += 0.5 * u_n * d  # u_n linear from u_n to 0
                p_t += f * d
                p_n += d
                u_t = 0.0 if d >= length else u_t + a_t * d
                u_n = 0.0
                length -= d
                compressing = False
                remaining = -beta_n * beta_n * work_c
            else:
                if math.isinf(length):
                    return 0.0, -1.0  # u_n never turns: no closed end (see module docstring)
                work_c += length * (u_n + 0.5 * a_n * length)
                p_t += f * length
                p_n += length
                u_n += a_n * length
                u_t = 0.0
                continue
        # restitution: u_n >= 0 and rising (a_n > 0 in every phase after a stop)
        if a_n <= 0.0:
            return p_t, p_n  # nothing left that raises u_n (degenerate): end here
        if energetic:
            if remaining <= 0.0:
                return p_t, p_n
            # u_n d + a_n d^2 / 2 = remaining, the root written without cancellation
            d = 2.0 * remaining / (u_n + math.sqrt(u_n * u_n + 2.0 * a_n * remaining))
        else:
            if u_n >= target:
                return p_t, p_n
            d = (target - u_n) / a_n
        if d <= length:
            return p_t + f * d, p_n + d
        remaining -= length * (u_n + 0.5 * a_n * length)
        p_t += f * length
        p_n += length
        u_n += a_n * length
        u_t = 0.0
    return p_t, p_n


@numba.njit(cache=True)
def exact_impulse(u_t, u_n, k_tt, k_tn, k_nn, beta_n, mu, energetic):
    """The exact Coulomb impact of one contact (module docstring).

    Parameters
    ----------
    u_t, u_n : float
        Tangential and normal velocity (m/s) of the contact point before the impact; u_n < 0.
    k_tt, k_tn, k_nn : float
        Contact mass matrix per unit mass (positive definite).
    beta_n : float
        Normal restitution (Newton's or Stronge's coefficient, per ``energetic``).
    mu : float
        Coulomb friction coefficient; 0: frictionless, inf: no slip limit.
    energetic : bool
        Stronge's energetic restitution instead of Newton's.

    Returns
    -------
    p_t, p_n : float
        Tangential and normal impulse per unit mass (m/s).
    clipped : int
        1 when Newton's terminal impulse would have gained energy and the energetic one was
        used instead (or the phases did not close and the frictionless impulse was used).
    """
    clipped = 0
    # one call site of _integrate (each call site is compiled anew: cold start)
    for _ in range(2):
        p_t, p_n = _integrate(u_t, u_n, k_tt, k_tn, k_nn, beta_n, mu, energetic)
        if p_n < 0.0:  # not expected (module docstring): the frictionless impulse, never a gain
            return 0.0, -(1.0 + beta_n) * u_n / k_nn, 1
        if energetic:
            return p_t, p_n, clipped
        # energy change of the impulse, exactly: P . u + P^T K P / 2
        gain = p_t * u_t + p_n * u_n + 0.5 * (k_tt * p_t * p_t + 2.0 * k_tn * p_t * p_n + k_nn * p_n * p_n)
        if gain <= 0.0:
            return p_t, p_n, 0
        energetic = True  # Newton's impulse would gain: the energetic terminal impulse instead
        clipped = 1
    return p_t, p_n, clipped
