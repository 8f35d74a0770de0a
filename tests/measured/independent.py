"""Synthetic tracked drops of a 2-D regular n-gon plate, written independently of the kernel.

This module re-implements the die's physics from the specification (docs/physics.md and
Smith 2014, eqs 6-13 and 25) with numpy, scipy and the standard library only. It imports
nothing from ``dice_sweep``, so tracks made here can test the model-fitting and diagnosis loop
against a truth that does not share the kernel's code (or its bugs). Only the test file
compares it with the kernel.

What is simulated
-----------------
* Flight of the centre of mass (COM) under gravity, in closed form, or, when air drag or the
  Magnus force is on, by scipy's DOP853 (rtol 1e-12) for the translation while the rotation
  stays in closed form.
* Impacts of one corner with the table (y = 0), by the ``paper`` law (eqs 9-13, with the
  documented fallback for its "undefined case 1") or the ``rigid`` corner impulse (Newton
  restitution, tangential restitution, the Coulomb cap, the energy rule). Where the cap binds,
  ``friction_rule`` says where the impulse goes: "aimed" (default), on the cone edge on the
  side of the impulse aimed at the targets; "sliding", the textbook branch
  P_t = -sign(u_t) mu P_n opposing the incoming slip (the aimed side when u_t = 0); both then
  keep the energy rule. "exact" is the exact Coulomb impact (Routh's method; Stronge): the
  contact velocity integrated over the normal impulse by scipy's solve_ivp with events for
  stick (when |K_tn/K_tt| <= mu), slip reversal (otherwise), the end of compression and the
  terminal condition, with ``restitution`` "newton" (u_n' = -beta_n u_n) or "energetic"
  (restitution work = beta_n^2 times minus the compression work); beta_tangential is not used;
  a Newton impact that would gain energy takes the energetic terminal. The paper law's
  fallback uses the same rule.
  Contacts are located by conservative advancement on a lower bound of each corner's height,
  to a height of 1e-12 R, i.e. a time error far below 1e-9 s.
* ``inertia``: I about the COM is ``inertia`` times eq. 25's I about the geometric centre, less
  M |com_offset|^2; it acts in every impact law (the paper law's alpha too).
* ``corner_radius`` r (rounded corners): the die is a core polygon of circumradius
  (a - r)/cos(pi/n) (a the apothem, kept; same corner directions) plus a disk of radius r.
  Corner k touches the table when its arc centre (the core's corner k) is at height r; the
  impulse acts at the contact point directly below the arc centre. The contact search uses
  each arc centre's height less r. The paper law keeps its lever R below the centre.
* Two corners on the table at once (docs/physics.md, "Two contacts at once"): a second corner
  that approaches and would arrive within ``window`` (s, at its present normal speed) joins the
  impact. Rigid law: Newton restitution at each contact where it pushes (otherwise the contact
  must leave at least that fast), one tangential impulse at the midpoint of the pressing corners
  with the target -beta_t u_t and a cap of friction times the summed normal impulses; of the
  admissible cases the one leaving the least kinetic energy, the energy rule towards the
  frictionless one, the frictionless one on a jam. With the "sliding" rule a case's edge is
  admissible only where its target impulse leaves the cone, and only the edge opposing the
  shared tangential row's incoming velocity. Paper law: one application of eqs 9-13
  (beta_normal of the faster approach) when the centre approaches and neither corner is left
  approaching, else the rigid two-contact law. Each case is solved here as a 3 x 3 linear system
  in the impulses (P_a, P_b, P_t) (``_two_corner_impulse``).
* The ``flat_landing`` effect (``contact_time`` T): a second corner arriving a delay d after the
  first, window < d < T (d its height over its approach speed), gives the two-contact impulse
  the share 1 - d/T and the first corner's single-contact impulse the rest (the velocities are
  blended); the second corner, if it still approaches, has its own impact when it arrives.
* Effects of the project's library: quadratic air drag on the COM, a loaded die (COM offset in
  the body frame), speed-dependent normal restitution, the inertia factor, rounded corners, the
  friction rules (above). Effects outside it: spin damping (d omega/dt = -k omega) and spin
  drag (d omega/dt = -k |omega| omega, ``spin_drag`` in 1/rad) in flight, both in closed form; a
  Magnus force in flight; a table tilted by ``table_tilt`` (the track's frame is the table's:
  gravity (g sin(tilt), -g cos(tilt)), so x and y are parabolas in flight); a normal
  restitution that differs by corner (``corner_beta_normal[k]`` for impacts at corner k, in
  every law); and a compliant contact of finite duration (``compliant_time``): every contact
  is then integrated in time, a spring-dashpot in compression and a spring in restitution at
  each corner in contact, with regularised Coulomb friction (:class:`_Contact`,
  :func:`compliant_constants`), in place of the impact laws. A stochastic impact law
  (``scatter_corner``, ``scatter_flat``, ``scatter_floor``, ``scatter_power`` p): after each
  impact a Gaussian velocity jump of sd min(sqrt((sigma v (u / v)^p)^2 + (floor v)^2), u),
  v = sqrt(g R), per component of
  (vx, vy, sqrt(I/M) omega), u the touching corner's approach speed (a share
  ``scatter_tail_share`` of impacts ``scatter_tail_factor`` times wider, capped at u; the spin
  component ``scatter_spin`` times the others),
  redrawn while it gains energy or leaves the corner approaching (numpy's generator, one
  stream per drop from ``scatter_seed`` and the release state). Measurement effects: a wrong clock, a wrong length scale and an angle
  offset, then Gaussian noise, dropped frames and one-frame glitches.

What is not simulated
---------------------
Sustained contact (resting, rocking about a corner, sliding flat) is not simulated. A track
ends at an impact whose normal approach speed is below ``min_bounce_speed``, when an impulse
would leave a touching corner (either of two at a flat landing) without a rebound or drive
another touching corner into the table, or at ``duration``. There is no two-contact exact
Coulomb impact: with ``friction_rule`` "exact" a track ends (``end`` "exact_two_contacts")
at an impact a second corner joins (within the window or the flat_landing contact time), and
:func:`impact` refuses one. ``restitution`` "energetic" is defined for the exact rule only
(ValueError otherwise). Tracks therefore do **not** end
with the die at rest; they stop while it is still bouncing. Walls are not simulated.

Conventions
-----------
SI units. y is the height of the geometric centre above the table (table at y = 0). phi is the
angle of corner 0 seen from the geometric centre, counterclockwise; corner k is at
phi + 2 pi k / n. A track reports the geometric centre (where a tracker sees the die's centre
mark); the dynamics follow the COM, which for a loaded die sits at ``com_offset`` from the
centre in the body frame (corner 0 along the body's +x axis).
"""

import csv
import math
from dataclasses import dataclass

import numpy as np
from scipy.integrate import solve_ivp
from scipy.optimize import brentq

__all__ = ["Truth", "Path", "simulate_path", "simulate_track", "simulate_drops", "write_csv", "impact", "energy",
           "kinetic_energy"]

CONTACT_TOL = 1e-12  # of R: an approaching corner this close to the table touches it
SECOND_CORNER_TOL = 1e-9  # of R: another corner this close that an impact drives into the table ends the track
REBOUND_MIN = 1e-9  # m/s: a touching corner leaving slower than this is sustained contact
MAX_SEARCH_STEPS = 200_000  # conservative steps in one flight before giving up
NUMERIC_MAX_STEP = 1e-3  # s: longest conservative step when the acceleration bound is not exact
APPROACH_SPEED = 1e-9  # of sqrt(g R): a corner approaching slower than this is at rest (joins no impact)
CASE_SLACK = 1e-12  # of the fastest approach: round-off allowed in the admissibility of a two-contact case
CASE_CONDITION = 1e12  # a two-contact case whose 3 x 3 system is worse conditioned than this is skipped
MAX_CONTACT_TIME = 1e-3  # s: the documented range of the window and of the contact time
FRICTION_RULES = ("aimed", "sliding", "exact")
RESTITUTION_LAWS = ("newton", "energetic")
EXACT_RTOL = 1e-12  # solve_ivp's relative tolerance over the normal impulse (the exact rule)
EXACT_MAX_PHASES = 50  # phases (slip, stick, reversal, compression, restitution) of one exact impact
COMPLIANT_SLIP = 1e-3  # m/s: slip speed over which the compliant contact's friction reaches its Coulomb value
COMPLIANT_LIMIT = 50.0  # contact times: a compliant contact longer than this is sustained (the track ends)


