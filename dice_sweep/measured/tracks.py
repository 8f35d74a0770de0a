"""Measured tracks of a die: reading, dropped frames, tracking glitches, angle convention.

A track file is CSV (optionally gzip-compressed, ``.gz``) with a header line. Pose tracks have
the columns ``traj,t,x,y,phi`` (SI: s, m, m, rad; x, y the geometric centre, y its height above
the table, phi unwrapped), with the aliases ``z`` for ``y`` and ``theta`` for ``phi``, and a
``frame`` column with a frame rate instead of ``t``. Marker tracks ``traj,t,cx,cy,kx,ky`` (a
centre dot and a corner-0 dot, as in Smith 2014) are turned into poses. Other columns are
ignored. Empty cells and ``nan`` are missing values.

:func:`load_tracks` then, per track (docs/calibration.md gives the rules and thresholds):

1. re-times dropped frames: a step whose motion is an integer number k >= 2 of the local
   per-frame motion, in all three pose coordinates at once, gets k - 1 missing (NaN) frames
   inserted before it;
2. flags tracking glitches: frames that jump away from the local motion and come back within
   ``MAX_GLITCH_FRAMES`` frames (or sit at an end of the track), and undoes angle jumps that
   stay, by the nearest whole number of turns of 2 pi / n (the tracker renaming the corners of
   a symmetric die, or a bad unwrap);
3. finds the angle convention: the zero from where dice come to rest, the sign from how the
   spin and the horizontal velocity are coupled near the table.
"""

import csv
import gzip
import hashlib
import math
import warnings
import zlib
from dataclasses import dataclass, replace

import numpy as np

from dice_sweep.errors import DiceSweepError
from dice_sweep.geometry import DOWN, inertia_ratio
from dice_sweep.inputs import not_a_file
from dice_sweep.measured.impacts import rest_pose, table_level, track_impacts

__all__ = ["Track", "TrackSet", "load_tracks", "ANGLE_MODES", "GAP_MODES"]

ANGLE_MODES = ("as-is", "auto")
GAP_MODES = ("auto", "as-is")
RATE_RANGE = (1.0, 1e6)  # Hz, frame rates of trackers (given or from the times)
MAX_TRACK_FRAMES = 10_000_000  # frames of one track on its re-timed clock, held in memory

# Glitches: a step whose pose residual (against the local median motion) exceeds this angle
# times R is a jump. 25 deg is about twice the largest change of the angular step at one impact
# of a die at 250 Hz (|omega| < 60 rad/s, 14 deg per frame), and a hundred times the noise.
GLITCH_ANGLE = math.radians(25.0)  # rad
MAX_GLITCH_FRAMES = 3  # frames a glitch may last before the track comes back
# An angle jump that stays, of at least this much, is the tracker renaming the corners (or a
# bad unwrap): 135 deg in one or two frames would be a spin of 300 rad/s or more.
RELABEL_MIN_ANGLE = math.radians(135.0)
NEIGHBOUR_STEPS = 3  # steps on each side that give the local median motion
# Dropped frames: the estimated frame count of a step must be this close to an integer, and the
# step's motion must match that many local steps to within this share of one step.
GAP_ROUNDING = 0.25
GAP_MISMATCH = 0.3
MOTION_FLOOR = 0.005  # circumradii per frame: slower local motion cannot reveal a gap
NOISE_FLOOR_SIGMAS = 4.0  # ... nor motion within this many noise sigmas of a step
# Angle convention
STANDARD_G = 9.81  # m/s^2: free fall taken out for the gap test and the sign test (no config here)
CLEAR_MAJORITY = 0.75  # share of the votes above which the sign is called clear
MAD_TO_SIGMA = 1.4826  # standard deviation of Gaussian noise per median absolute deviation


