"""How close any admissible impact law could come to a measured impact: the ideal rigid-body bound.

For one measured impact (the velocities just before and just after, from the free-flight fits
of :mod:`dice_sweep.measured.impacts`) this finds the impulse(s) at the contact point(s) that
bring the post-impact velocity closest to the measured one, over every impulse that

* has a non-negative normal part at each contact (the table pushes, never pulls), and
* does not add kinetic energy (T after <= T before),

with no friction cone and no restitution law. Any rigid-body impact law at those contact points
that pushes and does not create energy (the rigid law of :mod:`dice_sweep.physics.impact`,
Stronge's, Routh's, ...; not the paper's law, whose lever is R below the centre) predicts a
velocity in that set, so the distance from the measured velocity to the set is a lower bound on
the error of every such law at that impact: the "ideal rigid body" bound that Fazeli et al. and
the DAIR Lab (DAIRLab/ImpactModeling) used on these same drops. What a law's error has above the
bound, a better impact law can still gain; the bound itself needs something other than a rigid
body hit at those points (a contact patch, compliance, a different lever or inertia, tracking
error).

Conventions (docs/impact_bound.md)
----------------------------------
Per unit mass; the table's normal is +y, its tangent +x; a contact point r is seen from the
centre of mass (m). An impulse P = (P_t, P_n) (m/s: impulse per mass) at r changes

    v' = v + P,    omega' = omega + (r_x P_n - r_y P_t) / (I/M).

**Velocity error metric**: the kinetic-energy metric

    e = sqrt(dvx^2 + dvy^2 + (I/M) domega^2)    (m/s),

the norm in which the kinetic energy per mass is |v|^2 / 2. It weighs translation and rotation by
their share of the energy, does not depend on where the origin is, and makes the energy
constraint a ball: the bound is the distance, in this metric, from the measured post-impact
velocity to (ball of the pre-impact energy) intersected with (pre-impact velocity + cone of
admissible impulses). The translational (m/s) and angular (rad/s) parts of the residual at the
optimum are reported too.

**Solver**: exact. In whitened coordinates z = (vx, vy, sqrt(I/M) omega) the admissible set is
the intersection of a ball about 0 through z_before with the polyhedral cone
z_before + {sum_i P_t,i t_i + P_n,i n_i : P_n,i >= 0}. The closest point lies in the relative
interior of a face of the cone (the tangential directions and a subset of the normal ones),
where it is the projection onto (the face's affine hull) intersected with the ball, which has a
closed form. Every subset of normal directions (four subsets for two contacts) gives a
candidate; a candidate is kept when it lies in the cone (a bounded least-squares check), and the
nearest kept candidate is the minimum. This is the global optimum of the convex problem, not a
local one; tests/measured/test_impact_bound.py checks it against brute-force grids.

Laws
----
Beside the bounds, the errors of the project's laws at the same impacts: the single-contact law
at the touching corner (:func:`law_after`), the kernel's two-contact law at the corners of the
lowest side (:func:`two_contact_after`), and the ``flat_landing`` effect's blend of the two at
a contact time T (:func:`flat_landing_errors`, :func:`best_contact_time`): an impact-level
estimate, separate from the loop's fit of that effect to whole tracks.
"""

import dataclasses
import itertools
import math
from dataclasses import dataclass

import numpy as np
from scipy.optimize import lsq_linear

from dice_sweep.geometry import corner_angles, inertia_ratio
from dice_sweep.measured.calibrate import impact_row, trackset_impacts

__all__ = [
    "CONTACTS",
    "Bound",
    "inertia_per_mass",
    "contact_corners",
    "velocity_error",
    "kinetic_energy",
    "closest_admissible",
    "impact_bound",
    "law_after",
    "two_contact_after",
    "second_corner_delay",
    "flat_landing_share",
    "flat_landing_after",
    "flat_landing_errors",
    "best_contact_time",
    "CONTACT_TIME_SCAN",
    "CONTACT_TIMES",
    "velocity_noise",
    "first_impact_bounds",
    "summarise_bounds",
    "markdown_table",
    "TILT_BINS",
    "QUANTITIES",
    "CONE_QUANTITIES",
    "PAPER_TWO_QUANTITY",
    "RULE_QUANTITIES",
]

