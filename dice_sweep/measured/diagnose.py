"""The measured-data loop: fit the declared model to whole tracks, test each candidate effect,
add one only when it is a significant, non-null improvement that heavy tails cannot fake, judge
each added effect a cause or a stand-in, and say how far the result is from the tracking noise,
from every track's held-out error.

The steps (docs/measured_method.md states them for users):

1. Cross-fitting: the usable tracks are put in two folds (halves, by a hash of the trajectory
   id; more folds when the tracks are few). For each fold the whole selection below runs on the
   other folds' tracks, and its declared and final models predict the fold's tracks (states
   fitted, parameters held): every track's before and after errors come from a model, and a
   choice of effects, that never saw it.
2. Every model is fitted by multiple shooting (:mod:`dice_sweep.measured.fit`), from several
   starts per candidate.
3. Within a fold, each model's per-track error on tracks it was not fitted to comes from
   K-fold cross-validation over the fold's training tracks, each inner fold's refit taken as
   one Newton step of the reduced (states eliminated) problem.
4. A candidate is added only if (a) the per-track held-out errors fall significantly: a
   one-sided Wilcoxon signed-rank test across tracks, its threshold the 95 % quantile of the
   largest statistic over all candidates in data simulated from the current model (its
   linearisation, with the estimated tracking noise), and never below the Sidak-corrected
   normal quantile; (b) the 95 % bootstrap interval (over tracks) of each of its parameters
   excludes the null value; (c) it removes at least ``MIN_EXCESS_SHARE`` of the error in excess
   of the noise floor; (d) both the held-out RMS over tracks and the median per-track error
   fall (heavy tails: the RMS alone can fall by a few tracks, the median alone while a few
   tracks blow up; the RMS with the one track that changes most left out); (e) of the tracks whose error it moves by more than ``MARKED`` times the
   noise floor, at most ``MAX_WORSE_SHARE`` get worse (its share).
5. The named model: the effects the folds added, refitted on all tracks; one whose 95 %
   interval then holds its null value is taken out. Each named effect is a ``cause`` or a
   ``stand_in`` (:mod:`dice_sweep.measured.consistency`: the same value on independent parts
   of the data, and its residual signature present before).
6. Verdict, from all tracks' held-out errors: ``explained`` when their median is within
   ``EXPLAINED_FACTOR`` times the noise floor and no named effect is a stand-in, ``improved``
   when effects are named but it is not explained, ``unexplained`` when nothing is named and it
   is above; ``verdict_spread`` repeats it on re-splits of the tracks (the named effect set
   refitted on each half, not reselected). When the error stays above ``EXPLAINED_FACTOR``
   times the floor, sparse formulas for what the final model leaves are proposed
   (:mod:`dice_sweep.measured.propose`), and the residual signatures that remain are listed.

The loop is this module; its pieces have their own: :mod:`~dice_sweep.measured.split` (the
tracks and folds, step 1), :mod:`~dice_sweep.measured.fit` (step 2),
:mod:`~dice_sweep.measured.reduced` (the one-step refits of steps 3 and 4 and the intervals),
:mod:`~dice_sweep.measured.stats` (the rank test, the Sidak bound, bootstrap intervals),
:mod:`~dice_sweep.measured.consistency` (step 5), :mod:`~dice_sweep.measured.signatures`,
:mod:`~dice_sweep.measured.propose` and :mod:`~dice_sweep.measured.noise` (the noise floor).
:func:`fit_report` is the ``fit`` command: one model, fitted on the selection tracks of a
70/30 split and scored on the confirmation tracks, no candidates.
"""

import math

import numpy as np

from dice_sweep import effects as registry
from dice_sweep.errors import DiceSweepError
from dice_sweep.executor import default_workers, ordered_map
from dice_sweep.measured import fit as shooting
from dice_sweep.measured import propose
from dice_sweep.measured.calibrate import calibrate
from dice_sweep.measured.consistency import consistency, left_where_it_acts
from dice_sweep.measured.fit import relative_gain as relative_fall
from dice_sweep.measured.noise import residual_sigmas
from dice_sweep.measured.reduced import bootstrap_record, cv_errors, effect_away_from_null, parameter_intervals, project, reduce
from dice_sweep.measured.report import residual_by_bounce
from dice_sweep.measured.signatures import remaining_signatures, residual_signatures
from dice_sweep.measured.split import CONFIRM_FRACTION, CROSS_FOLDS, assign_folds, cross_fit_tracks, fit_context, split_tracks
from dice_sweep.measured.stats import BOOTSTRAP, LEVEL, bootstrap_rms, excess_share, median_interval, sidak_bound, signed_rank_z

FOLDS = 5
NULL_SIMULATIONS = 200
EXPLAINED_FACTOR = 1.5
MIN_EXCESS_SHARE = 0.1
MAX_CHAIN = 4
RESPLITS = 3  # re-splits of the tracks whose verdicts make verdict_spread
WORST_TRACKS = 5  # tracks listed as the worst, before and after
# A candidate may make only its share of tracks worse: of the tracks whose held-out error it
# moves by more than MARKED x the noise floor (noise alone moves a track's error far less),
# at most MAX_WORSE_SHARE may be worse. A change that only reshuffles tracks whose prediction
# is chaotic (near-flat landings) makes as many worse as better.
MARKED = 0.5
MAX_WORSE_SHARE = 0.25
POLISH_ITERATIONS = 150  # the baseline and each accepted model are fitted to convergence

METRIC = (
    "per track, RMS over its described frames of sqrt(dx^2 + dy^2 + (R dphi)^2) (m) between tracked and simulated poses; "
    "each flight has its own fitted state and is simulated through the next impact over the next flight (multiple shooting); "
    "a set's error is the RMS over its tracks"
)


# --- the declared model ------------------------------------------------------------------------

# The declared model's fit starts from the config's values and from values measured impact by
# impact (calibrate), and keeps the lower cost: from the config's beta_normal 0.3 and friction
# 0.5, hexagon drops at 1000 Hz (truth 0.4 and 0.3) stopped in optima at beta_normal 0.301,
# 0.382 and 0.393; from the measured values all three found the truth
# (tests/measured/test_diagnose.py::test_the_declared_model_starts_from_measured_values).
MIN_CALIBRATED_IMPACTS = 5  # clean impacts a measured start value needs
FRICTION_QUANTILE = 0.8  # of |tangential / normal impulse| over clean impacts: the slipping ones sit at the friction


