"""Cause or stand-in: whether an effect the loop added measures one thing, or soaks up a misfit
of physics the library lacks (issue 30, item 3).

An effect that improves the fit is called a *cause* only if it passes two tests; else it is a
*stand-in* and the verdict cannot be ``explained``:

1. **The same value on independent parts of the data.** The final model (every parameter
   free) is fitted on each side of three splits, by one Newton step of the side's reduced
   problem from the fit on all tracks (:func:`part_fit`):

   * ``track_halves``: the two halves of the tracks of the cross-fitting (whatever differs
     from track to track: a value one half needs and the other not);
   * ``first_vs_later_flights``: the first flight of every track with the first impact its
     prediction crosses (the fastest impact, from the release height) against the later flights
     and impacts (slower, the die spinning after the first bounce). A stand-in for a contact
     that depends on the impact speed (a compliant contact, a speed-dependent restitution)
     takes another value on each side; a real table offset, g or drag takes the same;
   * ``direction_of_motion``: the flights moving towards -x against those moving towards +x
     (the sign of vx in the segment's fitted state). Every effect of the library is the same
     in a mirror; a tilted table is not, and drag standing in for it (a deceleration along
     the motion for an acceleration along the table) takes another value on each side.

   For every parameter of the effect and every split, z = (a - b) / sqrt(sd_a^2 + sd_b^2),
   sd = the width of each side's 95 % interval (:func:`dice_sweep.measured.reduced.parameter_intervals`:
   the bootstrap over tracks and the tracking noise's share) over 2 x 1.96. The test fails when
   any |z| exceeds ``Z_AGREE``. A side that does not identify the parameter (no interval)
   cannot test it: that comparison is reported as ``untestable`` and does not fail.
2. **Its signature was there before.** The flight signature the registry says the effect
   leaves (:mod:`dice_sweep.measured.signatures`: vertical curvature, deceleration, wobble at
   the spin angle) was in the declared model's residual on all tracks (:func:`signature_present`).
   The signature of the contact effects, the extra error of frames predicted through an impact,
   does not count: it was absent before effects that were really there (inertia 0.8 of eq.
   25's, a corner impulse with friction), each flight's own state taking up part of a contact's
   misfit. A signature that could not be measured (no flight turned far enough for a wobble)
   cannot fail either; both are reported.

3. **Nothing left where it acts.** When the named model still leaves the error above 1.5
   times the floor, ``diagnose`` proposes sparse formulas for what it leaves
   (:mod:`dice_sweep.measured.propose`); a flight effect with a proposal for a flight target
   left (``flight.*``) has not taken up the misfit it was added for: drag named for a table
   tilted by 3 degrees left ``flight.x_acc ~ 1`` (0.50 m/s^2, held-out gain 0.99) and agreed
   with itself on every split (:func:`left_where_it_acts`). Contact effects are not tested so:
   the impact misfits are a catch-all, like the impact-prediction signature (on the real drops
   the friction pair, which halved the median error, left ``impact.dvy ~ u_n + tilt``, the
   normal rebound, which friction does not set); nor are measurement effects, which act
   everywhere.

docs/measured_method.md ("Cause or stand-in") gives the calibration.
"""

import math
from dataclasses import replace
from statistics import NormalDist

import numpy as np

from dice_sweep import effects as registry
from dice_sweep.measured import fit as shooting
from dice_sweep.measured.reduced import parameter_intervals, part_step
from dice_sweep.measured.stats import Z95

# |z| beyond which two parts' values disagree: two-sided 1 % (2.58). Not the 5 % quantile: the
# intervals are about 1.3 times too narrow for some parameters (docs/dev/measured_intervals.md),
# and three splits are tested per parameter.
Z_AGREE = NormalDist().inv_cdf(1.0 - 0.01 / 2.0)
MIN_PART_SEGMENTS = 8  # flights a side of a split needs to be fitted
SPLITS = ("track_halves", "first_vs_later_flights", "direction_of_motion")
TEST = (f"the final model fitted on each side of three splits (one Newton step of the side's reduced problem from the fit on all tracks): the two halves of "
        f"the tracks of the cross-fitting, the first flight of every track (with the first, fastest impact) against the later "
        f"flights, and the flights moving towards -x against those moving towards +x; for each parameter of the effect z = (a - b) / sqrt(sd_a^2 + sd_b^2), sd from each side's 95 % interval "
        f"(width / 3.92); a cause needs every |z| <= {Z_AGREE:.2f} and, for an effect with a flight signature, that signature in the "
        f"declared model's residual on all tracks (signed: interval excludes 0; wobble: above half the floor; the impact "
        f"prediction's signature does not count); and, when the named model leaves the error above 1.5 x the floor, no "
        f"proposal for a flight target left by a flight effect")


