"""Restitution coefficients measured impact by impact: the paper's method, automated.

Smith 2014 tracked a centre dot and a corner dot just before and after one collision and read
beta_normal from eq. 9 (vy' = -beta_normal vy) and beta_tangential from eq. 10
(vx' + R omega' = -beta_tangential (vx + R omega)). :func:`calibrate` does that for every impact
of every track (:mod:`dice_sweep.measured.impacts` finds them and fits the flight on each side),
and adds the corner-impulse counterparts: the same two laws on the velocity of the touching
corner, u = v + omega z x r, as the ``rigid`` contact model uses them. docs/calibration.md
states every rule and threshold.
"""

import math
from dataclasses import dataclass, field

import numpy as np

from dice_sweep.errors import DiceSweepError
from dice_sweep.geometry import inertia_ratio
from dice_sweep.measured import impacts
from dice_sweep.measured.impacts import MIN_FIT_FRAMES, landing_tilt, rest_pose, table_level, track_impacts

__all__ = ["CalibrationResult", "calibrate", "trackset_impacts", "summarise", "impact_row", "COEFFICIENTS", "DIAGNOSTICS", "GROUPS"]

# name -> what it is, for the summary and the figure
COEFFICIENTS = {
    "beta_normal": "eq. 9: -vy'/vy of the centre",
    "beta_tangential": "eq. 10: -(vx' + R w')/(vx + R w)",
    "corner_normal": "-un'/un of the touching corner",
    "corner_tangential": "-ut'/ut of the touching corner",
}
# summarised too, but not restitution coefficients
DIAGNOSTICS = {
    "impulse_ratio": "dvx/dvy: tangential over normal impulse, a lower bound on a Coulomb friction coefficient",
    "balance": "dw over the single-corner prediction M (r_x dvy - r_y dvx)/I: 1 for an impulse through the corner",
}
GROUPS = {
    "first": "first impacts",
    "first_corner": "first impacts on one corner (tilt >= FLAT_TILT)",
    "all": "all impacts",
}
FLAT_TILT = math.radians(15.0)  # rad: a landing with a side closer to flat hits with two corners
MIN_SPEED = 0.2  # in units of sqrt(g R): a slower approach gives no coefficient (as APPROACH_SPEED)
MIN_SHARE = 0.1  # a tangential denominator below this share of the normal speed gives none
OUTLIER_Z = 3.5  # robust z-score (0.6745 (c - median) / MAD) beyond which a value is an outlier
MAD_Z = 0.6745  # the robust z-score's scale: MAD of a Gaussian in standard deviations
# A clean impact: each side's free flight fits its frames to MAX_FIT_RMS R, both reach the
# table from above between their frames and the impact (else it is a sustained contact), and
# their poses there agree to MAX_MISMATCH R (corners rounded by a few mm put the two sides'
# contact times 1-4 ms apart, so this is loose).
MAX_FIT_RMS = 0.02
MAX_MISMATCH = 0.25


RULES = {
    "impact": f"local minimum of the lowest corner's height below {impacts.CONTACT_HEIGHT} R above the table "
    f"(the median lowest-corner height of the dice at rest), approached faster than {impacts.APPROACH_SPEED} sqrt(g R)",
    "fits": f"up to {impacts.FIT_FRAMES} usable frames (no glitch) on each side, the impact frame left out, at least "
    f"{impacts.MIN_FIT_FRAMES}; x and phi linear, y a parabola of curvature -g; each side followed to where its own "
    "lowest corner meets the table, velocities taken there",
    "clean": f"fit rms < {MAX_FIT_RMS} R, both sides reach the table from above, poses there within {MAX_MISMATCH} R",
    "defined": f"approach faster than {MIN_SPEED} sqrt(g R); tangential denominators above {MIN_SHARE} of the normal speed",
    "outliers": f"|0.6745 (c - median) / MAD| > {OUTLIER_Z}",
    "flat": f"a landing with a side within {math.degrees(FLAT_TILT):g} deg of the table is 'flat' (two corners)",
}


