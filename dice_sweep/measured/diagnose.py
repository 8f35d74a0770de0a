"""The measured-data loop: fit the declared model, read the residual, add the effect that
explains it, repeat while the held-out error still falls clearly; report the chain.

Selection is by cross-validation: every candidate is fitted on the training tracks and scored
by its RMS pose error on the held-out tracks; the best is kept only if it lowers the held-out
error by at least MIN_GAIN (relative). Extra parameters are penalised by having to earn that
gain on tracks they were not fitted to.
"""

import math

import numpy as np

from dice_sweep import geometry
from dice_sweep.measured.fit import (
    EFFECTS,
    HORIZON_AFTER_IMPACT,
    ModelSpec,
    TrackModel,
    declared_effects,
    fit_spec,
    gravity_of,
    held_out_error,
    model_config,
    prepare_tracks,
)

MIN_GAIN = 0.05
METRIC = (
    "RMS over frames of sqrt(dx^2 + dy^2 + (R dphi)^2) in m between tracked and simulated poses, "
    f"from the first frame to {HORIZON_AFTER_IMPACT * 1000:.0f} ms after the first impact, on held-out tracks"
)
SELECTION = (
    f"cross-validation: each candidate is fitted (soft-L1 least squares) on the training tracks and scored by "
    f"its held-out RMS error; an effect is added only if it lowers the held-out error by at least {MIN_GAIN:.0%}"
)


def _polyfit_coefficient(t, values, degree, index):
    if t.size < degree + 2:
        return math.nan
    return float(np.polyfit(t, values, degree)[::-1][index])


def residual_signatures(cfg, fit, prepared):
    """Structure of the residual of a fit on tracks, and what each signature points to.

    Returns a list of dicts {"signature", "value", "unit", "points_to", "note"}.
    """
    model = TrackModel(cfg, fit.spec, prepared)
    poses, _, states = model.simulate(fit.params)
    g = gravity_of(model_config(cfg, fit.spec, fit.params))
    diff = model.measured - poses
    curvature_y, curvature_x, wobble, impact_dv, impact_speed, lever = [], [], [], [], [], []
    for i, track in enumerate(prepared):
        rows = slice(model.starts[i], model.starts[i + 1])
        d = diff[rows]
        t = track.times
        free = track.free
        # in flight: an extra constant acceleration shows as curvature of the residual
        curvature_y.append(2 * _polyfit_coefficient(t[free], d[free, 1], 2, 2))
        curvature_x.append(2 * _polyfit_coefficient(t[free], d[free, 0], 2, 2) * -np.sign(states[i, 3] or 1.0))
        phi = track.pose[free, 2]
        if free.sum() >= 6:
            basis = np.column_stack([np.ones(free.sum()), t[free], np.cos(phi), np.sin(phi)])
            coef_x = np.linalg.lstsq(basis, d[free, 0], rcond=None)[0]
            wobble.append(float(np.hypot(coef_x[2], coef_x[3])))
        after = (t > track.t_impact) & (t <= track.t_impact + 0.03)
        if after.sum() >= 3:
            impact_dv.append(_polyfit_coefficient(t[after], d[after, 1], 1, 1))
            impact_speed.append(abs(states[i, 4] - g * track.t_impact))
            lowest = np.argmin(np.sin(track.pose[free, 2][-1] + 2 * np.pi * np.arange(cfg.die.sides) / cfg.die.sides))
            lever.append(abs(math.cos(track.pose[free, 2][-1] + 2 * np.pi * lowest / cfg.die.sides)))
    signatures = []

    def add(name, value, unit, points_to, note):
        signatures.append({"signature": name, "value": value, "unit": unit, "points_to": points_to, "note": note})

    add("flight_vertical_curvature", float(np.nanmedian(curvature_y)), "m/s^2", "gravity",
        "median extra vertical acceleration of the tracks over the model in free flight")
    add("flight_horizontal_deceleration", float(np.nanmedian(curvature_x)), "m/s^2", "air_drag",
        "median horizontal deceleration (against the motion) left in free flight")
    add("flight_wobble_at_spin", float(np.median(wobble)) if wobble else math.nan, "m", "com_offset",
        "median amplitude of the horizontal residual at the spin angle (cos phi, sin phi)")
    if len(impact_dv) >= 3:
        add("impact_dv_vs_speed", float(np.corrcoef(impact_speed, impact_dv)[0, 1]), "correlation", "speed_restitution",
            "correlation of the vertical velocity error after the first impact with the impact speed")
        add("impact_dv_vs_lever", float(np.corrcoef(lever, impact_dv)[0, 1]), "correlation", "corner_impulse",
            "correlation of that error with the touching corner's horizontal lever arm")
        add("impact_dv_median", float(np.median(impact_dv)), "m/s", "beta_normal",
            "median vertical velocity error after the first impact")
    return signatures