CONTACTS = {
    "corner": "the touching corner: the lowest corner at contact (one contact)",
    "side": "both corners of the lowest side: the lowest corner and its lower neighbour (two contacts)",
}
RANK_TOLERANCE = 1e-10  # relative singular value below which a direction is dropped (parallel contacts)
MEMBER_TOLERANCE = 1e-9  # relative distance below which a candidate counts as inside the cone
ACTIVE_TOLERANCE = 1e-9  # relative energy gap below which the energy constraint counts as active
SEQUENCE_LIMIT = 1000  # impulses at most at the two corners of a side (law_after, contacts "side")
SEQUENCE_TOLERANCE = 1e-9  # relative approach speed below which a corner counts as not approaching
TILT_BINS = ((0.0, 5.0), (5.0, 15.0), (15.0, 45.0))  # deg, landing tilt (0: flat, 45: a square's corner down)
BOOTSTRAP_RESAMPLES = 2000
CONTACT_TIMES = (0.0, 3e-5, 1e-4, 3e-4, 1e-3)  # s, the flat_landing effect's contact times tabulated by tilt
CONTACT_TIME_SCAN = tuple(np.logspace(-6.0, -3.0, 30))  # s, the scan for the best-fitting contact time
# per-impact quantity -> what it is (all m/s, kinetic-energy metric)
QUANTITIES = {
    "bound_corner": "ideal rigid-body bound, one contact (the touching corner)",
    "bound_side": "ideal rigid-body bound, two contacts (both corners of the lowest side)",
    "rigid_error": "error of the rigid law (corner_impulse at the touching corner, once)",
    "two_error": "error of the rigid two-contact law (resolve_two_contacts at both corners of the lowest side, share 1)",
    "rigid_side_error": "error of the rigid law applied in turn at both corners of the lowest side (sequential single impulses)",
    "paper_error": "error of the paper's law (with the given coefficients)",
    "change": "measured velocity change |after - before| (the scale)",
    "noise": "velocity noise of the two side fits (estimated from their residuals)",
    "noise_bound": "one-contact bound of an admissible impact (the closest one) with that noise added: the bound's noise floor",
}
# the rigid law at the touching corner under each other friction rule (docs/physics.md, "Friction
# rules"), at the same coefficients: what the rule alone changes, impact by impact
RULE_QUANTITIES = {
    "sliding_error": "error of the rigid law with the sliding friction rule (the cap opposing the incoming slip)",
    "exact_error": "error of the exact Coulomb impact (Routh), Newton restitution",
    "exact_energetic_error": "error of the exact Coulomb impact (Routh), energetic restitution",
    "exact_two_error": "error of the exact Coulomb impact at both corners of the lowest side (two_contact_after: equal contact springs)",
}
RULES = {"sliding_error": ("sliding", "newton"), "exact_error": ("exact", "newton"), "exact_energetic_error": ("exact", "energetic")}
# also in every row; a table column only where it differs from paper_error (scripts/impact_bound.py)
PAPER_TWO_QUANTITY = {"paper_two_error": "error of the paper's two-contact law (resolve_two_contacts, paper model, share 1)"}
# with first_impact_bounds(..., cone=mu): the bounds of laws that keep |P_t| <= mu P_n at each contact
CONE_QUANTITIES = {
    "bound_corner_cone": "bound with a friction cone, one contact",
    "bound_side_cone": "bound with a friction cone, two contacts",
}


@dataclass(frozen=True)
class Bound:
    """The admissible post-impact velocity closest to a measured one.

    Attributes
    ----------
    error : float
        The bound, m/s: the kinetic-energy-metric distance sqrt(dvx^2 + dvy^2 + (I/M) domega^2)
        from the measured post-impact velocity to the closest admissible one.
    velocity : numpy.ndarray, shape (3,)
        That admissible post-impact velocity (vx, vy, omega), m/s, m/s, rad/s.
    impulses : numpy.ndarray, shape (contacts, 2)
        One impulse per unit mass (P_t, P_n) at each contact that reaches it, m/s (unique for
        one contact; for two, one of a family with the same total effect).
    translation_error : float
        |measured (vx, vy) - admissible (vx, vy)|, m/s.
    spin_error : float
        |measured omega - admissible omega|, rad/s.
    energy_ratio : float
        Kinetic energy after over before at the admissible velocity (<= 1).
    energy_active : bool
        Whether the energy constraint binds at the optimum (the ratio is 1 there).
    """

    error: float
    velocity: np.ndarray
    impulses: np.ndarray
    translation_error: float
    spin_error: float
    energy_ratio: float
    energy_active: bool


def inertia_per_mass(sides, circumradius):
    """I/M of a uniform regular n-gon plate about its centre, m^2 (alpha R^2, geometry.py)."""
    return float(inertia_ratio(sides)) * circumradius**2


def contact_corners(sides, circumradius, phi, contacts="corner"):
    """Contact points seen from the centre, (m, 2) m, for a die at angle ``phi`` on the table.

    ``contacts``: "corner" (the lowest corner, as
    :func:`dice_sweep.measured.impacts.touching_corner`) or "side" (the lowest corner, then the
    lower of its two neighbours: the corners of the side that :func:`landing_tilt` measures).
    """
    if contacts not in CONTACTS:
        raise ValueError(f"contacts: {contacts!r} is not one of {', '.join(CONTACTS)}")
    angles = corner_angles(sides, phi)
    heights = np.sin(angles)
    lowest = int(np.argmin(heights))
    picked = [lowest]
    if contacts == "side":
        before, after = (lowest - 1) % sides, (lowest + 1) % sides
        picked.append(before if heights[before] < heights[after] else after)
    return circumradius * np.column_stack((np.cos(angles[picked]), np.sin(angles[picked])))


