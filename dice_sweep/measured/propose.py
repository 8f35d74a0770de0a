"""Proposals: a formula for what no effect explains (issue 30, item 4).

When the effects of the library leave the tracks' error above the floor, this module fits
sparse formulas to what a fitted model leaves, and says which terms the residual needs. It
never names an effect of the library: only terms of two fixed libraries.

* **Flights.** Every free flight of every track (:func:`dice_sweep.measured.fit.prepare_tracks`)
  with at least ``MIN_FLIGHT_FRAMES`` frames gets a quadratic in t for each of x, y and phi
  about its middle frame time. Its second coefficients are the flight's mean accelerations,
  its first the velocities there. The model is run by the kernel (all its effects, the
  measurement maps included) from the quadratics' state at the flight's first frame over the
  flight's frame times, lifted by ``ELEVATION`` so that no corner meets the table, and its
  poses get the same quadratic: the flight's *residual acceleration* is the measured curvature
  less the model's (the same projection of both, so what the quadratic misses of the model's
  own curve cancels). Its noise variance is the tracking sigma squared times the quadratic's
  variance factor. Targets ``flight.x_acc``, ``flight.y_acc`` (m/s^2), ``flight.phi_acc``
  (rad/s^2); terms :data:`FLIGHT_TERMS` at the middle frame (the quadratics' velocities and
  angle; ``abs(v)`` is the speed of the centre).
* **Impacts.** Every clean impact (:func:`dice_sweep.measured.calibrate.trackset_impacts` and
  :func:`~dice_sweep.measured.calibrate.impact_row`, as ``calibrate`` finds and judges them).
  The kernel runs the model from the before-side fit's state at the last frame before the
  impact, through the impact, to the after-side frames; a line in t (y with the fall of g taken
  out) through the measured after-side frames and one through the model's poses at the same
  times give the velocities at the first after frame, and the *velocity misfit* is measured
  less model: ``impact.dvx``, ``impact.dvy`` (m/s), ``impact.domega`` (rad/s). Its noise variance
  is that of the two sides' slopes. Terms :func:`impact_terms`: ``1``, the touching corner's
  normal and tangential velocity before (``u_n``, ``u_t``, m/s; u_n < 0 approaching), the spin
  ``omega``, the landing ``tilt`` (rad, 0 flat), the touching corner ``corner_k`` (one-hot),
  ``corner_k*u_n``, and the lowest side ``side_k`` (one-hot; side k joins corners k and k + 1).

Then, per target (:func:`sparse_fit`):

1. Weights: 1 / (noise variance + tau^2), tau^2 the scatter the noise does not explain
   (Paule-Mandel, on the full library's fit), times Huber weights (``HUBER`` standard
   deviations) of that fit's residuals, computed once.
2. Sparsity by cross-validation over tracks (``FOLDS`` folds of whole tracks, the
   independent units): for each size s = 0 .. ``MAX_TERMS`` the best subset of s terms on the
   training tracks (every subset when there are at most ``EXHAUSTIVE`` of them, else forward
   steps), its held-out weighted squared error on each held-out track; the smallest size within
   one standard error (over tracks) of the best is chosen, and cut back while its last term
   does not lower the held-out errors significantly (the one-sided signed-rank statistic over
   tracks of the step's per-track gains below ``STEP_Z``, 1.64).
3. The held-out gain is 1 - (held-out error at that size) / (held-out error of the model as
   it is, no term); its significance the one-sided signed-rank statistic over tracks of the
   per-track held-out gains. A proposal needs that statistic above ``PROPOSAL_Z`` and a gain
   of at least ``MIN_GAIN``.
4. The chosen subset is fitted on all tracks; 95 % intervals from ``BOOTSTRAP`` resamples of
   tracks. A term whose interval holds 0 is dropped and the rest refitted (its held-out gain
   is then that of the fixed remaining terms); nothing left, no proposal.

docs/measured_method.md ("Proposals: a formula for what no effect explains") states the
method and its null calibration.
"""