@dataclass(frozen=True)
class Truth:
    """The true physics of the synthetic drops and the tracker's view of them (SI units)."""

    sides: int = 4
    circumradius: float = 0.06 / math.sqrt(2)  # m
    g: float = 9.81  # m/s^2
    contact: str = "rigid"  # "rigid" or "paper"
    beta_normal: float = 0.4
    beta_tangential: float = 0.0
    friction: float = math.inf  # Coulomb coefficient (cap of the corner impulse)
    air_drag: float = 0.0  # 1/m, a = -c |v| v on the centre of mass
    com_offset: tuple = (0.0, 0.0)  # m, body frame (corner 0 along +x)
    speed_restitution: float = 0.0  # s/m, beta_normal / (1 + k |u_n|)
    window: float = 1e-6  # s, [contact] window: contacts arriving within it are one impact
    contact_time: float = 0.0  # s, the flat_landing effect (0: off)
    inertia: float = 1.0  # I_com = inertia * eq. 25's I about the centre - M |com_offset|^2
    friction_rule: str = "aimed"  # the corner impulse's Coulomb cap: "aimed", "sliding" or "exact"
    restitution: str = "newton"  # the exact rule's restitution: "newton" or "energetic" (Stronge)
    corner_radius: float = 0.0  # m, rounded corners (the sides keep the apothem)
    # measurement effects (what the tracker reports):
    angle_offset: float = 0.0  # rad, file phi = phi + offset
    time_scale: float = 1.0  # file t = t_true * time_scale (a clock that runs wrong)
    length_scale: float = 1.0  # file x, y = true x, y * length_scale; y measured from the table
    # physics OUTSIDE the project's effect library (for "unexplained" tests):
    spin_damping: float = 0.0  # 1/s, in flight d(omega)/dt = -k omega
    magnus: float = 0.0  # 1, in flight a = k * (omega z-hat x v) = k * omega * (-vy, vx)
    spin_drag: float = 0.0  # 1/rad, in flight d(omega)/dt = -k |omega| omega (quadratic spin drag)
    table_tilt: float = 0.0  # rad, the table tilted: in its frame gravity is (g sin(tilt), -g cos(tilt))
    corner_beta_normal: tuple = ()  # per corner index k: the beta_normal of corner k's impacts (empty: beta_normal)
    compliant_time: float = 0.0  # s, a compliant contact of this duration replaces the impact laws (0: off)
    # a stochastic impact law: after each impact a Gaussian velocity jump, sd scatter_* times the
    # touching corner's approach speed per component of (vx, vy, sqrt(I/M) omega); "flat" for a
    # landing with a side within 15 deg of the table or two corners at once (see _scatter)
    scatter_corner: float = 0.0
    scatter_flat: float = 0.0
    scatter_floor: float = 0.0  # in sqrt(g R): sd = min(sqrt((scatter u)^2 + (floor sqrt(g R))^2), u), both kinds
    # the spread term's power of the approach speed: scatter sqrt(g R) (u / sqrt(g R))^power (1: scatter u)
    scatter_power: float = 1.0
    # the jump's shape: a share of impacts jumps tail_factor times wider (heavy tails), and the
    # spin component's sd is scatter_spin times the others'
    scatter_tail_share: float = 0.0
    scatter_tail_factor: float = 1.0
    scatter_spin: float = 1.0
    scatter_seed: int = 0


class _Die:
    """Geometry and inertia of the plate, per unit mass, seen from its centre of mass.

    Parameters
    ----------
    truth : Truth
        The die and its physics.
    """

    def __init__(self, truth):
        if truth.contact not in ("rigid", "paper"):
            raise ValueError(f"contact must be 'rigid' or 'paper', not {truth.contact!r}")
        n, radius = int(truth.sides), float(truth.circumradius)
        if n < 3:
            raise ValueError("a plate needs at least 3 sides")
        for name in ("window", "contact_time"):
            if not 0.0 <= getattr(truth, name) <= MAX_CONTACT_TIME:
                raise ValueError(f"{name} must lie in [0, {MAX_CONTACT_TIME}] s, not {getattr(truth, name)!r}")
        self.n, self.radius = n, radius
        # Smith 2014 eq 25: I = M R^2 (sin^2(pi/n)/6 + cos^2(pi/n)/2) about the geometric centre
        alpha_centre = math.sin(math.pi / n) ** 2 / 6.0 + math.cos(math.pi / n) ** 2 / 2.0
        self.d = np.array(truth.com_offset, dtype=float)
        apothem = radius * math.cos(math.pi / n)
        if np.hypot(*self.d) >= apothem:
            raise ValueError("com_offset must lie inside the inscribed circle")
        if truth.friction_rule not in FRICTION_RULES:
            raise ValueError(f"friction_rule must be one of {FRICTION_RULES}, not {truth.friction_rule!r}")
        if truth.restitution not in RESTITUTION_LAWS:
            raise ValueError(f"restitution must be one of {RESTITUTION_LAWS}, not {truth.restitution!r}")
        if truth.restitution != "newton" and truth.friction_rule != "exact":
            raise ValueError("restitution 'energetic' is defined for friction_rule 'exact' only")
        factor = float(truth.inertia)
        if not (factor > 0.0 and factor * alpha_centre <= 1.0 + 1e-12):
            raise ValueError(f"inertia must lie in (0, {1.0 / alpha_centre:.6g}] (all mass at the corners), not {truth.inertia!r}")
        self.r_corner = float(truth.corner_radius)
        if not 0.0 <= self.r_corner < apothem:
            raise ValueError(f"corner_radius must lie in [0, {apothem!r}) m (below the apothem), not {truth.corner_radius!r}")
        # parallel-axis rule: I_com = inertia * I - M |d|^2 (per unit mass, m^2)
        self.inertia = factor * alpha_centre * radius**2 - float(self.d @ self.d)
        if not self.inertia > 0.0:
            raise ValueError("the moment of inertia about the centre of mass must be positive")
        self.alpha = self.inertia / radius**2  # I_com / (M R^2), the paper law's alpha
        # rounded corners: the die is a core polygon of circumradius (a - r) / cos(pi/n), same
        # corner directions, plus a disk of radius r; corner k's arc centre is the core's corner
        # k (with r = 0 the core is the die itself, taken as R exactly)
        core = radius if self.r_corner == 0.0 else (apothem - self.r_corner) / math.cos(math.pi / n)
        self.core_radius = core
        body = core * np.column_stack([np.cos(2 * np.pi * np.arange(n) / n), np.sin(2 * np.pi * np.arange(n) / n)])
        body = body - self.d  # arc centres (the corners when r = 0) seen from the COM, body frame
        self.rho = np.hypot(body[:, 0], body[:, 1])  # m, distance of each arc centre (corner) from the COM
        self.gamma = np.arctan2(body[:, 1], body[:, 0])  # rad, its body angle
        self.rule = truth.friction_rule
        self.restitution = truth.restitution
        if truth.spin_drag < 0.0 or truth.spin_damping < 0.0 or not math.isfinite(truth.spin_drag):
            raise ValueError("spin_drag and spin_damping must be >= 0")
        if truth.spin_drag != 0.0 and truth.spin_damping != 0.0:
            raise ValueError("spin_drag and spin_damping cannot both act (one closed form each)")
        if not abs(truth.table_tilt) < 0.5 * math.pi:
            raise ValueError(f"table_tilt must lie in (-pi/2, pi/2) rad, not {truth.table_tilt!r}")
        betas = tuple(truth.corner_beta_normal)
        if betas and (len(betas) != n or not all(0.0 <= float(b) <= 1.0 for b in betas)):
            raise ValueError(f"corner_beta_normal must hold {n} values in [0, 1] (one per corner), not {truth.corner_beta_normal!r}")
        if not 0.0 <= truth.compliant_time <= MAX_CONTACT_TIME:
            raise ValueError(f"compliant_time must lie in [0, {MAX_CONTACT_TIME}] s, not {truth.compliant_time!r}")
        if truth.compliant_time > 0.0:
            if not math.isfinite(truth.friction):
                raise ValueError("the compliant contact needs a finite friction coefficient")
            if truth.contact_time > 0.0 or truth.friction_rule == "exact":
                raise ValueError("the compliant contact replaces the impact laws: no contact_time, no friction_rule 'exact'")

    def offset(self, phi):
        """The COM seen from the geometric centre in the world frame at angle ``phi`` (m)."""
        c, s = math.cos(phi), math.sin(phi)
        return np.array([c * self.d[0] - s * self.d[1], s * self.d[0] + c * self.d[1]])

    def to_com(self, centre_state):
        """(x, y, phi, vx, vy, omega) of the geometric centre -> the same of the COM."""
        x, y, phi, vx, vy, w = (float(v) for v in centre_state)
        ox, oy = self.offset(phi)
        return np.array([x + ox, y + oy, phi, vx - w * oy, vy + w * ox, w])

    def to_centre(self, com_state):
        """(x, y, phi, vx, vy, omega) of the COM -> the same of the geometric centre."""
        x, y, phi, vx, vy, w = (float(v) for v in com_state)
        ox, oy = self.offset(phi)
        return np.array([x - ox, y - oy, phi, vx + w * oy, vy - w * ox, w])

    def corners(self, com_state):
        """Each corner's table contact point relative to the COM, (n, 2) in m, for a COM state:
        the corner itself, or with rounded corners the point of its arc directly below the arc
        centre (where the arc touches the table; impacts act there)."""
        ang = com_state[2] + self.gamma
        points = self.rho[:, None] * np.column_stack([np.cos(ang), np.sin(ang)])
        points[:, 1] -= self.r_corner
        return points

    def heights(self, com_state):
        """Height of each corner's lowest point above the table (m): its arc centre's height
        less the corner radius."""
        return com_state[1] + self.rho * np.sin(com_state[2] + self.gamma) - self.r_corner

    def normal_speeds(self, com_state):
        """d height / dt of each corner (m/s): the normal velocity of its contact point."""
        return com_state[4] + self.rho * com_state[5] * np.cos(com_state[2] + self.gamma)