def kinetic_energy(velocity, inertia):
    """Kinetic energy per unit mass of (vx, vy, omega), J/kg."""
    vx, vy, omega = velocity
    return 0.5 * (vx * vx + vy * vy + inertia * omega * omega)


def velocity_error(predicted, measured, inertia):
    """Kinetic-energy-metric distance between two (vx, vy, omega), m/s."""
    d = np.asarray(predicted, dtype=float) - np.asarray(measured, dtype=float)
    return float(math.sqrt(d[0] ** 2 + d[1] ** 2 + inertia * d[2] ** 2))


def _generators(corners, inertia):
    """Whitened velocity changes of a unit tangential and a unit normal impulse at each corner,
    as columns: (3, m) and (3, m)."""
    root = math.sqrt(inertia)
    rx, ry = corners[:, 0], corners[:, 1]
    ones, zeros = np.ones_like(rx), np.zeros_like(rx)
    return np.vstack((ones, zeros, -ry / root)), np.vstack((zeros, ones, rx / root))


def _orthonormal(columns):
    """An orthonormal basis (3, k) of the span of ``columns`` (3, m)."""
    if columns.shape[1] == 0:
        return np.zeros((columns.shape[0], 0))
    u, singular, _ = np.linalg.svd(columns, full_matrices=False)
    return u[:, singular > RANK_TOLERANCE * max(singular.max(initial=0.0), 1.0)]


def _in_cone(step, lines, rays, scale):
    """Coefficients (lines free, rays >= 0) with lines a + rays b = step, or None if there are none."""
    matrix = np.hstack((lines, rays))
    count = lines.shape[1]
    lower = np.r_[np.full(count, -np.inf), np.zeros(rays.shape[1])]
    fit = lsq_linear(matrix, step, bounds=(lower, np.full(matrix.shape[1], np.inf)), method="bvls", tol=1e-14)
    if np.linalg.norm(matrix @ fit.x - step) > MEMBER_TOLERANCE * scale:
        return None
    return fit.x


def closest_admissible(before, after, corners, inertia, friction=math.inf):
    """The bound for one impact, given the contact points (the solver; see the module docstring).

    Parameters
    ----------
    before, after : array_like, shape (3,)
        (vx, vy, omega) just before the impact and measured just after, m/s, m/s, rad/s.
    corners : array_like, shape (m, 2)
        Contact points seen from the centre of mass, m (table normal +y).
    inertia : float
        I/M, m^2.
    friction : float
        A Coulomb cone |P_t| <= friction P_n at each contact; inf (the default, the ideal
        rigid-body bound) for none. A finite value bounds only the laws that respect that cone.

    Returns
    -------
    Bound
    """
    before = np.asarray(before, dtype=float)
    after = np.asarray(after, dtype=float)
    corners = np.atleast_2d(np.asarray(corners, dtype=float))
    root = math.sqrt(inertia)
    whiten = np.array([1.0, 1.0, root])
    z0, zm = before * whiten, after * whiten
    tangents, normals = _generators(corners, inertia)
    coned = math.isfinite(friction)
    if not coned:
        lines, rays = tangents, normals
    elif friction > 0.0:  # the cone's two edges at each contact, no free direction
        lines, rays = np.zeros((3, 0)), np.hstack((normals + friction * tangents, normals - friction * tangents))
    else:
        lines, rays = np.zeros((3, 0)), normals
    radius2 = float(z0 @ z0)
    scale = max(math.sqrt(radius2), float(np.linalg.norm(zm)), 1e-12)
    best = None
    for size in range(rays.shape[1] + 1):
        for subset in itertools.combinations(range(rays.shape[1]), size):
            basis = _orthonormal(np.hstack((lines, rays[:, list(subset)])))
            point = z0 + basis @ (basis.T @ (zm - z0))
            centre = z0 - basis @ (basis.T @ z0)  # nearest point to 0 of the face's affine hull
            reach2 = max(radius2 - float(centre @ centre), 0.0)
            offset = point - centre
            if offset @ offset > reach2:
                point = centre + math.sqrt(reach2) * offset / math.sqrt(offset @ offset)
            coeffs = _in_cone(point - z0, lines, rays, scale)
            if coeffs is None:
                continue
            distance = float(np.linalg.norm(point - zm))
            if best is None or distance < best[0]:
                best = (distance, point, coeffs)
    distance, point, coeffs = best  # the face without normal directions always holds z0 itself
    velocity = point / whiten
    count = corners.shape[0]
    if not coned:
        impulses = np.column_stack((coeffs[:count], coeffs[count:]))
    elif friction > 0.0:
        up, down = coeffs[:count], coeffs[count:]
        impulses = np.column_stack((friction * (up - down), up + down))
    else:
        impulses = np.column_stack((np.zeros(count), coeffs))
    energy_before = kinetic_energy(before, inertia)
    ratio = kinetic_energy(velocity, inertia) / energy_before if energy_before > 0 else 1.0
    return Bound(
        error=distance,
        velocity=velocity,
        impulses=impulses,
        translation_error=float(np.hypot(*(velocity[:2] - after[:2]))),
        spin_error=float(abs(velocity[2] - after[2])),
        energy_ratio=float(ratio),
        energy_active=bool(radius2 - float(point @ point) <= ACTIVE_TOLERANCE * radius2),
    )