@dataclass(frozen=True)
class Track:
    """One measured trajectory, on a uniform time grid, in the model's conventions.

    Attributes
    ----------
    traj : int
        Trajectory id from the file.
    t : numpy.ndarray
        Times, s, float64, ascending, starting where the file starts; dropped frames found by
        :func:`load_tracks` are inserted as NaN poses.
    x, y : numpy.ndarray
        Geometric centre, m: horizontal position and height above the table (NaN: missing).
    phi : numpy.ndarray
        Angle of corner 0, rad, counterclockwise, unwrapped (the model's convention; NaN:
        missing).
    glitch : numpy.ndarray of bool
        True for frames flagged as tracking glitches (kept here, to be left out of fits).
    """

    traj: int
    t: np.ndarray
    x: np.ndarray
    y: np.ndarray
    phi: np.ndarray
    glitch: np.ndarray

    @property
    def usable(self):
        """Frames with a complete pose that are not glitches (bool array)."""
        return np.isfinite(self.x) & np.isfinite(self.y) & np.isfinite(self.phi) & ~self.glitch


@dataclass(frozen=True)
class TrackSet:
    """Tracks read from one file by :func:`load_tracks`, and what was done to them.

    Attributes
    ----------
    path : str
        The file.
    tracks : tuple of Track
        In file order.
    rate : float
        Frame rate, Hz (median over all steps of the file, or the rate given).
    angle_sign, angle_offset : int, float
        ``phi_model = angle_sign * phi_file + angle_offset`` (offset in rad).
    angle_note : str
        One line saying how the convention was found and how sure that is.
    glitch_count, glitch_tracks : int
        Frames flagged as glitches, and tracks with at least one.
    gap_frames, gap_tracks : int
        Dropped frames inserted, and tracks with at least one.
    relabels : int
        Jumps of the angle by whole turns of 2 pi / n (the tracker renaming the corners), undone
        in ``phi`` of the frames after them.
    unpaired_jumps : int
        Jumps that neither came back, nor matched a whole number of frames or of 2 pi / n turns
        (left alone; at an impact they are mostly frames dropped while the velocity changed).
    """

    path: str
    tracks: tuple
    rate: float
    angle_sign: int
    angle_offset: float
    angle_note: str
    glitch_count: int
    glitch_tracks: int
    gap_frames: int = 0
    gap_tracks: int = 0
    relabels: int = 0
    unpaired_jumps: int = 0

    def split(self, test_fraction=0.3, seed=0):
        """Deterministic train/test split by trajectory id.

        Each track is ranked by a hash of (seed, traj), so the split is the same in every run
        and on every machine; the ``round(test_fraction * N)`` lowest go to the test set (at
        least one each way when there are two tracks or more and 0 < test_fraction < 1).

        Parameters
        ----------
        test_fraction : float
            Share of the tracks held out, in [0, 1].
        seed : int
            Changes which tracks are held out.

        Returns
        -------
        train, test : TrackSet
            The same file and conventions, each with its tracks in file order.
        """
        if not 0.0 <= test_fraction <= 1.0:
            raise DiceSweepError(f"test_fraction: {test_fraction} is outside the allowed range [0, 1]")
        count = len(self.tracks)
        n_test = round(test_fraction * count)
        if count >= 2 and 0.0 < test_fraction < 1.0:
            n_test = min(max(n_test, 1), count - 1)
        ranked = sorted(range(count), key=lambda i: (split_hash(seed, self.tracks[i].traj), i))
        held_out = set(ranked[:n_test])
        test = tuple(track for i, track in enumerate(self.tracks) if i in held_out)
        train = tuple(track for i, track in enumerate(self.tracks) if i not in held_out)
        return self._with_tracks(train), self._with_tracks(test)

    def with_trajs(self, trajs):
        """A copy holding only the tracks whose trajectory id is in ``trajs`` (file order kept)."""
        wanted = set(trajs)
        return self._with_tracks(tuple(track for track in self.tracks if track.traj in wanted))

    def _with_tracks(self, tracks):
        """A copy holding only ``tracks``, with the glitch tallies recounted."""
        flagged = [int(np.count_nonzero(track.glitch)) for track in tracks]
        return replace(self, tracks=tracks, glitch_count=sum(flagged), glitch_tracks=sum(1 for f in flagged if f))


def split_hash(seed, traj):
    """A number in [0, 2^64) fixed by (seed, traj): the rank of a track in the split."""
    digest = hashlib.sha256(f"{seed}:{traj}".encode()).digest()
    return int.from_bytes(digest[:8], "big")


# --- reading -------------------------------------------------------------------------------