def energy(truth, com_state):
    """Specific mechanical energy (J/kg) of a COM state: translation, rotation about the COM,
    and the potential of gravity (the height of the COM; on a tilted table, minus g sin(tilt) x
    as well).

    Parameters
    ----------
    truth : Truth
    com_state : array_like
        (x, y, phi, vx, vy, omega) of the centre of mass.
    """
    die = _Die(truth)
    x, y, _, vx, vy, w = com_state
    tilt = truth.table_tilt  # gravity (g sin(tilt), -g cos(tilt)) in the table's frame
    return 0.5 * (vx * vx + vy * vy) + 0.5 * die.inertia * w * w + truth.g * (math.cos(tilt) * y - math.sin(tilt) * x)


def kinetic_energy(truth, com_state):
    """Specific kinetic energy (J/kg) of a COM state: translation and rotation about the COM."""
    die = _Die(truth)
    return 0.5 * (com_state[3] ** 2 + com_state[4] ** 2) + 0.5 * die.inertia * com_state[5] ** 2


# ----------------------------------------------------------------------------------- flight


class _Flight:
    """Free flight of the COM from time ``t0`` and COM state ``s0`` up to ``t_stop``.

    Gravity is (g sin(tilt), -g cos(tilt)) in the table's frame (``table_tilt``; (0, -g) on a
    level table). Without drag or Magnus force the translation is Smith's closed form
    (eqs 6-8, with that gravity). Otherwise it is integrated by DOP853 with dense output. The
    rotation is in closed form either way: omega = omega0 exp(-k t) with spin damping,
    omega = omega0 / (1 + k |omega0| t) and phi = phi0 + sign(omega0) ln(1 + k |omega0| t) / k
    with spin drag (d omega/dt = -k |omega| omega).
    """

    def __init__(self, truth, t0, s0, t_stop):
        self.truth = truth
        self.t0 = float(t0)
        self.s0 = np.array(s0, dtype=float)
        self.k_spin = float(truth.spin_damping)
        self.k_drag = float(truth.spin_drag)
        self.gravity = (float(truth.g) * math.sin(truth.table_tilt), -float(truth.g) * math.cos(truth.table_tilt))
        self.numeric = truth.air_drag != 0.0 or truth.magnus != 0.0
        self.sol = None
        if self.numeric and t_stop > self.t0:
            c, km = float(truth.air_drag), float(truth.magnus)
            ax, ay = self.gravity

            def rhs(tau, u):
                vx, vy = u[2], u[3]
                w = self.rotation(tau)[1]
                sp = math.hypot(vx, vy)
                return [vx, vy, ax - c * sp * vx - km * w * vy, ay - c * sp * vy + km * w * vx]

            u0 = [self.s0[0], self.s0[1], self.s0[3], self.s0[4]]
            self.sol = solve_ivp(rhs, (0.0, t_stop - self.t0), u0, method="DOP853", rtol=1e-12,
                                 atol=1e-15, dense_output=True)
            if not self.sol.success:
                raise RuntimeError(f"flight integration failed: {self.sol.message}")

    def rotation(self, tau):
        """(phi, omega, d omega/dt) at ``tau`` s after the start of the flight."""
        phi0, w0, k = self.s0[2], self.s0[5], self.k_spin
        if self.k_drag != 0.0:
            q = self.k_drag * abs(w0)  # 1/s: the spin's initial decay rate
            w = w0 / (1.0 + q * tau)
            return phi0 + math.copysign(1.0, w0) * math.log1p(q * tau) / self.k_drag, w, -self.k_drag * abs(w) * w
        if k == 0.0:
            return phi0 + w0 * tau, w0, 0.0
        # expm1 keeps (1 - exp(-k tau))/k exact for small k tau
        return phi0 - w0 * math.expm1(-k * tau) / k, w0 * math.exp(-k * tau), -k * w0 * math.exp(-k * tau)

    def state(self, t):
        """COM state (x, y, phi, vx, vy, omega) at absolute time ``t``."""
        tau = t - self.t0
        phi, w, _ = self.rotation(tau)
        if self.sol is None:
            x0, y0, _, vx0, vy0, _ = self.s0
            ax, ay = self.gravity
            return np.array([x0 + vx0 * tau + 0.5 * ax * tau * tau, y0 + vy0 * tau + 0.5 * ay * tau * tau, phi,
                             vx0 + ax * tau, vy0 + ay * tau, w])
        x, y, vx, vy = self.sol.sol(tau)
        return np.array([x, y, phi, vx, vy, w])

    def accel_bound(self, s, h):
        """Upper bound of |a_y| of the COM over the next ``h`` s from COM state ``s`` (m/s^2).

        Without drag and Magnus force it is g (exactly on a level table; g cos(tilt) is less). With
        them |v| can grow by at most g h
        (drag only slows, the Magnus force is perpendicular to v) and |omega| only decays.
        """
        g = self.truth.g
        if not self.numeric:
            return g
        vmax = math.hypot(s[3], s[4]) + g * h
        return g + self.truth.air_drag * vmax * vmax + abs(self.truth.magnus * s[5]) * vmax


def _next_contact(die, flight, t_start, t_stop):
    """First time in [t_start, t_stop] at which an approaching corner reaches the table.

    Conservative advancement: corner k's height obeys h(t + s) >= h + h' s - M2 s^2 / 2 with
    M2 = max |a_y| + rho_k (omega^2 + |omega'|), so stepping to the first root of that lower
    bound can never pass a contact, and near one it is a Newton step from the safe side
    (quadratic convergence).

    Returns
    -------
    (t, k, reason)
        ``k`` the touching corner, or ``None`` with ``reason`` "duration" (no contact before
        ``t_stop``) or "stalled" (the search did not converge).
    """
    tol = CONTACT_TOL * die.radius
    t = t_start
    for _ in range(MAX_SEARCH_STEPS):
        s = flight.state(t)
        phi, w = s[2], s[5]
        _, _, dw = flight.rotation(t - flight.t0)
        height = die.heights(s)  # lowest arc centre height - r: a lower bound's margin is the same
        speed = die.normal_speeds(s)  # d height / dt
        touching = (height <= tol) & (speed < 0.0)
        if touching.any():
            cand = np.flatnonzero(touching)
            return t, int(cand[np.argmin(height[cand])]), "contact"
        if t >= t_stop:
            return None, None, "duration"
        h_cap = t_stop - t if not flight.numeric else min(t_stop - t, NUMERIC_MAX_STEP)
        m2 = flight.accel_bound(s, h_cap) + die.rho * (w * w + abs(dw))
        gap = np.maximum(height, 0.0)
        steps = (speed + np.sqrt(speed * speed + 2.0 * m2 * gap)) / m2
        h = min(float(steps.min()), h_cap)
        if h <= 1e-15 * max(1.0, t):
            return t, None, "stalled"
        t = min(t + h, t_stop)
    return t, None, "stalled"


# ----------------------------------------------------------------------------------- impacts


def _contact_matrix(die, r):
    """K = 1 + r_perp r_perp^T / I (per unit mass) of a contact at ``r`` from the COM, rows and
    columns (tangential +x, normal +y): the contact velocity changes by K P."""
    inv_i = 1.0 / die.inertia
    # r_perp = z x r = (-r_y, r_x); the table's tangent is +x, its normal +y
    return np.array([[1.0 + r[1] * r[1] * inv_i, -r[0] * r[1] * inv_i],
                     [-r[0] * r[1] * inv_i, 1.0 + r[0] * r[0] * inv_i]])