def impact_bound(state, after, *, sides, circumradius, contacts="corner", inertia=None, friction=math.inf):
    """The ideal rigid-body bound of one measured impact.

    Parameters
    ----------
    state : array_like, shape (6,)
        (x, y, phi, vx, vy, omega) of the centre just before the impact (SI, the model's angle:
        corner 0 at phi). The position does not enter: the table is horizontal and the contact
        points are the die's corners.
    after : array_like, shape (3,)
        Measured (vx, vy, omega) just after, m/s, m/s, rad/s.
    sides, circumradius : int, float
        The die.
    contacts : str
        "corner" or "side" (:data:`CONTACTS`).
    inertia : float, optional
        I/M, m^2; a uniform plate's (:func:`inertia_per_mass`) when None.
    friction : float
        A Coulomb cone at each contact (inf, the default: none; see :func:`closest_admissible`).

    Returns
    -------
    Bound
    """
    state = np.asarray(state, dtype=float)
    inertia = inertia_per_mass(sides, circumradius) if inertia is None else float(inertia)
    corners = contact_corners(sides, circumradius, state[2], contacts)
    return closest_admissible(state[3:6], after, corners, inertia, friction)


def _law_params(cfg, *, model, beta_normal, beta_tangential, friction, inertia):
    """The kernel's (fpar, ipar) for ``cfg`` with its contact section replaced by the arguments
    and, when given, I/M (m^2) in place of the uniform plate's."""
    from dice_sweep.physics import pack_params  # lazy: compiles the kernels
    from dice_sweep.physics.params import FP_ALPHA, FP_INERTIA

    effects = cfg.effects
    if effects is not None and any(effects.com_offset):
        raise ValueError("impact laws here: a centre-of-mass offset is not supported (the state is the centre's)")
    contact = dataclasses.replace(cfg.contact, model=model, beta_normal=beta_normal, beta_tangential=beta_tangential, friction=friction)
    fpar, ipar = pack_params(dataclasses.replace(cfg, contact=contact))
    if inertia is not None:
        fpar[FP_INERTIA] = inertia
        fpar[FP_ALPHA] = inertia / cfg.die.circumradius**2
    return fpar, ipar


def _corner_indices(sides, circumradius, phi, contacts):
    """Kernel indices (corner k at phi + 2 pi k / n) of :func:`contact_corners`' points."""
    corners = contact_corners(sides, circumradius, phi, contacts)
    return corners, [int(k) for k in np.round((np.arctan2(corners[:, 1], corners[:, 0]) - phi) / (2.0 * math.pi / sides)) % sides]


def law_after(state, cfg, *, model, beta_normal, beta_tangential, friction=math.inf, contacts="corner", inertia=None, counts=None):
    """Post-impact (vx, vy, omega) that the project's single-contact impact law predicts.

    Calls of :func:`dice_sweep.physics.impact.resolve_impact` on the table, as the kernel makes
    them: ``model`` "rigid" is :func:`~dice_sweep.physics.impact.corner_impulse` at a corner
    (restitution targets, Coulomb cap ``friction``, energy clip); "paper" is the paper's law
    (eqs 9-13), falling back to the corner impulse where it is undefined. A corner that does not
    approach the table gets no impulse.

    ``contacts`` "corner": one call, at the touching corner. "side": calls at whichever corner
    of the lowest side approaches faster, until neither approaches (at most
    ``SEQUENCE_LIMIT`` calls), the pose held: sequential single impulses at a landing whose
    second corner is already on the table (zero separation), what the kernel did before its
    two-contact law (:func:`two_contact_after`).

    Parameters
    ----------
    state : array_like, shape (6,)
        (x, y, phi, vx, vy, omega) of the centre just before, SI, the model's angle.
    cfg : dice_sweep.config.Config
        The die and world (its contact section is replaced by the arguments; a centre-of-mass
        offset is not allowed: ``state`` is the centre's).
    model, beta_normal, beta_tangential, friction
        The contact law.
    contacts : str
        "corner" or "side" (:data:`CONTACTS`).
    inertia : float, optional
        I/M, m^2, in place of the uniform plate's that the kernel's parameters hold.
    counts : numpy.ndarray of int32, optional
        The kernel's event counts (``dice_sweep.physics.COUNT_COLUMNS``) to add these impacts'
        to: "impacts" (calls that gave an impulse), "corner_fallbacks" (the paper's law
        undefined) and "energy_clips".

    Returns
    -------
    numpy.ndarray, shape (3,)
    """
    from dice_sweep.physics.layout import COUNT_COLUMNS
    from dice_sweep.physics.flight import SURF_TABLE
    from dice_sweep.physics.impact import resolve_impact

    fpar, ipar = _law_params(cfg, model=model, beta_normal=beta_normal, beta_tangential=beta_tangential, friction=friction, inertia=inertia)
    sides, radius = cfg.die.sides, cfg.die.circumradius
    s = np.array(state, dtype=float)
    corners, index = _corner_indices(sides, radius, s[2], contacts)
    if counts is None:
        counts = np.zeros(len(COUNT_COLUMNS), dtype=np.int32)
    floor = SEQUENCE_TOLERANCE * max(float(np.linalg.norm(s[3:5])), radius * abs(s[5]), 1e-12)
    for _ in range(SEQUENCE_LIMIT if contacts == "side" else 1):
        approach = s[4] + s[5] * corners[:, 0]  # normal velocity of each corner (table: n = +y)
        k = int(np.argmin(approach))
        if approach[k] >= -floor:
            break
        resolve_impact(s, fpar, ipar, SURF_TABLE, index[k], counts)
        counts[COUNT_COLUMNS.index("impacts")] += 1
    return s[3:6].copy()