POSE_ALIASES = {"y": ("y", "z"), "phi": ("phi", "theta")}
MARKER_COLUMNS = ("cx", "cy", "kx", "ky")
MISSING_TEXT = {"", "nan", "na", "none", "null"}


def _open_text(path):
    """Open a CSV file, gzip-compressed or not (by its magic bytes), as text."""
    with open(path, "rb") as probe:
        compressed = probe.read(2) == b"\x1f\x8b"
    if compressed:
        return gzip.open(path, "rt", encoding="utf-8-sig", newline="")  # -sig: a BOM, as spreadsheets write
    return open(path, encoding="utf-8-sig", newline="")


def _read_rows(path):
    """Header names (lower case), data rows and the file line number of each row."""
    problem = not_a_file(path)  # a FIFO or /dev/zero would hang the reader
    if problem:
        raise DiceSweepError(f"{path}: file: {problem}")
    try:
        with _open_text(path) as file:
            reader = csv.reader(file)
            numbered = [(reader.line_num, row) for row in reader if row and any(cell.strip() for cell in row)]
    except (UnicodeDecodeError, gzip.BadGzipFile, EOFError, zlib.error, csv.Error) as error:
        raise DiceSweepError(f"{path}: file: not readable as CSV text ({error})") from None
    except FileNotFoundError:
        raise DiceSweepError(f"{path}: file: no such file (allowed: a track file, CSV or CSV.gz)") from None
    except IsADirectoryError:
        raise DiceSweepError(f"{path}: file: is a folder (allowed: a track file, CSV or CSV.gz)") from None
    if not numbered:
        raise DiceSweepError(f"{path}: file: empty (allowed: a header line, e.g. traj,t,x,y,phi, and data rows)")
    header = [name.strip().lower() for name in numbered[0][1]]
    if len(numbered) < 2:
        raise DiceSweepError(f"{path}: file: no data rows after the header (allowed: at least one row)")
    return header, [row for _, row in numbered[1:]], np.array([line for line, _ in numbered[1:]])


def _column(path, header, rows, lines, name, allowed):
    """The column ``name`` as float64, missing cells as NaN; one-line error if not numbers."""
    index = header.index(name)
    cells = [row[index].strip() if index < len(row) else "" for row in rows]
    cells = ["nan" if cell.lower() in MISSING_TEXT else cell for cell in cells]
    try:
        return np.array(cells).astype(np.float64)
    except ValueError:  # find the first bad cell for the message
        for i, cell in enumerate(cells):
            try:
                float(cell)
            except ValueError:
                raise DiceSweepError(f"{path}: column '{name}': line {lines[i]}: {cell!r} is not a number (allowed: {allowed})") from None
        raise


def _pick(header, names):
    """The first of ``names`` present in the header, or None."""
    return next((name for name in names if name in header), None)


def _require(path, header, names, allowed):
    """The first of ``names`` in the header; one-line error naming them if none is."""
    name = _pick(header, names)
    if name is None:
        spelled = " or ".join(f"'{n}'" for n in names)
        raise DiceSweepError(f"{path}: column {spelled}: missing (allowed: {allowed}; header is {','.join(header)})")
    return name