import itertools
import math
from dataclasses import dataclass
from statistics import NormalDist

import numpy as np

from dice_sweep.measured import fit as shooting
from dice_sweep.measured.calibrate import impact_row, trackset_impacts
from dice_sweep.measured.noise import tracking_noise
from dice_sweep.measured.stats import LEVEL, sidak_bound, signed_rank_z

__all__ = ["FLIGHT_TERMS", "FLIGHT_TARGETS", "IMPACT_TARGETS", "TARGETS", "impact_terms", "Rows", "flight_rows",
           "impact_rows", "sparse_fit", "propose_report", "propose"]

FLIGHT_TERMS = ("1", "vx", "vy", "omega", "abs(v)*vx", "abs(v)*vy", "abs(omega)*omega", "cos(phi)", "sin(phi)",
                "omega*vx", "omega*vy")
FLIGHT_TARGETS = ("flight.x_acc", "flight.y_acc", "flight.phi_acc")
IMPACT_TARGETS = ("impact.dvx", "impact.dvy", "impact.domega")
TARGETS = FLIGHT_TARGETS + IMPACT_TARGETS
UNITS = {"flight.x_acc": "m/s^2", "flight.y_acc": "m/s^2", "flight.phi_acc": "rad/s^2", "impact.dvx": "m/s",
         "impact.dvy": "m/s", "impact.domega": "rad/s"}
MIN_FLIGHT_FRAMES = 6  # frames a flight needs for a quadratic with spare degrees of freedom
ELEVATION = 1.0  # m: the model's flights are run this high, clear of the table
MAX_TERMS = 3  # terms per target, at most
FOLDS = 5
BOOTSTRAP = 1000
EXHAUSTIVE = 5000  # subsets of at most MAX_TERMS terms tried one by one up to this many, else forward steps
HUBER = 3.0  # standardised residuals beyond this are down-weighted (Huber)
CONDITION = 1e10  # a subset whose normal matrix is worse conditioned is skipped (collinear terms)
STEP_Z = NormalDist().inv_cdf(1.0 - LEVEL)  # each term added must lower the held-out errors of most tracks (signed rank)
# The statistic a proposal's held-out gain must beat: the Sidak bound for the six targets at
# LEVEL (2.39), raised to the largest value seen on control data (the independent generator
# with the library's own physics, nothing missing) where that was higher; docs/measured_method.md
# gives the calibration.
SIDAK_Z = sidak_bound(len(TARGETS))
PROPOSAL_Z = SIDAK_Z
MIN_GAIN = 0.01  # share of the residual's weighted variance a proposal must remove on held-out tracks


# --- rows ----------------------------------------------------------------------------------


@dataclass
class Rows:
    """Per row (a flight or an impact): targets (rows, k), their noise variances (rows, k),
    features (rows, p) named ``terms``, and the track (trajectory id) it belongs to."""

    targets: tuple
    values: np.ndarray
    variance: np.ndarray
    terms: tuple
    features: np.ndarray
    traj: np.ndarray

    @property
    def count(self):
        return int(self.values.shape[0])


@dataclass
class _Samples:
    """What :class:`dice_sweep.measured.fit.ShootingModel` needs of its segments: each segment's
    times from its start (file s) and the row offsets."""

    times: np.ndarray
    starts: np.ndarray

    @property
    def count(self):
        return len(self.starts) - 1


def _model(model, cfg):
    """(spec, params) of a fitted model: a FitResult (``.spec``, ``.params``), a (spec, params)
    pair, or a dict of parameters of the declared model."""
    if hasattr(model, "spec") and hasattr(model, "params"):
        return model.spec, dict(model.params)
    if isinstance(model, tuple):
        return model[0], dict(model[1])
    spec = shooting.ModelSpec.of(cfg)
    values = shooting.start_values(cfg, spec)
    values.update(model or {})
    return spec, values