def two_contact_after(state, cfg, *, model, beta_normal, beta_tangential, friction=math.inf, inertia=None, share=1.0, counts=None):
    """Post-impact (vx, vy, omega) of the kernel's two-contact law at the lowest side's corners.

    One call of :func:`dice_sweep.physics.multi_contact.resolve_two_contacts` on the table, the
    first contact the touching corner, the second the lower of its neighbours (the two points of
    ``contacts="side"``), as if both touched at once (the pose held; docs/physics.md, "Two
    contacts at once"). ``share`` < 1 blends it with the touching corner's single-contact law
    as the ``flat_landing`` effect does. Arguments as :func:`law_after`.

    Returns
    -------
    numpy.ndarray, shape (3,), or None
        None when no case of the two-contact law is admissible (the kernel then resolves the
        contacts one at a time).
    """
    from dice_sweep.physics.layout import COUNT_COLUMNS
    from dice_sweep.physics.flight import SURF_TABLE
    from dice_sweep.physics.multi_contact import resolve_two_contacts

    fpar, ipar = _law_params(cfg, model=model, beta_normal=beta_normal, beta_tangential=beta_tangential, friction=friction, inertia=inertia)
    s = np.array(state, dtype=float)
    _, (first, second) = _corner_indices(cfg.die.sides, cfg.die.circumradius, s[2], "side")
    if counts is None:
        counts = np.zeros(len(COUNT_COLUMNS), dtype=np.int32)
    if not resolve_two_contacts(s, fpar, ipar, SURF_TABLE, first, SURF_TABLE, second, float(share), counts):
        return None
    return s[3:6].copy()


def second_corner_delay(state, sides, circumradius):
    """Delay (s) after which the lowest side's second corner reaches the table, at its speed now.

    Its height above the touching corner (the table, at the before-side's contact time) divided
    by its approach speed -(vy + omega r_x); inf when it does not approach. The delay d of the
    ``flat_landing`` effect (docs/physics.md, "Flat landing"), taken from the before-state.
    """
    corners = contact_corners(sides, circumradius, state[2], "side")
    gap = max(float(corners[1, 1] - corners[0, 1]), 0.0)
    approach = -(state[4] + state[5] * corners[1, 0])
    return gap / approach if approach > 0.0 else math.inf


def flat_landing_share(delay, contact_time):
    """The two-contact impulse's share max(0, 1 - d/T) of the ``flat_landing`` effect; 0 at T = 0."""
    delay = np.asarray(delay, dtype=float)
    if contact_time <= 0.0:
        return np.zeros_like(delay)
    return np.clip(1.0 - delay / contact_time, 0.0, 1.0)


def flat_landing_after(single, both, delay, contact_time):
    """Post-impact velocities (n, 3) of the ``flat_landing`` effect at contact time T (s).

    ``single`` and ``both`` (n, 3): the touching corner's single-contact law and the two-contact
    law (rigid, as the kernel); ``delay`` (n,), s. The velocity changes are blended with the
    share max(0, 1 - d/T) of the two-contact one (:func:`flat_landing_share`); where ``both`` is
    NaN (no admissible two-contact case) the single-contact law stands, as in the kernel.
    """
    single = np.asarray(single, dtype=float)
    both = np.asarray(both, dtype=float)
    share = flat_landing_share(delay, contact_time)
    share = np.where(np.isnan(both).any(axis=1), 0.0, share)[:, None]
    return single + share * (np.nan_to_num(both) - single)


def flat_landing_errors(rows, contact_time, inertia):
    """The ``flat_landing`` effect's predictions at contact time T (s) for the impacts of
    :func:`first_impact_bounds` and their errors (kinetic-energy metric, m/s).

    Returns
    -------
    predicted : numpy.ndarray, shape (n, 3)
    errors : numpy.ndarray, shape (n,)
    """
    single = np.array([row["rigid_after"] for row in rows], dtype=float).reshape(-1, 3)
    both = np.array([row["two_after"] for row in rows], dtype=float).reshape(-1, 3)
    delay = np.array([row["delay"] for row in rows], dtype=float)
    measured = np.array([row["after"] for row in rows], dtype=float).reshape(-1, 3)
    predicted = flat_landing_after(single, both, delay, contact_time)
    d = predicted - measured
    return predicted, np.sqrt(d[:, 0] ** 2 + d[:, 1] ** 2 + inertia * d[:, 2] ** 2)