def _read_columns(path, rate):
    """Columns of a track file: traj, t (s), x, y (m), angle (rad, file convention), the layout
    ("pose" or "marker"), the time column's name and each row's line number."""
    header, rows, lines = _read_rows(path)
    traj_name = _require(path, header, ("traj",), "a 'traj' column of trajectory ids")
    traj = _column(path, header, rows, lines, traj_name, "integer trajectory ids")
    bad = ~np.isfinite(traj) | (traj != np.round(traj))
    if bad.any():
        row = int(np.argmax(bad))
        raise DiceSweepError(f"{path}: column 'traj': line {lines[row]}: {traj[row]} is not a trajectory id (allowed: integers)")
    if "t" in header:
        t = _column(path, header, rows, lines, "t", "times in s")
        time_name = "t"
    elif "frame" in header:
        if rate is None:
            raise DiceSweepError(f"{path}: column 'frame': needs the frame rate (allowed: --rate HZ with a 'frame' column, or a 't' column in s)")
        t = _column(path, header, rows, lines, "frame", "frame numbers") / rate
        time_name = "frame"
    else:
        raise DiceSweepError(f"{path}: column 't': missing (allowed: 't' in s, or 'frame' with --rate HZ; header is {','.join(header)})")
    if not np.isfinite(t).all():
        line = lines[np.argmax(~np.isfinite(t))]
        raise DiceSweepError(f"{path}: column '{time_name}': line {line}: missing (allowed: a finite time on every row)")
    pose_allowed = "pose columns x, y (or z), phi (or theta), or marker columns cx, cy, kx, ky"
    if "x" in header or not all(name in header for name in MARKER_COLUMNS):
        x = _column(path, header, rows, lines, _require(path, header, ("x",), pose_allowed), "x in m")
        y = _column(path, header, rows, lines, _require(path, header, POSE_ALIASES["y"], pose_allowed), "heights in m")
        angle = _column(path, header, rows, lines, _require(path, header, POSE_ALIASES["phi"], pose_allowed), "angles in rad")
        return {"traj": traj.astype(np.int64), "t": t, "x": x, "y": y, "angle": angle, "layout": "pose", "time": time_name, "lines": lines}
    cx, cy, kx, ky = (_column(path, header, rows, lines, name, "positions in m") for name in MARKER_COLUMNS)
    return {"traj": traj.astype(np.int64), "t": t, "x": cx, "y": cy, "angle": np.arctan2(ky - cy, kx - cx), "layout": "marker", "time": time_name, "lines": lines}


def _unwrap_finite(angle):
    """Unwrap an angle over its finite values, leaving NaNs in place."""
    out = angle.copy()
    finite = np.isfinite(angle)
    out[finite] = np.unwrap(angle[finite])
    return out


def _split_by_traj(path, columns):
    """Row indices of each trajectory, in order of first appearance; times must increase."""
    traj, t = columns["traj"], columns["t"]
    ids, first = np.unique(traj, return_index=True)
    groups = []
    for traj_id in ids[np.argsort(first)]:
        rows = np.flatnonzero(traj == traj_id)
        steps = np.diff(t[rows])
        if (steps <= 0).any():
            line = columns["lines"][rows[np.argmax(steps <= 0) + 1]]
            raise DiceSweepError(
                f"{path}: column '{columns['time']}': line {line}: trajectory {traj_id} does not increase in time "
                "(allowed: strictly increasing times within a trajectory)"
            )
        groups.append((int(traj_id), rows))
    return groups


# --- local motion --------------------------------------------------------------------------


def _neighbour_median(steps, sides=(-1, 1)):
    """Median of the NEIGHBOUR_STEPS steps before (-1) and/or after (+1) every step, the step
    itself left out.

    ``steps`` is (m, 3); rows of NaN do not count. Returns (m, 3), NaN where no neighbour exists.
    """
    m = steps.shape[0]
    padded = np.full((m + 2 * NEIGHBOUR_STEPS, steps.shape[1]), np.nan)
    padded[NEIGHBOUR_STEPS : NEIGHBOUR_STEPS + m] = steps
    offsets = [side * o for side in sides for o in range(1, NEIGHBOUR_STEPS + 1)]
    window = np.stack([padded[NEIGHBOUR_STEPS + o : NEIGHBOUR_STEPS + o + m] for o in offsets], axis=1)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)  # all-NaN windows give NaN, as meant
        return np.nanmedian(window, axis=1)


def _step_noise(steps, frames):
    """Noise (one sigma) of a one-frame step, per pose coordinate, from second differences."""
    single = (frames[1:] == 1) & (frames[:-1] == 1)
    second = (steps[1:] - steps[:-1])[single]
    if second.shape[0] < 3:
        return np.zeros(steps.shape[1])
    deviation = np.median(np.abs(second - np.median(second, axis=0)), axis=0)
    # a second difference of white noise has variance 6 s^2, a step 2 s^2
    return MAD_TO_SIGMA * deviation * math.sqrt(2.0 / 6.0)


def _pose(x, y, angle, circumradius):
    """(N, 3) pose rows (x, y, R angle), all in m, so that the three coordinates weigh alike."""
    return np.column_stack((x, y, circumradius * angle))


