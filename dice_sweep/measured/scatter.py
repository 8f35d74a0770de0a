"""How much a real bounce scatters around the best deterministic law: the ``[scatter]``
spreads estimated from tracked drops, with 95 % intervals (issue 31).

The model (docs/physics.md, "Scattered impacts"): each impact's velocity jump is the
deterministic law's plus a Gaussian of variance floor^2 + (sigma v (u / v)^p)^2 per
component of (vx, vy, sqrt(I/M) omega), u the touching corner's approach speed, v = sqrt(g R),
sigma and floor by the landing tilt (``corner`` or ``flat``), the power p shared. The estimator
(docs/measured_method.md, "The scatter of real bounces"), per clean impact i of the tracks
given (calibrate's impacts and cleanliness rules):

1. the state just before it (the free-flight fit of the frames before, followed to the table)
   is rolled by the kernel at the fitted parameters, deterministic, from BACKOFF before the
   contact to the middle of the after-fit's frames; the residual r_i is the measured velocity
   there (the fit of the frames after) minus the kernel's, in (vx, vy, sqrt(I/M) omega). An
   impact after which the kernel has another impact within the after-fit's frames is left
   out (that fit is not of one flight);
2. the tracking noise's share of |r_i|^2, n_i, is measured by REPLICATES refits with
   Gaussian noise of the tracking sigma added to the frames: E|r'_i - r_i|^2 = n_i in the
   linear regime;
3. impacts whose noise share alone is a spread above UNSTABLE are left out (counted); the
   rest's residual components are taken as Gaussian of variance floor^2 + sigma^2 v^2 (u_i /
   v)^(2p) + n_i / 3, and floor, sigma of each kind (>= 0) by maximum likelihood at each power
   p of POWERS, p the one whose summed likelihood over both kinds is largest. (Until issue 31's
   third pass: p = 1 and two rounds of weighted least squares, whose second round's weights,
   from the first round's line, could give one slow impact most of the weight: the real
   corner floor came out 0.273 where the likelihood's is 0.129);
4. 95 % intervals from BOOTSTRAP resamples of the tracks (the independent units; a track's
   impacts of both kinds together), the power chosen again in each (an interval of sigma or
   the floor reaching 0 holds 0: no scatter of that form is within the data).

What this sigma holds: every way the real impact differs from the fitted law's, systematic
or random, at the scale of the approach speed. That is what a forecast's ensemble lacks.

The jump's shape (:func:`estimate_shape`, issue 31's fourth pass): the same impacts component
by component under the mixture law (a share w of impacts k times wider, the spin component c
times the others; docs/measured_method.md, "The jump's shape"), by its own likelihood.
"""

import math
from dataclasses import dataclass

import numpy as np

from dice_sweep import effects as registry
from dice_sweep.measured.calibrate import impact_row
from dice_sweep.measured.fit import kernel_config
from dice_sweep.measured.impacts import FIT_FRAMES, find_impacts, fit_impact, landing_tilt
from dice_sweep.physics.kernel import roll_one, sample_records
from dice_sweep.physics.layout import COUNT_COLUMNS, EVENT_IMPACT, REC_EVENT, REC_T, REC_WIDTH
from dice_sweep.physics.params import FP_INERTIA, FP_TMAX, IP_CONTINUE, pack_params
from dice_sweep.physics.scatter import FLAT_TILT

__all__ = ["ImpactResidual", "impact_residuals", "estimate_spreads", "estimate_shape", "spreads_law", "shape_law", "excess_kurtosis", "scatter_section",
           "fitted_scatter", "jump_sd", "KINDS", "POWERS", "SHAPE_POWERS"]

BACKOFF = 2e-3  # s (true time) before the fitted contact the kernel starts: clear of the table
REPLICATES = 16  # noisy refits per impact: half probe its stability, half measure its noise share
BOOTSTRAP = 2000  # resamples of the tracks
KINDS = registry.SCATTER_KINDS  # the [scatter] landing kinds, by tilt (FLAT_TILT)
# An impact whose noise share alone is a relative spread above this is left out: the kernel's
# outcome jumps within the tracking noise there (a second corner joining or not, a pivot or a
# bounce), and such refits gave noise shares 10 times the residual on synthetic drops. The rule
# reads the state before the impact only, not its outcome, so it selects no jump sizes.
UNSTABLE = 0.1
RECORDS = 64  # segments kept of the kernel's roll through one impact