def best_contact_time(rows, inertia, contact_times=None, *, resamples=BOOTSTRAP_RESAMPLES, seed=0):
    """The contact time T of the ``flat_landing`` effect that minimises the median impact error.

    A scan over ``contact_times`` (s; default :data:`CONTACT_TIME_SCAN`, 30 log-spaced values in
    [1e-6, 1e-3]); the interval is the 2.5 and 97.5 percentiles of the minimiser over a
    bootstrap of tracks (a track's impacts resampled together), so it is on the scan's values.
    A tie (a median flat over part of the scan) goes to the shortest T. An impact-level
    estimate: each impact's error at T, not the loop's fit of the effect to whole tracks.

    Returns
    -------
    dict
        contact_times (the scan), medians (median error at each, m/s), best (s), best_median
        (m/s), low and high (s), at_edge (the minimiser is the scan's first or last value),
        spread (largest minus smallest median over the scan, m/s), sharing (impacts whose
        second corner arrives within the scan's longest T, so that T moves their prediction).
    """
    times = np.asarray(CONTACT_TIME_SCAN if contact_times is None else contact_times, dtype=float)
    errors = np.column_stack([flat_landing_errors(rows, float(t), inertia)[1] for t in times])
    medians = np.median(errors, axis=0)
    best = int(np.argmin(medians))
    traj = np.array([row["traj"] for row in rows], dtype=np.int64)
    labels, inverse = np.unique(traj, return_inverse=True)
    members = [np.flatnonzero(inverse == k) for k in range(labels.size)]
    rng = np.random.default_rng(seed)
    picks = np.empty(resamples)
    for b in range(resamples):
        chosen = np.concatenate([members[k] for k in rng.integers(0, labels.size, labels.size)])
        picks[b] = times[int(np.argmin(np.median(errors[chosen], axis=0)))]
    low, high = np.percentile(picks, [2.5, 97.5], method="inverted_cdf")
    return {
        "contact_times": times,
        "medians": medians,
        "best": float(times[best]),
        "best_median": float(medians[best]),
        "low": float(low),
        "high": float(high),
        "at_edge": best in (0, times.size - 1),
        "spread": float(medians.max() - medians.min()),
        "sharing": int(sum(row["delay"] < times.max() for row in rows)),
    }


def velocity_noise(side, rate, circumradius, inertia):
    """Per-coordinate standard errors (vx, vy, omega) of one side fit's velocities, SI.

    From the fit's pose residual ``rms`` over its ``frames`` (k) at ``rate``: each of x, y and
    R phi gets the noise sigma^2 = rms^2 k / (3 (k - 2)) (two parameters a coordinate), and a
    slope over k evenly spaced frames has the variance sigma^2 / (dt^2 k (k^2 - 1) / 12). An
    estimate: the residual of five frames says little, and dropped frames are ignored.
    """
    k = side.frames
    if k <= 2:
        return np.full(3, np.nan)
    sigma = side.rms * math.sqrt(k / (3.0 * (k - 2)))
    spread = math.sqrt(k * (k * k - 1) / 12.0) / rate
    slope = sigma / spread
    return np.array([slope, slope, slope / circumradius])


