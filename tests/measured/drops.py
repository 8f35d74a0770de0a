"""Drops simulated by this project's kernel to rest, written as a tracker would write them.

The tracks follow the model exactly (sample_batch with IP_CONTINUE), then get what a measured
file has: Gaussian noise, the file's angle convention (``theta = FILE_SIGN * (phi - FLAT) +
FILE_ZERO``), missing frames, one-frame angle glitches and dropped frames. The loader and the
calibration are then checked against the simulation's own truth; nothing here uses their code.
"""

import dataclasses
import gzip
import math

import numpy as np

from dice_sweep.config import parse_config
from dice_sweep.physics import pack_params
from dice_sweep.physics.kernel import sample_batch
from dice_sweep.physics.params import IP_CONTINUE

RATE = 250.0  # Hz, as the shared data
RADIUS = 0.06 / math.sqrt(2)  # m, the shared data's plate
NOISE = (2e-4, math.radians(0.3))  # m, rad: one sigma of the tracker's position and angle
FLAT = math.pi / 4  # model phi of a square lying flat (mod pi/2)
FILE_SIGN = -1  # the file's angle turns clockwise ...
FILE_ZERO = math.radians(-2.0)  # ... and reads -2 deg when the die lies flat (as the real data)
GLITCH = math.radians(60.0)  # an injected tracking glitch: the angle off by this for one frame


def die_config(model="paper", beta_normal=0.4, beta_tangential=-0.2, duration=0.8):
    """The shared data's square with the given contact law, simulated for ``duration`` s."""
    return parse_config(
        f"[die]\nsides = 4\ncircumradius = {RADIUS!r}\n"
        f'[contact]\nmodel = "{model}"\nbeta_normal = {beta_normal}\nbeta_tangential = {beta_tangential}\n'
        f"[integrator]\nt_max = {duration + 0.01}\n"
    )


def simulate(cfg, states, duration=0.8):
    """Frame times (s) and the true (x, y, phi, vx, vy, omega) of each drop, (drops, frames, 6)."""
    times = np.arange(int(round(duration * RATE))) / RATE
    fpar, ipar = pack_params(cfg)
    ipar[IP_CONTINUE] = 1  # follow each die to rest, as a camera does
    states = np.asarray(states, dtype=float)
    all_times = np.tile(times, len(states))
    starts = np.arange(len(states) + 1) * times.size
    out = np.zeros((all_times.size, 6))
    sample_batch(fpar, ipar, states, all_times, starts, out, np.zeros(len(states), np.int8))
    return times, out.reshape(len(states), times.size, 6)


def real_like_states(count, seed):
    """Initial states like the shared data's: 12-17 cm up, falling, drifting in -x, spinning."""
    rng = np.random.default_rng(seed)
    return np.column_stack(
        [
            rng.uniform(-0.05, 0.05, count),
            rng.uniform(0.12, 0.17, count),
            rng.uniform(-math.pi, math.pi, count),
            rng.uniform(-0.8, -0.4, count),
            rng.uniform(-2.1, -1.7, count),
            rng.uniform(-8.0, 8.0, count),
        ]
    )


@dataclasses.dataclass
class FileTracks:
    """What goes into a track file, and what was done to it."""

    times: np.ndarray  # (frames,) s
    truth: np.ndarray  # (drops, frames, 6) model convention
    measured: np.ndarray  # (drops, frames, 3): x, y, theta in the file convention, NaN: missing
    glitches: set  # (drop, frame) with an injected glitch
    dropped: dict  # drop -> frames removed from the file


def first_fall_glitches(drop_ids, seed):
    """{drop: frame} with one glitch frame per drop, somewhere in the first fall."""
    rng = np.random.default_rng(seed)
    return {drop: int(rng.integers(3, 25)) for drop in drop_ids}


def to_file(times, truth, seed, *, sign=FILE_SIGN, glitches=None, missing_drops=(), dropped_frames=None):
    """Noise, the file's angle convention (``sign``), glitches ({drop: frame}, the angle off by
    GLITCH), missing frames (two per listed drop, after the first bounces) and dropped frames
    ({drop: [frames]}) applied to a simulation."""
    rng = np.random.default_rng(seed)
    measured = truth[:, :, :3] + rng.normal(size=truth[:, :, :3].shape) * [NOISE[0], NOISE[0], NOISE[1]]
    measured[:, :, 2] = sign * (measured[:, :, 2] - FLAT) + FILE_ZERO
    glitches = dict(glitches or {})
    for drop, frame in glitches.items():
        measured[drop, frame, 2] += GLITCH
    for drop in missing_drops:
        measured[drop, rng.choice(np.arange(40, times.size - 5), 2, replace=False)] = np.nan
    return FileTracks(times, truth, measured, set(glitches.items()), dict(dropped_frames or {}))


def write_csv(path, tracks, columns=("traj", "t", "x", "z", "theta"), frame_offset=0):
    """Write FileTracks as CSV (gzip when ``path`` ends in .gz); extra columns are written too.

    Known column names: traj, t, frame, x, y, z, phi, theta, cx, cy, kx, ky (the marker columns
    put the centre dot at (x, y) and the corner-0 dot at R along the file's angle), note.
    """
    lines = [",".join(columns)]
    for drop in range(tracks.measured.shape[0]):
        removed = set(tracks.dropped.get(drop, ()))
        kept = [frame for frame in range(tracks.times.size) if frame not in removed]
        # as in the shared data, the samples left are numbered on: t and frame lose the gaps
        for sample, frame in enumerate(kept):
            x, y, theta = tracks.measured[drop, frame]
            values = {
                "traj": drop + 1,
                "t": tracks.times[sample],
                "frame": sample + frame_offset,
                "x": x,
                "y": y,
                "z": y,
                "phi": theta,
                "theta": theta,
                "cx": x,
                "cy": y,
                "kx": x + RADIUS * math.cos(theta),
                "ky": y + RADIUS * math.sin(theta),
                "note": "tracked",
            }
            lines.append(",".join(_cell(values[name]) for name in columns))
    text = "\n".join(lines) + "\n"
    if str(path).endswith(".gz"):
        with gzip.open(path, "wt") as file:
            file.write(text)
    else:
        with open(path, "w") as file:
            file.write(text)
    return path


def _cell(value):
    if isinstance(value, str):
        return value
    if isinstance(value, (int, np.integer)):
        return str(value)
    return "" if not math.isfinite(value) else f"{value:.7f}"


def model_offset(sign=FILE_SIGN):
    """The offset that turns the file's angle back into the model's: phi = sign theta + offset."""
    return FLAT - sign * FILE_ZERO


def angle_error(a, b, period=math.pi / 2):
    """|a - b| reduced modulo ``period`` (rad): angles of a square agree up to quarter turns."""
    return np.abs((np.asarray(a) - b + period / 2) % period - period / 2)