@dataclass(frozen=True)
class ImpactResidual:
    """One clean impact: its track, kind, approach speed u (m/s), squared residual |r|^2 and
    noise share n ((m/s)^2), both in the kinetic-energy metric; ``probe2``: the noise share
    from other replicates, which alone decides whether the impact is unstable (selecting on
    ``noise2`` itself would keep its underestimates and bias sigma up)."""

    traj: int
    kind: str
    approach: float
    residual2: float
    noise2: float
    probe2: float
    impact: int = -1  # its index among the track's impacts (0: the first), for the checks by impact
    # per component (vx, vy, sqrt(I/M) omega): squared residual and noise share, for the checks of the form
    components2: tuple = ()
    noise_components2: tuple = ()


def _kernel(cfg, effects, params):
    """fpar, ipar of the fitted model, deterministic, followed past the decision; and the
    measurement maps file -> true."""
    spec_cfg = kernel_config(cfg, _spec(cfg, effects), params)
    fpar, ipar = pack_params(spec_cfg)
    ipar[IP_CONTINUE] = 1
    times_to_true, state_to_true, _ = registry.measurement_maps(cfg, params)
    return fpar, ipar, times_to_true, state_to_true, spec_cfg


def _spec(cfg, effects):
    from dice_sweep.measured.fit import ModelSpec

    return ModelSpec.of(cfg, tuple(e for e in effects if e not in registry.declared_effects(cfg)))


def _backed_off(state, tau, g):
    """A free-flight state moved back by tau seconds (m, rad, m/s)."""
    x, y, phi, vx, vy, w = state
    return np.array([x - vx * tau, y - vy * tau - 0.5 * g * tau * tau, phi - w * tau, vx, vy + g * tau, w])


def _ahead(state, tau, g):
    x, y, phi, vx, vy, w = state
    return np.array([x + vx * tau, y + vy * tau - 0.5 * g * tau * tau, phi + w * tau, vx, vy - g * tau, w])


class _Predictor:
    """The kernel's velocity at the middle of an impact's after-fit frames."""

    def __init__(self, cfg, effects, params):
        self.fpar, self.ipar, self.times_to_true, self.state_to_true, self.kcfg = _kernel(cfg, effects, params)
        self.g = self.kcfg.world.g
        self.lever = math.sqrt(self.fpar[FP_INERTIA])  # sqrt(I/M), m: spin in the kinetic-energy metric

    def true(self, impact, table, window):
        """(before state, after state at the comparison time, that time from the kernel's
        start, the after-fit's window from it) in true units for one fitted impact (file units,
        y from ``table``; ``window``: file times of the after-fit's first and last frames)."""
        before = impact.before.state.copy()
        after = impact.after.state.copy()
        before[1] -= table
        after[1] -= table
        before, after = self.state_to_true(np.array([before, after]))
        t0 = impact.before.t_contact
        first, last, contact = self.times_to_true(np.array([window[0] - t0, window[1] - t0, impact.after.t_contact - t0]))
        middle = 0.5 * (first + last)
        return before, _ahead(after, middle - contact, self.g), BACKOFF + middle, (BACKOFF + first, BACKOFF + last)

    def residual(self, case):
        """The residual vector (3,) in the kinetic-energy metric of one case of :meth:`true`,
        and whether the kernel has an impact inside the after-fit's window (its fit is then
        not of one flight)."""
        before, after, when, (first, last) = case
        fpar = self.fpar.copy()
        fpar[FP_TMAX] = last + BACKOFF
        rec = np.zeros((RECORDS, REC_WIDTH))
        counts = np.zeros(len(COUNT_COLUMNS), np.int32)
        *_, n_rec = roll_one(fpar, self.ipar, _backed_off(before, BACKOFF, self.g), rec, counts)
        out = np.empty((1, 6))
        sample_records(fpar, self.ipar, rec, n_rec, np.array([when]), out)
        times = rec[:n_rec, REC_T][rec[:n_rec, REC_EVENT] == EVENT_IMPACT]
        crowded = bool(np.any((times >= first) & (times <= last))) or n_rec == RECORDS
        d = after[3:] - out[0, 3:]
        d[2] *= self.lever
        return d, crowded