@dataclass(frozen=True)
class CalibrationResult:
    """Coefficients per impact and their summary.

    Attributes
    ----------
    path : str
        The track file.
    die : dict
        sides, circumradius (m), g (m/s^2) used, the config's contact model.
    tracks : dict
        Counts from loading: tracks, rate (Hz), glitch frames and tracks, dropped frames, the
        angle convention and the table level (m).
    rows : tuple of dict
        One per fitted impact (see :func:`impact_row`).
    summary : dict
        ``{"first": {name: stats}, "all": {name: stats}}`` over clean impacts, stats as in
        :func:`summarise`.
    skipped : dict
        Impacts found but not fitted or not clean, by reason.
    """

    path: str
    die: dict
    tracks: dict
    rows: tuple
    summary: dict
    skipped: dict = field(default_factory=dict)

    @property
    def coefficients(self) -> dict:
        """The coefficients measured at each impact: name -> what it is (for pictures)."""
        return COEFFICIENTS

    def to_dict(self):
        """JSON-ready dict (floats, ints, strings, None for undefined values)."""
        return _json_ready(
            {
                "path": self.path,
                "die": self.die,
                "tracks": self.tracks,
                "rules": RULES,
                "summary": self.summary,
                "skipped": self.skipped,
                "impacts": list(self.rows),
            }
        )

    def values(self, name, group="all"):
        """Defined values of ``name`` (a key of COEFFICIENTS or DIAGNOSTICS) over the clean
        impacts of ``group`` (a key of GROUPS), as an ndarray."""
        return np.array([row[name] for row in self.rows if row[name] is not None and _in_group(row, group)], dtype=float)

    def describe(self):
        """A short human summary: what was read and the coefficients' medians and spreads."""
        info = self.tracks
        lines = [
            f"{self.path}: {info['count']} tracks at {info['rate']:.4g} Hz; {info['glitch_count']} glitch frames in "
            f"{info['glitch_tracks']} tracks; {info['gap_frames']} dropped frames re-inserted in {info['gap_tracks']} tracks; "
            f"{info['relabels']} corner relabellings undone; {info['unpaired_jumps']} other jumps left alone",
            f"angle: {info['angle_note']}",
            f"table at {1000 * info['table']:+.2f} mm (median lowest-corner height of the dice at rest)",
            f"impacts: {sum(r['clean'] for r in self.rows)} clean of {len(self.rows)} fitted "
            f"({sum(r['clean'] and r['first'] for r in self.rows)} clean first impacts); skipped: "
            + (", ".join(f"{n} {reason}" for reason, n in self.skipped.items()) or "none"),
            "n, median [IQR], outliers (|robust z| > 3.5) over clean impacts of each group:",
            f"{'':18s} " + " ".join(f"{title:36s}" for title in ("first impacts", "first, on one corner", "all impacts")),
        ]
        for name in {**COEFFICIENTS, **DIAGNOSTICS}:
            lines.append(f"{name:18s} " + " ".join(f"{_stats_text(self.summary[group][name]):36s}" for group in GROUPS).rstrip())
        return "\n".join(lines)


def _in_group(row, group):
    """Whether an impact row is clean and belongs to a group of GROUPS."""
    if not row["clean"]:
        return False
    if group == "first":
        return row["first"]
    if group == "first_corner":
        return row["first"] and row["kind"] == "corner"
    return True


def _stats_text(stats):
    if stats["n"] == 0:
        return "n = 0"
    return f"{stats['n']:4d}, {stats['median']:+.3f} [{stats['q25']:+.3f}, {stats['q75']:+.3f}], {stats['outliers']}"


def _json_ready(value):
    """Numbers as plain floats (NaN as None), arrays as lists, recursively."""
    if isinstance(value, dict):
        return {key: _json_ready(item) for key, item in value.items()}
    if isinstance(value, (list, tuple, np.ndarray)):
        return [_json_ready(item) for item in value]
    if isinstance(value, (bool, np.bool_)):
        return bool(value)
    if isinstance(value, (int, np.integer)):
        return int(value)
    if isinstance(value, (float, np.floating)):
        return float(value) if math.isfinite(value) else None
    return value


