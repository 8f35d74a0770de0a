"""Measured-like tracks made by the simulator: 250 Hz, Gaussian noise, the file's conventions.

The tracks are simulated by this project's own kernel with the effect under test switched on,
so a test that diagnoses them checks that the loop finds an effect the kernel can express,
not that the kernel's effect is physically right (tests/physics and the pymunk comparison do
that).
"""

import dataclasses
import math

import numpy as np

from dice_sweep.config import parse_config
from dice_sweep.measured.tracks import Track, TrackSet
from dice_sweep.physics import pack_params
from dice_sweep.physics.kernel import sample_batch
from dice_sweep.physics.params import IP_CONTINUE

SQUARE_RADIUS = 0.06 / math.sqrt(2)  # m, the shared data's plate
DECLARED = f"""
[die]
sides = 4
circumradius = {SQUARE_RADIUS!r}
[contact]
beta_normal = 0.2
beta_tangential = -0.35
[integrator]
t_max = 3.0
"""


def declared_config(contact=""):
    """The config a user declares: the paper model at Table I coefficients (plus ``contact``
    lines, e.g. 'model = "rigid"')."""
    return parse_config(DECLARED.replace("[contact]", "[contact]\n" + contact))


def true_config(contact="", effects=""):
    """The hidden truth: beta_normal 0.4, beta_tangential -0.2, plus what is given."""
    text = DECLARED.replace("beta_normal = 0.2", "beta_normal = 0.4").replace("-0.35", "-0.2")
    return parse_config(text.replace("[contact]", "[contact]\n" + contact) + effects)


def synthetic_tracks(cfg, count, seed, *, rate=250.0, duration=0.3, noise=(1e-4, 0.003),
                     height=(0.12, 0.17), vy=(-2.1, -1.7), angle_shift=0.0):
    """A TrackSet of ``count`` simulated drops like the shared data's (heights in m, speeds
    in m/s), with noise (m, rad) and the tracker's angle zero shifted by ``angle_shift``."""
    rng = np.random.default_rng(seed)
    t = np.arange(int(duration * rate)) / rate
    cfg = dataclasses.replace(cfg, integrator=dataclasses.replace(cfg.integrator, t_max=duration + 0.01))
    fpar, ipar = pack_params(cfg)
    ipar[IP_CONTINUE] = 1
    states = np.column_stack([
        rng.uniform(-0.05, 0.05, count), rng.uniform(*height, count), rng.uniform(-np.pi, np.pi, count),
        rng.uniform(-0.8, -0.4, count), rng.uniform(*vy, count), rng.uniform(-8.0, 8.0, count),
    ])
    times = np.tile(t, count)
    starts = np.arange(0, times.size + 1, t.size)
    out = np.zeros((times.size, 6))
    sample_batch(fpar, ipar, states, times, starts, out, np.zeros(count, np.int8))
    tracks = []
    for i in range(count):
        pose = out[starts[i]:starts[i + 1], :3] + rng.normal(0.0, 1.0, (t.size, 3)) * [noise[0], noise[0], noise[1]]
        tracks.append(Track(i + 1, t.copy(), pose[:, 0], pose[:, 1], pose[:, 2] + angle_shift, np.zeros(t.size, bool)))
    return TrackSet("<synthetic>", tuple(tracks), rate, 1, 0.0, "synthetic: model convention", 0, 0)


def pymunk_tracks(cfg, count, seed, *, rate=250.0, duration=0.3, noise=(1e-4, 0.003), dt=1e-4):
    """Like :func:`synthetic_tracks`, but simulated by pymunk (Chipmunk2D), an engine that
    shares no code with the kernel: Newton restitution at the corner and Coulomb friction
    (``cfg``'s beta_normal and friction; pymunk has no tangential restitution)."""
    from dice_sweep.reference.pymunk_die import PymunkDie

    rng = np.random.default_rng(seed)
    frames = int(duration * rate)
    steps_per_frame = int(round(1.0 / (rate * dt)))
    t = np.arange(frames) / rate
    tracks = []
    for i in range(count):
        state = (rng.uniform(-0.05, 0.05), rng.uniform(0.12, 0.17), rng.uniform(-np.pi, np.pi),
                 rng.uniform(-0.8, -0.4), rng.uniform(-2.1, -1.7), rng.uniform(-8.0, 8.0))
        die = PymunkDie.from_config(cfg, state, dt=dt)
        pose = np.zeros((frames, 3))
        for k in range(frames):
            pose[k] = die.state()[:3]
            for _ in range(steps_per_frame):
                die.step()
        pose += rng.normal(0.0, 1.0, pose.shape) * [noise[0], noise[0], noise[1]]
        tracks.append(Track(i + 1, t.copy(), pose[:, 0], pose[:, 1], pose[:, 2], np.zeros(frames, bool)))
    return TrackSet("<pymunk>", tuple(tracks), rate, 1, 0.0, "synthetic: model convention", 0, 0)