def _approach(state, sides, radius):
    """The lowest corner's approach speed (m/s) of a state just before contact."""
    angles = state[2] + 2.0 * np.pi * np.arange(sides) / sides
    k = int(np.argmin(np.sin(angles)))
    return -(state[4] + state[5] * radius * math.cos(angles[k]))


def impact_residuals(tracks, cfg, effects, params, *, sigma, table=0.0, seed=0, replicates=REPLICATES):
    """:class:`ImpactResidual` of every clean impact of ``tracks`` (Track objects, file units)
    for the fitted model (``effects`` added to the config's, ``params`` its values), with the
    tracking noise ``sigma`` (x, y in m, phi in rad) for the noise share."""
    sides, radius, g = cfg.die.sides, cfg.die.circumradius, float(params.get("g", cfg.world.g))
    floor = 0.2 * math.sqrt(g * radius)  # calibrate's MIN_SPEED: slower approaches give no coefficient either
    die = {"sides": sides, "circumradius": radius, "table": table, "g": g}
    rng = np.random.default_rng([seed, 31])
    predictor = _Predictor(cfg, effects, params)
    out = []
    for track in tracks:
        usable = track.usable
        frames = np.flatnonzero(usable)
        found = find_impacts(track.t, track.y, track.phi, usable, **die)
        for k, frame in enumerate(found):
            around = {"previous": found[k - 1] if k else None, "following": found[k + 1] if k + 1 < len(found) else None}
            impact = fit_impact(track.t, track.x, track.y, track.phi, usable, frame, **around, **die)
            if impact is None or not impact_row(track.traj, k, impact, sides=sides, circumradius=radius, g=g)["clean"]:
                continue
            stop = track.t.size if around["following"] is None else around["following"]
            fitted = frames[(frames > frame) & (frames < stop)][:FIT_FRAMES]  # the after-fit's frames, as fit_impact takes them
            window = (track.t[fitted[0]], track.t[fitted[-1]])
            case = predictor.true(impact, table, window)
            u = _approach(case[0], sides, radius)
            residual, crowded = predictor.residual(case)
            if u < floor or crowded:
                continue
            kind = "corner" if landing_tilt(sides, case[0][2]) >= FLAT_TILT else "flat"
            shares, parts = [], []
            for _ in range(replicates):
                x = track.x + sigma[0] * rng.normal(size=track.x.size)
                y = track.y + sigma[1] * rng.normal(size=track.y.size)
                phi = track.phi + sigma[2] * rng.normal(size=track.phi.size)
                again = fit_impact(track.t, x, y, phi, usable, frame, **around, **die)
                if again is not None:
                    parts.append((predictor.residual(predictor.true(again, table, window))[0] - residual) ** 2)
                    shares.append(float(np.sum(parts[-1])))
            half = len(shares) // 2
            n2 = float(np.mean(shares[half:])) if shares else 0.0
            p2 = float(np.mean(shares[:half])) if half else n2
            noise_parts = tuple(float(v) for v in np.mean(parts[half:], axis=0)) if shares else (0.0, 0.0, 0.0)
            out.append(ImpactResidual(int(track.traj), kind, float(u), float(residual @ residual), n2, p2, k,
                                      tuple(float(v) for v in residual**2), noise_parts))
    return out


def _sigma(value):
    return math.sqrt(max(value, 0.0))


POWERS = tuple(round(0.2 * k, 1) for k in range(21))  # the power's profile grid, 0 to MAX_POWER
IRLS_STEPS = 30  # reweighting steps of the maximum-likelihood fit (on the real drops: settled to 1e-6 by 20)
STARTS = (0.9, 0.5, 0.1)  # shares of the mean square in the floor that the fit starts from
STEP_SHARES = (1.0, 0.5, 0.2)  # of a scoring step, tried in turn; the best that climbs is taken
_TINY = 1e-30  # (m/s)^2: keeps a variance of exactly 0 (no scatter, no noise) out of a division


# Two estimators on the same residuals, on purpose: this one (estimate_spreads) fits the
# isotropic Gaussian law with signed variances, so that with no scatter the estimate is not
# pushed up and its interval straddles 0 (the control of tests/measured/test_scatter.py), and
# profiles the power finely; estimate_shape fits the mixture per component within the law's
# bounds (variances >= 0, w <= 0.5), where a signed variance has no meaning. The mixture held
# at its nulls would be this law with a bound at 0, biased up near 0.


