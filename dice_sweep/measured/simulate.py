"""Synthetic tracked drops made by this project's own kernel (``dice-sweep simulate-drops``).

Something to try the measured-data loop on when no tracked data are at hand: drops of the
config's die, under its contact law and [effects], followed to rest by the kernel and written
as a tracker would write them (``traj,t,x,y,phi``, read by
:func:`dice_sweep.measured.tracks.load_tracks`), with the config's [tracking] measurement
effects, Gaussian noise, dropped frames and one-frame glitches. docs/simulate_drops.md says
what this is good for and what not: the data come from the same kernel the loop fits with, so
they cannot test the loop's model independently (tests/measured/independent.py does that).

Per drop, in this order:

1. an initial state of the geometric centre (x0, y0, phi0, vx0, vy0, omega0), each value drawn
   uniformly from its range (:data:`DROP_RANGES` by default, or the config's [initial] value
   with ``initial="config"``; ``ranges`` overrides any of them);
2. the kernel (``roll_one``, then ``sample_batch``, both with ``ipar[IP_CONTINUE] = 1``)
   follows the die to rest; the track ends :data:`REST_TAIL` s of true time after the die comes
   to rest, or at ``duration``, or where the kernel stopped or its record buffer ran out (the
   track is then cut there and the cut counted, never extrapolated);
3. frames at the file times k / rate (k = 0, 1, ...) are mapped to true times and the true
   pose to the file's pose by the registry's measurement maps
   (:func:`dice_sweep.effects.measurement_maps` with the config's [tracking] values), and phi
   is unwrapped;
4. Gaussian noise of sigmas (sx, sy, sphi) is added (file units), each frame independently
   becomes a glitch with probability ``glitch_prob`` (its pose jumped by :data:`GLITCH_SIZE`
   R in a random direction of (x, y, R phi); neighbouring glitch frames of a track are one
   glitch of several frames, with one jump), and each frame independently is dropped (its row
   removed) with probability ``drop_prob``.

Every random draw comes from one ``seed`` through separate streams (initial states, noise,
glitches, dropped frames), so the same seed gives the same drops and the same dropped frames
whatever the noise, and the same file byte for byte.
"""

import math
import os
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from dice_sweep import __version__
from dice_sweep.config import PARAM_UNITS, config_to_toml
from dice_sweep.effects import measurement_maps
from dice_sweep.errors import ConfigError, DiceSweepError
from dice_sweep.geometry import DOWN, support
from dice_sweep.physics import pack_params
from dice_sweep.physics.layout import STATE_COLUMNS
from dice_sweep.physics.kernel import roll_one, sample_batch
# SAMPLE_RECORDS: sample_batch's record buffer; a drop with more records is cut where they run out
from dice_sweep.physics.layout import COUNT_COLUMNS, REC_KIND, REC_T, REC_WIDTH, ROLL_RECORDS, SAMPLE_RECORDS, SEG_END
from dice_sweep.physics.params import FP_TMAX, IP_CONTINUE

__all__ = ["DROP_RANGES", "INITIAL_MODES", "SimulatedDrops", "simulate_drops", "csv_chunks", "provenance",
           "parse_noise", "parse_range", "sidecar_path"]

# Default initial states, like hand drops onto a table: released from rest-ish 10-30 cm up
# (height of the centre), at any angle, with a modest spin and horizontal speed.
DROP_RANGES = {
    "x0": (0.0, 0.0),  # m
    "y0": (0.10, 0.30),  # m
    "phi0": (-math.pi, math.pi),  # rad
    "vx0": (-0.3, 0.3),  # m/s
    "vy0": (-0.5, 0.0),  # m/s
    "omega0": (-10.0, 10.0),  # rad/s
}
INITIAL_MODES = ("drops", "config")
# Defaults of the options (the shared real drops: 250 Hz, 0.2 mm and 0.3 deg of noise)
RATE = 250.0  # Hz
NOISE = (2e-4, 2e-4, 5.236e-3)  # m, m, rad (0.3 deg)
DROP_PROB = 0.002
GLITCH_PROB = 0.002
DURATION = 1.5  # s
SEED = 0
# A glitch moves the pose by this many circumradii in (x, y, R phi): up to R in position or
# 1 rad in angle, twice the loader's glitch threshold (25 deg times R, tracks.GLITCH_ANGLE).
GLITCH_SIZE = 1.0
REST_TAIL = 0.2  # s of true time kept after a die comes to rest (the loader's rest test needs 0.1)
MAX_PROB = 0.5  # more than half the frames dropped or glitched is not a tracker
MAX_TRACKS = 100_000
MAX_NOISE = 1.0  # --noise sigmas, m, m and rad: a metre of tracking noise on a die is no tracker's
MIN_FRAMES = 3  # frames in --duration, at least: fewer give the loader no frame rate or motion
MAX_FRAMES = 5_000_000  # tracks x frames per track, at most (memory: ~200 bytes a frame while simulating)
OVERRUN = 1.0  # s of true time the first pass runs past the last frame
COLUMNS = ("traj", "t", "x", "y", "phi")
SYNTHETIC_NOTE = ("SYNTHETIC: simulated by dice_sweep's own kernel (dice-sweep simulate-drops), not measured. "
                  "It cannot test the model independently: the loop fits with the same kernel.")