def _corner_impulse(die, r, u, beta_n, beta_t, mu):
    """Impulse per unit mass (P_t, P_n) at corner offset ``r`` (from the COM) on the table.

    Newton restitution u_n' = -beta_n u_n, tangential target u_t' = -beta_t u_t, through the
    contact mass matrix K = 1 + r_perp r_perp^T / I; when the target impulse leaves the
    Coulomb cone, the die's ``friction_rule`` says where the capped impulse lies: "aimed", on
    the cone edge on the target's side; "sliding", on the edge opposing the incoming slip,
    P_t = -sign(u_t) mu P_n (the target's side when u_t = 0); a jam (the edge cannot meet the
    normal condition) takes the frictionless impulse. The energy rule then moves it along the
    segment towards the frictionless impulse only as far as needed. "exact" is the exact
    Coulomb impact instead (:func:`_exact_impulse`).

    Returns
    -------
    P : ndarray, shape (2,)
        (P_t, P_n), N s / kg.
    info : dict
        ``capped``, ``clipped`` (energy rule used), ``dT`` (J/kg); for the exact rule also
        ``stick``, ``reversal``, ``jam`` and ``energetic_terminal`` (see :func:`_exact_impulse`).
    """
    K = _contact_matrix(die, r)
    if die.rule == "exact":
        return _exact_corner_impulse(K, u, beta_n, mu, die.restitution)
    target = np.array([-beta_t * u[0], -beta_n * u[1]])
    P = np.linalg.solve(K, target - u)
    frictionless = np.array([0.0, -(1.0 + beta_n) * u[1] / K[1, 1]])
    capped = False
    if math.isfinite(mu) and abs(P[0]) > mu * P[1]:
        capped = True
        sgn = math.copysign(1.0, P[0])
        if die.rule == "sliding" and u[0] != 0.0:
            sgn = -math.copysign(1.0, u[0])  # the textbook branch: opposing the incoming slip
        denom = K[1, 1] + sgn * mu * K[0, 1]
        if denom > 0.0:
            pn = -(1.0 + beta_n) * u[1] / denom
            P = np.array([sgn * mu * pn, pn])
        else:
            # a jam, as the doc specifies. Unreachable for the aimed rule: the target meets the
            # normal condition L(P) > 0 outside the cone on side sgn, and L is linear, so L of
            # the edge direction, which is this denominator, is then positive as well. The
            # sliding rule's edge can jam (friction large against the lever).
            P = frictionless.copy()

    def d_energy(p):
        return float(p @ u + 0.5 * p @ K @ p)

    dT = d_energy(P)
    clipped = False
    if dT > 0.0 or P[1] < 0.0:
        clipped = True
        D = frictionless - P
        lam = 0.0
        if dT > 0.0:
            # dT(lam) = dT + b lam + a lam^2 is convex with dT(1) <= 0: take its lower root
            a = 0.5 * float(D @ K @ D)
            b = float(D @ u + D @ K @ P)
            disc = max(b * b - 4.0 * a * dT, 0.0)
            q = 0.5 * (-b + math.sqrt(disc))  # b < 0 here, so q > 0 and the lower root is dT / q
            lam = dT / q if q > 0.0 else 1.0
        if P[1] < 0.0:
            lam = max(lam, -P[1] / D[1])
        lam = min(max(lam, 0.0), 1.0)
        P = P + lam * D
        dT = d_energy(P)
    return P, {"capped": capped, "clipped": clipped, "dT": dT}


def _exact_impulse(K, u, beta_n, mu, restitution, *, terminal=None):
    """The exact Coulomb impact of one contact (Routh's method; Stronge, *Impact Mechanics*):
    impulse per unit mass (P_t, P_n) and info.

    The contact velocity u = (u_t, u_n) is integrated over the normal impulse p by scipy's
    solve_ivp with events: du/dp = K (f, 1), dP_t/dp = f, with f = -mu sign(u_t) while the
    contact slides. When u_t reaches 0 the contact sticks if |K_tn / K_tt| <= mu (then
    f = -K_tn / K_tt keeps u_t = 0), else the slip reverses (to the side sign(K_tn), the only
    one whose own friction keeps it going). The work of the normal force W = int u_n dp is
    integrated alongside. Compression ends at u_n = 0 (work W_c); the impact ends at
    u_n = -beta_n u_n(0) ("newton") or when the restitution phase's work is beta_n^2 (-W_c)
    ("energetic"). A Newton impact that would gain energy takes the energetic terminal
    instead. With friction inf the slip is stopped at zero normal impulse (the limit of large
    mu) and the contact sticks. A phase that never reached its next event would be a jam (the
    frictionless impulse is then used), but with K positive definite none exists: a slip that
    slows reaches u_t = 0, and one that speeds up needs |K_tn| > mu K_tt, where
    K_nn - mu sign(u_t) K_tn > 0 and the normal velocity grows (a guard only).

    Parameters
    ----------
    K : ndarray (2, 2)
        Contact matrix (tangential, normal) per unit mass.
    u : ndarray (2,)
        (u_t, u_n) before the impact, u_n < 0 (m/s).
    terminal : str or None
        Overrides ``restitution`` (used for the energy rule).
    """
    u = np.asarray(u, dtype=float)
    law = terminal or restitution
    un0 = float(u[1])
    frictionless = np.array([0.0, -(1.0 + beta_n) * un0 / K[1, 1]])
    info = {"capped": False, "clipped": False, "stick": False, "reversal": False, "jam": False,
            "energetic_terminal": law == "energetic" and restitution == "newton"}

    def finish(P):
        info["dT"] = float(P @ u + 0.5 * P @ K @ P)
        return P, info

    if un0 >= 0.0:
        return finish(np.zeros(2))
    ktt, ktn, knn = float(K[0, 0]), float(K[0, 1]), float(K[1, 1])
    if mu == 0.0:
        sticks = False
    else:
        sticks = abs(ktn) <= mu * ktt if math.isfinite(mu) else True
    y = np.array([u[0], u[1], 0.0, 0.0])  # u_t, u_n, P_t, W
    p = 0.0
    if not math.isfinite(mu) and y[0] != 0.0:
        # the limit mu -> inf: the slip is stopped at once, at zero normal impulse
        jump = -y[0] / ktt
        y[:3] += [ktt * jump, ktn * jump, jump]
        y[0] = 0.0
        info["stick"] = True
    if y[0] != 0.0:
        mode = math.copysign(1.0, y[0])
    elif sticks:
        mode, info["stick"] = 0.0, True
    else:
        mode = math.copysign(1.0, ktn) if ktn != 0.0 else 1.0
    compressed, work_c = False, None
    scale = (abs(u[0]) + abs(un0)) / min(np.linalg.eigvalsh(K))  # an impulse of the impact's size
    for _ in range(EXACT_MAX_PHASES):
        if not compressed and y[1] >= 0.0:
            compressed, work_c = True, float(y[3])
        if compressed:
            if law == "newton" and y[1] >= -beta_n * un0:
                return finish(np.array([y[2], p]))
            if law == "energetic" and y[3] - (1.0 - beta_n**2) * work_c >= 0.0:
                return finish(np.array([y[2], p]))
        f = -mu * mode if mode != 0.0 else -ktn / ktt
        if mode != 0.0 and mu > 0.0:
            info["capped"] = True  # friction at its cap (sliding) for part of the impact
        rate = np.array([ktt * f + ktn, ktn * f + knn, f])

        def rhs(_, z, rate=rate):
            return [rate[0], rate[1], rate[2], z[1]]

        events = []
        if mode != 0.0:
            def slip(_, z):
                return z[0]
            slip.terminal, slip.direction = True, -mode
            events.append(("slip", slip))
        if not compressed:
            def compression(_, z):
                return z[1]
            compression.terminal, compression.direction = True, 1.0
            events.append(("compression", compression))
        else:
            def end(_, z):
                return z[1] + beta_n * un0 if law == "newton" else z[3] - (1.0 - beta_n**2) * work_c
            end.terminal, end.direction = True, 1.0
            events.append(("end", end))
        span, hit = 4.0 * scale, None
        for _ in range(60):
            sol = solve_ivp(rhs, (p, p + span), y, method="DOP853", rtol=EXACT_RTOL, atol=1e-15 * scale,
                            events=[e for _, e in events])
            if not sol.success:
                raise RuntimeError(f"exact impact integration failed: {sol.message}")
            found = [(float(te[0]), name, ye[0]) for (name, _), te, ye in zip(events, sol.t_events, sol.y_events) if te.size]
            if found:
                hit = min(found, key=lambda h: h[0])
                break
            p, y = float(sol.t[-1]), sol.y[:, -1].copy()
            span *= 2.0
        if hit is None:  # the phase never ends: a jam
            info.update(jam=True, capped=False, stick=False, reversal=False)
            return finish(frictionless)
        p, name, y = hit[0], hit[1], np.array(hit[2], dtype=float)
        if name == "slip":
            y[0] = 0.0
            if sticks:
                mode, info["stick"] = 0.0, True
            else:
                mode, info["reversal"] = math.copysign(1.0, ktn), True
        elif name == "compression":
            y[1] = 0.0
            compressed, work_c = True, float(y[3])
        else:
            return finish(np.array([y[2], p]))
    raise RuntimeError("exact impact: too many phases")


