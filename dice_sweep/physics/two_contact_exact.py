"""The exact Coulomb impact with two contacts at once (``friction_rule = "exact"``).

With one contact the impact is Routh's integration over the normal impulse
(physics/exact_impact.py). With two, a rigid body does not say how the normal impulse is shared
between the contacts: that takes a contact model. Here each contact is a normal spring of the
same stiffness k (the compliance ratio is 1: identical corners on the same materials), as in
Stronge (*Impact Mechanics*, 2000, ch. 7) and the Darboux-Keller multi-contact models. The
configuration is frozen during the impact and gravity is left out (an impulsive impact), so the
result does not depend on k; only the ratio matters.

Contact i's normal force per unit mass, from its compression d_i (k = 1):

* loading (d_i at its largest so far, d_max): N_i = d_i;
* unloading: N_i = max(0, (d_i - d_max (1 - e^2)) / e^2), the stiffer line of Walton's
  hysteresis, so a contact gives back e^2 of the work it took (Stronge's energetic coefficient,
  e = beta_normal at the contact's incoming speed, at least ``LEAST_RESTITUTION``).

Friction is Coulomb at each contact: a tangential impulse inside the cone mu N that stops the
slip when it can, else on the cone's edge opposing the slip. Two corners on one surface share
one tangential row at their midpoint (as in multi_contact.py: the split moves neither the die nor
its spin) with the cone mu (N_a + N_b); on two surfaces each has its own row and cone (a
projected Gauss-Seidel solve of the 2 x 2 problem).

Integration: velocity Verlet in the spring time (kick, drift, kick), ``STEPS_PER_PERIOD`` steps
per period of the stiffest normal mode, until neither contact presses nor approaches, at most
``MAX_STEPS`` steps. Springs and friction are passive, so the exact solution never gains
energy; the integrator's own O(h^2) error can, and a gain is clipped (the velocity change
scaled back until the energy is the incoming one, counted as an energy clip).

When only one contact was ever compressed, the impact was that contact's alone, and its
closed-form exact impact (with ``[contact] restitution``, Newton or energetic) is used instead of
the integration, if it leaves the other contact not approaching. With both compressed,
restitution is the per-contact energetic law above whatever ``restitution`` says: a kinematic
(Newton) coefficient per contact has no meaning when the contacts exchange impulse through the
body.
"""

import math

import numba
import numpy as np

from dice_sweep.physics.impact import corner_normal_velocity, exact_corner_impulse

STEPS_PER_PERIOD = 400  # velocity error <= 3e-5 of the impact speed (tests/physics/test_two_contact_exact.py)
MAX_STEPS = 200_000  # a slow mode 500 times softer than the stiffest: give up, the caller falls back
TURN_REFINE = 32  # steps per step across a contact's turn from loading to unloading
# e below this is taken as this: a plastic contact's force would jump from 0 to d_max when it is
# pressed again, an O(h) error at every re-contact (0.4 % of the speed in a plastic landing with
# spin, test_two_contacts_agree_with_a_plain_integrator); 1e-4 of the work is then given back
LEAST_RESTITUTION = 0.01


@numba.njit(cache=True)
def _normal_force(d, d_max, e2):
    """Spring force per unit mass (k = 1) at compression ``d`` after the largest ``d_max``."""
    if d >= d_max:
        return max(d, 0.0)
    return max((d - d_max * (1.0 - e2)) / e2, 0.0)


@numba.njit(cache=True)
def _push(v, jac, row, impulse, inertia):
    """Add ``impulse`` along Jacobian row ``row`` to the velocity v = (vx, vy, omega)."""
    v[0] += jac[row, 0] * impulse
    v[1] += jac[row, 1] * impulse
    v[2] += jac[row, 2] * impulse / inertia


@numba.njit(cache=True)
def _along(v, jac, row):
    return jac[row, 0] * v[0] + jac[row, 1] * v[1] + jac[row, 2] * v[2]


@numba.njit(cache=True)
def _cap(mu, force, h):
    """Largest friction impulse mu force h; none without a normal force (mu = inf included)."""
    return mu * force * h if force > 0.0 else 0.0