def _kind_arrays(chosen, speed, track_of):
    """Per impact of one kind: the approach in units of ``speed``, |r|^2 / 3, n / 3 ((m/s)^2),
    and its track's row."""
    return (np.array([r.approach for r in chosen]) / speed, np.array([r.residual2 for r in chosen]) / 3.0,
            np.array([r.noise2 for r in chosen]) / 3.0, np.array([track_of[r.traj] for r in chosen]))


def _variance(a, b, x, n):
    """a + b x + n per impact (rows, impacts), kept above 0: a or b may be below 0 (a noise share
    measured high), as long as the variance is not."""
    return np.maximum(a[:, None] + b[:, None] * x + n, _TINY)


def _loglik(a, b, x, y, n, counts):
    """Log-likelihood (rows,) of Gaussian residual components of variance a + b x + n."""
    v = _variance(a, b, x, n)
    return (counts * (-1.5 * np.log(v) - 1.5 * y / v)).sum(axis=1)


def _ml_fit(x, y, n, counts, start):
    """:func:`_fit_from` from the share ``start`` of the mean excess over the noise in a."""
    mean = max(float(np.mean(y - n)), _TINY)
    rows = counts.shape[0]
    return _fit_from(x, y, n, counts, np.full(rows, start * mean), np.full(rows, (1.0 - start) * mean / max(float(np.mean(x)), _TINY)))


def _fit_from(x, y, n, counts, a, b):
    """Maximum likelihood of the per-component variance a + b x + n of Gaussian
    residuals whose mean square is y, each impact counted ``counts`` times (rows: bootstrap
    resamples): Fisher scoring (least squares of y - n on (1, x) weighted by 1 / variance^2),
    each step shortened as far as STEP_SHARES says to climb the likelihood (a full step can
    overshoot to a lower stationary point), from (a, b) (rows,). Returns a, b, log-likelihood,
    each of shape (rows,)."""
    target = y - n
    loglik = _loglik(a, b, x, y, n, counts)
    for _ in range(IRLS_STEPS):
        v = _variance(a, b, x, n)
        w = counts / (v * v)
        sw, sx, sxx = w.sum(axis=1), (w * x).sum(axis=1), (w * x * x).sum(axis=1)
        sy, sxy = (w * target).sum(axis=1), (w * x * target).sum(axis=1)
        det = sw * sxx - sx * sx
        ok = det > 1e-12 * np.maximum(sw * sxx, _TINY)  # one approach speed only: no line, stay
        a_new = np.where(ok, (sxx * sy - sx * sxy) / np.where(ok, det, 1.0), a)
        b_new = np.where(ok, (sw * sxy - sx * sy) / np.where(ok, det, 1.0), b)
        best = (a, b, loglik)
        for share in STEP_SHARES:
            ta, tb = a + share * (a_new - a), b + share * (b_new - b)
            tl = _loglik(ta, tb, x, y, n, counts)
            better = tl > best[2]
            best = tuple(np.where(better, new, old) for new, old in zip((ta, tb, tl), best))
        a, b, loglik = best
    return a, b, loglik


def _best_fit(x, y, n, counts, near=None):
    """(a, b, log-likelihood) of the best line (the likelihood can have more than one
    stationary point: from STARTS, or from ``near``, an (a, b) of the whole sample that a
    resample starts from). a and b are signed, as a least-squares line's would be: an excess
    below the noise share reads below 0, so an interval can reach 0 and hold it."""
    rows = counts.shape[0]
    if near is None:
        fits = [_ml_fit(x, y, n, counts, start) for start in STARTS]
    else:
        fits = [_fit_from(x, y, n, counts, np.full(rows, near[0]), np.full(rows, near[1]))]
    best = fits[0]
    for got in fits[1:]:
        better = got[2] > best[2]
        best = tuple(np.where(better, new, old) for new, old in zip(got, best))
    return best


def _profile(arrays, counts, speed, powers, near=None):
    """For each power: (a, b) per kind and the summed log-likelihood, rows as ``counts``
    (resamples x tracks): {kind: (a (powers, rows), b)}, loglik (powers, rows). ``near``: a
    profile of the whole sample (one row) whose fits the resamples start from."""
    fits = {kind: (np.zeros((len(powers), counts.shape[0])), np.zeros((len(powers), counts.shape[0]))) for kind in arrays}
    total = np.zeros((len(powers), counts.shape[0]))
    for kind, (u, y, n, track) in arrays.items():
        per_impact = counts[:, track]
        for k, power in enumerate(powers):
            start = None if near is None else (near[kind][0][k, 0], near[kind][1][k, 0])
            a, b, loglik = _best_fit(speed**2 * u ** (2.0 * power), y, n, per_impact, start)
            fits[kind][0][k], fits[kind][1][k] = a, b
            total[k] += loglik
    return fits, total