def _find_gaps(frame, pose, circumradius, rate):
    """Frames dropped before each step between valid rows (0 for most steps).

    A step is k >= 2 frames long when it is k times the mean of the median steps before and
    after it, coordinate by coordinate (exact in free flight, where each coordinate's step
    changes linearly with time), and the steps before and after it differ by free fall only
    (no impact in between).

    Parameters
    ----------
    frame : ndarray of int
        Frame number of each valid row.
    pose : ndarray, shape (N, 3)
        Poses of the valid rows (from :func:`_pose`).
    circumradius, rate : float
        R (m) and the frame rate (Hz).

    Returns
    -------
    ndarray of int
        Frames to insert before row i + 1, for each step i.
    """
    steps = np.diff(pose, axis=0)
    file_frames = np.diff(frame)
    fall = np.array([0.0, STANDARD_G / rate**2, 0.0])  # how much a height step shrinks per frame
    frames = file_frames.astype(float)
    noise = _step_noise(steps, file_frames)
    floor = max(MOTION_FLOOR * circumradius, NOISE_FLOOR_SIGMAS * float(np.linalg.norm(noise)))
    for _ in range(3):  # a gap next to a gap is found once its neighbour is
        unit = steps / frames[:, None]
        before, after = _neighbour_median(unit, (-1,)), _neighbour_median(unit, (1,))
        local = 0.5 * (before + after)
        speed2 = np.einsum("ij,ij->i", local, local)
        with np.errstate(invalid="ignore", divide="ignore"):
            estimate = np.einsum("ij,ij->i", steps, local) / speed2
        count = np.round(estimate)
        allowed = GAP_MISMATCH * np.abs(local) + 3.0 * noise * np.sqrt(np.maximum(count, 1.0))[:, None]
        found = (
            (speed2 > floor**2)
            & (count > frames)
            & (np.abs(estimate - count) < GAP_ROUNDING)
            & (np.abs(steps - count[:, None] * local) < allowed).all(axis=1)
            # the medians sit NEIGHBOUR_STEPS - 1 frames before and after the k frames
            & (np.abs(before - after - fall * (count + 2 * NEIGHBOUR_STEPS - 3)[:, None]) < allowed).all(axis=1)
        )
        if not found.any():
            break
        frames[found] = count[found]
    return (frames - file_frames).astype(np.int64)


def _relabel_turns(residual, sides, circumradius):
    """Whole turns m of 2 pi / n nearest to a persistent angle jump of at least
    ``RELABEL_MIN_ANGLE`` (a die cannot turn that far in a frame or two); else 0."""
    angle = residual[2] / circumradius
    return round(angle / (2.0 * math.pi / sides)) if abs(angle) >= RELABEL_MIN_ANGLE else 0


def _find_glitches(frame, pose, sides, circumradius):
    """Glitch rows, angle corrections for relabelled corners, and counts.

    A jump is a step whose pose residual ``step - frames * local median step`` is longer than
    ``GLITCH_ANGLE * R``. Two jumps at most ``MAX_GLITCH_FRAMES`` steps apart whose residuals
    cancel (their sum under half the larger) enclose glitch rows. When their sum, or a single
    jump, turns the angle by ``RELABEL_MIN_ANGLE`` or more, the rows after it are relabelled:
    shifted back by the nearest whole number of turns of 2 pi / n. A jump at either end of the
    track marks the end row.

    Returns
    -------
    glitch : ndarray of bool
        Per row.
    shift : ndarray
        Angle to add to each row, rad (multiples of 2 pi / n).
    relabels, unpaired : int
        Relabellings undone; jumps that are none of these (left alone).
    """
    glitch = np.zeros(frame.size, dtype=bool)
    shift = np.zeros(frame.size)
    if frame.size < 3:
        return glitch, shift, 0, 0
    steps = np.diff(pose, axis=0)
    frames = np.diff(frame).astype(float)
    residual = np.nan_to_num(steps - frames[:, None] * _neighbour_median(steps / frames[:, None]))
    size = np.linalg.norm(residual, axis=1)
    jumps = list(np.flatnonzero(size > GLITCH_ANGLE * circumradius))
    period = 2.0 * math.pi / sides
    relabels = unpaired = 0
    while jumps:
        first = jumps.pop(0)
        partner, turns = None, 0
        for j in jumps:
            if j - first > MAX_GLITCH_FRAMES:
                break
            total = residual[first] + residual[j]
            turns = _relabel_turns(total, sides, circumradius)
            if turns or np.linalg.norm(total) < 0.5 * max(size[first], size[j]):
                partner = j
                break
        if partner is not None:
            glitch[first + 1 : partner + 1] = True
            jumps = [j for j in jumps if j > partner]
            end = partner
        elif first in (0, steps.shape[0] - 1):
            glitch[0 if first == 0 else -1] = True
            continue
        else:
            turns = _relabel_turns(residual[first], sides, circumradius)
            unpaired += not turns
            end = first
        if turns:
            shift[end + 1 :] -= turns * period
            relabels += 1
    return glitch, shift, relabels, unpaired