def _exact_corner_impulse(K, u, beta_n, mu, restitution):
    """:func:`_exact_impulse` with the energy rule: a Newton impact that would gain energy
    takes the energetic terminal instead (``clipped``)."""
    P, info = _exact_impulse(K, u, beta_n, mu, restitution)
    if restitution == "newton" and info["dT"] > 0.0:
        P, info = _exact_impulse(K, u, beta_n, mu, restitution, terminal="energetic")
        info["clipped"] = True
    return P, info


def _kinetic(die, q):
    """Specific kinetic energy (J/kg) of the velocities q = (vx, vy, omega) of the COM."""
    return 0.5 * (q[0] * q[0] + q[1] * q[1] + die.inertia * q[2] * q[2])


def _two_corner_impulse(die, q, ra, rb, targets, beta_t, mu, frictionless=False):
    """The rigid two-contact law on the table for corners at ``ra`` and ``rb`` (from the COM).

    Unknowns: the normal impulses P_a, P_b and one tangential impulse P_t (per unit mass) at
    the midpoint of the pressing corners. A case fixes, per corner, "pushes" (its normal
    velocity after equals its Newton target) or "no impulse" (P = 0), and for P_t "on its
    target" (u_t' = -beta_t u_t at the midpoint), "+ edge" (P_t = +mu (P_a + P_b)) or "- edge"
    (P_t = -mu (P_a + P_b)): three linear equations in (P_a, P_b, P_t). A case is admissible
    when its normal impulses push, a contact without impulse leaves at least as fast as its
    target, a tangential impulse on target lies in the cone, and an edge impulse falls short of
    its target (friction rule "aimed"). With the rule "sliding" an edge is taken only where
    the case's target impulse lies outside the cone, and only the edge opposing the row's
    incoming tangential velocity (both edges, as aimed, if that velocity is 0). The admissible
    case leaving the least kinetic energy is returned.

    Parameters
    ----------
    q : ndarray (3,)
        (vx, vy, omega) of the COM before.
    targets : (float, float)
        Newton targets -beta_n u_n of the two corners (m/s).
    frictionless : bool
        No tangential impulse at all.

    Returns
    -------
    (dq, info) or (None, None)
        The velocity change of the chosen case and ``{"case": (on_a, on_b, mode), "P": ...}``;
        None when no case is admissible.
    """
    inv_i = 1.0 / die.inertia
    corners = (np.asarray(ra, float), np.asarray(rb, float))

    def velocity_map(rx, ry, tangential):
        # velocity along +x (tangential) or +y (normal) of the point (rx, ry): row . (vx, vy, w)
        return np.array([1.0, 0.0, -ry]) if tangential else np.array([0.0, 1.0, rx])

    normal_rows = [velocity_map(r[0], r[1], False) for r in corners]
    u_before = np.array([row @ q for row in normal_rows])
    slack = CASE_SLACK * max(abs(u_before).max(), 1e-300)
    if frictionless or mu == 0.0:
        modes = ("none",)
    elif math.isinf(mu):
        modes = ("target",)
    else:
        modes = ("target", "+edge", "-edge")
    best = (math.inf, None, None)
    for on in ((True, True), (True, False), (False, True)):
        pressing = [r for r, flag in zip(corners, on) if flag]
        mid = sum(pressing) / len(pressing)
        t_row = velocity_map(mid[0], mid[1], True)
        t_target = -beta_t * float(t_row @ q)
        u_t_in = float(t_row @ q)
        # the sliding rule: an edge only where the target lies outside the cone, on the side
        # opposing the row's incoming tangential velocity (both sides, as aimed, when it is 0)
        sliding = die.rule == "sliding" and u_t_in != 0.0
        target_outside = True
        # impulse -> velocity change: dq = W (P_a n_a + P_b n_b + P_t t), W = diag(1, 1, 1/I)
        gen = np.column_stack([normal_rows[0], normal_rows[1], t_row]) * np.array([[1.0], [1.0], [inv_i]])
        for mode in modes:
            A = np.zeros((3, 3))
            b = np.zeros(3)
            for i in range(2):
                if on[i]:
                    A[i] = normal_rows[i] @ gen
                    b[i] = targets[i] - u_before[i]
                else:
                    A[i, i] = 1.0
            if mode == "target":
                A[2] = t_row @ gen
                b[2] = t_target - float(t_row @ q)
            else:
                sign = {"+edge": 1.0, "-edge": -1.0, "none": 0.0}[mode]
                A[2] = [-sign * mu * on[0], -sign * mu * on[1], 1.0] if mode != "none" else [0.0, 0.0, 1.0]
            if sliding and mode.endswith("edge") and (not target_outside or (mode == "+edge") != (u_t_in < 0.0)):
                continue
            if np.linalg.cond(A) > CASE_CONDITION:
                continue
            P = np.linalg.solve(A, b)
            if mode == "target":
                target_outside = not (math.isinf(mu) or abs(P[2]) <= mu * (P[0] + P[1]) + slack)
            dq = gen @ P
            after = q + dq
            ok = True
            for i in range(2):
                if on[i]:
                    ok &= P[i] >= -slack
                else:
                    ok &= float(normal_rows[i] @ after) >= targets[i] - slack
            u_t = float(t_row @ after)
            if mode == "target":
                ok &= math.isinf(mu) or abs(P[2]) <= mu * (P[0] + P[1]) + slack
            elif mode == "+edge" and not sliding:
                ok &= u_t <= t_target + slack
            elif mode == "-edge" and not sliding:
                ok &= u_t >= t_target - slack
            if not ok:
                continue
            left = _kinetic(die, after)
            if left < best[0]:
                best = (left, dq, {"case": (on[0], on[1], mode), "P": P})
    return best[1], best[2]


def _two_corner_rigid(die, q, ra, rb, targets, beta_t, mu):
    """The rigid two-contact velocity change with the energy rule (frictionless on a jam).

    Returns (dq, info) with ``capped`` (an edge case), ``clipped`` (energy rule), ``jam``;
    (None, None) if even the frictionless case has no admissible solution.
    """
    free, _ = _two_corner_impulse(die, q, ra, rb, targets, beta_t, mu, frictionless=True)
    if free is None:
        return None, None
    dq, info = _two_corner_impulse(die, q, ra, rb, targets, beta_t, mu)
    jam = dq is None
    if jam:
        dq, info = free, {"case": "frictionless"}
    gain = lambda lam: _kinetic(die, q + dq + lam * (free - dq)) - _kinetic(die, q)  # noqa: E731
    clipped = bool(gain(0.0) > 0.0)
    if clipped:
        # the gain is convex along the segment and not positive at the frictionless end:
        # move only as far as needed (its one root in [0, 1])
        lam = 1.0 if gain(1.0) >= 0.0 else brentq(gain, 0.0, 1.0, xtol=1e-16, rtol=4 * np.finfo(float).eps)
        dq = dq + lam * (free - dq)
    info.update(capped=isinstance(info["case"], tuple) and info["case"][2].endswith("edge"), clipped=clipped, jam=jam)
    return dq, info