def _simulate(cfg, spec, params, states, times):
    """The model's poses (file units) from ``states`` (segments, 6; file units) at ``times``
    (a list of arrays, s from each state)."""
    starts = np.concatenate([[0], np.cumsum([t.size for t in times])]).astype(np.int64)
    samples = _Samples(np.concatenate(times) if times else np.zeros(0), starts)
    poses, _ = shooting.ShootingModel(cfg, spec, samples).simulate(params, np.ascontiguousarray(states, dtype=float))
    return [poses[starts[k]:starts[k + 1]] for k in range(len(times))]


def _quadratic(tau):
    """Design (frames, 3) of a quadratic p0 + p1 tau + p2 tau^2 / 2, and its projection (3, frames)."""
    design = np.column_stack([np.ones_like(tau), tau, 0.5 * tau * tau])
    return design, np.linalg.pinv(design)


def flight_rows(prepared, cfg, spec, params, sigma):
    """Residual accelerations of the free flights (targets :data:`FLIGHT_TARGETS`).

    Parameters
    ----------
    prepared : list of dice_sweep.measured.fit.PreparedTrack
    cfg : dice_sweep.config.Config
    spec, params
        The fitted model (:class:`~dice_sweep.measured.fit.ModelSpec` and its parameters).
    sigma : array_like, shape (3,)
        Tracking noise sigma of x, y (m) and phi (rad).

    Returns
    -------
    Rows
    """
    sigma = np.asarray(sigma, dtype=float)
    kept, states, times, projections, features, variance, traj, measured = [], [], [], [], [], [], [], []
    for prep in prepared:
        for first, last in prep.flights:
            if last - first + 1 < MIN_FLIGHT_FRAMES:
                continue
            t = prep.t[first:last + 1]
            pose = prep.pose[first:last + 1]
            mid = 0.5 * (t[0] + t[-1])
            design, proj = _quadratic(t - mid)
            coef = proj @ pose  # (3, 3): rows p0, p1, p2; columns x, y, phi
            a, v, acc = coef
            start = t[0] - mid
            state = np.r_[a + v * start + 0.5 * acc * start * start, v + acc * start]
            state[1] += ELEVATION
            states.append(state)
            times.append(t - t[0])
            projections.append(proj)
            measured.append(acc)
            factor = float(np.linalg.pinv(design.T @ design)[2, 2])
            variance.append(sigma**2 * factor)
            vx, vy, w = v
            speed = math.hypot(vx, vy)
            phi = a[2]
            features.append([1.0, vx, vy, w, speed * vx, speed * vy, abs(w) * w, math.cos(phi), math.sin(phi), w * vx, w * vy])
            traj.append(prep.traj)
    values = np.zeros((0, 3))
    if states:
        simulated = _simulate(cfg, spec, params, np.array(states), times)
        model_acc = np.array([proj @ (poses - [0.0, ELEVATION, 0.0]) for proj, poses in zip(projections, simulated)])[:, 2, :]
        values = np.array(measured) - model_acc
    return Rows(FLIGHT_TARGETS, values, np.array(variance).reshape(-1, 3), FLIGHT_TERMS,
                np.array(features, dtype=float).reshape(-1, len(FLIGHT_TERMS)), np.array(traj, dtype=np.int64))


def impact_terms(sides):
    """The impact library's term names for an n-gon."""
    return (("1", "u_n", "u_t", "omega", "tilt") + tuple(f"corner_{k}" for k in range(sides))
            + tuple(f"corner_{k}*u_n" for k in range(sides)) + tuple(f"side_{k}" for k in range(sides)))


def _slopes(t, pose, t_ref, g):
    """Velocities (vx, vy, omega) at ``t_ref`` of a line in t through x, y + g dt^2 / 2, phi."""
    dt = t - t_ref
    target = pose.copy()
    target[:, 1] += 0.5 * g * dt * dt
    design = np.column_stack([np.ones_like(dt), dt])
    return np.linalg.lstsq(design, target, rcond=None)[0][1]