# --- angle convention ----------------------------------------------------------------------


def _flat_phase(sides):
    """Angle of corner 0 (mod 2 pi / n) when a side lies flat on the table, rad."""
    return (DOWN - math.pi / sides) % (2.0 * math.pi / sides)


def _wrap(angle, period):
    """Angle reduced to [-period/2, period/2)."""
    return (np.asarray(angle) + 0.5 * period) % period - 0.5 * period


def _track_arrays(raw, circumradius, offset):
    """(t, x, y, angle + offset, usable) of a prepared track, for the impact functions."""
    pose = raw["pose"]
    usable = np.isfinite(pose).all(axis=1) & ~raw["glitch"]
    return raw["t"], pose[:, 0], pose[:, 1], pose[:, 2] / circumradius + offset, usable


def _balance_misfits(raws, sides, circumradius, offset, table):
    """Angular momentum misfits at each track's first impact, for both signs and both levers.

    At an impact through one point r (seen from the centre), I dw = M (r_x dvy - r_y dvx) for
    any contact law. Reflecting the file's angle about the vertical (sign -1) flips omega and
    r_x, so only the friction term r_y dvx tells the signs apart. The lever is either the
    touching corner (a rigid die) or the point R below the centre (the paper's eq. 11).

    Returns
    -------
    ndarray, shape (tracks, 2 levers, 2 signs)
        |s dw - (s r_x dvy - r_y dvx) / (alpha R^2)|, rad/s; signs ordered (+1, -1).
    """
    alpha = float(inertia_ratio(sides))
    misfits = []
    for raw in raws:
        t, x, y, angle, usable = _track_arrays(raw, circumradius, offset)
        found = track_impacts(t, x, y, angle, usable, first_only=True, sides=sides, circumradius=circumradius, table=table, g=STANDARD_G)
        if not found or found[0][1] is None:
            continue
        impact = found[0][1]
        dvx, dvy, dspin = impact.after.state[3:] - impact.before.state[3:]
        rows = []
        for lever_x, lever_y in (impact.corner, (0.0, -circumradius)):
            rows.append([abs(s * dspin - (s * lever_x * dvy - lever_y * dvx) / (alpha * circumradius**2)) for s in (1, -1)])
        misfits.append(rows)
    return np.array(misfits).reshape(-1, 2, 2)