def sidecar_path(path):
    """The provenance file written next to a data file: ``drops.csv`` -> ``drops.csv.json``."""
    return Path(f"{path}.json")


# --- options ---------------------------------------------------------------------------------


def _number(text, option, what):
    try:
        value = float(text)
    except ValueError:
        raise DiceSweepError(f"{option}: {text!r} is not a number (allowed: {what})") from None
    if not math.isfinite(value):
        raise DiceSweepError(f"{option}: {text!r} is not finite (allowed: {what})")
    return value


def parse_noise(text):
    """``SX,SY,SPHI`` (m, m, rad) -> a tuple of three floats in [0, MAX_NOISE] (one-line error
    naming --noise)."""
    allowed = f"SX,SY,SPHI: three numbers >= 0 and at most {MAX_NOISE:g}, m, m, rad"
    parts = [part.strip() for part in str(text).split(",")]
    if len(parts) != 3:
        raise DiceSweepError(f"--noise: {text!r} is not three sigmas (allowed: {allowed})")
    values = tuple(_number(part, "--noise", allowed) for part in parts)
    if min(values) < 0:
        raise DiceSweepError(f"--noise: {text!r} has a negative sigma (allowed: {allowed})")
    if max(values) > MAX_NOISE:
        raise DiceSweepError(f"--noise: {text!r} has a sigma above {MAX_NOISE:g} (allowed: {allowed})")
    return values


def parse_range(text):
    """``PARAM=LOW:HIGH`` (or ``PARAM=VALUE``) -> (param, (low, high)); PARAM one of the
    initial values x0, y0, phi0, vx0, vy0, omega0 in SI units."""
    allowed = f"PARAM=LOW:HIGH or PARAM=VALUE with PARAM one of {', '.join(STATE_COLUMNS)} and LOW <= HIGH, SI units"
    name, sep, values = str(text).partition("=")
    name = name.strip()
    if not sep or name not in STATE_COLUMNS:
        raise DiceSweepError(f"--range: {text!r} does not name an initial value (allowed: {allowed})")
    low_text, colon, high_text = values.partition(":")
    low = _number(low_text.strip(), "--range", allowed)
    high = _number(high_text.strip(), "--range", allowed) if colon else low
    if low > high:
        raise DiceSweepError(f"--range: {text!r} has LOW > HIGH (allowed: {allowed})")
    return name, (low, high)


def _check_in(option, value, low, high, unit="", low_open=False, high_open=False):
    bad = (value < low or (low_open and value == low) or value > high or (high_open and value == high)
           or not math.isfinite(value))
    if bad:
        interval = f"{'(' if low_open else '['}{low:g}, {high:g}{')' if high_open else ']'}"
        raise DiceSweepError(f"{option}: {value:g}{' ' + unit if unit else ''} is outside the allowed range {interval}")


def _max_reach(sides, radius, phi_low, phi_high, direction):
    """Largest reach of the die along ``direction`` over phi in [phi_low, phi_high], m: R if a
    corner points that way somewhere in the range, else the larger of the ends (the reach
    peaks only where a corner points along the direction)."""
    spacing = 2.0 * math.pi / sides
    if (direction - phi_low) % spacing <= phi_high - phi_low:
        return radius
    return float(max(support(sides, radius, phi_low, direction), support(sides, radius, phi_high, direction)))