def estimate_spreads(residuals, *, speed, seed=0, draws=BOOTSTRAP, power=None):
    """{corner, flat: {value, ci95, floor, floor_ci95, variance, impacts, tracks, unstable}, power:
    {value, ci95, ...}} (a kind without impacts: value None): the per-component variance of
    the jump, floor^2 + sigma^2 speed^2 (u / speed)^(2 power) (``speed`` = sqrt(g R), m/s; floor
    in its units), fitted by maximum likelihood of the impacts' residuals as Gaussian with that
    variance plus their noise share, the power shared by both kinds (the best of POWERS, or
    ``power`` held). Intervals: bootstrap over tracks (a track's impacts of both kinds together),
    the power chosen again in every resample."""
    rng = np.random.default_rng([seed, 3131])
    out, arrays = {}, {}
    chosen = {}
    for kind in KINDS:
        of_kind = [r for r in residuals if r.kind == kind]
        chosen[kind] = [r for r in of_kind if r.probe2 <= 3.0 * UNSTABLE**2 * r.approach**2]
        trajs = sorted({r.traj for r in chosen[kind]})
        out[kind] = {"value": None, "ci95": None, "floor": None, "floor_ci95": None, "variance": None, "impacts": len(chosen[kind]),
                     "tracks": len(trajs), "unstable": len(of_kind) - len(chosen[kind])}
    trajs = sorted({r.traj for kind in KINDS for r in chosen[kind]})
    track_of = {t: k for k, t in enumerate(trajs)}
    for kind in KINDS:
        if len(chosen[kind]) >= 3 and out[kind]["tracks"] >= 2:
            arrays[kind] = _kind_arrays(chosen[kind], speed, track_of)
    powers = POWERS if power is None else (float(power),)
    if not arrays:
        out["power"] = {"value": float(power if power is not None else 1.0), "ci95": None, "held": power is not None}
        return out
    ones = np.ones((1, len(trajs)))
    fits, total = _profile(arrays, ones, speed, powers)
    best = int(np.argmax(total[:, 0]))
    counts = rng.multinomial(len(trajs), np.full(len(trajs), 1.0 / len(trajs)), size=draws).astype(float)
    boot_fits, boot_total = _profile(arrays, counts, speed, powers, near=fits)
    boot_best = np.argmax(boot_total, axis=0)
    rows = np.arange(draws)
    for kind in arrays:
        a, b = fits[kind][0][best, 0], fits[kind][1][best, 0]
        a_boot, b_boot = boot_fits[kind][0][boot_best, rows], boot_fits[kind][1][boot_best, rows]
        a_lo, a_hi = np.nanpercentile(a_boot, [2.5, 97.5])
        b_lo, b_hi = np.nanpercentile(b_boot, [2.5, 97.5])
        out[kind].update({"value": _sigma(b), "ci95": [_sigma(b_lo), _sigma(b_hi)], "variance": float(b),
                          "variance_ci95": [float(b_lo), float(b_hi)], "floor": _sigma(a) / speed,
                          "floor_ci95": [_sigma(a_lo) / speed, _sigma(a_hi) / speed], "floor_variance_m2_s2": float(a)})
    chosen_powers = np.asarray(powers)[boot_best]
    out["power"] = {"value": float(powers[best]), "ci95": [float(v) for v in np.percentile(chosen_powers, [2.5, 97.5])],
                    "held": power is not None, "at_grid_end": power is None and best in (0, len(powers) - 1),
                    "profile_log_likelihood": {f"{p:g}": float(v) for p, v in zip(powers, total[:, 0] - total[best, 0])},
                    # the law's best spreads and floors at every power, for a choice of the power by other means
                    "by_power": {f"{p:g}": {kind: {"value": _sigma(fits[kind][1][k, 0]), "floor": _sigma(fits[kind][0][k, 0]) / speed}
                                            for kind in arrays} for k, p in enumerate(powers)}}
    return out