def first_impact_velocity_error(cfg, fit, prepared):
    """RMS (m/s) over tracks of the velocity error sqrt(dvx^2 + dvy^2 + (R domega)^2) 30 ms
    after the first impact, measured velocities from a linear fit over the frames there."""
    model = TrackModel(cfg, fit.spec, prepared)
    poses, _, _ = model.simulate(fit.params)
    errors = []
    for i, track in enumerate(prepared):
        rows = slice(model.starts[i], model.starts[i + 1])
        after = (track.times > track.t_impact + 0.004) & (track.times <= track.t_impact + 0.03)
        if after.sum() < 3:
            continue
        t = track.times[after]
        measured = [np.polyfit(t, track.pose[after, k], 1)[0] for k in range(3)]
        simulated = [np.polyfit(t, poses[rows][after, k], 1)[0] for k in range(3)]
        d = np.subtract(simulated, measured)
        errors.append(math.sqrt(d[0] ** 2 + d[1] ** 2 + (cfg.die.circumradius * d[2]) ** 2))
    return float(np.sqrt(np.mean(np.square(errors)))) if errors else math.nan


def first_impact_spin(cfg, fit, prepared):
    """How the simulated spin after the first impact compares with the tracked one: share of
    tracks with the same sign, and the correlation (slopes of phi 6-50 ms after the impact)."""
    model = TrackModel(cfg, fit.spec, prepared)
    poses, _, _ = model.simulate(fit.params)
    pairs = []
    for i, track in enumerate(prepared):
        rows = slice(model.starts[i], model.starts[i + 1])
        after = (track.times > track.t_impact + 0.006) & (track.times < track.t_impact + 0.05)
        if after.sum() < 4:
            continue
        t = track.times[after]
        pairs.append((np.polyfit(t, track.pose[after, 2], 1)[0], np.polyfit(t, poses[rows][after, 2], 1)[0]))
    if len(pairs) < 3:
        return {"sign_agreement": math.nan, "correlation": math.nan, "tracks": len(pairs)}
    measured, simulated = np.array(pairs).T
    return {"sign_agreement": float(np.mean(np.sign(measured) == np.sign(simulated))),
            "correlation": float(np.corrcoef(measured, simulated)[0, 1]),
            "measured_range_rad_s": [float(measured.min()), float(measured.max())],
            "simulated_range_rad_s": [float(simulated.min()), float(simulated.max())],
            "tracks": len(pairs)}


def final_side_agreement(cfg, fit, trackset):
    """Share of tracks whose simulated resting side equals the tracked one (tracks that end
    at rest, simulated to their last frame), and how many tracks were compared."""
    long_prep = prepare_tracks(trackset, cfg, horizon_after_impact=1e9)
    by_traj = {track.traj: track for track in trackset.tracks}
    model = TrackModel(cfg, fit.spec, long_prep)
    poses, _, _ = model.simulate(fit.params)
    agree = compared = 0
    for i, prep in enumerate(long_prep):
        track = by_traj[prep.traj]
        tail = np.isfinite(track.phi[-5:]) & ~track.glitch[-5:]
        if tail.sum() < 3 or np.ptp(track.y[-5:][tail]) > 1e-3:
            continue  # not at rest at the end of the track
        measured_side = int(geometry.side_below(cfg.die.sides, np.median(track.phi[-5:][tail])))
        simulated_side = int(geometry.side_below(cfg.die.sides, poses[model.starts[i + 1] - 1, 2] - fit.params.get("angle_offset", 0.0)))
        compared += 1
        agree += measured_side == simulated_side
    return (agree / compared if compared else math.nan), compared