def impact_rows(trackset, cfg, spec, params, sigma, found=None):
    """Velocity misfits of the clean impacts (targets :data:`IMPACT_TARGETS`).

    Parameters
    ----------
    trackset : dice_sweep.measured.tracks.TrackSet
        Tracks in the model's convention.
    cfg, spec, params, sigma
        As :func:`flight_rows`.
    found : list, optional
        :func:`dice_sweep.measured.calibrate.trackset_impacts`'s third value, if at hand.

    Returns
    -------
    Rows
    """
    sides, radius, g = cfg.die.sides, cfg.die.circumradius, cfg.world.g
    sigma = np.asarray(sigma, dtype=float)
    if found is None:
        _, _, found = trackset_impacts(trackset, cfg)
    names = impact_terms(sides)
    states, times, rows = [], [], []
    for track, index, imp in found:
        if imp is None:
            continue
        row = impact_row(track.traj, index, imp, sides=sides, circumradius=radius, g=g)
        if not row["clean"]:
            continue
        usable = np.flatnonzero(track.usable)
        before = usable[usable < imp.frame][-imp.before.frames:]
        after = usable[usable > imp.frame][:imp.after.frames]
        if before.size < 2 or after.size < 2:
            continue
        t_start = float(track.t[before[-1]])
        dt = t_start - imp.before.t_contact
        x, y, phi, vx, vy, w = imp.before.state
        states.append([x + vx * dt, y + vy * dt - 0.5 * g * dt * dt, phi + w * dt, vx, vy - g * dt, w])
        times.append(track.t[after] - t_start)
        pose = np.column_stack([track.x[after], track.y[after], track.phi[after]])
        spread_before = float(np.sum((track.t[before] - track.t[before].mean()) ** 2))
        spread_after = float(np.sum((track.t[after] - track.t[after].mean()) ** 2))
        rx, ry = imp.corner
        k = int(round((math.atan2(ry, rx) - phi) / (2.0 * math.pi / sides))) % sides
        heights = np.sin(phi + 2.0 * math.pi * np.arange(sides) / sides)
        lower = (k + 1) % sides if heights[(k + 1) % sides] < heights[(k - 1) % sides] else (k - 1) % sides
        side = k if lower == (k + 1) % sides else lower
        un, ut = row["corner_before"]["un"], row["corner_before"]["ut"]
        onehot = np.zeros(sides)
        onehot[k] = 1.0
        sided = np.zeros(sides)
        sided[side] = 1.0
        rows.append({"traj": track.traj, "pose": pose, "t": track.t[after],
                     "variance": sigma**2 * (1.0 / spread_before + 1.0 / spread_after),
                     "features": np.r_[1.0, un, ut, w, row["tilt"], onehot, onehot * un, sided]})
    values = np.zeros((0, 3))
    if rows:
        simulated = _simulate(cfg, spec, params, np.array(states), times)
        values = np.array([_slopes(r["t"], r["pose"], r["t"][0], g) - _slopes(r["t"], model, r["t"][0], g)
                           for r, model in zip(rows, simulated)])
    return Rows(IMPACT_TARGETS, values, np.array([r["variance"] for r in rows]).reshape(-1, 3), names,
                np.array([r["features"] for r in rows], dtype=float).reshape(-1, len(names)),
                np.array([r["traj"] for r in rows], dtype=np.int64))


# --- sparse regression ---------------------------------------------------------------------


def _solve(gram, rhs, subset):
    """Coefficients of ``subset`` from the normal equations, or None when they are too badly
    conditioned (collinear terms)."""
    if not subset:
        return np.zeros(0)
    g = gram[np.ix_(subset, subset)]
    if np.linalg.cond(g) > CONDITION:
        return None
    return np.linalg.solve(g, rhs[list(subset)])