def measured_starts(trackset, cfg, spec):
    """Start values of the spec's contact parameters measured on the tracks (``calibrate``): the
    median of the clean first impacts on one corner for beta_normal and beta_tangential (of the
    touching corner for a corner-impulse model, of eqs. 9 and 10 for the paper's), and for
    friction the FRICTION_QUANTILE quantile of |impulse ratio| over all clean impacts (an impact
    that slips has the ratio at the friction, one that sticks below it). Clipped to the fit
    bounds; {} when fewer than MIN_CALIBRATED_IMPACTS clean first impacts land on one corner:
    drops released near flat have none, and a start with friction alone (0.31, their flat
    landings' impulse ratio) led the declared model to an optimum that hid the flat landing
    (tests/measured/test_diagnose.py::test_flat_landing_contact_time_is_found)."""
    try:
        result = calibrate(trackset, cfg)
    except DiceSweepError:
        return {}
    names = spec.param_names()
    corner = "corner_impulse" in spec.declared + spec.effects
    sources = {"beta_normal": "corner_normal" if corner else "beta_normal",
               "beta_tangential": "corner_tangential" if corner else "beta_tangential"}
    if result.values(sources["beta_normal"], "first_corner").size < MIN_CALIBRATED_IMPACTS:
        return {}
    starts = {}
    for name, source in sources.items():
        values = result.values(source, "first_corner")
        if name in names and values.size >= MIN_CALIBRATED_IMPACTS:
            starts[name] = float(np.median(values))
    ratios = np.abs(result.values("impulse_ratio", "all"))
    if "friction" in names and ratios.size >= MIN_CALIBRATED_IMPACTS:
        starts["friction"] = float(np.quantile(ratios, FRICTION_QUANTILE))
    for name, value in starts.items():
        low, high = registry.param(name).bounds_of(cfg)
        starts[name] = min(max(value, low), high)
    return starts


def _fit_from(task):
    """One start of :func:`fit_from_starts`. Runs in a worker."""
    cfg, spec, segments, start, max_iterations = task
    return shooting.fit_spec(cfg, spec, segments, start=start, max_iterations=max_iterations)


def fit_from_starts(cfg, spec, segments, trackset, *, workers=1, max_iterations=shooting.MAX_ITERATIONS):
    """The spec fitted from the config's values and from :func:`measured_starts` (in parallel),
    the lower cost kept. Returns (fit, record): per start its ``source``, the ``start`` values
    that differ from the config's, the fitted ``cost`` and ``params``, and which was ``chosen``."""
    starts = [("config", {})]
    measured = measured_starts(trackset, cfg, spec)
    config = shooting.start_values(cfg, spec)
    if any(not math.isclose(value, config[name]) for name, value in measured.items()):
        starts.append(("calibrate", measured))
    fits = _map(_fit_from, [(cfg, spec, segments, start, max_iterations) for _, start in starts], workers)
    best = min(range(len(fits)), key=lambda k: fits[k].cost)
    record = [{"source": source, "start": {**config, **start}, "cost": fit.cost, "params": dict(fit.params), "chosen": k == best}
              for k, ((source, start), fit) in enumerate(zip(starts, fits))]
    return fits[best], record


# --- one candidate ---------------------------------------------------------------------------


def _start_grid(effect_name, cfg):
    """Start values of an effect's parameters: the registry's starts, taken in step, or the
    null value when it lists none."""
    params = registry.effect(effect_name).params
    if not params:
        return [{}]
    starts = {p.name: p.starts_of(cfg) or (p.null_value(cfg),) for p in params}
    count = max(len(v) for v in starts.values())
    return [{name: values[min(k, len(values) - 1)] for name, values in starts.items()} for k in range(count)]


SCOUT_ITERATIONS = 6  # iterations each start gets before the best one is carried on


def fit_candidate(cfg, current, effect_name, segments, previous=None):
    """``current`` plus one effect, fitted from each of the registry's starts for a few
    iterations (warm states); the best start is then carried on to convergence. ``previous``:
    the candidate's fit in a round that was repeated; when its cost is below the current
    model's it is a start at least as good as any, and the fit goes on from it alone; else its
    own parameters are the one start, with the current model's. An effect at impacts whose
    parameter ends at a bound (not its null) is fitted once more, each flight's state refreshed
    from its guess where that fits better (fit_spec's ``refresh``)."""
    spec = current.spec.with_effect(effect_name)
    if previous is not None and previous.spec == spec:
        if previous.cost < current.cost:
            return shooting.fit_spec(cfg, spec, segments, start=previous.params, states=previous.states)
        own = {p.name: previous.params[p.name] for p in registry.effect(effect_name).params}
        return shooting.fit_spec(cfg, spec, segments, start={**current.params, **own}, states=current.states)
    starts = _start_grid(effect_name, cfg)
    # an effect at impacts can send a bounce another way at its start values: the flights after
    # it then start from fresh states where those fit better (a flight or measurement effect
    # moves every flight smoothly, and a fresh fit at drag 0.5 cost 14 s on the real drops)
    refresh = registry.effect(effect_name).kind == "contact"
    best = None
    for start in starts:
        values = dict(current.params)
        values.update(start)
        iterations = SCOUT_ITERATIONS if len(starts) > 1 else shooting.MAX_ITERATIONS
        result = shooting.fit_spec(cfg, spec, segments, start=values, states=current.states, max_iterations=iterations, refresh=refresh)
        if best is None or result.cost < best.cost:
            best = result
    if not best.converged and len(starts) > 1:
        best = shooting.fit_spec(cfg, spec, segments, start=best.params, states=best.states)
    if refresh and at_a_bound_off_null(best, effect_name, cfg):
        # once more at the fitted values: on flat-landing drops the fit from the start
        # values' states ended at the bound 1e-3 s (cost 0.039); 79
        # flights then fitted better from their guesses, and the refit reached 9.7e-4 s at cost
        # 0.0014 (tests/measured/test_diagnose.py::test_flat_landing_contact_time_is_found).
        # Not for every candidate, nor at a null bound (speed_restitution at 0): on the real
        # drops that cost 25 s of diagnose's 2 minutes, in rounds repeated for optima 1 % lower.
        best = shooting.fit_spec(cfg, spec, segments, start=best.params, states=best.states, refresh=True)
    return best


def at_a_bound_off_null(fit, effect_name, cfg):
    """Whether a parameter of the effect ends at a fit bound (``fit.at_bound``) that is not its
    null value: at a null bound (speed_restitution at 0) the effect is simply absent."""
    for p in registry.effect(effect_name).params:
        low, high = p.bounds_of(cfg)
        if fit.at_bound.get(p.name) and abs(fit.params[p.name] - p.null_value(cfg)) > shooting.AT_BOUND * (high - low):
            return True
    return False


# --- the loop --------------------------------------------------------------------------------


NULL_KIND = "gauss"
NULL_BATCH = 25  # simulations computed together (memory: rows x 3 x this many floats, a few times)