def _fit_summary(cfg, fit, test_err):
    return {
        "model": "rigid" if "corner_impulse" in fit.spec.effects else cfg.contact.model,
        "effects": list(declared_effects(cfg)) + list(fit.spec.effects),
        "params": fit.params,
        "train_error": fit.train_error,
        "test_error": test_err,
    }


def diagnose(trackset, cfg, *, test_fraction=0.3, seed=0, min_gain=MIN_GAIN, max_chain=4, candidates=None, log=None,
             keep_fits=False):
    """Run the loop on tracked drops; returns the report dict (docs/measured.md).

    With ``keep_fits`` the report also holds "_fits": [("baseline", fit), ("after", fit)] for
    pictures (not JSON).
    """
    say = log or (lambda message: None)
    train_set, test_set = trackset.split(test_fraction, seed)
    train = prepare_tracks(train_set, cfg)
    test = prepare_tracks(test_set, cfg)
    declared = declared_effects(cfg)
    pool = [e for e in (candidates or EFFECTS) if e not in declared]
    say(f"{len(train)} training and {len(test)} held-out tracks usable; candidates: {', '.join(pool)}")
    current = fit_spec(cfg, ModelSpec(), train)
    current_test = held_out_error(cfg, current, test)
    baseline, baseline_test = current, current_test
    say(f"baseline: held-out error {current_test * 1000:.2f} mm, params {current.params}")
    chain = []
    first_round = None
    while len(chain) < max_chain:
        results = []
        for effect in pool:
            if effect in current.spec.effects:
                continue
            fit = fit_spec(cfg, current.spec.with_effect(effect), train, start=current.params)
            err = held_out_error(cfg, fit, test)
            results.append({"effect": effect, "params": fit.params, "test_error": err, "score": err,
                            "train_error": fit.train_error, "_fit": fit})
            say(f"  + {effect}: held-out error {err * 1000:.2f} mm")
        if not results:
            break
        results.sort(key=lambda r: r["score"])
        if first_round is None:
            first_round = results
        best = results[0]
        gain = 1.0 - best["test_error"] / current_test
        chain.append({"step": len(chain) + 1, "best": best["effect"], "test_error": best["test_error"],
                      "gain": gain, "accepted": gain >= min_gain})
        if gain < min_gain:
            say(f"stop: the best, {best['effect']}, gains {gain:.1%} < {min_gain:.0%}")
            break
        current, current_test = best["_fit"], best["test_error"]
        say(f"added {best['effect']}: held-out error {current_test * 1000:.2f} mm")
    before_side, compared = final_side_agreement(cfg, baseline, test_set)
    after_side, _ = final_side_agreement(cfg, current, test_set)
    report = {
        "metric": METRIC,
        "selection": SELECTION,
        "data": {"path": trackset.path, "tracks": len(trackset.tracks), "rate_hz": trackset.rate,
                 "train_tracks_used": len(train), "test_tracks_used": len(test),
                 "glitch_frames": trackset.glitch_count, "glitch_tracks": trackset.glitch_tracks,
                 "angle_convention": trackset.angle_note,
                 "robust_loss": "soft-L1 least squares, scale 3 mm; glitch frames excluded"},
        "baseline": _fit_summary(cfg, baseline, baseline_test),
        "signatures": residual_signatures(cfg, baseline, test),
        "candidates": [{k: v for k, v in r.items() if not k.startswith("_")} for r in (first_round or [])],
        "best_effect": chain[0]["best"] if chain and chain[0]["accepted"] else None,
        "after": _fit_summary(cfg, current, current_test),
        "chain": chain,
        "first_impact_velocity_error": {"before": first_impact_velocity_error(cfg, baseline, test),
                                        "after": first_impact_velocity_error(cfg, current, test),
                                        "unit": "m/s"},
        "final_side_agreement": {"before": before_side, "after": after_side, "tracks": compared},
        "first_impact_spin": {"before": first_impact_spin(cfg, baseline, test), "after": first_impact_spin(cfg, current, test)},
    }
    report["after"]["effects_added"] = list(current.spec.effects)
    if keep_fits:
        report["_fits"] = [("baseline", baseline), ("after: " + "+".join(current.spec.effects or ("none",)), current)]
    return report