def _rss_drop(gram, rhs, subset):
    """How much ``subset``'s least-squares fit lowers the weighted sum of squares (b' G^-1 b)."""
    beta = _solve(gram, rhs, subset)
    return -math.inf if beta is None else float(beta @ rhs[list(subset)])


def _best_subsets(gram, rhs, max_terms):
    """The best subset (tuple of column indices) of each size 0 .. max_terms: every subset when
    there are at most EXHAUSTIVE, else forward steps."""
    p = gram.shape[0]
    best = [()]
    total = sum(math.comb(p, s) for s in range(1, max_terms + 1))
    if total <= EXHAUSTIVE:
        for size in range(1, min(max_terms, p) + 1):
            scored = [(_rss_drop(gram, rhs, c), c) for c in itertools.combinations(range(p), size)]
            drop, chosen = max(scored, key=lambda item: item[0])
            best.append(chosen if math.isfinite(drop) else best[-1])
        return best
    current = ()
    for _ in range(min(max_terms, p)):
        scored = [(_rss_drop(gram, rhs, tuple(sorted(current + (j,)))), j) for j in range(p) if j not in current]
        drop, j = max(scored, key=lambda item: item[0])
        if math.isfinite(drop):
            current = tuple(sorted(current + (j,)))
        best.append(current)
    return best


def _track_sums(z, y, weight, group, groups):
    """Per track: Gram matrices (T, p, p), right-hand sides (T, p) and sums of w y^2 (T,)."""
    p = z.shape[1]
    gram = np.zeros((groups, p, p))
    np.add.at(gram, group, weight[:, None, None] * z[:, :, None] * z[:, None, :])
    rhs = np.zeros((groups, p))
    np.add.at(rhs, group, (weight * y)[:, None] * z)
    total = np.bincount(group, weight * y * y, minlength=groups)
    return gram, rhs, total


def _held_out(gram_t, rhs_t, total_t, subset, beta):
    """Weighted squared error of each track under coefficients ``beta`` of ``subset``."""
    if not subset:
        return total_t.copy()
    s = list(subset)
    g = gram_t[:, s][:, :, s]
    return total_t - 2.0 * rhs_t[:, s] @ beta + np.einsum("i,tij,j->t", beta, g, beta)


def _weights(z, y, variance):
    """Row weights 1 / (noise variance + tau^2) times Huber weights, from the full library's
    fit; and tau^2."""
    from scipy.optimize import brentq

    p = z.shape[1]
    huber = np.ones_like(y)
    tau2 = 0.0
    for _ in range(3):
        w = huber / (variance + tau2)
        gram = z.T @ (w[:, None] * z) + 1e-10 * np.trace(z.T @ (w[:, None] * z)) / p * np.eye(p)
        beta = np.linalg.solve(gram, z.T @ (w * y))
        r = y - z @ beta
        dof = max(float(huber.sum()) - p, 1.0)

        def excess(t2):
            return float(np.sum(huber * r * r / (variance + t2))) - dof

        tau2 = 0.0 if excess(0.0) <= 0.0 else brentq(excess, 0.0, float(np.max(r * r)) * 10.0 + 1e-300)
        scaled = np.abs(r) / np.sqrt(variance + tau2)
        huber = np.minimum(1.0, HUBER / np.maximum(scaled, 1e-300))
    return huber / (variance + tau2), tau2


def _cross_validate(gram_t, rhs_t, total_t, fold_of_track, folds, max_terms, fixed=None):
    """Held-out weighted squared error per size (sizes, T) and per track, selecting the best
    subset of each size on the training tracks (or fitting ``fixed`` terms only)."""
    sizes = 1 if fixed is not None else max_terms + 1
    errors = np.zeros((sizes, total_t.size))
    gram, rhs = gram_t.sum(axis=0), rhs_t.sum(axis=0)
    for f in range(folds):
        out = fold_of_track == f
        if not out.any():
            continue
        g_train, b_train = gram - gram_t[out].sum(axis=0), rhs - rhs_t[out].sum(axis=0)
        subsets = [fixed] if fixed is not None else _best_subsets(g_train, b_train, max_terms)
        for s, subset in enumerate(subsets):
            beta = _solve(g_train, b_train, subset)
            if beta is None:  # collinear in this fold: no correction
                subset, beta = (), np.zeros(0)
            errors[s, out] = _held_out(gram_t[out], rhs_t[out], total_t[out], subset, beta)
    return errors