def _two_corner_impact(truth, die, s, k, j):
    """The whole two-contact impact of corners ``k`` and ``j`` on a COM state; (new, info) or
    (None, None) when no case is admissible."""
    corners = die.corners(s)
    ra, rb = corners[k], corners[j]
    q = s[3:].copy()
    u_n = np.array([q[1] + q[2] * ra[0], q[1] + q[2] * rb[0]])
    betas = np.array([_corner_beta(truth, k), _corner_beta(truth, j)]) / (1.0 + truth.speed_restitution * np.abs(u_n))
    beta_t = truth.beta_tangential
    info = {"u_n": float(u_n[0]), "u_n_second": float(u_n[1]), "capped": False, "clipped": False}
    if truth.contact == "paper" and q[1] < 0.0:
        # one application of eqs 9, 12, 13: the law does not depend on the corner
        faster = (k, j)[int(np.argmax(np.abs(u_n)))]
        beta_n = _corner_beta(truth, faster) / (1.0 + truth.speed_restitution * float(np.abs(u_n).max()))
        a, R = die.alpha, die.radius
        vx, vy, w = q
        q2 = np.array([-((a * beta_t - 1.0) * vx + a * (beta_t + 1.0) * R * w) / (a + 1.0), -beta_n * vy,
                       -((beta_t + 1.0) * vx - R * w * (a - beta_t)) / (R * (a + 1.0))])
        if min(q2[1] + q2[2] * ra[0], q2[1] + q2[2] * rb[0]) >= 0.0:
            new = s.copy()
            new[3:] = q2
            info.update(law="paper", beta_n=beta_n)
            return new, info
    targets = -betas * np.minimum(u_n, 0.0)
    dq, extra = _two_corner_rigid(die, q, ra, rb, targets, beta_t, truth.friction)
    if dq is None:
        return None, None
    info.update(extra)
    info.update(law="rigid" if truth.contact == "rigid" else "fallback", beta_n=float(betas[0]))
    new = s.copy()
    new[3:] = q + dq
    return new, info


def _corner_beta(truth, corner):
    """beta_normal of impacts at ``corner``: its entry of ``corner_beta_normal``, else
    ``beta_normal``."""
    return float(truth.corner_beta_normal[corner]) if truth.corner_beta_normal else float(truth.beta_normal)


def impact(truth, com_state, corner, second=None, share=1.0):
    """The table impact of ``corner`` (and ``second``, if given) for a COM state.

    Parameters
    ----------
    truth : Truth
    com_state : array_like
        (x, y, phi, vx, vy, omega) of the centre of mass just before the impact.
    corner : int
        Index of the touching corner.
    second : int or None
        A second corner that joins the impact (two contacts at once).
    share : float
        In (0, 1]: the share of the two-contact impulse (the flat_landing effect); the first
        corner's single-contact impulse has the rest (the velocities are blended).

    Returns
    -------
    new_state : ndarray
        The COM state just after the impact (positions unchanged).
    info : dict
        ``law`` ("paper", "fallback" or "rigid"), ``u_n`` and ``u_n_after`` (the corner's normal
        velocity, m/s), ``beta_n`` (effective normal restitution), ``capped``, ``clipped``
        (with the exact rule ``capped`` means it slid for part of the impact, ``clipped`` that
        it took the energetic terminal, and ``stick``, ``reversal``, ``jam``,
        ``energetic_terminal`` are given),
        ``dT`` (J/kg); with a second corner also ``contacts`` (2), ``share``, ``u_n_second`` and
        ``u_n_second_after``; ``contacts`` 1 when there was none or no two-contact case was
        admissible.
    """
    die = _Die(truth)
    if second is not None and truth.friction_rule == "exact":
        raise NotImplementedError("no two-contact impact with friction_rule 'exact' (simulate_path ends the track there)")
    s = np.array(com_state, dtype=float)
    single, info = _single_impact(truth, die, s, corner)
    info.update(contacts=1, share=0.0)
    if second is not None:
        both, info2 = _two_corner_impact(truth, die, s, corner, second)
        if both is not None:
            new = s.copy()
            new[3:] = share * both[3:] + (1.0 - share) * single[3:] if share < 1.0 else both[3:]
            if share < 1.0:
                info2.update(single_law=info["law"], capped=info2["capped"] or info["capped"],
                             clipped=info2["clipped"] or info["clipped"])
            info = info2
            info.update(contacts=2, share=float(share))
            single = new
    r = die.corners(single)
    info["u_n_after"] = float(single[4] + single[5] * r[corner][0])
    if second is not None:
        info["u_n_second_after"] = float(single[4] + single[5] * r[second][0])
    info["dT"] = _kinetic(die, single[3:]) - _kinetic(die, s[3:])
    return single, info


def _single_impact(truth, die, s, corner):
    """The single-corner table impact of ``corner`` by the truth's contact law: (new, info)."""
    r = die.corners(s)[corner]
    vx, vy, w = s[3], s[4], s[5]
    u = np.array([vx - w * r[1], vy + w * r[0]])  # corner velocity v + omega z x r
    beta_n = _corner_beta(truth, corner) / (1.0 + truth.speed_restitution * abs(u[1]))
    beta_t = truth.beta_tangential
    info = {"u_n": float(u[1]), "beta_n": beta_n, "capped": False, "clipped": False}
    if truth.contact == "paper" and vy < 0.0:
        # eqs 9, 12, 13 with lever R (circumradius) below the COM and alpha = I_com / (M R^2)
        a, R = die.alpha, die.radius
        vy2 = -beta_n * vy
        vx2 = -((a * beta_t - 1.0) * vx + a * (beta_t + 1.0) * R * w) / (a + 1.0)
        w2 = -((beta_t + 1.0) * vx - R * w * (a - beta_t)) / (R * (a + 1.0))
        un2 = vy2 + w2 * r[0]
        if un2 >= 0.0:  # the paper's law is defined here: centre approaching, corner released
            new = s.copy()
            new[3:] = vx2, vy2, w2
            info.update(law="paper")
            return new, info
    P, extra = _corner_impulse(die, r, u, beta_n, beta_t, truth.friction)
    info.update(extra)
    new = s.copy()
    new[3] += P[0]
    new[4] += P[1]
    new[5] += (r[0] * P[1] - r[1] * P[0]) / die.inertia
    info["law"] = "rigid" if truth.contact == "rigid" else "fallback"
    return new, info


# ----------------------------------------------------------------------------------- compliant contact


def _loading_decay(zeta):
    """f(zeta) with -ln(beta) = zeta f(zeta) for the compliant contact (see :func:`compliant_constants`):
    arccos(zeta)/sqrt(1 - zeta^2) below 1, 1 at 1, arccosh(zeta)/sqrt(zeta^2 - 1) above."""
    if abs(zeta - 1.0) < 1e-9:
        return 1.0
    if zeta < 1.0:
        return math.acos(zeta) / math.sqrt(1.0 - zeta * zeta)
    return math.acosh(zeta) / math.sqrt(zeta * zeta - 1.0)


def compliant_constants(beta_normal, duration):
    """Stiffness K (1/s^2) and damping C (1/s), per unit mass, of the compliant contact.

    The normal force per unit mass at a corner that has sunk delta > 0 into the table is
    F_n = K delta + C max(d delta/dt, 0): a Kelvin-Voigt spring-dashpot while the corner goes
    in, a spring alone while it comes out (so the force is never a pull, and it falls to zero
    exactly where the corner leaves). A point mass hitting it at speed v (no gravity) goes in
    for f(zeta)/omega_n, to delta_max = (v/omega_n) exp(-zeta f(zeta)), and comes out in
    pi/(2 omega_n) at omega_n delta_max, with omega_n = sqrt(K), zeta = C/(2 omega_n) and f of
    :func:`_loading_decay`. So its restitution is exp(-zeta f(zeta)) and its contact lasts
    (f(zeta) + pi/2)/omega_n: K and C are set so that these are ``beta_normal`` and
    ``duration``. (A die's corner has less effective mass than the die, and turns while it is
    in: its own restitution and duration differ.)
    """
    if not 0.0 < beta_normal <= 1.0:
        raise ValueError(f"the compliant contact needs beta_normal in (0, 1], not {beta_normal!r}")
    target = -math.log(beta_normal)
    zeta = 0.0 if target == 0.0 else brentq(lambda z: z * _loading_decay(z) - target, 0.0, 1e6, xtol=1e-15, rtol=1e-14)
    omega_n = (_loading_decay(zeta) + 0.5 * math.pi) / duration
    return omega_n * omega_n, 2.0 * zeta * omega_n