def initial_ranges(cfg, initial="drops", ranges=None):
    """{param: (low, high)} of the initial values drawn, checked to keep every start clear of
    the table and the walls (one-line error naming --range and the allowed range)."""
    if initial not in INITIAL_MODES:
        raise DiceSweepError(f"--initial: {initial!r} is not a mode (allowed: {', '.join(INITIAL_MODES)})")
    if initial == "drops":
        bounds = dict(DROP_RANGES)
    else:
        bounds = {name: (getattr(cfg.initial, name),) * 2 for name in STATE_COLUMNS}
    for name, (low, high) in (ranges or {}).items():
        if name not in STATE_COLUMNS or not (math.isfinite(low) and math.isfinite(high) and low <= high):
            raise DiceSweepError(f"--range: {name}={low}:{high} is not a range (allowed: one of {', '.join(STATE_COLUMNS)}, finite LOW <= HIGH)")
        bounds[name] = (float(low), float(high))
    n, radius = cfg.die.sides, cfg.die.circumradius
    phi = bounds["phi0"]
    down = _max_reach(n, radius, *phi, DOWN)
    if bounds["y0"][0] < down * (1.0 - 1e-12):
        raise DiceSweepError(f"--range y0: {bounds['y0'][0]:g} m puts a corner into the table at some phi0 in "
                             f"[{phi[0]:g}, {phi[1]:g}] rad (allowed: y0 >= {down:.6g} m)")
    if cfg.walls.separation is not None:
        half = 0.5 * cfg.walls.separation
        low_x = _max_reach(n, radius, *phi, math.pi) - half
        high_x = half - _max_reach(n, radius, *phi, 0.0)
        x = bounds["x0"]
        if x[0] < low_x or x[1] > high_x:
            raise DiceSweepError(f"--range x0: [{x[0]:g}, {x[1]:g}] m puts a corner into a wall at some phi0 in "
                                 f"[{phi[0]:g}, {phi[1]:g}] rad (allowed: {low_x:.6g} <= x0 <= {high_x:.6g} m)")
    return bounds


def check_options(cfg, tracks, *, seed=SEED, rate=RATE, noise=NOISE, drop_prob=DROP_PROB, glitch_prob=GLITCH_PROB,
                  duration=DURATION, initial="drops", ranges=None):
    """Every option checked before any work; returns the initial ranges. One-line errors
    naming the option and the allowed range (:class:`DiceSweepError`)."""
    if isinstance(tracks, bool) or not isinstance(tracks, (int, np.integer)):
        raise DiceSweepError(f"--tracks: {tracks!r} is not a whole number (allowed: 1 to {MAX_TRACKS})")
    _check_in("--tracks", tracks, 1, MAX_TRACKS)
    if isinstance(seed, bool) or not isinstance(seed, (int, np.integer)) or seed < 0:
        raise DiceSweepError(f"--seed: {seed!r} is outside the allowed range [0, inf) (whole numbers)")
    _check_in("--rate", float(rate), 0.0, math.inf, "Hz", low_open=True, high_open=True)
    if len(noise) != 3 or any(not math.isfinite(s) or s < 0 for s in noise):
        raise DiceSweepError(f"--noise: {noise!r} is not three sigmas (allowed: SX,SY,SPHI: three numbers >= 0, m, m, rad)")
    _check_in("--drop-prob", float(drop_prob), 0.0, MAX_PROB)
    _check_in("--glitch-prob", float(glitch_prob), 0.0, MAX_PROB)
    if cfg.integrator.method != "event":
        raise ConfigError(cfg.source, "integrator.method", f"{cfg.integrator.method!r} stops at the decision, not at rest "
                                                         "(allowed for simulate-drops: \"event\")")
    times_to_true, _, _ = measurement_maps(cfg, {})
    # the file clock's longest duration whose true time is the config's t_max (time_scale s: s t_max)
    limit = cfg.integrator.t_max * 1.0 / float(times_to_true(np.array([1.0]))[0])
    if not (math.isfinite(duration) and 0.0 < duration <= limit):
        raise DiceSweepError(f"--duration: {duration:g} s is outside the allowed range (0, {limit:g}] s (its true time "
                             f"at most the config's integrator.t_max = {cfg.integrator.t_max:g} s)")
    per_track = _frame_count(duration, rate)
    if per_track < MIN_FRAMES:
        raise DiceSweepError(f"--rate: {rate:g} Hz gives {per_track} frames in --duration {duration:g} s "
                             f"(allowed: at least {MIN_FRAMES} frames, rate >= {(MIN_FRAMES - 1) / duration:g} Hz)")
    frames = int(tracks) * per_track
    if frames > MAX_FRAMES:
        raise DiceSweepError(f"--tracks: {tracks} tracks of up to {per_track} frames are "
                             f"{frames:,} frames (allowed: at most {MAX_FRAMES:,}; fewer tracks, a lower --rate or a shorter --duration)")
    return initial_ranges(cfg, initial, ranges)