def summarise(values):
    """Median, quartiles, MAD and robust outliers of some coefficient values.

    Parameters
    ----------
    values : array_like
        Defined values.

    Returns
    -------
    dict
        n, median, q25, q75, iqr, mad, outliers (count with robust z-score
        ``0.6745 (c - median) / MAD`` beyond ``OUTLIER_Z``), median_inliers.
    """
    values = np.asarray(values, dtype=float)
    if values.size == 0:
        return {"n": 0, "median": None, "q25": None, "q75": None, "iqr": None, "mad": None, "outliers": 0, "median_inliers": None}
    median = float(np.median(values))
    q25, q75 = (float(q) for q in np.percentile(values, [25, 75]))
    mad = float(np.median(np.abs(values - median)))
    z = MAD_Z * (values - median) / mad if mad > 0 else np.zeros_like(values)
    inliers = values[np.abs(z) <= OUTLIER_Z]
    return {
        "n": int(values.size),
        "median": median,
        "q25": q25,
        "q75": q75,
        "iqr": q75 - q25,
        "mad": mad,
        "outliers": int(values.size - inliers.size),
        "median_inliers": float(np.median(inliers)),
    }


def _ratio(after, before, floor):
    """-after/before, or None when |before| is below ``floor``."""
    return None if abs(before) < floor else float(-after / before)


def impact_row(traj, index, impact, *, sides, circumradius, g):
    """One impact as a JSON-ready row: velocities on both sides and the four coefficients.

    Parameters
    ----------
    traj, index : int
        Trajectory id and the impact's index among the impacts found in it (0: first).
    impact : dice_sweep.measured.impacts.Impact
        The fitted impact.
    sides, circumradius, g : int, float, float
        n, R (m) and free fall (m/s^2) of the die.

    Returns
    -------
    dict
        traj, impact, first, t (s), frame, before/after {vx, vy, omega} (m/s, rad/s),
        corner [rx, ry] (m), tilt (rad), kind ("corner", or "flat" below FLAT_TILT),
        corner_before/after {ut, un} (m/s), the coefficients and diagnostics (None when
        undefined), gap_frames, mismatch (m), fit_rms_before/after (m), touched, clean.
    """
    vx, vy, spin = impact.before.state[3:]
    vx2, vy2, spin2 = impact.after.state[3:]
    rx, ry = impact.corner
    # corner velocity u = v + omega z x r, with z x r = (-ry, rx); tangent +x, normal +y
    ut, un = vx - spin * ry, vy + spin * rx
    ut2, un2 = vx2 - spin2 * ry, vy2 + spin2 * rx
    floor = MIN_SPEED * math.sqrt(g * circumradius)
    approaching = vy < -floor
    corner_approaching = un < -floor
    dvx, dvy, dspin = vx2 - vx, vy2 - vy, spin2 - spin
    predicted_spin = (rx * dvy - ry * dvx) / (float(inertia_ratio(sides)) * circumradius**2)
    tilt = landing_tilt(sides, impact.before.state[2])
    clean = (
        impact.before.touched
        and impact.after.touched
        and impact.mismatch < MAX_MISMATCH * circumradius
        and max(impact.before.rms, impact.after.rms) < MAX_FIT_RMS * circumradius
    )
    return {
        "traj": int(traj),
        "impact": int(index),
        "first": index == 0,
        "t": impact.before.t_contact,
        "frame": impact.frame,
        "before": {"vx": vx, "vy": vy, "omega": spin},
        "after": {"vx": vx2, "vy": vy2, "omega": spin2},
        "corner": [rx, ry],
        "tilt": tilt,
        "kind": "corner" if tilt >= FLAT_TILT else "flat",
        "corner_before": {"ut": ut, "un": un},
        "corner_after": {"ut": ut2, "un": un2},
        "beta_normal": _ratio(vy2, vy, floor) if approaching else None,
        "beta_tangential": _ratio(vx2 + circumradius * spin2, vx + circumradius * spin, MIN_SHARE * abs(vy)) if approaching else None,
        "corner_normal": _ratio(un2, un, floor) if corner_approaching else None,
        "corner_tangential": _ratio(ut2, ut, MIN_SHARE * abs(un)) if corner_approaching else None,
        "impulse_ratio": _ratio(-dvx, dvy, floor),
        "balance": _ratio(-dspin, predicted_spin, MIN_SPEED * math.sqrt(g / circumradius)),
        "gap_frames": impact.gap_frames,
        "mismatch": impact.mismatch,
        "fit_rms_before": impact.before.rms,
        "fit_rms_after": impact.after.rms,
        "touched": bool(impact.before.touched and impact.after.touched),
        "clean": bool(clean),
    }