# The jump's shape (issue 31, fourth pass): a share w of impacts jumps k times wider (a scale
# mixture of two Gaussians: heavy tails) and the spin component s times the others (anisotropy).
SHAPE_POWERS = tuple(0.5 * k for k in range(9))  # the power's profile grid of the shape fit, 0 to MAX_POWER
SHAPE_BOOTSTRAP = 500  # resamples of the tracks for the shape's intervals (each a 7-parameter fit, about 15 ms)
MAX_TAIL_SHARE = 0.5  # the wide component is the smaller one by definition (w and 1 - w with k and 1/k are one law)
MIN_SPIN = 0.05  # the fit's lower bound on s: 0 would leave the spin's likelihood undefined without noise
SHAPE_STARTS = ((0.2, 3.0), (0.05, 2.0), (0.3, 1.5))  # (w, k) the full sample's fit starts from


def _shape_arrays(residuals, speed):
    """Per clean impact with per-component residuals: corner (bool), (u / speed)^2, squared
    residual and noise share per component in units of speed^2 (n, 3), its track's row."""
    rows = [r for r in residuals if r.components2 and r.probe2 <= 3.0 * UNSTABLE**2 * r.approach**2]
    trajs = sorted({r.traj for r in rows})
    track_of = {t: k for k, t in enumerate(trajs)}
    return (np.array([r.kind == "corner" for r in rows]), np.array([r.approach for r in rows]) / speed,
            np.array([r.components2 for r in rows]) / speed**2, np.array([r.noise_components2 for r in rows]) / speed**2,
            np.array([track_of[r.traj] for r in rows], dtype=int), len(trajs))


def _shape_loglik(theta, corner, u, y, n, power, weights=None):
    """Log-likelihood per impact of the mixture law at theta = (floor^2, sigma^2 of corner,
    then of flat, w, k, s), all in units of speed: the narrow jump's variance
    min(floor^2 + sigma^2 u^(2 power), u^2) per velocity component, the wide one's
    min(k^2 that, u^2), the spin component's s^2 times either, plus each component's noise
    share. With ``weights``: (their weighted sum, its gradient in theta) instead."""
    a_c, b_c, a_f, b_f, w, k, s = theta
    grow = u ** (2.0 * power)
    law = np.where(corner, a_c + b_c * grow, a_f + b_f * grow)
    scale = np.array([1.0, 1.0, s * s])
    parts = []
    for factor in (1.0, k * k):
        jump = np.minimum(factor * law, u * u)
        v = jump[:, None] * scale + n + _TINY
        parts.append((-0.5 * np.sum(np.log(v) + y / v, axis=1), 0.5 * (y - v) / (v * v), jump, factor * law < u * u))
    if w <= 0.0:
        total, wide = parts[0][0], np.zeros(u.size)
    else:
        total = np.logaddexp(math.log1p(-w) + parts[0][0], math.log(w) + parts[1][0])
        wide = np.exp(math.log(w) + parts[1][0] - total)  # each impact's probability of being wide
    if weights is None:
        return total
    grad = np.zeros(7)
    for tail, ((_, g, jump, free), factor, share) in enumerate(zip(parts, (1.0, k * k), (1.0 - wide, wide))):
        by_law = weights * share * free * factor * (g @ scale)  # d/d law
        grad[:4] += [np.sum(by_law * corner), np.sum(by_law * corner * grow), np.sum(by_law * ~corner), np.sum(by_law * ~corner * grow)]
        grad[6] += np.sum(weights * share * g[:, 2] * jump) * 2.0 * s
        if tail:
            grad[5] += np.sum(weights * share * free * law * (g @ scale)) * 2.0 * k
    if w > 0.0:
        grad[4] = np.sum(weights * (wide / w - (1.0 - wide) / (1.0 - w)))
    else:  # at w = 0 the wide component's density, less the narrow's, is the slope
        grad[4] = np.sum(weights * (np.exp(parts[1][0] - parts[0][0]) - 1.0))
    return float(weights @ total), grad


def _shape_bounds():
    return [(0.0, 1.0)] * 4 + [(0.0, MAX_TAIL_SHARE), (1.0, registry.MAX_TAIL_FACTOR), (MIN_SPIN, registry.MAX_SPIN)]