def _null_threshold(cfg, current, lin_current, candidates_lin, segments, fold, sigmas, rng, simulations):
    """95 % quantile of the largest signed-rank statistic over the candidates in data simulated
    from the current model (its linearisation) with the tracking noise, and the Sidak bound.
    The simulated residual is the noise itself (the model is true in the simulation), so each
    simulation is a few linear maps of it (:func:`~dice_sweep.measured.reduced.project`), a batch at a time."""
    sidak = sidak_bound(len(candidates_lin))
    usable = [(lin, names) for name, lin, names in candidates_lin if lin is not None]
    if not usable or simulations <= 0:
        return sidak, sidak, 0
    rows = lin_current.residual.shape[0]
    weight = lin_current.weight if NULL_KIND == "signs" else np.ones(rows)
    base = reduce(lin_current, segments, weight=weight)
    reduced = []
    for lin, names in usable:
        values = dict(current.params)
        values.update({n: registry.param(n).null_value(cfg) for n in names if n not in values})
        reduced.append((reduce(lin, segments, weight=weight), names, values))
    best = []
    for first in range(0, simulations, NULL_BATCH):
        size = min(NULL_BATCH, simulations - first)
        if NULL_KIND == "signs":
            signs = rng.choice([-1.0, 1.0], size=(segments.count, size))
            noise = lin_current.residual[:, :, None] * signs[segments.segment_rows][:, None, :]
        else:
            # one draw per frame: a flight's frames are also rows of the segment before
            noise = (rng.normal(size=(segments.frames, 3, size)) * np.asarray(sigmas)[None, :, None])[segments.frame_rows]
        e_base = cv_errors(base, segments, fold, list(current.free), current.params, cfg, project(base, segments, noise, centre=False))
        top = np.full(size, -np.inf)
        for red, names, values in reduced:
            e_cand = cv_errors(red, segments, fold, names, values, cfg, project(red, segments, noise, centre=False))
            top = np.maximum(top, [signed_rank_z(e_base[:, s] ** 2 - e_cand[:, s] ** 2) for s in range(size)])
        best.extend(top)
    simulated = float(np.quantile(best, 1.0 - LEVEL))
    return max(simulated, sidak), sidak, simulations


def _null_linearisation(cfg, current, effect_name, segments):
    """The current fit linearised with a candidate's parameters at their null value (None when
    the candidate has no parameters, or a null at infinity, where no linearisation exists)."""
    params = registry.effect(effect_name).params
    if not params:
        return None, None
    values = dict(current.params)
    for p in params:
        null = p.null_value(cfg)
        if not math.isfinite(null):
            return None, None
        values[p.name] = null
    spec = current.spec.with_effect(effect_name)
    at_null = shooting.FitResult(spec, values, current.states, tuple(spec.param_names()), current.cost, 0, True, {})
    return shooting.linearise(cfg, at_null, segments), list(spec.param_names())


def _held_out(cfg, fit, segments, fold):
    """A fit's linearisation, its reduced pieces and its per-track held-out errors."""
    lin = shooting.linearise(cfg, fit, segments)
    red = reduce(lin, segments)
    return lin, red, cv_errors(red, segments, fold, list(fit.free), fit.params, cfg)


def confirmation_errors(cfg, fit, segments, held=False):
    """Per-track errors on held-out tracks (states fitted, parameters held) and the residual
    rows (m) they come from; with ``held``, the held fit (its states) too."""
    fitted = shooting.fit_spec(cfg, fit.spec, segments, start=fit.params, fixed=True)
    residual = shooting.ShootingModel(cfg, fit.spec, segments).residuals(fitted.params, fitted.states)
    errors = shooting.track_errors(segments, residual)
    return (errors, residual, fitted) if held else (errors, residual)


MAX_RESTARTS = 2  # times one round may be repeated because the current model found a lower optimum
# (per round: after flat_landing was added at a local optimum, the next round's candidates
# found the model's better one with their own parameters null, and with the count spent in
# round one the loop credited gravity with that fall; test_flat_landing_contact_time_is_found)
# relative fall of the current model's cost that counts as a lower optimum: a tenth of the
# smallest share of the excess an effect must remove, so that a smaller fall cannot make one pass
BETTER_OPTIMUM = 0.1 * MIN_EXCESS_SHARE


def _better_optimum(cfg, current, results, segments, restarts):
    """(refitted current model, candidate name) when a candidate that kept its own parameters
    at their null value reached a clearly lower cost; else None."""
    if restarts >= MAX_RESTARTS:
        return None
    nulls = [r for r in results if not r["null_excluded"] and r["fit"].cost < current.cost * (1.0 - BETTER_OPTIMUM)]
    if not nulls:
        return None
    best = min(nulls, key=lambda r: r["fit"].cost)
    start = {k: v for k, v in best["fit"].params.items() if k in current.params}
    refit = shooting.fit_spec(cfg, current.spec, segments, start=start, states=best["fit"].states, max_iterations=POLISH_ITERATIONS)
    # the refit must keep the fall: else it came from the candidate's own (non-null) parameter
    return (refit, best["effect"]) if refit.cost < current.cost * (1.0 - BETTER_OPTIMUM) else None


NULL_REASON = "added in a round, but the final model's 95 % interval holds its null value"


def _weakest_step(cfg, current, chain, segments, fold, e_current):
    """The final model tested against itself without each added step (an effect, or a pair
    added together): each step's ``final_z`` is the signed-rank statistic of the held-out gain
    it keeps. The step with the smallest, when that is not above the threshold it passed when
    added, and the model refitted without it; else None.

    Why: a later round's refit can shrink an effect to a value near, but not at, its null: on
    flat-landing drops with T = 5e-4 s, angle_offset was added at 0.013 rad and ended at 0.0036
    [0.0015, 0.0056] rad, its interval clear of 0 (tests/measured/test_diagnose.py)."""
    weakest = None
    for step in chain:
        present = [name for name in step["effects"] if name in current.spec.effects]
        if not present:
            continue
        without = shooting.fit_spec(cfg, current.spec.without(present), segments, start=current.params, states=current.states)
        _, _, e_without = _held_out(cfg, without, segments, fold)
        step["final_z"] = signed_rank_z(e_without**2 - e_current**2)
        if step["final_z"] <= step["threshold_z"] and (weakest is None or step["final_z"] < weakest[0]["final_z"]):
            weakest = (step, without)
    return weakest


def _test_fit(cfg, cand, names, segments, fold, e_current, floor, bootstrap, sigmas, rng):
    """The tests of a fitted candidate (one effect or a pair): held-out errors, statistic,
    intervals, null and bounds."""
    _, cand_red, e_cand = _held_out(cfg, cand, segments, fold)
    _, params = parameter_intervals(cand, cand_red, segments, cfg, rng, sigmas, bootstrap)
    excluded = all(effect_away_from_null(name, params, cfg) for name in names)
    new = [p.name for name in names for p in registry.effect(name).params]
    worse, better = marked_tracks(e_current, e_cand, floor)
    return {"effect": "+".join(names), "effects": list(names), "fit": cand, "red": cand_red, "errors": e_cand,
            "z": signed_rank_z(e_current**2 - e_cand**2), "params": params, "null_excluded": bool(excluded),
            "excess_share": excess_share(e_current, e_cand, floor), "test_error": shooting.rms(e_cand),
            "median_error": float(np.median(e_cand)), "median_falls": bool(np.median(e_cand) < np.median(e_current)),
            "rms_falls": rms_falls(e_current, e_cand), "rms_falls_all_tracks": bool(shooting.rms(e_cand) < shooting.rms(e_current)),
            "worse_tracks": worse, "better_tracks": better,
            "worse_share": worse / (worse + better) if worse + better else 0.0,
            "worse_within_share": bool(worse <= MAX_WORSE_SHARE * (worse + better)),
            "at_bound": [n for n in new if params[n]["at_bound"]], "converged": cand.converged, "iterations": cand.iterations}