class _Contact:
    """A compliant contact of the die with the table, integrated in time from ``t0`` and COM state
    ``s0`` (a corner touching, approaching).

    Every corner in contact (depth delta under the table, from when it reaches the table until
    it leaves it) pushes with F_n = K delta + C max(d delta/dt, 0) (:func:`compliant_constants`,
    K and C from that corner's beta_normal and ``compliant_time``) and rubs with the regularised
    Coulomb force F_t = -mu F_n u_t / sqrt(u_t^2 + ``COMPLIANT_SLIP``^2) (u_t the contact point's
    tangential velocity), both at its contact point; gravity (with the tilt) acts too, drag and
    spin drag do not. The rigid body's equations of motion are integrated by scipy's LSODA in
    phases with a fixed set of corners in contact (a phase ends where another corner reaches
    the table or one leaves it: the force jumps by C u_n where a corner arrives, and an
    integrator must not straddle that), until none is in contact (``t1``, ``after``). ``ended``
    is False when that took more than ``COMPLIANT_LIMIT`` contact times (sustained contact).
    """

    def __init__(self, truth, die, t0, s0):
        self.t0 = float(t0)
        betas = [_corner_beta(truth, k) for k in range(die.n)]
        constants = np.array([compliant_constants(b, truth.compliant_time) for b in betas])
        stiff, damp = constants[:, 0], constants[:, 1]
        mu, inv_i = float(truth.friction), 1.0 / die.inertia
        ax, ay = truth.g * math.sin(truth.table_tilt), -truth.g * math.cos(truth.table_tilt)
        clear = 2.0 * CONTACT_TOL * die.radius  # a corner this close to the table, approaching, is in contact

        def rhs(_, z, inside):
            fx, fy, torque = ax, ay, 0.0
            if inside.any():
                points = die.corners(z)[inside]
                delta = -die.heights(z)[inside]
                rate = -(z[4] + z[5] * points[:, 0])  # d delta / dt = -u_n
                fn = np.maximum(stiff[inside] * delta + damp[inside] * np.maximum(rate, 0.0), 0.0)
                ut = z[3] - z[5] * points[:, 1]
                ft = -mu * fn * ut / np.sqrt(ut * ut + COMPLIANT_SLIP**2)
                fx += float(ft.sum())
                fy += float(fn.sum())
                torque = float((points[:, 0] * fn - points[:, 1] * ft).sum()) * inv_i
            return [z[3], z[4], z[5], fx, fy, torque]

        def crossing(i, entering):
            def event(_, z, inside):
                depth = -die.heights(z)[i]
                return depth if entering else depth + clear
            event.terminal, event.direction = True, (1.0 if entering else -1.0)
            return event

        span = COMPLIANT_LIMIT * truth.compliant_time
        z = np.array(s0, dtype=float)
        inside = (-die.heights(z) > -clear) & (die.normal_speeds(z) < 0.0)
        tau, self.phases, touched = 0.0, [], inside.copy()
        while inside.any() and tau < span:
            events = [crossing(i, not inside[i]) for i in range(die.n)]
            sol = solve_ivp(rhs, (tau, span), z, method="LSODA", rtol=1e-10, atol=1e-13, events=events,
                            dense_output=True, args=(inside,), max_step=truth.compliant_time / 20.0)
            if not sol.success:
                raise RuntimeError(f"compliant contact integration failed: {sol.message}")
            hits = [(float(te[0]), i, ye[0]) for i, (te, ye) in enumerate(zip(sol.t_events, sol.y_events)) if te.size]
            if not hits:
                self.phases.append((tau, span, sol.sol))
                tau, z = span, sol.y[:, -1]
                break
            when, i, z = min(hits, key=lambda h: h[0])
            self.phases.append((tau, when, sol.sol))
            tau, z = when, np.array(z, dtype=float)
            inside = inside.copy()
            inside[i] = not inside[i]
            touched |= inside
        self.ended = not inside.any()
        self.t1 = self.t0 + tau
        self.after = z
        self.contacts = int(touched.sum())  # corners that were in contact

    def state(self, t):
        """COM state at absolute time ``t`` in [t0, t1]."""
        tau = min(max(t - self.t0, 0.0), self.t1 - self.t0)
        for begin, end, sol in self.phases:
            if tau <= end:
                return np.asarray(sol(tau), dtype=float)
        return self.after.copy()


# ----------------------------------------------------------------------------------- paths


class Path:
    """A simulated drop: flights between impacts, the impacts, and why it ended.

    Attributes
    ----------
    flights : list of (t_begin, t_end, _Flight)
    impacts : list of dict
        Per impact: ``t`` (s), ``corner``, ``second`` (a corner that joined it, or None),
        ``contacts``, ``share``, ``before`` and ``after`` (COM states), ``law``, ``u_n``,
        ``u_n_after``, ``beta_n``, ``capped``, ``clipped``, ``dT`` (see :func:`impact`).
    t_end : float
        Time at which the path ends (s).
    end : str
        "duration", "slow_impact", "no_rebound", "second_corner", "exact_two_contacts" or
        "stalled".
    """

    def __init__(self, truth):
        self.truth = truth
        self.die = _Die(truth)
        self.flights = []
        self.impacts = []
        self.t_end = 0.0
        self.end = ""

    def com_state(self, t):
        """COM state at time ``t`` (s) within [0, t_end]; at an impact, the state after it."""
        for t0, t1, fl in reversed(self.flights):
            if t >= t0:
                return fl.state(min(t, t1))
        return self.flights[0][2].state(0.0)

    def centre_state(self, t):
        """(x, y, phi, vx, vy, omega) of the geometric centre at time ``t`` (s)."""
        return self.die.to_centre(self.com_state(t))


def _joining_corner(truth, die, height, speed, k):
    """The corner that joins the impact of corner ``k``, and its share of the impact.

    Another corner joins when it approaches (faster than APPROACH_SPEED sqrt(g R)) and would
    reach the table, at its present normal speed, within the window (share 1) or, with the
    flat_landing effect, after a delay d below the contact time T (share 1 - d/T); of several,
    the earliest. Returns (None, 0.0) when none does.
    """
    slowest = APPROACH_SPEED * math.sqrt(truth.g * die.radius)
    tol = CONTACT_TOL * die.radius
    best, delay = None, math.inf
    for j in range(die.n):
        if j == k or speed[j] >= -slowest:
            continue
        d = max(height[j], 0.0) / -speed[j]
        if (height[j] <= tol or d <= truth.window or d < truth.contact_time) and d < delay:
            best, delay = j, d
    if best is None:
        return None, 0.0
    if height[best] <= tol or delay <= truth.window:
        return best, 1.0
    return best, 1.0 - delay / truth.contact_time


SCATTER_FLAT_TILT = math.radians(15.0)  # a landing with a side this near the table is "flat"
SCATTER_TRIES = 16  # jumps drawn before the deterministic outcome is kept


def _scatter(truth, die, before, after, k, two, rng):
    """``after`` with the stochastic law's jump: sd sigma u per component of (vx, vy,
    sqrt(I) omega), u corner k's approach speed before; a jump gaining kinetic energy over
    ``before`` or leaving corner k approaching is drawn again (SCATTER_TRIES times at most)."""
    n = die.n
    phi_k = before[2] + 2 * math.pi * k / n  # corner k seen from the geometric centre
    # tilt of the lower side next to corner k: pi/n less the corner's angle from straight down
    off = (phi_k + 0.5 * math.pi) % (2 * math.pi)
    off = min(off, 2 * math.pi - off)
    tilt = max(math.pi / n - off, 0.0)
    sigma = truth.scatter_flat if (two or tilt < SCATTER_FLAT_TILT) else truth.scatter_corner
    u = -float(die.normal_speeds(before)[k])
    floor = truth.scatter_floor * math.sqrt(truth.g * truth.circumradius)
    if (sigma <= 0.0 and floor <= 0.0) or u <= 0.0:
        return after
    unit = math.sqrt(truth.g * truth.circumradius)
    spread = sigma * u if truth.scatter_power == 1.0 else sigma * unit * (u / unit) ** truth.scatter_power
    wide = truth.scatter_tail_factor if truth.scatter_tail_share > 0.0 and rng.random() < truth.scatter_tail_share else 1.0
    size = min(math.hypot(spread, floor) * wide, u)
    root = math.sqrt(die.inertia)
    limit = _kinetic(die, before[3:])
    for _ in range(SCATTER_TRIES):
        xi = rng.normal(size=3) * size
        new = after.copy()
        new[3] += xi[0]
        new[4] += xi[1]
        new[5] += xi[2] * truth.scatter_spin / root
        if die.normal_speeds(new)[k] >= 0.0 and _kinetic(die, new[3:]) <= limit:
            return new
    return after