# --- simulation ------------------------------------------------------------------------------


@dataclass
class SimulatedDrops:
    """Drops made by :func:`simulate_drops`.

    Row arrays (one row per frame written; rows of a track in time order, tracks in order):
    ``traj`` (1..N), ``t`` (file time, s), ``pose`` ((rows, 3): x, y, phi as written),
    ``true_pose`` (the same frames with the measurement maps but no noise and no glitch),
    ``true_t`` (the kernel's time of each row, s), ``glitch`` (bool) and ``frame`` (the
    frame number k of the file clock, t = k / rate unless ``renumber``).

    Per track: ``states`` ((N, 6) initial states, STATE_COLUMNS), ``outcome`` (side it came to
    rest on, -1 undecided), ``ending`` ("rest", "duration", "stopped" or "records": how the
    track ends), ``frames`` (frames before dropping). ``options`` holds every option.
    """

    traj: np.ndarray
    t: np.ndarray
    pose: np.ndarray
    true_pose: np.ndarray
    true_t: np.ndarray
    glitch: np.ndarray
    frame: np.ndarray
    states: np.ndarray
    outcome: np.ndarray
    ending: list
    frames: np.ndarray
    options: dict = field(default_factory=dict)

    @property
    def dropped(self):
        """Frames removed (rows not written)."""
        return int(self.frames.sum()) - int(self.traj.size)

    def describe(self, path=None):
        """One line for the user."""
        endings = {name: self.ending.count(name) for name in ("rest", "duration", "stopped", "records")}
        ends = f"{endings['rest']} at rest"
        if endings["duration"]:
            ends += f", {endings['duration']} still moving at --duration"
        if endings["stopped"]:
            ends += f", {endings['stopped']} cut where the kernel stopped early"
        if endings["records"]:
            ends += f", {endings['records']} cut where the kernel's record buffer ran out"
        where = f"wrote {path}: " if path else ""
        side = f"; provenance in {sidecar_path(path)}" if path else ""
        o = self.options
        return (f"{where}{len(self.ending)} SYNTHETIC tracks (this project's kernel, seed {o['seed']}), "
                f"{self.traj.size} frames at {o['rate']:g} Hz ({ends}); {self.dropped} frames dropped, "
                f"{int(self.glitch.sum())} glitches{side}")


def _draw_states(rng, bounds, count):
    """(count, 6) initial states, each value uniform in its range (STATE_COLUMNS order)."""
    low = np.array([bounds[name][0] for name in STATE_COLUMNS])
    high = np.array([bounds[name][1] for name in STATE_COLUMNS])
    return low + (high - low) * rng.random((count, 6))


def _frame_count(duration, rate):
    """Frames of the file clock in [0, duration]: k / rate for k = 0 .. floor(duration rate)."""
    return int(math.floor(duration * rate * (1.0 + 1e-12))) + 1