def rms_falls(e_current, e_cand):
    """Whether the RMS over tracks of the held-out errors falls, the one track whose squared
    error changes most left out: no single track decides (as for a parameter,
    ``one_track_decides``). On loaded-die drops com_offset (really there) made 43 of 45 tracks
    better at z = 5.3, and one track whose prediction crosses a near-flat landing so much worse
    that the RMS over all 45 rose; three tracks blown up still count."""
    e_current, e_cand = np.asarray(e_current, dtype=float), np.asarray(e_cand, dtype=float)
    keep = np.ones(e_current.size, dtype=bool)
    if e_current.size > 2:
        keep[np.nanargmax(np.abs(e_cand**2 - e_current**2))] = False
    return bool(shooting.rms(e_cand[keep]) < shooting.rms(e_current[keep]))


def marked_tracks(e_current, e_cand, floor):
    """(tracks made worse, tracks made better) by more than MARKED x the noise floor."""
    change = np.asarray(e_cand) - np.asarray(e_current)
    return int(np.sum(change > MARKED * floor)), int(np.sum(change < -MARKED * floor))


ALIKE_SHARE = 0.01  # candidates whose shares of the excess differ by less, and
ALIKE_Z = 1.96  # whose per-track errors no signed-rank test tells apart, fit alike


def best_candidate(accepted, pool):
    """The accepted candidate that removes most of the excess error, and the names of those
    that fit these tracks alike (a share within ALIKE_SHARE of its, and |z| < ALIKE_Z in a
    two-sided signed-rank test of the per-track squared errors). Among candidates alike, the
    one with fewest effects, then first in ``pool`` (the registry's order) is taken: with an
    infinite friction the corner impulse and both friction rules stick at every impact and fit
    alike (shares 1.0004 and 0.9999, tracks apart by the refits' rounding), and the pick
    between them was the rounding's, differing between folds; now it is the simplest, the
    others reported."""
    top = max(accepted, key=lambda r: r["excess_share"])

    def alike(r):
        return (r is top or top["excess_share"] - r["excess_share"] < ALIKE_SHARE
                and abs(signed_rank_z(np.asarray(top["errors"]) ** 2 - np.asarray(r["errors"]) ** 2)) < ALIKE_Z)

    same = [r for r in accepted if alike(r)]
    order = {name: k for k, name in enumerate(pool)}
    best = min(same, key=lambda r: (len(r["effects"]), [order.get(name, len(order)) for name in r["effects"]]))
    return best, [r["effect"] for r in same if r is not best]


def untried_effects(pool, spec):
    """Candidates of a round: those not in the model, and not indistinguishable from one in it
    or from one earlier in the pool (the registry's ``equivalent``: the same fit twice)."""
    tried = []
    model = set(spec.effects) | set(spec.declared)
    switched = {pair for name in model for pair in registry.effect(name).switch}
    for name in pool:
        have = model | set(tried)
        entry = registry.effect(name)
        implied = entry.switch and set(entry.switch) <= switched  # a switch the model has thrown already
        if name not in have and not have & set(entry.equivalent) and not implied and not any(_conflict(name, m) for m in model):
            tried.append(name)
    return tried


def candidate_passes(result):
    """Whether a tested candidate is added (``significant`` set from the round's threshold)."""
    return bool(result["significant"] and result["null_excluded"] and result["excess_share"] >= MIN_EXCESS_SHARE
                and result["median_falls"] and result["rms_falls"] and result["worse_within_share"] and not result["at_bound"])


def _try_candidate(task):
    """Fit one candidate and test it: (result dict, its null linearisation). Runs in a worker."""
    (cfg, current, segments, fold, e_current, floor, bootstrap, sigmas, seed), name, previous = task
    rng = np.random.default_rng([seed, registry.names().index(name)])  # the same draws in any worker
    cand = fit_candidate(cfg, current, name, segments, previous)
    result = _test_fit(cfg, cand, (name,), segments, fold, e_current, floor, bootstrap, sigmas, rng)
    return result, (name, *_null_linearisation(cfg, current, name, segments))


def candidate_pairs(results):
    """Pairs worth fitting together when no single effect passes: the two with the largest
    statistics, and every pair the registry says acts together (``acts_with``: one may help
    only with the other, a corner impulse only with friction capping it, say). Two effects
    that set one config key to different values (two friction rules) are never a pair."""
    tried = [r["effect"] for r in results]
    top = [r["effect"] for r in sorted(results, key=lambda r: -r["z"]) if r["z"] > 0][:2]
    pairs = [tuple(top)] if len(top) == 2 else []
    for a in tried:
        for b in registry.effect(a).acts_with:
            if b in tried and (a, b) not in pairs and (b, a) not in pairs:
                pairs.append((a, b))
    return [pair for pair in pairs if not _conflict(*pair)]


def _conflict(a, b):
    """Whether effects a and b switch one config key to different values."""
    switch_a = dict(registry.effect(a).switch)
    return any(key in switch_a and switch_a[key] != value for key, value in registry.effect(b).switch)


def _try_pair(task):
    """Fit a pair of effects together, from their single fits, and test it. Runs in a worker."""
    (cfg, current, segments, fold, e_current, floor, bootstrap, sigmas, seed, singles), names = task
    spec = current.spec.with_effect(names[0]).with_effect(names[1])
    start = dict(current.params)
    for name in names:
        start.update({k: v for k, v in singles[name].params.items() if k not in current.params})
    best = min((singles[n] for n in names), key=lambda f: f.cost)
    cand = shooting.fit_spec(cfg, spec, segments, start=start, states=best.states)
    rng = np.random.default_rng([seed, 1000 + registry.names().index(names[0]), registry.names().index(names[1])])
    return _test_fit(cfg, cand, names, segments, fold, e_current, floor, bootstrap, sigmas, rng)


class _Apply:
    """Picklable task: item k is ``function(tasks[k])``."""

    def __init__(self, function, tasks):
        self.function = function
        self.tasks = list(tasks)

    def __call__(self, k):
        return self.function(self.tasks[k])


def _map(function, tasks, workers):
    """``function`` over ``tasks`` in order, in ``workers`` processes of the one worker pool (1: here)."""
    return ordered_map(_Apply(function, tasks), len(tasks), workers)