def simulate_path(truth, state0, t_end, *, min_bounce_speed=0.05):
    """Simulate one drop from a geometric-centre state until ``t_end`` or sustained contact.

    Parameters
    ----------
    truth : Truth
    state0 : array_like
        (x, y, phi, vx, vy, omega) of the geometric centre at t = 0 (m, rad, m/s, rad/s).
    t_end : float
        Last time simulated (s).
    min_bounce_speed : float
        An impact approaching slower than this (m/s) is taken as the start of sustained
        contact; the path ends there, before it.

    Returns
    -------
    Path
    """
    path = Path(truth)
    die = path.die
    t, s = 0.0, die.to_com(state0)
    # the scatter's generator: fixed by the seed and the release state (one stream per drop)
    scatter_rng = np.random.default_rng([truth.scatter_seed, *np.frombuffer(np.asarray(state0, float).tobytes(), np.uint32)])
    tol2 = SECOND_CORNER_TOL * die.radius
    while True:
        flight = _Flight(truth, t, s, t_end)
        tc, k, reason = _next_contact(die, flight, t, t_end)
        if k is None:
            path.flights.append((t, tc if tc is not None else t_end, flight))
            path.t_end, path.end = (t_end if tc is None else tc), reason
            return path
        path.flights.append((t, tc, flight))
        before = flight.state(tc)
        height = die.heights(before)
        speed = die.normal_speeds(before)
        path.t_end = tc
        if -speed[k] < min_bounce_speed:
            path.end = "slow_impact"
            return path
        if truth.compliant_time > 0.0:
            contact = _Contact(truth, die, tc, before)
            path.flights.append((tc, contact.t1, contact))
            path.t_end = contact.t1
            after = contact.after
            path.impacts.append({"t": tc, "corner": k, "second": None, "contacts": contact.contacts, "share": 0.0,
                                 "before": before, "after": after, "law": "compliant", "duration": contact.t1 - tc,
                                 "u_n": float(speed[k]), "u_n_after": float(die.normal_speeds(after)[k]),
                                 "beta_n": _corner_beta(truth, k), "capped": False, "clipped": False,
                                 "dT": _kinetic(die, after[3:]) - _kinetic(die, before[3:])})
            if not contact.ended:
                path.end = "no_rebound"  # the contact went on: the die rests, rocks or slides on the table
                return path
            t, s = contact.t1, after
            continue
        j, share = _joining_corner(truth, die, height, speed, k)
        if j is not None and truth.friction_rule == "exact":
            path.end = "exact_two_contacts"  # no two-contact exact Coulomb impact here: the track ends
            return path
        after, info = impact(truth, before, k, j, share)
        if truth.scatter_corner > 0.0 or truth.scatter_flat > 0.0 or truth.scatter_floor > 0.0:
            after = _scatter(truth, die, before, after, k, info["contacts"] == 2, scatter_rng)
            info["u_n_after"] = float(die.normal_speeds(after)[k])
            if j is not None:
                info["u_n_second_after"] = float(die.normal_speeds(after)[j])
        info.update(t=tc, corner=k, second=j if info["contacts"] == 2 else None, before=before, after=after)
        path.impacts.append(info)
        arrived = info["contacts"] == 2 and share >= 1.0  # the second corner is at the table too
        if info["u_n_after"] < REBOUND_MIN or (arrived and info["u_n_second_after"] < REBOUND_MIN):
            path.end = "no_rebound"  # sustained contact: a pivot, or the die lying flat
            return path
        speed_after = die.normal_speeds(after)
        if any(i not in (k, j) and height[i] <= tol2 and speed_after[i] < 0.0 for i in range(die.n)):
            path.end = "second_corner"
            return path
        t, s = tc, after


def simulate_track(truth, state0, t_end, rate, *, min_bounce_speed=0.05):
    """True poses of the geometric centre sampled at the frames, without any measurement effect.

    Frames are at j / rate for j = 0, 1, ... while below ``t_end``, and stop where the path
    ends (sustained contact; see the module docstring).

    Parameters
    ----------
    truth : Truth
    state0 : array_like
        (x, y, phi, vx, vy, omega) of the geometric centre at t = 0.
    t_end : float
        Duration (s).
    rate : float
        Frame rate (Hz).
    min_bounce_speed : float
        See :func:`simulate_path` (m/s).

    Returns
    -------
    dict
        ``t``, ``x``, ``y``, ``phi`` (frames), plus ``vx``, ``vy``, ``omega`` (true velocities
        of the geometric centre), ``impacts`` (impact times, s), ``end`` and ``t_stop`` (why
        and when the path ended), ``path`` (the :class:`Path`).
    """
    path = simulate_path(truth, state0, t_end, min_bounce_speed=min_bounce_speed)
    frames = int(math.ceil(t_end * rate - 1e-9))
    t = np.arange(frames) / rate
    t = t[t <= path.t_end]
    poses = np.array([path.centre_state(ti) for ti in t]).reshape(-1, 6)
    return {"t": t, "x": poses[:, 0], "y": poses[:, 1], "phi": poses[:, 2], "vx": poses[:, 3],
            "vy": poses[:, 4], "omega": poses[:, 5], "impacts": np.array([i["t"] for i in path.impacts]),
            "end": path.end, "t_stop": path.t_end, "path": path}


def simulate_drops(truth, count, seed, *, rate=500.0, duration=0.5, noise=(2e-4, 4e-3), drop_prob=0.0,
                   glitch_prob=0.0, height=(0.12, 0.17), vx=(-0.8, -0.4), vy=(-2.1, -1.7), spin=(-8.0, 8.0),
                   phi=(-np.pi, np.pi), min_bounce_speed=0.05):
    """Tracked drops as a tracker would report them.

    Release states of the geometric centre are drawn first, all at once, from
    ``numpy.random.default_rng(seed)``: x0 uniform in +-0.05 m, y0 in ``height`` (m), phi0 in
    ``phi`` (rad), vx0 in ``vx``, vy0 in ``vy`` (m/s), omega0 in ``spin`` (rad/s), in that order
    (columns). Then, per track, with the same generator: the noise, the glitches and the
    dropped frames (always drawn, so the noise does not depend on the probabilities).

    Parameters
    ----------
    truth : Truth
        Physics and measurement effects.
    count : int
        Number of drops.
    seed : int
        Seed of the random generator.
    rate : float
        True frame rate (Hz); the file's times carry ``truth.time_scale``.
    duration : float
        Longest track (s of true time).
    noise : (float, float)
        One sigma of the Gaussian noise on x and y (m, in the file's units) and on phi (rad).
    drop_prob : float
        Probability that a frame is missing from the file.
    glitch_prob : float
        Probability that a frame is a glitch: its pose jumps by 5-20 mm in a random direction
        and by 0.3-1.0 rad with a random sign, for that frame only.
    height, vx, vy, spin, phi : (float, float)
        Ranges of the release state (phi default [-pi, pi)).
    min_bounce_speed : float
        Impacts slower than this end a track (m/s).

    Returns
    -------
    list of dict
        Per drop: ``traj`` (1-based), ``t``, ``x``, ``y``, ``phi`` (file convention, missing
        frames removed), ``state0`` (the true release state of the geometric centre),
        ``glitch_t`` (file times of the glitched frames kept), ``end`` and ``impacts`` (true
        times).
    """
    rng = np.random.default_rng(seed)
    states = np.column_stack([
        rng.uniform(-0.05, 0.05, count), rng.uniform(*height, count), rng.uniform(*phi, count),
        rng.uniform(*vx, count), rng.uniform(*vy, count), rng.uniform(*spin, count),
    ])
    tracks = []
    for i, state0 in enumerate(states):
        true = simulate_track(truth, state0, duration, rate, min_bounce_speed=min_bounce_speed)
        m = true["t"].size
        t = true["t"] * truth.time_scale
        x = true["x"] * truth.length_scale
        y = true["y"] * truth.length_scale
        phi = true["phi"] + truth.angle_offset
        eps = rng.normal(0.0, 1.0, (m, 3))
        x = x + noise[0] * eps[:, 0]
        y = y + noise[0] * eps[:, 1]
        phi = phi + noise[1] * eps[:, 2]
        glitch = rng.random(m) < glitch_prob
        jump = rng.uniform(0.005, 0.020, m)
        direction = rng.uniform(-np.pi, np.pi, m)
        turn = rng.uniform(0.3, 1.0, m) * rng.choice([-1.0, 1.0], m)
        x = np.where(glitch, x + jump * np.cos(direction), x)
        y = np.where(glitch, y + jump * np.sin(direction), y)
        phi = np.where(glitch, phi + turn, phi)
        keep = ~(rng.random(m) < drop_prob)
        tracks.append({"traj": i + 1, "t": t[keep], "x": x[keep], "y": y[keep], "phi": phi[keep],
                       "state0": tuple(float(v) for v in state0), "glitch_t": t[glitch & keep],
                       "end": true["end"], "impacts": true["impacts"]})
    return tracks


def write_csv(path, tracks):
    """Write tracks as CSV with header ``traj,t,x,y,phi``, one row per frame kept.

    Parameters
    ----------
    path : str or os.PathLike
    tracks : list of dict
        As returned by :func:`simulate_drops`.
    """
    with open(path, "w", newline="") as fh:
        out = csv.writer(fh)
        out.writerow(["traj", "t", "x", "y", "phi"])
        for tr in tracks:
            for row in zip(tr["t"], tr["x"], tr["y"], tr["phi"]):
                out.writerow([tr["traj"]] + [repr(float(v)) for v in row])