def _shape_fit(arrays, power, weights, starts, bounds=None):
    """(theta, log-likelihood) of the best mixture law from ``starts`` (thetas), impacts
    weighted, within ``bounds`` (default: every parameter free)."""
    from scipy.optimize import minimize

    corner, u, y, n = arrays[:4]
    bounds = bounds or _shape_bounds()

    def cost(theta):
        value, grad = _shape_loglik(theta, corner, u, y, n, power, weights)
        return -value, -grad

    best = None
    for start in starts:
        got = minimize(cost, start, jac=True, method="TNC", bounds=bounds)  # L-BFGS-B: 40x slower with BLAS threads on a busy machine
        if best is None or -got.fun > best[1]:
            best = (np.clip(got.x, [b[0] for b in bounds], [b[1] for b in bounds]), -float(got.fun))
    return best


def excess_kurtosis(w, k):
    """A velocity component's excess kurtosis under the mixture (0: Gaussian, the null)."""
    return 3.0 * (1.0 - w + w * k**4) / (1.0 - w + w * k * k) ** 2 - 3.0


def estimate_shape(residuals, *, speed, seed=0, draws=SHAPE_BOOTSTRAP):
    """The mixture law of the jump by maximum likelihood of the clean impacts' per-component
    residuals (Gaussian components of the law's variance plus their noise share): floor and
    sigma per kind, the power (best of SHAPE_POWERS), and the shape shared by both kinds: the
    tail's share w and factor k and the spin factor s. Intervals: bootstrap over tracks at the
    power chosen (the power's own interval: :func:`estimate_spreads`'), and for comparison the
    isotropic Gaussian law's log-likelihood at that power on the same impacts. Returns a
    JSON-ready dict (floors and sigmas in units of ``speed``, as [scatter] takes them), or None
    with fewer than 3 tracks."""
    arrays = _shape_arrays(residuals, speed)
    corner, u, y, n, track, tracks = arrays
    if tracks < 3:
        return None
    mean = max(float(np.mean(np.sum(y - n, axis=1))) / 3.0, 1e-6)  # the mean excess per component, half in the floor
    ones = np.ones(u.size)
    profile = {}
    for power in SHAPE_POWERS:
        line = [0.5 * mean, 0.5 * mean / max(float(np.mean(u ** (2.0 * power))), 1e-6)] * 2
        profile[power] = _shape_fit(arrays, power, ones, [np.array(line + [w, k, 1.0]) for w, k in SHAPE_STARTS])
    power = max(profile, key=lambda p: profile[p][1])
    theta, loglik = profile[power]
    bounds = _shape_bounds()
    null = _shape_fit(arrays, power, ones, [np.array(list(theta[:4]) + [0.0, 1.0, 1.0])], bounds[:4] + [(0.0, 0.0), (1.0, 1.0), (1.0, 1.0)])
    rng = np.random.default_rng([seed, 3134])
    counts = rng.multinomial(tracks, np.full(tracks, 1.0 / tracks), size=draws).astype(float)
    boot = np.array([_shape_fit(arrays, power, c[track], [theta])[0] for c in counts])
    kurt = excess_kurtosis(boot[:, 4], boot[:, 5])

    def entry(value, samples, sqrt=False):
        low, high = np.percentile(samples, [2.5, 97.5])
        f = (lambda v: math.sqrt(max(float(v), 0.0))) if sqrt else float
        return {"value": f(value), "ci95": [f(low), f(high)]}

    out = {"power": power, "impacts": int(u.size), "tracks": tracks, "log_likelihood": loglik, "draws": int(draws),
           "profile_log_likelihood": {f"{p:g}": profile[p][1] - loglik for p in SHAPE_POWERS},
           "tail_share": entry(theta[4], boot[:, 4]), "tail_factor": entry(theta[5], boot[:, 5]), "spin": entry(theta[6], boot[:, 6]),
           "excess_kurtosis": entry(excess_kurtosis(theta[4], theta[5]), kurt)}
    for j, kind in enumerate(KINDS):
        out[kind] = {"floor": entry(theta[2 * j], boot[:, 2 * j], sqrt=True), "value": entry(theta[2 * j + 1], boot[:, 2 * j + 1], sqrt=True)}
    out["gaussian_log_likelihood"] = null[1]  # the same power, w = 0, s = 1: the law before the shape
    return out