def _angle_convention(raws, sides, circumradius, path):
    """(sign, offset, note) turning the file's angle into the model's phi."""
    period = 2.0 * math.pi / sides
    flat = _flat_phase(sides)
    rests = [p for p in (rest_pose(raw["pose"][:, 0], raw["pose"][:, 1], raw["pose"][:, 2] / circumradius, _track_arrays(raw, circumradius, 0.0)[4], circumradius, raw["t"]) for raw in raws) if p is not None]
    if rests:
        residual = _wrap(np.array([p[2] for p in rests]), period)
        median_residual = float(np.median(residual))
        q25, q75 = np.percentile(residual, [25, 75])
        rest_text = (
            f"zero: {len(rests)} of {len(raws)} tracks end at rest, a file angle {math.degrees(median_residual):+.2f} deg "
            f"(IQR {math.degrees(q25):+.2f} to {math.degrees(q75):+.2f}) off a multiple of {math.degrees(period):g} deg is flat"
        )
    else:
        # the zero is measured only from dice at rest: no guess (a guess was pi/n off and the
        # sign test then called the wrong sign clear)
        raise DiceSweepError(
            f"{path}: --angle auto: no track ends at rest, so the angle's zero cannot be measured "
            "(allowed: --angle as-is, the file's phi is the model's angle, or a file with tracks that end at rest)"
        )
    offset_plus = flat - median_residual
    # the lowest corner's height is the same for both signs: find the table with sign +1
    table = table_level([(p[0], p[1], p[2] + offset_plus) for p in rests], sides=sides, circumradius=circumradius)
    misfits = _balance_misfits(raws, sides, circumradius, offset_plus, table)
    if misfits.shape[0] == 0:
        sign, sign_text = 1, "sign +1 kept, not measured: no track has a first impact with frames on both sides"
    else:
        lever = int(np.argmin(np.median(misfits.min(axis=2), axis=0)))
        plus_wins = int(np.count_nonzero(misfits[:, lever, 0] < misfits[:, lever, 1]))
        votes = misfits.shape[0]
        share = max(plus_wins, votes - plus_wins) / votes
        sign = 1 if plus_wins * 2 >= votes else -1
        strength = "clear" if share >= CLEAR_MAJORITY else "weak" if share > 0.55 else "undecided"
        if strength == "undecided":
            sign = 1
        medians = np.median(misfits[:, lever, :], axis=0)
        sign_text = (
            f"sign {sign:+d} ({strength}): angular momentum about the {('touching corner', 'point R below the centre')[lever]} "
            f"balances better at the first impact with sign {sign:+d} in {max(plus_wins, votes - plus_wins)} of {votes} tracks "
            f"(median misfit {medians[0]:.1f} rad/s with +1, {medians[1]:.1f} with -1)"
        )
    offset = float((flat - sign * median_residual) % period)
    return sign, offset, f"{sign_text}; {rest_text}; phi = {sign:+d} * angle + {offset:.4f} rad"


# --- loading -------------------------------------------------------------------------------


def _check_rate(path, rate, where="rate: {} Hz is not a frame rate"):
    low, high = RATE_RANGE
    if not low <= rate <= high:
        raise DiceSweepError(f"{path}: {where.format(f'{rate:g}')} (allowed: {low:g} to {high:g} Hz)")


def _check_options(path, rate, angle, gaps):
    if rate is not None:
        _check_rate(path, rate)
    if angle not in ANGLE_MODES:
        raise DiceSweepError(f"{path}: angle: {angle!r} is not a mode (allowed: {', '.join(ANGLE_MODES)})")
    if gaps not in GAP_MODES:
        raise DiceSweepError(f"{path}: gaps: {gaps!r} is not a mode (allowed: {', '.join(GAP_MODES)})")


def _prepare_track(t, x, y, angle, rate, sides, circumradius, gaps):
    """Dropped frames inserted and glitches flagged for one track (file angle kept)."""
    # frame numbers from the times; a step shorter than half a frame still counts as one
    frame = np.concatenate(([0], np.cumsum(np.maximum(np.round(np.diff(t) * rate), 1)))).astype(np.int64)
    file_frame = frame
    pose = _pose(x, y, angle, circumradius)
    valid = np.flatnonzero(np.isfinite(pose).all(axis=1))
    inserted = np.zeros(t.size, dtype=np.int64)  # frames inserted before each row
    if gaps == "auto" and valid.size >= 3:
        inserted[valid[1:]] = _find_gaps(frame[valid], pose[valid], circumradius, rate)
    frame = frame + np.cumsum(inserted)
    total = int(frame[-1]) + 1 if t.size else 0
    grid_pose = np.full((total, 3), np.nan)
    grid_pose[frame] = pose
    grid_t = t[0] + np.arange(total) / rate
    grid_t[frame] = t + (frame - file_frame) / rate  # file rows keep their own times, shifted by the gaps
    grid_valid = frame[valid]
    glitch = np.zeros(total, dtype=bool)
    flagged, shift, relabels, unpaired = _find_glitches(grid_valid, grid_pose[grid_valid], sides, circumradius)
    glitch[grid_valid[flagged]] = True
    grid_pose[grid_valid, 2] += circumradius * shift
    return {"t": grid_t, "pose": grid_pose, "glitch": glitch, "inserted": int(inserted.sum()), "relabels": relabels, "unpaired": unpaired}