def _worst(trajs, first, second, count=WORST_TRACKS):
    """The ``count`` tracks with the largest ``first`` error: trajectory id and both errors (m)."""
    order = np.argsort(-np.nan_to_num(first, nan=-np.inf))[:count]
    return [{"traj": int(trajs[i]), "error": float(first[i]), "other": float(second[i])} for i in order]


def _select(cfg, seg, prepared, select_set, *, floor, sigmas, rng, seed, folds, pool, max_chain, bootstrap, null_simulations,
            workers, say):
    """The selection on one set of tracks (a cross-fitting fold's training tracks): the declared
    model fitted from its starts, candidates tried round by round and added when they pass,
    the final checks. Returns a dict: ``baseline`` and ``current`` (FitResult), ``chain``,
    ``rounds``, ``removed`` (name -> why), ``baseline_starts``, ``e_current`` (per-track
    held-out errors of the inner cross-validation), ``described`` (the final model's
    parameters with intervals on these tracks)."""
    fold = assign_folds(prepared, folds, seed)
    trajs = [p.traj for p in prepared]
    current, baseline_starts = fit_from_starts(cfg, shooting.ModelSpec.of(cfg), seg, select_set, workers=workers,
                                               max_iterations=POLISH_ITERATIONS)
    lin, red, e_current = _held_out(cfg, current, seg, fold)
    baseline = current
    say(f"  baseline: held-out {shooting.rms(e_current) * 1000:.3f} mm, {current.params}")
    chain, rounds = [], []
    restarts = 0
    previous = {}  # a repeated round's candidate fits, to go on from
    while len(chain) < max_chain:
        tried = untried_effects(pool, current.spec)
        if not tried:
            break
        job = (cfg, current, seg, fold, e_current, floor, bootstrap, sigmas, seed)
        outcomes = _map(_try_candidate, [(job, name, previous.get(name)) for name in tried], workers)
        previous = {}
        results = [r for r, _ in outcomes]
        null_lins = [n for _, n in outcomes]
        for r in results:
            new = [p.name for p in registry.effect(r["effect"]).params]
            say(f"  + {r['effect']}: held-out {r['test_error'] * 1000:.3f} mm (median {r['median_error'] * 1000:.3f}), z = {r['z']:.2f}, "
                f"share of excess {r['excess_share']:.0%}, worse/better tracks {r['worse_tracks']}/{r['better_tracks']}, "
                f"null excluded: {r['null_excluded']}, " + ", ".join(f"{n} = {r['params'][n]['value']:.4g} {r['params'][n]['ci95']}" for n in new))
        better = _better_optimum(cfg, current, results, seg, restarts)
        if better is not None:
            # a candidate whose own parameters stayed null found a lower cost for the others:
            # that is the current model's optimum, not the candidate's gain; take it and redo
            restarts += 1
            say(f"  the current model has a lower optimum (found by {better[1]}, cost {relative_fall(current.cost, better[0].cost):.2%} "
                f"lower): refitted, round repeated")
            previous = {r["effect"]: r["fit"] for r in results}
            current = better[0]
            lin, red, e_current = _held_out(cfg, current, seg, fold)
            if not chain:
                baseline = current
            continue
        threshold, sidak, sims = _null_threshold(cfg, current, lin, null_lins, seg, fold, sigmas, rng, null_simulations)
        for r in results:
            r["significant"] = r["z"] > threshold
            r["accepted"] = candidate_passes(r)
        results.sort(key=lambda r: -r["z"])
        rounds.append({"threshold_z": threshold, "sidak_z": sidak, "null_simulations": sims,
                       "candidates": [{k: v for k, v in r.items() if k not in ("fit", "red", "errors")} for r in results]})
        accepted = [r for r in results if r["accepted"]]
        if not accepted:
            pairs = candidate_pairs(results)
            singles = {r["effect"]: r["fit"] for r in results}
            tested = _map(_try_pair, [((*job, singles), p) for p in pairs], workers)
            # the pairs are more comparisons, chosen after seeing the singles: a stricter bound
            pair_threshold = max(threshold, sidak_bound(len(results) + len(pairs)))
            for pair in tested:
                pair["significant"] = pair["z"] > pair_threshold
                pair["accepted"] = candidate_passes(pair)
                say(f"  + {pair['effect']} together: held-out {pair['test_error'] * 1000:.3f} mm, z = {pair['z']:.2f}, "
                    f"share of excess {pair['excess_share']:.0%}, worse/better tracks {pair['worse_tracks']}/{pair['better_tracks']}, "
                    f"null excluded: {pair['null_excluded']}, added: {pair['accepted']}")
            rounds[-1]["pair_threshold_z"] = pair_threshold
            rounds[-1]["pairs"] = [{k: v for k, v in p.items() if k not in ("fit", "red", "errors")} for p in tested]
            accepted = [p for p in tested if p["accepted"]]
        if not accepted:
            say(f"  stop: no candidate passes (threshold z = {threshold:.2f})")
            break
        best, alike = best_candidate(accepted, pool)
        equivalent = sorted({e for name in best["effects"] for e in registry.effect(name).equivalent})
        chain.append({"step": len(chain) + 1, "effect": best["effect"], "effects": best["effects"], "equivalent": equivalent,
                      "alike_here": alike,
                      "z": best["z"], "threshold_z": threshold, "excess_share": best["excess_share"], "test_error": best["test_error"],
                      "median_error": best["median_error"], "worse_tracks": best["worse_tracks"], "better_tracks": best["better_tracks"],
                      "worst_before": _worst(trajs, e_current, best["errors"]), "worst_after": _worst(trajs, best["errors"], e_current)})
        current = best["fit"]
        restarts = 0
        if any(registry.effect(name).kind == "contact" for name in best["effects"]):
            # a contact effect sends bounces other ways: each flight's state is compared with a
            # fresh fit from its guess (refresh). On the real drops, after the friction pair the
            # next round's flat_landing candidate found a 42 % lower cost with its own parameter
            # null that way, and the round was repeated: 40 s of each fold's 140.
            current = shooting.fit_spec(cfg, current.spec, seg, start=current.params, states=current.states,
                                        max_iterations=POLISH_ITERATIONS, refresh=True)
        elif not current.converged:
            # carried on, so that the next round's candidates are compared with a converged
            # model and not credited with what more iterations give any model
            current = shooting.fit_spec(cfg, current.spec, seg, start=current.params, states=current.states,
                                        max_iterations=POLISH_ITERATIONS)
        lin, red, e_current = _held_out(cfg, current, seg, fold)
        say(f"  added {best['effect']}: held-out {shooting.rms(e_current) * 1000:.3f} mm")

    draws, described = parameter_intervals(current, red, seg, cfg, rng, sigmas, bootstrap)
    # an effect is named by the final model, not by the model it was added to: a later round's
    # refit moved one back to its null (angle_offset 0.0024 [-0.0006, 0.0053] rad, added at 0.03
    # on flat-landing drops: tests/measured/test_diagnose.py), or near it with a gain no longer
    # significant (_weakest_step); it is taken out, the rest refitted, and the checks repeated
    removed = {}  # name -> why
    while True:
        null = [name for name in current.spec.effects if not effect_away_from_null(name, described, cfg)]
        if null:
            removed.update({name: NULL_REASON for name in null})
            say(f"  removed {', '.join(null)}: the final model's 95 % interval holds its null value")
            spec = current.spec.without(null)
            current = shooting.fit_spec(cfg, spec, seg, start=current.params, states=current.states, max_iterations=POLISH_ITERATIONS)
        else:
            weakest = _weakest_step(cfg, current, chain, seg, fold, e_current)
            if weakest is None:
                break
            step, current = weakest
            reason = (f"its gain in the final model is not significant: z = {step['final_z']:.2f} against the "
                      f"{step['threshold_z']:.2f} it passed when added")
            removed.update({name: reason for name in step["effects"] if name not in removed})
            say(f"  removed {step['effect']}: {reason}")
        lin, red, e_current = _held_out(cfg, current, seg, fold)
        draws, described = parameter_intervals(current, red, seg, cfg, rng, sigmas, bootstrap)
    for step in chain:
        step["removed"] = [name for name in step["effects"] if name in removed]
    return {"baseline": baseline, "current": current, "chain": chain, "rounds": rounds, "removed": removed,
            "baseline_starts": baseline_starts, "e_current": e_current, "described": described, "draws": draws}