def _track_ends(fpar, ipar, states, t_true_max):
    """Per drop: (true time the track ends, how it ends, outcome side), from a first pass of
    the kernel with a large record buffer, run OVERRUN s past the last frame: a roll stopped
    at its time limit in the middle of a pivot reports the pivot's start as its end, and that
    must not pass for a kernel that stopped early."""
    rec = np.zeros((ROLL_RECORDS, REC_WIDTH))
    counts = np.zeros(len(COUNT_COLUMNS), dtype=np.int32)
    own = fpar.copy()
    own[FP_TMAX] = t_true_max + OVERRUN
    ends, endings, outcomes = [], [], []
    for state in states:
        outcome, _, _, t_end, n_rec = roll_one(own, ipar, state.copy(), rec, counts)
        if rec[n_rec - 1, REC_KIND] == SEG_END and t_end <= t_true_max:
            end, ending = min(t_true_max, float(t_end) + REST_TAIL), "rest"
        elif t_end >= t_true_max:
            end, ending = t_true_max, "duration"
        else:
            end, ending = float(t_end), "stopped"  # stalled, balanced on a corner or out of events
        if n_rec > SAMPLE_RECORDS and rec[SAMPLE_RECORDS, REC_T] < end:
            # sample_batch keeps the first SAMPLE_RECORDS segments: beyond the start of
            # the next one its last segment would be extrapolated
            end, ending = float(rec[SAMPLE_RECORDS, REC_T]), "records"
        ends.append(end)
        endings.append(ending)
        outcomes.append(int(outcome))
    return np.array(ends), endings, np.array(outcomes, dtype=np.int64)


def simulate_drops(cfg, tracks, *, seed=SEED, rate=RATE, noise=NOISE, drop_prob=DROP_PROB, glitch_prob=GLITCH_PROB,
                   duration=DURATION, initial="drops", ranges=None, renumber=False):
    """Simulate ``tracks`` drops of a validated config and return them as a tracker would.

    Parameters
    ----------
    cfg : Config
        The die, the contact law, [effects] (in the kernel) and [tracking] (the measurement
        maps); ``integrator.method`` must be "event".
    tracks : int
        Number of drops, 1 to MAX_TRACKS.
    seed : int
        Seed (>= 0) of every random draw.
    rate : float
        Frame rate of the file's clock, Hz (> 0).
    noise : (float, float, float)
        Sigmas of the Gaussian noise on x, y (m) and phi (rad), in the file's units.
    drop_prob, glitch_prob : float
        Probability, per frame and independently, that the frame is dropped (row removed) or a
        glitch (pose jumped by GLITCH_SIZE R), each in [0, MAX_PROB].
    duration : float
        Longest track, s of the file's clock (its true time at most integrator.t_max).
    initial : {"drops", "config"}
        Default ranges of the initial values: DROP_RANGES, or the config's [initial] values.
    ranges : dict, optional
        {param: (low, high)}: uniform ranges that replace the defaults (param in x0, y0, phi0,
        vx0, vy0, omega0).
    renumber : bool
        Number the rows left consecutively (t = row / rate), as trackers that drop frames
        silently do, instead of keeping each frame's own time.

    Returns
    -------
    SimulatedDrops
    """
    bounds = check_options(cfg, tracks, seed=seed, rate=rate, noise=noise, drop_prob=drop_prob, glitch_prob=glitch_prob,
                           duration=duration, initial=initial, ranges=ranges)
    state_seed, noise_seed, glitch_seed, drop_seed = np.random.SeedSequence(int(seed)).spawn(4)
    states = _draw_states(np.random.default_rng(state_seed), bounds, int(tracks))
    times_to_true, _, pose_to_file = measurement_maps(cfg, {})
    file_t = np.arange(_frame_count(duration, rate)) / rate  # the file clock's frames
    true_t = np.asarray(times_to_true(file_t), dtype=float)
    fpar, ipar = pack_params(cfg)
    ipar[IP_CONTINUE] = 1  # follow every die to rest, as a camera does
    fpar[FP_TMAX] = true_t[-1]
    ends, endings, outcomes = _track_ends(fpar, ipar, states, float(true_t[-1]))
    counts = np.searchsorted(true_t, ends, side="right")  # frames of each track, >= 1
    starts = np.concatenate(([0], np.cumsum(counts)))
    all_true_t = np.concatenate([true_t[:c] for c in counts])
    all_frame = np.concatenate([np.arange(c) for c in counts])
    sampled = np.zeros((all_true_t.size, 6))
    sample_batch(fpar, ipar, states, all_true_t, starts, sampled, np.zeros(int(tracks), np.int8))
    pose = sampled[:, :3].copy()
    for i in range(int(tracks)):
        pose[starts[i]:starts[i + 1], 2] = np.unwrap(pose[starts[i]:starts[i + 1], 2])
    true_pose = np.asarray(pose_to_file(pose), dtype=float)
    rows = true_pose.shape[0]
    measured = true_pose + np.random.default_rng(noise_seed).standard_normal((rows, 3)) * np.asarray(noise, dtype=float)
    glitch_rng = np.random.default_rng(glitch_seed)
    glitch = glitch_rng.random(rows) < glitch_prob
    direction = glitch_rng.standard_normal((rows, 3))
    direction /= np.linalg.norm(direction, axis=1, keepdims=True)
    radius = cfg.die.circumradius
    jump = GLITCH_SIZE * radius * direction * np.array([1.0, 1.0, 1.0 / radius])
    # glitch frames next to each other in a track are one glitch: they share the first one's jump
    first = glitch.copy()
    first[1:] &= ~glitch[:-1] | (all_frame[1:] == 0)
    run_start = np.maximum.accumulate(np.where(first, np.arange(rows), 0))
    measured[glitch] += jump[run_start[glitch]]
    kept = np.random.default_rng(drop_seed).random(rows) >= drop_prob
    traj = np.repeat(np.arange(1, int(tracks) + 1), counts)
    frame = all_frame
    if renumber:
        frame = np.concatenate([np.arange(np.count_nonzero(kept[starts[i]:starts[i + 1]])) for i in range(int(tracks))])
    else:
        frame = frame[kept]
    options = {
        "tracks": int(tracks), "seed": int(seed), "rate": float(rate), "noise": [float(s) for s in noise],
        "drop_prob": float(drop_prob), "glitch_prob": float(glitch_prob), "duration": float(duration),
        "initial": initial, "ranges": {name: list(bounds[name]) for name in STATE_COLUMNS}, "renumber": bool(renumber),
    }
    return SimulatedDrops(
        traj=traj[kept], t=frame / rate, pose=measured[kept], true_pose=true_pose[kept], true_t=all_true_t[kept],
        glitch=glitch[kept], frame=frame, states=states, outcome=outcomes, ending=endings, frames=counts, options=options,
    )


