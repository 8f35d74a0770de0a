"""The die, declared configs and hidden truth shared by the loop's tests and
scripts/coverage_measured.py: the shared data's square, a declared model the tracks are to
correct, and the true coefficients of the independent generator."""

import math

RADIUS = 0.06 / math.sqrt(2)  # m, the shared data's plate
NOISE = (2e-4, 4e-3)  # m, rad: one sigma of the tracker at 500 Hz
DECLARED_RIGID = f"""
[die]
sides = 4
circumradius = {RADIUS!r}
[contact]
model = "rigid"
beta_normal = 0.3
beta_tangential = 0.0
friction = 0.5
"""
DECLARED_PAPER = DECLARED_RIGID.replace('model = "rigid"', 'model = "paper"').replace("friction = 0.5\n", "")
TRUE_COEFFICIENTS = {"beta_normal": 0.4, "beta_tangential": 0.0, "friction": 0.3}
TRUTH = dict(contact="rigid", **TRUE_COEFFICIENTS)  # keyword arguments of independent.Truth


def truth_tracks(folder, count, seed, noise=NOISE):
    """``count`` drops of TRUTH from the independent generator (500 Hz, tracking noise
    ``noise``) written to ``folder``/drops.csv and read back as a TrackSet of the plate."""
    from dice_sweep.measured.tracks import load_tracks
    from tests.measured.independent import Truth, simulate_drops, write_csv

    path = folder / "drops.csv"
    write_csv(path, simulate_drops(Truth(**TRUTH), count, seed, rate=500.0, noise=noise))
    return load_tracks(path, sides=4, circumradius=RADIUS)