class _Prefixed:
    """A log that puts a prefix before each line (a fold's lines, from its worker)."""

    def __init__(self, say, prefix):
        self.say, self.prefix = say, prefix

    def __call__(self, message):
        self.say(self.prefix + message)


def _cross_fold(task):
    """Cross-fitting fold k: the selection on the other folds' tracks (:func:`_select`), then its
    declared and final models predict fold k's tracks. Returns (selection, (errors, residual,
    held fit) before, the same after). Runs in a worker."""
    cfg, cross, k, options = task
    train, seg_train, train_set, test, seg_test = cross.part(k)
    options["say"](f"choosing on {len(train)} tracks, predicting {int(test.sum())}")
    sel = _select(cfg, seg_train, train, train_set, **options)
    return sel, confirmation_errors(cfg, sel["baseline"], seg_test, held=True), confirmation_errors(cfg, sel["current"], seg_test, held=True)


def named_effects(models):
    """The effects the folds' models added, in the order first added, one of each set of
    indistinguishable effects (``equivalent``) and of effects that switch one config key to
    different values (the one more folds chose, else the first)."""
    counts = {}
    for model in models:
        for name in model.spec.effects:
            counts[name] = counts.get(name, 0) + 1
    out = []
    for name in sorted(counts, key=lambda n: (-counts[n], next(k for k, m in enumerate(models) if n in m.spec.effects))):
        if any(name in registry.effect(m).equivalent or m in registry.effect(name).equivalent or _conflict(name, m) for m in out):
            continue
        out.append(name)
    first_seen = [n for m in models for n in m.spec.effects]
    return sorted(out, key=first_seen.index)


def _mean_params(models, names):
    """Start values: per name, the mean over the models that have it."""
    out = {}
    for name in names:
        values = [m.params[name] for m in models if name in m.params]
        if values:
            out[name] = float(np.mean(values))
    return out


def _all_tracks_fit(task):
    """A spec fitted on all tracks from stitched states and mean start values. Runs in a worker."""
    cfg, spec, segments, start, states = task
    return shooting.fit_spec(cfg, spec, segments, start=start, states=states, max_iterations=POLISH_ITERATIONS)


def verdict_of(median, floor, named, stand_ins):
    """explained: the median held-out error within EXPLAINED_FACTOR x the floor and no stand-in
    named; improved: a cause named, not explained; unexplained: no cause named (nothing, or
    stand-ins alone), not explained."""
    if median <= EXPLAINED_FACTOR * floor and not stand_ins:
        return "explained"
    return "improved" if set(named) - set(stand_ins) else "unexplained"


def _resplits(cfg, final, red, cross, floor, named, stand_ins, seed, count):
    """The verdict over ``count`` re-splits of the tracks in two halves (other seeds): the final
    model's effect set refitted on each half (one Newton step of the reduced problem from the fit
    on all tracks, the held-out tracks' states refitted to first order), not reselected."""
    out = []
    for k in range(1, count + 1):
        fold = assign_folds(cross.prepared, 2, f"resplit:{seed}:{k}")
        errors = cv_errors(red, cross.segments, fold, list(final.free), final.params, cfg)
        median = float(np.median(errors[np.isfinite(errors)]))
        out.append({"split": f"resplit {k}", "verdict": verdict_of(median, floor, named, stand_ins), "median_error": median,
                    "median_multiple_of_floor": median / floor, "test_error": shooting.rms(errors)})
    return out