def load_tracks(path, *, sides, circumradius, rate=None, angle="as-is", gaps="auto"):
    """Read measured tracks, re-time dropped frames, flag glitches and find the angle convention.

    Parameters
    ----------
    path : str or os.PathLike
        CSV or CSV.gz file (module docstring: columns and aliases).
    sides : int
        n of the die.
    circumradius : float
        R of the die, m.
    rate : float, optional
        Frame rate, Hz: needed with a ``frame`` column and no ``t``. Default: the median rate
        of the file's times.
    angle : {"as-is", "auto"}
        "as-is" (the default) takes the file's angle as the model's phi (sign +1, offset 0), as
        the file format says; "auto" measures the sign and zero of the file's angle
        (docs/calibration.md) and refuses when no track ends at rest (the zero is then not
        measured).
    gaps : {"auto", "as-is"}
        "auto" inserts NaN frames where frames were dropped; "as-is" keeps the file's times.

    Returns
    -------
    TrackSet

    Raises
    ------
    DiceSweepError
        One line naming the file, the column and what is allowed, for a missing column, no
        rows, a cell that is not a number, ``frame`` without a rate, or times that do not
        increase within a trajectory.
    """
    path = str(path)
    _check_options(path, rate, angle, gaps)
    columns = _read_columns(path, rate)
    groups = _split_by_traj(path, columns)
    t, x, y = columns["t"], columns["x"], columns["y"]
    if rate is None:
        steps = np.concatenate([np.diff(t[rows]) for _, rows in groups])
        if steps.size == 0:
            raise DiceSweepError(f"{path}: column '{columns['time']}': one row per trajectory gives no frame rate (allowed: --rate HZ, or two rows or more)")
        rate = 1.0 / float(np.median(steps))
        _check_rate(path, rate, f"column '{columns['time']}': its median step gives {{}} Hz, not a frame rate (are the times in s?)")
    raws = []
    for traj_id, rows in groups:
        frames = (t[rows][-1] - t[rows][0]) * rate + rows.size
        if frames > MAX_TRACK_FRAMES:
            raise DiceSweepError(f"{path}: trajectory {traj_id}: {frames:.3g} frames of 1/{rate:g} s over "
                                 f"{t[rows][-1] - t[rows][0]:g} s (allowed: at most {MAX_TRACK_FRAMES:.0e} a track; "
                                 "check --rate and that the times are in s)")
        track_angle = columns["angle"][rows]
        if columns["layout"] == "marker":  # atan2 of the dots wraps at pi
            track_angle = _unwrap_finite(track_angle)
        raws.append(_prepare_track(t[rows], x[rows], y[rows], track_angle, rate, sides, circumradius, gaps))
    if angle == "auto":
        sign, offset, note = _angle_convention(raws, sides, circumradius, path)
    else:
        sign, offset, note = 1, 0.0, "as-is: the file's angle is used unchanged (sign +1, offset 0)"
    tracks = tuple(
        Track(
            traj=traj_id,
            t=raw["t"],
            x=raw["pose"][:, 0].copy(),
            y=raw["pose"][:, 1].copy(),
            phi=sign * raw["pose"][:, 2] / circumradius + offset,
            glitch=raw["glitch"],
        )
        for (traj_id, _), raw in zip(groups, raws)
    )
    flagged = [int(raw["glitch"].sum()) for raw in raws]
    return TrackSet(
        path=path,
        tracks=tracks,
        rate=float(rate),
        angle_sign=int(sign),
        angle_offset=float(offset),
        angle_note=note,
        glitch_count=sum(flagged),
        glitch_tracks=sum(1 for f in flagged if f),
        gap_frames=sum(raw["inserted"] for raw in raws),
        gap_tracks=sum(1 for raw in raws if raw["inserted"]),
        relabels=sum(raw["relabels"] for raw in raws),
        unpaired_jumps=sum(raw["unpaired"] for raw in raws),
    )