# --- the file's contents (the app layer writes them) ----------------------------------------


CHUNK_ROWS = 100_000  # rows formatted at a time


def csv_chunks(drops):
    """The CSV text of the drops (``traj,t,x,y,phi``: the header, then one row per frame) as
    UTF-8 bytes, a chunk of CHUNK_ROWS rows at a time."""
    yield (",".join(COLUMNS) + "\n").encode("utf-8")
    for lo in range(0, drops.traj.size, CHUNK_ROWS):
        hi = lo + CHUNK_ROWS
        rows = zip(drops.traj[lo:hi].tolist(), drops.t[lo:hi].tolist(), drops.pose[lo:hi].tolist())
        yield "".join(f"{traj},{t:.10g},{x:.10g},{y:.10g},{phi:.10g}\n" for traj, t, (x, y, phi) in rows).encode("utf-8")


def provenance(drops, cfg, path):
    """The sidecar's contents for the data file ``path``: that the data are synthetic, the
    config, the options and the truth of every drop (its initial state, side and ending)."""
    glitches = [[int(traj), float(t)] for traj, t in zip(drops.traj[drops.glitch], drops.t[drops.glitch])]
    return {
        "synthetic": True,
        "note": SYNTHETIC_NOTE,
        "generator": f"dice-sweep simulate-drops (dice_sweep {__version__})",
        "data": os.path.basename(str(path)),
        "columns": {"traj": "1..N", "t": "s, the file clock", "x": "m", "y": "m, height above the table",
                    "phi": "rad, angle of corner 0, counterclockwise, unwrapped (+ [tracking] angle_offset)"},
        "config_source": cfg.source,
        "config": config_to_toml(cfg),
        "options": drops.options,
        "initial_units": {name: PARAM_UNITS[name] for name in STATE_COLUMNS},
        "rest_tail_s": REST_TAIL,
        "glitch_size_R": GLITCH_SIZE,
        "frames_written": int(drops.traj.size),
        "frames_dropped": drops.dropped,
        "glitch_frames": glitches,
        "per_track": [
            {"traj": i + 1, "initial_state": [float(v) for v in drops.states[i]], "side": int(drops.outcome[i]),
             "ends": drops.ending[i], "frames_before_dropping": int(drops.frames[i])}
            for i in range(len(drops.ending))
        ],
    }