@numba.njit(cache=True)
def _kick(v, jac, w_tt, n_t, force, mu, h, inertia):
    """Normal impulses ``force * h``, then the friction rows' Coulomb impulses (module docstring)."""
    for i in range(2):
        if force[i] > 0.0:
            _push(v, jac, i, force[i] * h, inertia)
    if mu == 0.0:
        return
    if n_t == 1:
        cap = _cap(mu, force[0] + force[1], h)
        if cap > 0.0:
            lam = -_along(v, jac, 2) / w_tt[0, 0]
            _push(v, jac, 2, min(max(lam, -cap), cap), inertia)
        return
    # two surfaces: projected Gauss-Seidel on the 2 x 2 tangential problem (converges: W_tt is
    # symmetric positive definite); a few sweeps reach round-off for two rows
    u0 = _along(v, jac, 2)
    u1 = _along(v, jac, 3)
    lam0 = 0.0
    lam1 = 0.0
    cap0 = _cap(mu, force[0], h)
    cap1 = _cap(mu, force[1], h)
    for _ in range(20):
        lam0 = min(max(-(u0 + w_tt[0, 1] * lam1) / w_tt[0, 0], -cap0), cap0)
        lam1 = min(max(-(u1 + w_tt[1, 0] * lam0) / w_tt[1, 1], -cap1), cap1)
    _push(v, jac, 2, lam0, inertia)
    _push(v, jac, 3, lam1, inertia)


@numba.njit(cache=True)
def compliant_two_contacts(v, inertia, mu, contacts, e, same_surface, loaded):
    """Integrate the two-contact impact (module docstring) on the velocity v, in place.

    Parameters
    ----------
    v : ndarray (3,)
        (vx, vy, omega) of the centre of mass (m/s, rad/s) before; after on return.
    inertia : float
        Moment of inertia per unit mass about the centre of mass (m^2).
    mu : float
        Coulomb friction coefficient (inf: no slip limit).
    contacts : ndarray (2, 4)
        Per contact: the surface normal (nx, ny) and the lever (rx, ry, m) from the centre of
        mass to the contact point.
    e : ndarray (2,)
        Energetic restitution coefficient of each contact.
    same_surface : bool
        Both contacts on one surface (one shared tangential row).
    loaded : ndarray (2,) of bool
        Set to whether each contact was ever compressed.

    Returns
    -------
    bool
        False when the integration did not end within ``MAX_STEPS`` (v is then undefined).
    """
    jac = np.zeros((4, 3))
    for i in range(2):
        nx = contacts[i, 0]
        ny = contacts[i, 1]
        rx = contacts[i, 2]
        ry = contacts[i, 3]
        jac[i, 0] = nx
        jac[i, 1] = ny
        jac[i, 2] = -ry * nx + rx * ny  # r_perp . n, r_perp = z x r
    n_t = 1 if same_surface else 2
    for k in range(n_t):
        i = k
        tx = contacts[i, 1]
        ty = -contacts[i, 0]
        rx = contacts[i, 2]
        ry = contacts[i, 3]
        if same_surface:  # the midpoint of the two levers
            rx = 0.5 * (contacts[0, 2] + contacts[1, 2])
            ry = 0.5 * (contacts[0, 3] + contacts[1, 3])
        jac[2 + k, 0] = tx
        jac[2 + k, 1] = ty
        jac[2 + k, 2] = -ry * tx + rx * ty
    w_tt = np.empty((2, 2))
    for a in range(n_t):
        for b in range(n_t):
            w_tt[a, b] = jac[2 + a, 0] * jac[2 + b, 0] + jac[2 + a, 1] * jac[2 + b, 1] + jac[2 + a, 2] * jac[2 + b, 2] / inertia
    # stiffest normal mode: the largest eigenvalue of the normal Delassus matrix (k = 1)
    w00 = jac[0, 0] * jac[0, 0] + jac[0, 1] * jac[0, 1] + jac[0, 2] * jac[0, 2] / inertia
    w11 = jac[1, 0] * jac[1, 0] + jac[1, 1] * jac[1, 1] + jac[1, 2] * jac[1, 2] / inertia
    w01 = jac[0, 0] * jac[1, 0] + jac[0, 1] * jac[1, 1] + jac[0, 2] * jac[1, 2] / inertia
    half_trace = 0.5 * (w00 + w11)
    stiffest = half_trace + math.sqrt(0.25 * (w00 - w11) ** 2 + w01 * w01)
    h = 2.0 * math.pi / (math.sqrt(stiffest) * STEPS_PER_PERIOD)
    d = np.zeros(2)
    d_max = np.zeros(2)
    force = np.zeros(2)
    e2 = np.empty(2)
    for i in range(2):
        e2[i] = max(e[i], LEAST_RESTITUTION) ** 2
        loaded[i] = False
    for _ in range(MAX_STEPS):
        step = h
        for i in range(2):
            force[i] = _normal_force(d[i], d_max[i], e2[i])
            # a loading contact about to turn: the force's slope jumps to 1/e^2 there, an O(h)
            # error per turn (3e-4 of the speed at e = 0.05); shorter steps across the turn
            if d[i] > 0.0 and d[i] >= d_max[i] and _along(v, jac, i) > -2.0 * force[i] * h:
                step = h / TURN_REFINE
            elif force[i] > 0.0 and d[i] < d_max[i]:  # unloading: a period e times the loading one
                step = min(step, h * max(math.sqrt(e2[i]), 1.0 / TURN_REFINE))
        _kick(v, jac, w_tt, n_t, force, mu, 0.5 * step, inertia)
        done = True
        for i in range(2):
            u_n = _along(v, jac, i)
            d[i] -= u_n * step
            if d[i] > d_max[i]:
                d_max[i] = d[i]
                loaded[i] = True
            force[i] = _normal_force(d[i], d_max[i], e2[i])
            if force[i] > 0.0 or u_n < 0.0:
                done = False
        _kick(v, jac, w_tt, n_t, force, mu, 0.5 * step, inertia)
        if done:
            return True
    return False


