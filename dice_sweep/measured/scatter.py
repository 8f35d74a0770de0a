"""How much a real bounce scatters around the best deterministic law: the ``[scatter]``
spreads estimated from tracked drops, with 95 % intervals (issue 31).

The model (docs/physics.md, "Scattered impacts"): each impact's velocity jump is the
deterministic law's plus a Gaussian of standard deviation sigma u per component of
(vx, vy, sqrt(I/M) omega), u the touching corner's approach speed, sigma = ``flat`` or
``corner`` by the landing tilt. The estimator (docs/measured_method.md, "The scatter of real
bounces"), per clean impact i of the tracks given (calibrate's impacts and cleanliness rules):

1. the state just before it (the free-flight fit of the frames before, followed to the table)
   is rolled by the kernel at the fitted parameters, deterministic, from BACKOFF before the
   contact to the middle of the after-fit's frames; the residual r_i is the measured velocity
   there (the fit of the frames after) minus the kernel's, in (vx, vy, sqrt(I/M) omega). An
   impact after which the kernel has another impact within the after-fit's frames is left
   out (that fit is not of one flight);
2. the tracking noise's share of |r_i|^2, n_i, is measured by REPLICATES refits with
   Gaussian noise of the tracking sigma added to the frames: E|r'_i - r_i|^2 = n_i in the
   linear regime;
3. impacts whose noise share alone is a spread above UNSTABLE are left out (counted); over
   the impacts of a kind, (|r_i|^2 - n_i) / 3 = floor^2 + sigma^2 u_i^2 (E|r_i|^2 = 3 (floor^2
   + sigma^2 u_i^2) + n_i) is fitted by least squares weighted by the inverse square of the
   fitted variance; sigma = sqrt(max(sigma^2, 0)), the same for the floor;
4. their 95 % intervals from BOOTSTRAP resamples of the tracks (the independent units), the
   percentiles of sigma^2 and floor^2 taken to sigma the same way (an interval reaching below 0
   holds 0: no scatter of that form is within the data).

What this sigma holds: every way the real impact differs from the fitted law's, systematic
or random, at the scale of the approach speed. That is what a forecast's ensemble lacks.
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

__all__ = ["ImpactResidual", "impact_residuals", "estimate_spreads", "scatter_section", "fitted_scatter", "KINDS"]

BACKOFF = 2e-3  # s (true time) before the fitted contact the kernel starts: clear of the table
REPLICATES = 16  # noisy refits per impact: half probe its stability, half measure its noise share
BOOTSTRAP = 2000  # resamples of the tracks
KINDS = ("corner", "flat")  # the [scatter] keys, by landing tilt (FLAT_TILT)
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
            shares = []
            for _ in range(replicates):
                x = track.x + sigma[0] * rng.normal(size=track.x.size)
                y = track.y + sigma[1] * rng.normal(size=track.y.size)
                phi = track.phi + sigma[2] * rng.normal(size=track.phi.size)
                again = fit_impact(track.t, x, y, phi, usable, frame, **around, **die)
                if again is not None:
                    shares.append(float(np.sum((predictor.residual(predictor.true(again, table, window))[0] - residual) ** 2)))
            half = len(shares) // 2
            n2 = float(np.mean(shares[half:])) if shares else 0.0
            p2 = float(np.mean(shares[:half])) if half else n2
            out.append(ImpactResidual(int(track.traj), kind, float(u), float(residual @ residual), n2, p2, k))
    return out


def _sigma(value):
    return math.sqrt(max(value, 0.0))


def _line(sums):
    """(a, b) of the weighted least-squares line y = a + b x from the sums (w, wx, wxx, wy, wxy)."""
    w, wx, wxx, wy, wxy = sums
    det = w * wxx - wx * wx
    if not det > 1e-12 * w * wxx:  # one approach speed only (a resample of one track): no line
        return math.nan, math.nan
    return (wxx * wy - wx * wxy) / det, (w * wxy - wx * wy) / det


def _track_sums(chosen, index, weights, size):
    """Per track: the five sums of :func:`_line` over its impacts, x = u^2, y = (|r|^2 - n) / 3."""
    sums = np.zeros((size, 5))
    for r, w in zip(chosen, weights):
        x, y = r.approach**2, (r.residual2 - r.noise2) / 3.0
        sums[index[r.traj]] += w * np.array([1.0, x, x * x, y, x * y])
    return sums


def estimate_spreads(residuals, *, speed, seed=0, draws=BOOTSTRAP):
    """{kind: {value, ci95, floor, floor_ci95, variance, impacts, tracks, unstable}} for ``corner``
    and ``flat`` (value None for a kind without impacts): per component, the jump's variance
    (|r|^2 - n) / 3 = floor^2 + sigma^2 u^2 fitted by least squares weighted by the inverse
    square of that variance (from a first unweighted pass); ``floor`` in units of ``speed``
    = sqrt(g R) (m/s). Intervals: bootstrap over tracks with the weights held."""
    rng = np.random.default_rng([seed, 3131])
    out = {}
    for kind in KINDS:
        of_kind = [r for r in residuals if r.kind == kind]
        chosen = [r for r in of_kind if r.probe2 <= 3.0 * UNSTABLE**2 * r.approach**2]
        trajs = sorted({r.traj for r in chosen})
        if len(chosen) < 3 or len(trajs) < 2:
            out[kind] = {"value": None, "ci95": None, "floor": None, "floor_ci95": None, "variance": None, "impacts": len(chosen),
                         "tracks": len(trajs), "unstable": len(of_kind) - len(chosen)}
            continue
        index = {t: k for k, t in enumerate(trajs)}
        a, b = _line(_track_sums(chosen, index, np.ones(len(chosen)), len(trajs)).sum(axis=0))
        scale = max(a, 0.0) + max(b, 0.0) * np.array([r.approach**2 for r in chosen])
        weights = 1.0 / np.maximum(scale, 1e-12 * speed**2) ** 2
        sums = _track_sums(chosen, index, weights / weights.mean(), len(trajs))
        a, b = _line(sums.sum(axis=0))
        counts = rng.multinomial(len(trajs), np.full(len(trajs), 1.0 / len(trajs)), size=draws)
        boot = np.array([_line(c @ sums) for c in counts])
        a_lo, a_hi = np.nanpercentile(boot[:, 0], [2.5, 97.5])
        b_lo, b_hi = np.nanpercentile(boot[:, 1], [2.5, 97.5])
        out[kind] = {"value": _sigma(b), "ci95": [_sigma(b_lo), _sigma(b_hi)], "variance": float(b), "variance_ci95": [float(b_lo), float(b_hi)],
                     "floor": _sigma(a) / speed, "floor_ci95": [_sigma(a_lo) / speed, _sigma(a_hi) / speed],
                     "floor_variance_m2_s2": float(a), "impacts": len(chosen), "tracks": len(trajs), "unstable": len(of_kind) - len(chosen)}
    return out


def scatter_section(spreads):
    """The ``[scatter]`` TOML of estimated spreads (a kind without impacts: 0)."""
    lines = ["[scatter]"]
    for kind in KINDS:
        for key, name in (("value", kind), ("floor", f"{kind}_floor")):
            value = spreads[kind][key]
            lines.append(f"{name} = {value if value is not None else 0.0!r}")
    return "\n".join(lines) + "\n"


def fitted_scatter(trackset, cfg, effects, params, *, confirm_fraction, seed=0, log=None):
    """The spreads of a fit (``effects`` added to the config's, ``params`` their values) on the
    selection tracks of its split, for the JSON of ``fit`` and ``diagnose``: {corner, flat (as
    :func:`estimate_spreads`), toml (the ``[scatter]`` section), impacts, unstable, model}."""
    from dice_sweep.measured.noise import tracking_noise

    select_set, _ = trackset.split(confirm_fraction, seed)
    table, _, sigma = tracking_noise(trackset, cfg)
    residuals = impact_residuals(select_set.tracks, cfg, effects, params, sigma=sigma, table=table, seed=seed)
    spreads = estimate_spreads(residuals, speed=math.sqrt(float(params.get("g", cfg.world.g)) * cfg.die.circumradius), seed=seed)
    if log:
        log("scatter of the bounces around the fitted law (selection tracks): " + "; ".join(
            f"{kind} {s['value']:.3f} [{s['ci95'][0]:.3f}, {s['ci95'][1]:.3f}], floor {s['floor']:.3f} [{s['floor_ci95'][0]:.3f}, "
            f"{s['floor_ci95'][1]:.3f}] sqrt(gR) ({s['impacts']} impacts)" for kind, s in spreads.items() if s["value"] is not None))
    return {**spreads, "toml": scatter_section(spreads), "tracks": "selection", "model": MODEL}


MODEL = ("each impact's velocity jump: the fitted law's plus a Gaussian of sd min(sqrt((sigma u)^2 + (floor sqrt(g R))^2), u) per "
         "component of (vx, vy, sqrt(I/M) omega), u the touching corner's approach speed; sigma and floor 'flat' for landings within "
         "15 deg of flat, else 'corner' "
         "(docs/physics.md, 'Scattered impacts'; estimator: docs/measured_method.md)")