def diagnose(trackset, cfg, *, seed=0, folds=FOLDS, cross_folds=CROSS_FOLDS, candidates=None, max_chain=MAX_CHAIN,
             bootstrap=BOOTSTRAP, null_simulations=NULL_SIMULATIONS, resplits=RESPLITS, proposals=True, log=None, angle_reading=None,
             workers=None):
    """Run the loop on tracked drops; returns the report dict (the JSON contract of
    docs/measured_method.md).

    Cross-fitting: the usable tracks are put in ``cross_folds`` folds (halves; more when the
    tracks are few); for each fold the whole selection (:func:`_select`: the declared model's
    fit, the candidates, the final checks) runs on the other folds' tracks, and its baseline and
    final model predict the fold's tracks (states fitted, parameters held). Every track's
    before and after errors thus come from models, and choices of effects, that never saw it;
    the verdict uses them all. The named model is the effects the folds added, refitted on
    all tracks; each is judged cause or stand-in (:mod:`dice_sweep.measured.consistency`)."""
    say = log or (lambda message: None)
    rng = np.random.default_rng(seed)
    workers = default_workers() if workers is None else workers
    cross = cross_fit_tracks(trackset, cfg, seed, cross_folds)
    noise, floor, seg_all, prepared = cross.noise, cross.noise["pose"], cross.segments, cross.prepared
    sigmas = residual_sigmas(noise, cfg)
    declared = registry.declared_effects(cfg)
    pool = [e for e in (candidates or registry.names()) if e not in declared]
    say(f"{len(prepared)} tracks ({seg_all.count} flights) in {cross.folds} cross-fitting folds; noise floor {floor * 1000:.3f} mm; "
        f"candidates: {', '.join(pool)}")
    n = len(prepared)
    e_before, e_after = np.full(n, np.nan), np.full(n, np.nan)
    res_before, res_after = np.zeros((seg_all.times.size, 3)), np.zeros((seg_all.times.size, 3))
    states_before, states_after = np.zeros((seg_all.count, 6)), np.zeros((seg_all.count, 6))
    selections, fold_reports = [], []
    jobs = [(cfg, cross, k, dict(floor=floor, sigmas=sigmas, rng=np.random.default_rng([seed, k]), seed=seed, folds=folds, pool=pool,
                                  max_chain=max_chain, bootstrap=bootstrap, null_simulations=null_simulations,
                                  workers=max(1, workers // cross.folds), say=_Prefixed(say, f"[fold {k + 1}] ")))
            for k in range(cross.folds)]
    # the folds run side by side, each with its share of the workers: a fold alone leaves a
    # core idle in its serial phases (the baseline fit, the null simulations, the final checks)
    for k, (sel, (eb, rb, held_b), (ea, ra, held_a)) in enumerate(_map(_cross_fold, jobs, min(workers, cross.folds))):
        test = cross.fold == k
        rows, segs = test[seg_all.track_rows], test[seg_all.track]
        e_before[test], e_after[test] = eb, ea
        res_before[rows], res_after[rows] = rb, ra
        states_before[segs], states_after[segs] = held_b.states, held_a.states
        selections.append(sel)
        added = [name for name in sel["current"].spec.effects]
        say(f"fold {k + 1}: chosen on {len(test) - int(test.sum())} tracks, added {', '.join(added) or 'nothing'}; its "
            f"{int(test.sum())} held-out tracks: median {np.median(eb) * 1000:.3f} -> {np.median(ea) * 1000:.3f} mm")
        fold_reports.append({"fold": k, "chosen_on_tracks": len(test) - int(test.sum()), "held_out_tracks": int(test.sum()),
                             "effects_added": added,
                             "effects_removed": [{"effect": e, "reason": why} for e, why in sel["removed"].items()],
                             "params": {name: {key: entry[key] for key in ("value", "ci95")} for name, entry in sel["described"].items()},
                             "baseline_params": dict(sel["baseline"].params), "baseline_starts": sel["baseline_starts"],
                             "held_out": {"baseline": {"test_error": shooting.rms(eb), "median_error": float(np.median(eb))},
                                          "after": {"test_error": shooting.rms(ea), "median_error": float(np.median(ea))}}})

    # the named model: the folds' effects refitted on all tracks, from the folds' values and
    # each track's states as its held-out prediction fitted them
    baselines, finals = [s["baseline"] for s in selections], [s["current"] for s in selections]
    spec_base = shooting.ModelSpec.of(cfg)
    spec_final = shooting.ModelSpec.of(cfg, tuple(named_effects(finals)))
    tasks = [(cfg, spec_base, seg_all, _mean_params(baselines, spec_base.param_names()), states_before),
             (cfg, spec_final, seg_all, _mean_params(finals, spec_final.param_names()), states_after)]
    baseline, current = _map(_all_tracks_fit, tasks, workers)
    lin_before = shooting.linearise(cfg, baseline, seg_all)
    _, described_before = parameter_intervals(baseline, reduce(lin_before, seg_all), seg_all, cfg, rng, sigmas, bootstrap)
    removed = {}
    while True:
        lin = shooting.linearise(cfg, current, seg_all)
        red = reduce(lin, seg_all)
        draws_after, described = parameter_intervals(current, red, seg_all, cfg, rng, sigmas, bootstrap)
        null = [name for name in current.spec.effects if not effect_away_from_null(name, described, cfg)]
        if not null:
            break
        removed.update({name: "added by a fold, but its 95 % interval on all tracks holds its null value" for name in null})
        say(f"removed {', '.join(null)}: on all tracks its 95 % interval holds its null value")
        current = shooting.fit_spec(cfg, current.spec.without(null), seg_all, start=current.params, states=current.states,
                                    max_iterations=POLISH_ITERATIONS)
    named = list(current.spec.effects)
    signatures_before = residual_signatures(prepared, seg_all, lin_before.residual, cfg.die.circumradius)
    halves = (cross.fold < max(cross.folds // 2, 1))[seg_all.track]
    judged = consistency(cfg, current, red, seg_all, halves, signatures_before, floor, [seed, 99], sigmas, bootstrap)
    after_error = shooting.rms(e_after)
    median_before, median_before_ci = median_interval(e_before, rng, bootstrap)
    median_after, median_after_ci = median_interval(e_after, rng, bootstrap)
    proposal_report = None
    if proposals and median_after > EXPLAINED_FACTOR * floor:
        say(f"the error is {median_after / floor:.1f} x the noise floor: proposals for what the named model leaves")
        proposal_report = propose.propose_report(trackset, cfg, current, sigma=cross.sigma, table=cross.table, prepared=prepared, seed=seed)
        left_where_it_acts(judged, proposal_report["proposals"])
    stand_ins = [name for name in named if judged[name]["cause"] == "stand_in"]
    for name in named:
        say(f"{name}: {judged[name]['cause']}" + (f" ({'; '.join(judged[name]['consistency']['failed'])})" if name in stand_ins else ""))
    verdict = verdict_of(median_after, floor, named, stand_ins)
    spread = [{"split": f"cross-fitting, seed {seed}", "verdict": verdict, "median_error": median_after,
               "median_multiple_of_floor": median_after / floor, "test_error": after_error}]
    spread += _resplits(cfg, current, red, cross, floor, named, stand_ins, seed, resplits)
    signatures = residual_signatures(prepared, seg_all, lin.residual, cfg.die.circumradius)
    trajs = [p.traj for p in prepared]
    chain = [dict(step, fold=k) for k, sel in enumerate(selections) for step in sel["chain"]]
    rounds = [dict(rnd, fold=k) for k, sel in enumerate(selections) for rnd in sel["rounds"]]
    effects_removed = ([{"effect": name, "reason": why, "fold": k} for k, sel in enumerate(selections) for name, why in sel["removed"].items()]
                       + [{"effect": name, "reason": why, "fold": None} for name, why in removed.items()])
    report = {
        "verdict": verdict,
        "verdict_rule": (f"from every track's held-out error ({cross.folds}-fold cross-fitting: each fold's effects chosen and fitted "
                         f"on the other folds' tracks): explained: median per-track error <= {EXPLAINED_FACTOR} x noise_floor and no "
                         "effect named a stand_in; improved: an effect named a cause, not explained; unexplained: no cause named "
                         "(nothing, or stand-ins alone), not explained"),
        "verdict_spread": {"verdicts": [s["verdict"] for s in spread], "splits": spread, "agree": len({s["verdict"] for s in spread}) == 1,
                           "method": (f"the verdict of the cross-fitting, then of {resplits} re-splits of the tracks in halves (other "
                                      "seeds), each half predicted by the named model's effect set refitted on the other half (one "
                                      "Newton step of the reduced problem from the fit on all tracks, states refitted to first order): "
                                      "the effects are not reselected per re-split")},
        "signatures": signatures,
        "signatures_before": signatures_before,
        "signatures_remaining": remaining_signatures(signatures, floor) if verdict != "explained" else [],
        "effects_added": named,
        "effects": {name: judged[name] for name in named},
        "effects_removed": effects_removed,
        "equivalent_effects": {name: list(registry.effect(name).equivalent) for name in named if registry.effect(name).equivalent},
        "angle_reading": angle_reading or trackset.angle_note,
        "noise_floor": floor,
        "noise": noise,
        "baseline": {"test_error": shooting.rms(e_before), "ci95": bootstrap_rms(e_before, rng, bootstrap),
                     "multiple_of_floor": shooting.rms(e_before) / floor, "median_error": median_before, "median_ci95": median_before_ci,
                     "median_multiple_of_floor": median_before / floor, "params": described_before, "effects": list(declared)},
        "after": {"test_error": after_error, "ci95": bootstrap_rms(e_after, rng, bootstrap), "multiple_of_floor": after_error / floor,
                  "median_error": median_after, "median_ci95": median_after_ci, "median_multiple_of_floor": median_after / floor,
                  "params": described, "effects": list(declared) + named},
        "worst_tracks": {"before": [{"traj": w["traj"], "before": w["error"], "after": w["other"]} for w in _worst(trajs, e_before, e_after)],
                         "after": [{"traj": w["traj"], "after": w["error"], "before": w["other"]} for w in _worst(trajs, e_after, e_before)]},
        "proposals": proposal_report["proposals"] if proposal_report else [],
        "proposals_note": (proposal_report["method"] if proposal_report else
                           f"not computed: the median error is within {EXPLAINED_FACTOR} x the noise floor" if proposals else "not computed (turned off)"),
        "folds": fold_reports,
        "chain": chain,
        "rounds": rounds,
        "metric": METRIC,
        "selection": (f"{cross.folds}-fold cross-fitting over tracks: in each fold the effects are chosen on the other folds' tracks "
                      f"with {folds}-fold cross-validation over them (one-step refits); an effect is added when the one-sided Wilcoxon "
                      f"signed-rank statistic of the per-track held-out squared errors beats the 95 % quantile of its largest value over "
                      f"all candidates in {null_simulations} simulations from the current model (never below the Sidak bound), every "
                      f"parameter's 95 % bootstrap interval excludes its null value, no parameter ends at a bound, it removes at least "
                      f"{MIN_EXCESS_SHARE:.0%} of the error above the noise floor, the held-out RMS and the median per-track error both "
                      f"fall, and of the tracks whose error moves by more than {MARKED:g} x the noise floor at most "
                      f"{MAX_WORSE_SHARE:.0%} get worse; the named effects are those of the folds, refitted on all tracks"),
        "data": {"path": trackset.path, "tracks": len(trackset.tracks), "rate_hz": trackset.rate, "usable_tracks": n,
                 "flights": seg_all.count, "cross_folds": cross.folds,
                 "glitch_frames": trackset.glitch_count, "gap_frames": trackset.gap_frames,
                 "table_height_m": cross.table, "table_note": "median lowest-corner height of the dice at rest (0: none at rest); flights are cut there"},
        "_fits": {"baseline": baseline, "after": current, "confirm_errors": (e_before, e_after),
                  "confirm_residuals": {"baseline": res_before, "after": res_after},
                  "segments": (seg_all, seg_all), "prepared": (prepared, prepared), "proposals": proposal_report},
    }
    params = {}
    for name, entry in described.items():
        params[name] = {key: entry[key] for key in ("value", "ci95", "ci95_tracks", "sd_noise", "at_bound", "unit",
                                                     "one_track_decides", "top_track_share")}
    report["params"] = params
    report["bootstrap_draws"] = bootstrap_record(current.free, draws_after)
    report.update(fit_context(cfg, CONFIRM_FRACTION, seed))
    if cross.file_halves:
        # what ``forecast`` reads: fold 0's model, chosen and fitted on fold 1's tracks, and the
        # split whose held-out half is fold 0 (TrackSet.split(0.5, seed)): tracks it never saw
        held = selections[0]["current"]
        report["held_out_model"] = {
            "fold": 0, "effects": list(declared) + list(held.spec.effects),
            "params": {name: {key: entry[key] for key in ("value", "ci95", "unit")} for name, entry in selections[0]["described"].items()},
            "bootstrap_draws": bootstrap_record(held.free, selections[0]["draws"]),
            "split": {"confirm_fraction": 0.5, "seed": seed},
            "note": "fold 0's model (effects chosen and fitted on fold 1's tracks); split's held-out half is fold 0"}
    report["by_bounce"], report["by_tilt"] = residual_by_bounce(cfg, report["_fits"])
    return report


def fit_report(trackset, cfg, *, effects=(), seed=0, workers=None):
    """The ``fit`` command's work: the declared model plus ``effects`` fitted on the selection
    tracks from its starts (:func:`fit_from_starts`), with 95 % intervals (bootstrap over tracks
    and the tracking noise's share), scored on the confirmation tracks.

    Returns
    -------
    result : dict
        The JSON contract of ``dice-sweep fit --json`` (docs/measured_method.md).
    split : Split
        The tracks, as :func:`dice_sweep.measured.split.split_tracks` made them ready.
    residual : numpy.ndarray
        (rows, 3) residual (m) of the confirmation tracks' segments (the residual picture).
    """
    split = split_tracks(trackset, cfg, CONFIRM_FRACTION, seed, roles=("fitting", "scoring"))
    rng = np.random.default_rng(seed)
    declared = registry.declared_effects(cfg)
    extra = tuple(e for e in effects if e not in declared)
    spec = shooting.ModelSpec.of(cfg, extra)
    workers = default_workers() if workers is None else workers
    fit, starts = fit_from_starts(cfg, spec, split.seg_select, split.select_set, workers=workers)
    lin = shooting.linearise(cfg, fit, split.seg_select)
    red = reduce(lin, split.seg_select)
    draws, params = parameter_intervals(fit, red, split.seg_select, cfg, rng, residual_sigmas(split.noise, cfg))
    e_train = shooting.track_errors(split.seg_select, lin.residual)
    e_test, residual_test = confirmation_errors(cfg, fit, split.seg_confirm)
    result = {
        "metric": METRIC,
        "model": cfg.contact.model if "corner_impulse" not in extra else "rigid",
        "effects": list(declared) + list(extra),
        "params": params,
        "train_error": shooting.rms(e_train),
        "test_error": shooting.rms(e_test),
        "ci95": bootstrap_rms(e_test, rng),
        "noise_floor": split.noise["pose"],
        "train_tracks": len(split.select),
        "test_tracks": len(split.confirm),
        "converged": fit.converged,
        "starts": starts,
        "angle_reading": trackset.angle_note,
        "glitch_frames": trackset.glitch_count,
        "data": {"path": trackset.path},
        "bootstrap_draws": bootstrap_record(fit.free, draws),
        **fit_context(cfg, CONFIRM_FRACTION, seed),
    }
    return result, split, residual_test
