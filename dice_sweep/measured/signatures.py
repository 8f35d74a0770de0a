"""Residual signatures: the structure a fit leaves in its residual, and the effects of the
registry each points to.

Per track, over the frames of each flight its own state was fitted to: the curvature left in
the vertical position, the deceleration along the motion, the change of the spin, and a wobble
of the centre at the spin angle (a loaded die); and the extra error of the frames predicted
through an impact. Each signature's value is the median over tracks with a 95 % interval
(bootstrap over tracks); an effect names the signature it leaves in ``registry.EFFECTS``.
"""

import math

import numpy as np

from dice_sweep import effects as registry
from dice_sweep.measured.stats import bootstrap_quantiles

WOBBLE_MIN_TURN = math.pi  # rad a flight must turn for a wobble at the spin angle to be seen

SIGNATURES = {
    # name: (unit, what it measures, registry signature names it points to)
    "flight_vertical_curvature": ("m/s^2", "extra vertical acceleration left in the flights the states were fitted to"),
    "flight_deceleration": ("m/s^2", "deceleration along the motion left in the flights"),
    "flight_spin_change": ("rad/s^2", "angular acceleration left in the flights (no effect of the library changes the spin in flight)"),
    "flight_wobble_at_spin": ("m", "amplitude of the flights' residual of the centre at the spin angle"),
    "impact_prediction": ("m", "RMS error of the frames predicted through an impact, over the flight frames' error"),
}


def residual_signatures(prepared, segments, residual, radius):
    """Structure left in the residual of a fit, track by track; each value with a 95 % interval
    (bootstrap over tracks) and what it points to in the effect registry."""
    per_track = {name: [] for name in SIGNATURES}
    for i in range(segments.tracks):
        curv, decel, spin, wobble = [], [], [], []
        for j in np.flatnonzero(segments.track == i):
            rows = np.arange(segments.starts[j], segments.starts[j + 1])
            own = rows[~segments.predicted[rows]]
            if own.size < 6:
                continue
            t = segments.times[own]
            d = -residual[own]  # tracked minus simulated
            pose = segments.measured[own]
            quad = np.polyfit(t, d, 2)  # (3, 3): highest power first
            curv.append(2 * quad[0, 1])
            v = np.polyfit(t, pose[:, :2], 1)[0]
            speed = math.hypot(*v)
            if speed > 0:
                decel.append(-2 * (quad[0, 0] * v[0] + quad[0, 1] * v[1]) / speed)
            spin.append(2 * quad[0, 2] / radius)
            if np.ptp(pose[:, 2]) > WOBBLE_MIN_TURN:  # else cos, sin of phi are near 1 and t
                basis = np.column_stack([np.ones_like(t), t, np.cos(pose[:, 2]), np.sin(pose[:, 2])])
                coef = np.linalg.lstsq(basis, d[:, 0], rcond=None)[0]
                wobble.append(math.hypot(coef[2], coef[3]))
        rows = np.flatnonzero(segments.track_rows == i)
        pred = rows[segments.predicted[rows]]
        own = rows[~segments.predicted[rows]]
        for name, values in (("flight_vertical_curvature", curv), ("flight_deceleration", decel), ("flight_spin_change", spin),
                             ("flight_wobble_at_spin", wobble)):
            if values:
                per_track[name].append(float(np.median(values)))
        if pred.size and own.size:
            e_pred = math.sqrt(np.mean(np.sum(residual[pred] ** 2, axis=1)))
            e_own = math.sqrt(np.mean(np.sum(residual[own] ** 2, axis=1)))
            per_track["impact_prediction"].append(e_pred - e_own)
    rng = np.random.default_rng(0)
    out = []
    for name, values in per_track.items():
        values = np.array(values)
        unit, note = SIGNATURES[name]
        points = [e.name for e in registry.EFFECTS if e.signature == name]
        if values.size < 3:
            out.append({"signature": name, "value": math.nan, "ci95": [math.nan, math.nan], "unit": unit, "points_to": points, "note": note})
            continue
        out.append({"signature": name, "value": float(np.median(values)), "ci95": bootstrap_quantiles(values, np.median, rng, 500),
                    "unit": unit, "points_to": points or ["none in the library"], "note": note, "tracks": int(values.size)})
    return out


def remaining_signatures(signatures, floor):
    """Signatures left in the residual: a signed one whose interval excludes 0, an amplitude
    (wobble) or the impact prediction's extra error whose interval lies above half the floor."""
    left = []
    for s in signatures:
        if not np.isfinite(s["value"]):
            continue
        if s["signature"] in ("impact_prediction", "flight_wobble_at_spin"):
            if s["ci95"][0] > 0.5 * floor:
                left.append(s["signature"])
        elif not (s["ci95"][0] <= 0.0 <= s["ci95"][1]):
            left.append(s["signature"])
    return left