def trackset_impacts(trackset, cfg, *, first_only=False):
    """The impacts of every track, fitted as :func:`calibrate` fits them.

    Parameters
    ----------
    trackset : dice_sweep.measured.tracks.TrackSet
        Tracks in the model's convention.
    cfg : dice_sweep.config.Config
        The die (sides, circumradius) and free fall (``[world] g``).
    first_only : bool
        Only each track's first impact (fitted exactly as among all of them).

    Returns
    -------
    rests : list
        Per track, its pose at rest (x, y, phi) or None (:func:`~dice_sweep.measured.impacts.rest_pose`).
    table : float
        Height of the table in the tracks' frame, m (the median lowest-corner height at rest).
    found : list of (Track, int, Impact or None)
        In track order: the track, the impact's index among those found in it (0: first) and
        the fitted impact (None when a side has too few frames).
    """
    sides, radius = cfg.die.sides, cfg.die.circumradius
    rests = [rest_pose(tr.x, tr.y, tr.phi, tr.usable, radius, tr.t) for tr in trackset.tracks]
    table = table_level([p for p in rests if p is not None], sides=sides, circumradius=radius)
    found = []
    for track in trackset.tracks:
        for index, impact in track_impacts(
            track.t, track.x, track.y, track.phi, track.usable, first_only=first_only, sides=sides, circumradius=radius, table=table, g=cfg.world.g
        ):
            found.append((track, index, impact))
    return rests, table, found


def _require_usable_tracks(trackset) -> None:
    """A one-line error when no track has the frames an impact fit needs on both sides: a file
    of NaN poses, of glitches only, or of tracks too short (issue 16: it reported 0 impacts)."""
    needed = 2 * MIN_FIT_FRAMES + 1
    if not any(int(np.count_nonzero(track.usable)) >= needed for track in trackset.tracks):
        raise DiceSweepError(
            f"{trackset.path}: tracks: no usable track: every track has fewer than {needed} usable frames "
            "(finite pose, not a glitch) (allowed: at least one track with an impact and "
            f"{MIN_FIT_FRAMES} usable frames on each side of it)"
        )


def calibrate(trackset, cfg):
    """Measure the restitution coefficients at every impact of every track.

    Parameters
    ----------
    trackset : dice_sweep.measured.tracks.TrackSet
        Tracks in the model's convention (from :func:`~dice_sweep.measured.tracks.load_tracks`).
    cfg : dice_sweep.config.Config
        The die (sides, circumradius), free fall (``[world] g``) and the declared contact model (reported, not used).

    Returns
    -------
    CalibrationResult
    """
    sides, radius = cfg.die.sides, cfg.die.circumradius
    g = cfg.world.g
    _require_usable_tracks(trackset)
    rests, table, found = trackset_impacts(trackset, cfg)
    rows = []
    skipped = {"too few frames on a side": 0, "not clean (fit, contact or continuity)": 0}
    for track, index, impact in found:
        if impact is None:
            skipped["too few frames on a side"] += 1
        else:
            rows.append(impact_row(track.traj, index, impact, sides=sides, circumradius=radius, g=g))
    skipped["not clean (fit, contact or continuity)"] = sum(not row["clean"] for row in rows)
    result = CalibrationResult(
        path=trackset.path,
        die={"sides": sides, "circumradius": radius, "g": g, "contact_model": cfg.contact.model},
        tracks={
            "count": len(trackset.tracks),
            "rate": trackset.rate,
            "glitch_count": trackset.glitch_count,
            "glitch_tracks": trackset.glitch_tracks,
            "gap_frames": trackset.gap_frames,
            "gap_tracks": trackset.gap_tracks,
            "relabels": trackset.relabels,
            "unpaired_jumps": trackset.unpaired_jumps,
            "angle_sign": trackset.angle_sign,
            "angle_offset": trackset.angle_offset,
            "angle_note": trackset.angle_note,
            "table": table,
            "at_rest": sum(p is not None for p in rests),
        },
        rows=tuple(rows),
        summary={},
        skipped=skipped,
    )
    summary = {group: {name: summarise(result.values(name, group)) for name in {**COEFFICIENTS, **DIAGNOSTICS}} for group in GROUPS}
    return CalibrationResult(**{**result.__dict__, "summary": summary})