def _bootstrap(gram_t, rhs_t, subset, rng, draws):
    """Coefficients of ``subset`` refitted on ``draws`` resamples of tracks (draws, |subset|)."""
    s = list(subset)
    counts = rng.multinomial(gram_t.shape[0], np.full(gram_t.shape[0], 1.0 / gram_t.shape[0]), size=draws).astype(float)
    g = np.einsum("bt,tij->bij", counts, gram_t[:, s][:, :, s])
    b = counts @ rhs_t[:, s]
    good = np.linalg.cond(g) < CONDITION
    out = np.full((draws, len(s)), np.nan)
    out[good] = np.linalg.solve(g[good], b[good][:, :, None])[:, :, 0]
    return out


def sparse_fit(y, variance, features, terms, traj, *, folds=FOLDS, max_terms=MAX_TERMS, bootstrap=BOOTSTRAP, seed=0,
               threshold=None, min_gain=MIN_GAIN):
    """A sparse formula for one target (the module docstring gives the steps).

    Parameters
    ----------
    y, variance : array_like, shape (rows,)
        The target and its noise variance per row.
    features : array_like, shape (rows, p)
        The terms' values per row, named by ``terms``.
    traj : array_like of int, shape (rows,)
        The track of each row (the units of cross-validation and bootstrap).
    threshold : float, optional
        The signed-rank statistic a proposal must beat (default ``PROPOSAL_Z``).

    Returns
    -------
    dict
        ``proposed`` (bool), ``terms`` {term: coefficient}, ``ci95`` {term: [lo, hi]},
        ``heldout_gain``, ``z`` (the held-out gain's signed-rank statistic over tracks),
        ``size`` (terms chosen by cross-validation), ``step_z`` (the signed-rank statistic of
        each size's held-out gain over the size before), ``dropped`` (terms whose interval held 0),
        ``cv_error`` (held-out weighted squared error per size), ``tau`` (the scatter beyond the
        noise, target units), ``rows``, ``tracks``, ``reason`` (why nothing is proposed).
    """
    threshold = PROPOSAL_Z if threshold is None else threshold
    y = np.asarray(y, dtype=float)
    variance = np.asarray(variance, dtype=float)
    features = np.asarray(features, dtype=float)
    traj = np.asarray(traj, dtype=np.int64)
    ok = np.isfinite(y) & np.isfinite(variance) & (variance > 0) & np.isfinite(features).all(axis=1)
    y, variance, features, traj = y[ok], variance[ok], features[ok], traj[ok]
    labels, group = np.unique(traj, return_inverse=True)
    result = {"proposed": False, "terms": {}, "ci95": {}, "heldout_gain": 0.0, "z": 0.0, "size": 0, "step_z": [], "dropped": [],
              "cv_error": [], "tau": math.nan, "rows": int(y.size), "tracks": int(labels.size), "reason": ""}
    if labels.size < 2 * folds or y.size <= len(terms):
        result["reason"] = f"too few tracks ({labels.size}) or rows ({y.size})"
        return result
    scale = np.sqrt(np.mean(features**2, axis=0))
    scale[scale == 0.0] = 1.0
    z = features / scale
    weight, tau2 = _weights(z, y, variance)
    result["tau"] = math.sqrt(tau2)
    gram_t, rhs_t, total_t = _track_sums(z, y, weight, group, labels.size)
    rng = np.random.default_rng(seed)
    fold_of_track = _fold_of(labels, folds, seed)
    errors = _cross_validate(gram_t, rhs_t, total_t, fold_of_track, folds, max_terms)
    cv = errors.sum(axis=1)
    result["cv_error"] = [float(e) for e in cv]
    best = int(np.argmin(cv))
    size = best
    for s in range(best):
        diff = errors[s] - errors[best]
        if cv[s] <= cv[best] + math.sqrt(labels.size) * float(np.std(diff, ddof=1)):
            size = s
            break
    steps = [signed_rank_z(errors[s - 1] - errors[s]) for s in range(1, errors.shape[0])]
    result["step_z"] = [float(v) for v in steps]
    while size and steps[size - 1] < STEP_Z:  # the last term chosen must pay its way on most tracks
        size -= 1
    result["size"] = size
    gain = 1.0 - cv[size] / cv[0] if cv[0] > 0 else 0.0
    zstat = signed_rank_z(errors[0] - errors[size]) if size else 0.0
    result.update(heldout_gain=float(gain), z=float(zstat))
    if size == 0:
        result["reason"] = "cross-validation chose no term"
        return result
    gram, rhs = gram_t.sum(axis=0), rhs_t.sum(axis=0)
    subset = _best_subsets(gram, rhs, size)[size]
    dropped = []
    while subset:
        beta = _solve(gram, rhs, subset)
        draws = _bootstrap(gram_t, rhs_t, subset, rng, bootstrap)
        low, high = np.nanpercentile(draws, [2.5, 97.5], axis=0)
        holds = [(k, j) for k, j in enumerate(subset) if low[k] <= 0.0 <= high[k]]
        if not holds:
            break
        # the weakest term (its interval furthest over 0, relative to its width) goes
        k, j = max(holds, key=lambda h: min(-low[h[0]], high[h[0]]) / max(high[h[0]] - low[h[0]], 1e-300))
        dropped.append(terms[j])
        subset = tuple(i for i in subset if i != j)
    result["dropped"] = dropped
    if not subset:
        result["reason"] = "every chosen term's 95 % interval holds 0"
        return result
    if dropped:
        fixed = _cross_validate(gram_t, rhs_t, total_t, fold_of_track, folds, max_terms, fixed=subset)[0]
        gain = 1.0 - fixed.sum() / cv[0] if cv[0] > 0 else 0.0
        zstat = signed_rank_z(errors[0] - fixed)
        result.update(heldout_gain=float(gain), z=float(zstat))
    result["terms"] = {terms[j]: float(beta[k] / scale[j]) for k, j in enumerate(subset)}
    result["ci95"] = {terms[j]: [float(low[k] / scale[j]), float(high[k] / scale[j])] for k, j in enumerate(subset)}
    if result["z"] < threshold:
        result["reason"] = f"held-out gain not significant (z = {result['z']:.2f} < {threshold:.2f})"
    elif result["heldout_gain"] < min_gain:
        result["reason"] = f"held-out gain {result['heldout_gain']:.3f} below {min_gain}"
    else:
        result["proposed"] = True
    return result