@numba.njit(cache=True)
def exact_two_contacts(s, inertia, mu, energetic, contacts, beta, same_surface):
    """The two-contact exact Coulomb impact (module docstring) on the state s, in place.

    ``contacts`` rows hold (nx, ny, rx, ry, ...) per contact (multi_contact's layout), ``beta``
    each contact's restitution coefficient. Returns (ok, clips): ok False, s untouched, when the
    integration did not end; clips 1 when an energy gain of the integrator was clipped or the
    one-contact impulse was.
    """
    v = np.empty(3)
    v[0] = s[3]
    v[1] = s[4]
    v[2] = s[5]
    loaded = np.zeros(2, np.bool_)
    if not compliant_two_contacts(v, inertia, mu, contacts, beta, same_surface, loaded):
        return False, 0
    if loaded[0] != loaded[1]:
        # one contact's impact: its closed form, with the config's restitution law
        i = 0 if loaded[0] else 1
        j = 1 - i
        trial = s.copy()
        clips = exact_corner_impulse(trial, inertia, beta[i], mu, energetic,
                                     contacts[i, 2], contacts[i, 3], contacts[i, 0], contacts[i, 1])
        if corner_normal_velocity(trial, contacts[j, 2], contacts[j, 3], contacts[j, 0], contacts[j, 1]) >= 0.0:
            for k in range(3, 6):
                s[k] = trial[k]
            return True, clips
    # kinetic energy per unit mass (times 2) before and after; a gain is the integrator's
    before = s[3] * s[3] + s[4] * s[4] + inertia * s[5] * s[5]
    d0 = v[0] - s[3]
    d1 = v[1] - s[4]
    d2 = v[2] - s[5]
    gain = 2.0 * (s[3] * d0 + s[4] * d1 + inertia * s[5] * d2) + d0 * d0 + d1 * d1 + inertia * d2 * d2
    clips = 0
    lam = 1.0
    if gain > 0.0 and before > 0.0:
        # the largest scale lam of the change with no gain: lam (2 b + lam q) = 0
        q = d0 * d0 + d1 * d1 + inertia * d2 * d2
        lam = min(1.0, -2.0 * (s[3] * d0 + s[4] * d1 + inertia * s[5] * d2) / q)
        lam = max(lam, 0.0)
        clips = 1
    s[3] += lam * d0
    s[4] += lam * d1
    s[5] += lam * d2
    return True, clips