def spreads_law(spreads, power=None):
    """The [scatter] keys (spreads, floors and power) of an :func:`estimate_spreads` dict, or of
    one of its ``power["by_power"]`` entries with that ``power``: the isotropic Gaussian law (a
    kind without impacts, absent or None: 0)."""
    law = {name: spreads.get(kind, {}).get(key) or 0.0 for kind in KINDS for key, name in zip(("value", "floor"), registry.scatter_spread_keys(kind))}
    return {**law, "power": spreads.get("power", {}).get("value", 1.0) if power is None else power}


def shape_law(shape):
    """The [scatter] keys (spreads, floors, power and shape) of an :func:`estimate_shape` dict."""
    law = {name: shape[kind][key]["value"] for kind in KINDS for key, name in zip(("value", "floor"), registry.scatter_spread_keys(kind))}
    return {**law, "power": shape["power"], **{name: shape[name]["value"] for name in registry.SCATTER_SHAPE}}


def jump_sd(law, kind, u):
    """The law's jump sd per component at approach speed u, both in sqrt(g R), capped at u as
    the kernel caps it; ``law``: [scatter] keys (a missing power: 1)."""
    spread = law.get(kind, 0.0) * u ** law.get("power", 1.0)
    return min(math.hypot(spread, law.get(f"{kind}_floor", 0.0)), u)


def scatter_section(spreads):
    """The ``[scatter]`` TOML of estimated spreads (a kind without impacts: 0), the power and
    the shape keys the law has (tail_share, tail_factor, spin: {value, ...} entries)."""
    lines = ["[scatter]"] + [f"{name} = {float(value)!r}" for name, value in spreads_law(spreads).items()]
    lines += [f"{name} = {float(spreads[name]['value'])!r}" for name in registry.SCATTER_SHAPE if isinstance(spreads.get(name), dict)]
    return "\n".join(lines) + "\n"


def fitted_scatter(trackset, cfg, effects, params, *, confirm_fraction, seed=0, log=None):
    """The spreads of a fit (``effects`` added to the config's, ``params`` their values) on the
    selection tracks of its split, for the JSON of ``fit`` and ``diagnose``: {corner, flat (as
    :func:`estimate_spreads`), toml (the ``[scatter]`` section), impacts, unstable, model}."""
    from dice_sweep.measured.noise import tracking_noise

    select_set, _ = trackset.split(confirm_fraction, seed)
    table, _, sigma = tracking_noise(trackset, cfg)
    residuals = impact_residuals(select_set.tracks, cfg, effects, params, sigma=sigma, table=table, seed=seed)
    speed = math.sqrt(float(params.get("g", cfg.world.g)) * cfg.die.circumradius)
    spreads = estimate_spreads(residuals, speed=speed, seed=seed)
    if log:
        log("scatter of the bounces around the fitted law (selection tracks): " + "; ".join(
            f"{kind} {s['value']:.3f} [{s['ci95'][0]:.3f}, {s['ci95'][1]:.3f}], floor {s['floor']:.3f} [{s['floor_ci95'][0]:.3f}, "
            f"{s['floor_ci95'][1]:.3f}] sqrt(gR) ({s['impacts']} impacts)" for kind, s in ((k, spreads[k]) for k in KINDS)
            if s["value"] is not None) + f"; power {spreads['power']['value']:g} {spreads['power']['ci95']}")
    shape = estimate_shape(residuals, speed=speed, seed=seed)
    if log and shape:
        log("its shape (mixture law, power {power:g}): tail share {w[value]:.3f} {w[ci95]}, tail factor {k[value]:.2f} {k[ci95]}, spin "
            "{s[value]:.2f} {s[ci95]}; log-likelihood {gain:+.1f} over the Gaussian at that power".format(
                power=shape["power"], w=shape["tail_share"], k=shape["tail_factor"], s=shape["spin"],
                gain=shape["log_likelihood"] - shape["gaussian_log_likelihood"]))
    return {**spreads, "shape": shape, "toml": scatter_section(spreads), "tracks": "selection", "model": MODEL}


MODEL = ("each impact's velocity jump: the fitted law's plus a Gaussian of sd min(sqrt((sigma sqrt(g R) (u / sqrt(g R))^power)^2 + "
         "(floor sqrt(g R))^2), u) per "
         "component of (vx, vy, sqrt(I/M) omega), u the touching corner's approach speed; sigma and floor 'flat' for landings within "
         "15 deg of flat, else 'corner' "
         "(docs/physics.md, 'Scattered impacts'; estimator: docs/measured_method.md)")