def _fold_of(labels, folds, seed):
    """Fold of each track (labels sorted): a seeded permutation dealt round-robin."""
    rng = np.random.default_rng([seed, 30])
    fold = np.empty(labels.size, dtype=np.int64)
    fold[rng.permutation(labels.size)] = np.arange(labels.size) % folds
    return fold


# --- entry points --------------------------------------------------------------------------


def propose_report(trackset, cfg, model, *, sigma=None, table=None, prepared=None, found=None, seed=0, folds=FOLDS,
                   max_terms=MAX_TERMS, bootstrap=BOOTSTRAP, threshold=None, min_gain=MIN_GAIN):
    """Sparse formulas for the residual a fitted model leaves on tracked drops, with everything
    that decided them.

    Parameters
    ----------
    trackset : dice_sweep.measured.tracks.TrackSet
        Tracks in the model's convention.
    cfg : dice_sweep.config.Config
        The config the model was fitted with.
    model
        The fitted model: a :class:`dice_sweep.measured.fit.FitResult` (``spec`` and ``params``,
        as ``diagnose`` and ``fit`` produce), a (spec, params) pair, or a dict of the declared
        model's parameters.
    sigma : array_like, optional
        Tracking noise sigma of x, y (m) and phi (rad); measured when None (as
        :func:`dice_sweep.measured.diagnose.tracking_noise` measures it), with the table's height.
    table : float, optional
        The table's height in the file (m), for the flights' contact tests.
    prepared : list, optional
        :func:`dice_sweep.measured.fit.prepare_tracks` of the same tracks, if at hand.
    found : list, optional
        :func:`dice_sweep.measured.calibrate.trackset_impacts`'s impacts, if at hand.
    seed, folds, max_terms, bootstrap, threshold, min_gain
        See :func:`sparse_fit`.

    Returns
    -------
    dict
        ``proposals`` (as :func:`propose`), ``targets`` (per target the whole
        :func:`sparse_fit` result, ``unit`` too), ``threshold_z``, ``min_gain``, ``flights``
        and ``impacts`` (rows used), ``method``.
    """
    spec, params = _model(model, cfg)
    if sigma is None or (prepared is None and table is None):
        measured_table, _, measured_sigma = tracking_noise(trackset, cfg)
        sigma = measured_sigma if sigma is None else sigma
        table = measured_table if table is None else table
    if prepared is None:
        prepared = shooting.prepare_tracks(trackset, cfg, noise=np.asarray(sigma, dtype=float), table=table)
    threshold = PROPOSAL_Z if threshold is None else threshold
    flights = flight_rows(prepared, cfg, spec, params, sigma)
    impacts = impact_rows(trackset, cfg, spec, params, sigma, found=found)
    targets, proposals = {}, []
    for rows in (flights, impacts):
        for k, name in enumerate(rows.targets):
            fitted = sparse_fit(rows.values[:, k], rows.variance[:, k], rows.features, rows.terms, rows.traj, folds=folds,
                                max_terms=max_terms, bootstrap=bootstrap, seed=seed, threshold=threshold, min_gain=min_gain)
            fitted["unit"] = UNITS[name]
            targets[name] = fitted
            if fitted["proposed"]:
                proposals.append({"target": name, "terms": fitted["terms"], "ci95": fitted["ci95"],
                                  "heldout_gain": fitted["heldout_gain"], "z": fitted["z"], "unit": UNITS[name],
                                  "tracks": fitted["tracks"], "rows": fitted["rows"]})
    return {
        "proposals": proposals,
        "targets": targets,
        "threshold_z": threshold,
        "min_gain": min_gain,
        "flights": flights.count,
        "impacts": impacts.count,
        "method": ("residual accelerations of free flights (quadratic in t per flight, measured less the model's on the same "
                   "frames) and velocity misfits of clean impacts (measured less the model run from the measured state before), "
                   f"sparse regression on term libraries: best subset of at most {max_terms} terms, size by {folds}-fold "
                   "cross-validation over tracks (one-standard-error rule), weights 1 / (noise variance + tau^2) with Huber "
                   f"down-weighting; proposed when the held-out gain's signed-rank z over tracks beats {threshold:.2f} and removes "
                   f"at least {min_gain:.0%}; 95 % intervals by bootstrap over tracks ({bootstrap}); terms whose interval holds 0 dropped"),
    }


def propose(trackset, cfg, model, **options):
    """Proposals for what a fitted model leaves: a list of ``{target, terms: {term: coefficient},
    ci95: {term: [lo, hi]}, heldout_gain}`` (plus ``z``, ``unit``, ``tracks`` and ``rows``), one
    per target whose sparse formula passes (:func:`propose_report` takes the same arguments)."""
    return propose_report(trackset, cfg, model, **options)["proposals"]