def first_impact_bounds(trackset, cfg, *, rigid, paper, clean_only=True, inertia=None, cone=None, seed=0):
    """Bounds and law errors at the first impact of every track.

    The impacts are found and fitted as :func:`dice_sweep.measured.calibrate.calibrate` does
    (:func:`~dice_sweep.measured.calibrate.trackset_impacts`), and described by its
    :func:`~dice_sweep.measured.calibrate.impact_row` (tilt, clean).

    Parameters
    ----------
    trackset : dice_sweep.measured.tracks.TrackSet
        Tracks in the model's convention.
    cfg : dice_sweep.config.Config
        The die, g, the kernel's settings (its contact section is not used).
    rigid : dict
        beta_normal, beta_tangential, friction of the rigid law.
    paper : dict
        beta_normal, beta_tangential of the paper's law.
    clean_only : bool
        Only clean impacts (calibrate's rule: fits, contact and continuity).
    inertia : float, optional
        I/M, m^2; the uniform plate's when None.
    cone : float, optional
        A friction coefficient: also the bounds of the laws that respect that Coulomb cone at
        each contact (:data:`CONE_QUANTITIES`).
    seed : int
        Of the noise drawn for ``noise_bound``.

    Returns
    -------
    rows : list of dict
        Per impact: traj, tilt (rad, :func:`~dice_sweep.measured.impacts.landing_tilt`), kind,
        the :data:`QUANTITIES` (m/s) and, with ``cone``, the :data:`CONE_QUANTITIES`;
        bound_corner_energy and bound_side_energy (whether the energy constraint binds),
        bound_corner_spin (rad/s) and bound_corner_translation (m/s) (the parts of the
        one-contact bound), paper_fallback (the paper's law undefined there), paper_two_fallback
        (the paper's two-contact law fell back to the rigid two-contact impulse), two_clip (the
        rigid two-contact law's energy clip acted), paper_two_vs_single (m/s, the distance
        between the paper's two-contact and single-contact predictions), delay (s,
        :func:`second_corner_delay`), and the (3,) velocities after (measured), rigid_after
        and two_after (the rigid single- and two-contact laws; NaN when the latter has no
        admissible case), from which :func:`flat_landing_errors` blends. A law with no
        admissible case has a NaN error.
    skipped : dict
        First impacts left out, by reason.
    """
    from dice_sweep.physics.layout import COUNT_COLUMNS

    sides, radius, g = cfg.die.sides, cfg.die.circumradius, cfg.world.g
    inertia = inertia_per_mass(sides, radius) if inertia is None else float(inertia)
    rng = np.random.default_rng(seed)
    _, _, found = trackset_impacts(trackset, cfg, first_only=True)
    rows = []
    skipped = {"no impact found": len(trackset.tracks) - len(found), "too few frames on a side": 0, "not clean": 0}
    for track, index, impact in found:
        if impact is None:
            skipped["too few frames on a side"] += 1
            continue
        described = impact_row(track.traj, index, impact, sides=sides, circumradius=radius, g=g)
        if clean_only and not described["clean"]:
            skipped["not clean"] += 1
            continue
        state, after = impact.before.state, impact.after.state[3:]
        before = state[3:]
        corner = impact_bound(state, after, sides=sides, circumradius=radius, contacts="corner", inertia=inertia)
        side = impact_bound(state, after, sides=sides, circumradius=radius, contacts="side", inertia=inertia)
        rigid_after = law_after(state, cfg, model="rigid", inertia=inertia, **rigid)
        rigid_side_after = law_after(state, cfg, model="rigid", contacts="side", inertia=inertia, **rigid)
        two_counts = np.zeros(len(COUNT_COLUMNS), dtype=np.int32)
        two_after = two_contact_after(state, cfg, model="rigid", inertia=inertia, counts=two_counts, **rigid)
        counts = np.zeros(len(COUNT_COLUMNS), dtype=np.int32)
        paper_after = law_after(state, cfg, model="paper", friction=math.inf, inertia=inertia, counts=counts, **paper)
        by_rule = {
            name: law_after(state, dataclasses.replace(cfg, contact=dataclasses.replace(cfg.contact, friction_rule=rule, restitution=law)),
                            model="rigid", inertia=inertia, **rigid)
            for name, (rule, law) in RULES.items()
        }
        exact_cfg = dataclasses.replace(cfg, contact=dataclasses.replace(cfg.contact, friction_rule="exact", restitution="energetic"))
        exact_two_after = two_contact_after(state, exact_cfg, model="rigid", inertia=inertia, **rigid)
        paper_counts = np.zeros(len(COUNT_COLUMNS), dtype=np.int32)
        paper_two_after = two_contact_after(state, cfg, model="paper", friction=math.inf, inertia=inertia, counts=paper_counts, **paper)
        nan = np.full(3, np.nan)
        sigma_before = velocity_noise(impact.before, trackset.rate, radius, inertia)
        sigma_after = velocity_noise(impact.after, trackset.rate, radius, inertia)
        weights = np.array([1.0, 1.0, inertia])
        noise = math.sqrt(float(weights @ (sigma_before**2 + sigma_after**2)))
        noisy = state.copy()
        noisy[3:] += sigma_before * rng.standard_normal(3)
        # an admissible impact (the closest one) seen through the fits' noise
        noise_bound = impact_bound(noisy, corner.velocity + sigma_after * rng.standard_normal(3), sides=sides, circumradius=radius, inertia=inertia)
        row = {
            "traj": int(track.traj),
            "tilt": float(described["tilt"]),
            "kind": described["kind"],
            "bound_corner": corner.error,
            "bound_side": side.error,
            "rigid_error": velocity_error(rigid_after, after, inertia),
            "two_error": math.nan if two_after is None else velocity_error(two_after, after, inertia),
            "rigid_side_error": velocity_error(rigid_side_after, after, inertia),
            "paper_error": velocity_error(paper_after, after, inertia),
            **{name: velocity_error(law, after, inertia) for name, law in by_rule.items()},
            "exact_two_error": math.nan if exact_two_after is None else velocity_error(exact_two_after, after, inertia),
            "paper_two_error": math.nan if paper_two_after is None else velocity_error(paper_two_after, after, inertia),
            "change": velocity_error(before, after, inertia),
            "noise": noise,
            "noise_bound": noise_bound.error,
            "bound_corner_energy": corner.energy_active,
            "bound_side_energy": side.energy_active,
            "bound_corner_spin": corner.spin_error,
            "bound_corner_translation": corner.translation_error,
            "paper_fallback": bool(counts[COUNT_COLUMNS.index("corner_fallbacks")]),
            "paper_two_fallback": bool(paper_counts[COUNT_COLUMNS.index("corner_fallbacks")]),
            "two_clip": bool(two_counts[COUNT_COLUMNS.index("energy_clips")]),
            "paper_two_vs_single": math.nan if paper_two_after is None else velocity_error(paper_two_after, paper_after, inertia),
            "delay": second_corner_delay(state, sides, radius),
            "after": np.array(after, dtype=float),
            "rigid_after": rigid_after,
            "two_after": nan if two_after is None else two_after,
        }
        if cone is not None:
            for name, contacts in (("bound_corner_cone", "corner"), ("bound_side_cone", "side")):
                row[name] = impact_bound(state, after, sides=sides, circumradius=radius, contacts=contacts, inertia=inertia, friction=cone).error
        rows.append(row)
    return rows, skipped


