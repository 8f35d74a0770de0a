"""No roll stalls: the contact search must converge for dice lying flat and sliding, lifting off
a sliding pivot (a corner leaving with zero normal speed and acceleration), at any n and
friction. The default suite rolls a sample; ``make test-fuzz`` rolls 10^5 starts."""

import math

import numpy as np
import pytest

from dice_sweep.physics.kernel import REC_ENERGY, STATUS_DECIDED, STATUS_STALLED
from dice_sweep.physics.layout import C_MULTI
from tests.physics.conftest import TABLE1_RADIUS, make_params, run_batch, run_one


def test_flat_sliding_hexagon_of_issue_15_does_not_stall():
    """A hexagon resting flat on side 0, 1e-7 apothems above rest, sliding at 1 m/s, friction
    1.2, beta_normal 0.2 (rigid law): it trips over its leading corner, lifts off the sliding
    pivot, and used to stall in the next contact search."""
    apothem = TABLE1_RADIUS * math.cos(math.pi / 6)
    params = make_params(sides=6, model="rigid", beta_n=0.2, friction=1.2)
    out, status, t_decided, _, rec, counts = run_one(params, [0.0, apothem * (1 + 1e-7), -2 * math.pi / 3, 1.0, 0.0, 0.0])
    assert status == STATUS_DECIDED and t_decided < 1.0
    energy = rec[:, REC_ENERGY]
    assert np.all(np.diff(energy) <= 1e-12 * energy[0])  # never gains energy along the way
    assert counts[C_MULTI] >= 1  # the flat start is a two-contact impact
    # regression value of this kernel (3e50c94): the hexagon trips onto side 5; a change to it
    # must be explained (the stall this test was written for ended it with status "stalled")
    assert out == 5


def fuzz_starts(rng, count, sides):
    """Half lying flat (within 1e-6 rad, up to 1e-3 apothems above rest) and sliding at up to
    2 m/s, half dropped from random poses."""
    apothem = TABLE1_RADIUS * math.cos(math.pi / sides)
    flat = count // 2
    states = np.zeros((count, 6))
    side = rng.integers(0, sides, flat)
    # side k is down when phi = -pi/2 - pi/n - 2 pi k/n (side 0 between corners 0 and 1)
    states[:flat, 2] = -math.pi / 2 - math.pi / sides - 2 * math.pi * side / sides + rng.normal(0, 1e-6, flat)
    states[:flat, 1] = apothem * (1 + rng.uniform(0, 1e-3, flat))
    states[:flat, 3] = rng.uniform(-2, 2, flat)
    rest = count - flat
    states[flat:, 1] = rng.uniform(TABLE1_RADIUS * 1.01, 0.15, rest)
    states[flat:, 2] = rng.uniform(-math.pi, math.pi, rest)
    states[flat:, 3] = rng.uniform(-1.5, 1.5, rest)
    states[flat:, 4] = rng.uniform(-1.0, 1.0, rest)
    states[flat:, 5] = rng.uniform(-40, 40, rest)
    return states


def run_fuzz(total, seed):
    rng = np.random.default_rng(seed)
    stalled = 0
    rolls = 0
    per = max(total // 36, 2)
    for sides in range(3, 21):
        for model in ("rigid", "paper"):
            friction = float(rng.uniform(0.05, 2.0)) if model == "rigid" else math.inf
            params = make_params(sides=sides, model=model, beta_n=float(rng.uniform(0.05, 0.8)),
                                 beta_t=float(rng.uniform(-0.8, 0.8)), friction=friction)
            _, status, _, _ = run_batch(params, fuzz_starts(rng, per, sides))
            stalled += int(np.sum(status == STATUS_STALLED))
            rolls += per
    return stalled, rolls


def test_no_stalls_in_a_sample():
    stalled, rolls = run_fuzz(3600, seed=1)
    assert rolls >= 3600
    assert stalled == 0


@pytest.mark.slow
def test_no_stalls_in_the_fuzz():
    stalled, rolls = run_fuzz(100_000, seed=2)
    assert rolls >= 99_900
    assert stalled == 0