def flight_index(segments):
    """Index of each segment's flight within its track (0: the first flight)."""
    return np.arange(segments.count) - segments.track_segment_starts[segments.track]


def part_fit(cfg, fit, red, segments, keep, rng, sigmas, bootstrap):
    """The model of ``fit`` on the segments where ``keep`` holds, with its described parameters
    (None when no segment is kept): one Newton step of the part's reduced problem from the fit
    on all tracks (``red``), intervals from the one-step bootstrap over the part's tracks and
    the tracking noise, as on all tracks.

    Why not a refit: warm Levenberg-Marquardt refits of the parts stayed at their start on the
    real drops (friction moved 2e-5 on halves whose sd is 3e-3: a rough cost rejects the
    Gauss-Newton step and the damped ones gain too little), so no split tested friction."""
    if not np.any(keep):
        return None
    names = list(fit.free)
    values, red_part, part = part_step(red, segments, keep, names, fit.params, cfg)
    stepped = replace(fit, params=values, states=fit.states[keep], at_bound=shooting.at_bounds(cfg, values, names))
    _, described = parameter_intervals(stepped, red_part, part, cfg, rng, sigmas, bootstrap)
    return {"segments": int(part.count), "tracks": int(part.tracks), "params": described}


def _sd(entry):
    low, high = entry["ci95"]
    if low is None or high is None or not (math.isfinite(low) and math.isfinite(high)) or not entry.get("identified", True):
        return math.nan
    return (high - low) / (2.0 * Z95)


# A part fit starts from the value on all tracks; two independent parts land about one sd of
# their difference apart, so sides that both stay within MIN_MOVE of it did not refit (on the
# real drops friction moved 2e-5 on halves whose sd is 3e-3: |z| <= 0.007 on all three splits,
# odds about 1e-7 for parts that did refit) and cannot say that they agree.
MIN_MOVE = 0.05  # of the sd of the two parts' difference


def compare(name, first, second, start=None):
    """One parameter on two parts: values, intervals and z (NaN when a side has no interval).
    With ``start`` (the value on all tracks that both part fits started from), a comparison in
    which neither side moved from it by MIN_MOVE x the sd of the difference is not testable
    (``moved`` false): the part fits stayed where they started."""
    a, b = first["params"][name], second["params"][name]
    sd_a, sd_b = _sd(a), _sd(b)
    spread = math.hypot(sd_a, sd_b)
    z = (a["value"] - b["value"]) / spread if math.isfinite(spread) and spread > 0 else math.nan
    moved = bool(start is None or not math.isfinite(z)
                 or max(abs(a["value"] - start), abs(b["value"] - start)) > MIN_MOVE * spread)
    testable = bool(math.isfinite(z) and moved)
    return {"param": name, "values": [a["value"], b["value"]], "ci95": [list(a["ci95"]), list(b["ci95"])],
            "z": z, "moved": moved, "agree": bool(not testable or abs(z) <= Z_AGREE), "testable": testable}


COUNTED = ("flight_vertical_curvature", "flight_deceleration", "flight_wobble_at_spin", "flight_spin_change")


def signature_present(entry, floor):
    """Whether a signature (:func:`dice_sweep.measured.signatures.residual_signatures`'s entry)
    is in a residual: a signed one when its 95 % interval excludes 0; the impact prediction's
    extra error when its interval lies above 0; the wobble at the spin angle, an amplitude that
    the noise alone keeps above 0, when its interval lies above half the noise floor. None when
    it could not be measured."""
    if not entry or entry.get("value") is None or not np.isfinite(entry["value"]):
        return None
    low, high = entry["ci95"]
    if entry["signature"] == "flight_wobble_at_spin":
        return bool(low > 0.5 * floor)
    if entry["signature"] == "impact_prediction":
        return bool(low > 0.0)
    return bool(not low <= 0.0 <= high)


DOMAINS = {"flight": "flight."}  # kind -> the proposals' targets it must leave empty