def _median_interval(values, groups, rng, resamples):
    """Median of ``values`` and its percentile-bootstrap 95 % interval, resampling ``groups``."""
    labels, inverse = np.unique(groups, return_inverse=True)
    members = [np.flatnonzero(inverse == k) for k in range(labels.size)]
    medians = np.empty(resamples)
    for b in range(resamples):
        picked = rng.integers(0, labels.size, labels.size)
        medians[b] = np.median(values[np.concatenate([members[k] for k in picked])])
    low, high = np.percentile(medians, [2.5, 97.5])
    return float(np.median(values)), float(low), float(high)


def summarise_bounds(rows, *, bins=TILT_BINS, quantities=tuple(QUANTITIES), resamples=BOOTSTRAP_RESAMPLES, seed=0):
    """Medians of the per-impact quantities by landing-tilt bin, with 95 % intervals.

    The intervals are percentile bootstraps over tracks (a track's impacts are resampled
    together). Bins are [low, high) degrees, the last one closed; an "all" bin follows. NaN
    values (a law without an admissible case) are left out of their quantity's median.

    Returns
    -------
    list of dict
        Per bin: label, impacts, tracks, and per quantity {median, low, high} (None when empty).
    """
    rng = np.random.default_rng(seed)
    tilt = np.degrees([row["tilt"] for row in rows]) if rows else np.zeros(0)
    traj = np.array([row["traj"] for row in rows], dtype=np.int64)
    out = []
    ranges = [(lo, hi, f"{lo:g}-{hi:g} deg") for lo, hi in bins] + [(bins[0][0], bins[-1][1], "all")]
    for k, (lo, hi, label) in enumerate(ranges):
        last = k >= len(bins) - 1
        inside = (tilt >= lo) & ((tilt <= hi) if last else (tilt < hi))
        entry = {"label": label, "impacts": int(inside.sum()), "tracks": int(np.unique(traj[inside]).size)}
        for name in quantities:
            values = np.array([row[name] for row in rows], dtype=float)
            kept = inside & np.isfinite(values)  # NaN: a law with no admissible case there
            if not kept.any():
                entry[name] = None
                continue
            median, low, high = _median_interval(values[kept], traj[kept], rng, resamples)
            entry[name] = {"median": median, "low": low, "high": high}
        out.append(entry)
    return out


HEADERS = {
    "bound_corner": "bound, 1 contact",
    "bound_side": "bound, 2 contacts",
    "rigid_error": "rigid law",
    "two_error": "two-contact law",
    "rigid_side_error": "rigid law, sequential at both corners",
    "paper_error": "paper law",
    "paper_two_error": "paper law, two contacts",
    "change": "measured change",
    "noise": "velocity noise",
    "noise_bound": "bound of noise alone",
    "bound_corner_cone": "bound, 1 contact, cone",
    "bound_side_cone": "bound, 2 contacts, cone",
    "sliding_error": "rigid law, sliding rule",
    "exact_error": "exact Coulomb, Newton",
    "exact_energetic_error": "exact Coulomb, energetic",
    "exact_two_error": "exact Coulomb, both corners of the side",
}


def markdown_table(summary, quantities=tuple(QUANTITIES), headers=None):
    """A Markdown table of :func:`summarise_bounds`: medians [95 % interval], m/s; ``headers``
    (name -> column title) adds to or overrides :data:`HEADERS`."""
    titles = {**HEADERS, **(headers or {})}
    header = ["landing tilt", "impacts"] + [titles.get(name, name) for name in quantities]
    lines = ["| " + " | ".join(header) + " |", "|" + "---|" * len(header)]
    for entry in summary:
        cells = [entry["label"], str(entry["impacts"])]
        for name in quantities:
            stats = entry[name]
            cells.append("-" if stats is None else f"{stats['median']:.3f} [{stats['low']:.3f}, {stats['high']:.3f}]")
        lines.append("| " + " | ".join(cells) + " |")
    return "\n".join(lines)