def left_where_it_acts(judged, proposals):
    """Test 3 on :func:`consistency`'s result (changed in place and returned): a flight effect
    with a proposal for a flight target becomes a stand-in, the proposals named in
    ``consistency.left``."""
    for name, entry in judged.items():
        prefix = DOMAINS.get(registry.effect(name).kind)
        left = [p for p in proposals if prefix and p["target"].startswith(prefix)]
        entry["consistency"]["left"] = [{"target": p["target"], "terms": dict(p["terms"]), "heldout_gain": p["heldout_gain"]} for p in left]
        for p in left:
            terms = " + ".join(p["terms"])
            entry["consistency"]["failed"].append(f"left where it acts: {p['target']} ~ {terms} (held-out gain {p['heldout_gain']:.2f})")
        if left:
            entry["cause"] = "stand_in"
            entry["consistency"]["passed"] = False
    return judged


def _part_fit(task):
    """:func:`part_fit` of one task."""
    cfg, fit, red, segments, keep, seed, sigmas, bootstrap = task
    return part_fit(cfg, fit, red, segments, keep, np.random.default_rng(seed), sigmas, bootstrap)


def consistency(cfg, fit, red, segments, halves, signatures_before, floor, seed, sigmas, bootstrap, effects=None, mapper=None):
    """Cause or stand-in for each added effect of ``fit`` (the final model on all tracks).

    Parameters
    ----------
    fit : FitResult
        The final model, fitted on ``segments`` (all tracks).
    red : Reduced
        Its reduced problem on all tracks (:func:`dice_sweep.measured.reduced.reduce`).
    halves : numpy.ndarray
        bool per segment: the first half of the tracks (the cross-fitting's first fold).
    signatures_before : list
        :func:`dice_sweep.measured.signatures.residual_signatures` of the declared model on all tracks.
    floor : float
        The noise floor (m), for :func:`signature_present`.
    effects : list, optional
        The effects to judge (default: the model's added effects).
    mapper : callable, optional
        ``mapper(function, tasks)`` -> results in order; default here (a part is a linear solve).

    Returns
    -------
    dict
        effect -> ``{"cause": "cause" | "stand_in", "consistency": {test, passed, z_limit,
        comparisons, signature, failed}}``.
    """
    effects = list(fit.spec.effects if effects is None else effects)
    if not effects:
        return {}
    first = flight_index(segments) == 0
    leftward = fit.states[:, 3] < 0.0
    sides = {"track_halves": (np.asarray(halves, dtype=bool), ~np.asarray(halves, dtype=bool)),
             "first_vs_later_flights": (first, ~first), "direction_of_motion": (leftward, ~leftward)}
    # a split with too few flights on a side is not fitted (its comparisons are left out)
    usable = [split for split, pair in sides.items() if min(int(pair[0].sum()), int(pair[1].sum())) >= MIN_PART_SEGMENTS]
    tasks = [(cfg, fit, red, segments, keep, [seed, k], sigmas, bootstrap) for k, keep in enumerate(keep for split in usable for keep in sides[split])]
    fitted = (mapper or (lambda f, items: [f(item) for item in items]))(_part_fit, tasks)
    parts = {split: fitted[2 * k:2 * k + 2] for k, split in enumerate(usable)}
    by_name = {s["signature"]: s for s in signatures_before}
    out = {}
    for name in effects:
        comparisons = []
        for split, (one, two) in parts.items():
            for p in registry.effect(name).params:
                if one is None or two is None or p.name not in one["params"]:
                    continue
                entry = compare(p.name, one, two, start=fit.params.get(p.name))
                entry["split"] = split
                entry["sides"] = [{"segments": one["segments"], "tracks": one["tracks"]}, {"segments": two["segments"], "tracks": two["tracks"]}]
                comparisons.append(entry)
        signature = registry.effect(name).signature
        before = by_name.get(signature, {})
        present = signature_present(before, floor) if signature else None
        counts = signature in COUNTED and present is not None
        failed = [f"{c['split']}: {c['param']} z = {c['z']:.2f}" for c in comparisons if not c["agree"]]
        if counts and not present:
            failed.append(f"signature {signature} not present before the effect was added")
        if registry.effect(name).params and not any(c["testable"] for c in comparisons) and not (counts and present):
            # a value that no split could test and no signature backs is not shown to be one thing
            stuck = [f"{c['split']}: {c['param']}" for c in comparisons if not c["moved"]]
            failed.append("untested: no split refitted it" + (f" (the part fits stayed at the value on all tracks: {', '.join(stuck)})"
                                                              if stuck else ""))
        out[name] = {"cause": "stand_in" if failed else "cause",
                     "consistency": {"test": TEST, "passed": not failed, "z_limit": Z_AGREE, "comparisons": comparisons,
                                     "signature": {"name": signature or None, "present_before": present, "counts": counts, "value": before.get("value"),
                                                   "ci95": before.get("ci95")},
                                     "failed": failed, "left": []}}
    return out
