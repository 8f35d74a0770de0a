"""A die sliding on a table corner and a wall corner at once: energy is kept without friction and
only taken with it, the path sampled is the path rolled, and friction can hold it still."""

import numpy as np
import pytest

from dice_sweep.physics.impact import specific_energy
from dice_sweep.physics.ladder import LADDER_AT_REST, LADDER_DECIDED, LADDER_OFF_WALL, ladder, ladder_at, ladder_state
from tests.physics.conftest import make_params

RADIUS = 0.01
# A pentagon turned 1 rad (0.989 rad): corner 3 on the table left of the centre of mass and
# corner 4 on the right wall above it, the side between them leaning on the wall like a ladder.
TABLE, WALL, RIGHT = 3, 4, 1.0


def pentagon(friction):
    return make_params(sides=5, radius=RADIUS, model="rigid", friction=friction, separation=0.05)[0]


def energies(fpar, phi, omega, tau, count=40):
    s = np.zeros(6)
    out = []
    for t in np.linspace(0.0, tau, count):
        ladder_at(fpar, 5, TABLE, WALL, RIGHT, phi, omega, t, s)
        out.append(specific_energy(s, fpar))
    return np.array(out)


@pytest.mark.parametrize("omega", [3.0, -3.0])
def test_a_frictionless_ladder_keeps_its_energy_until_it_leaves_the_wall(omega):
    """Without friction the contact forces do no work: the energy after 0.02-0.03 s of sliding
    (about 1000 steps) is the energy before to round-off, which a wrong normal force (the two
    contacts' 2x2 system) would break; then the wall lets go."""
    fpar = pentagon(0.0)
    start = np.zeros(6)
    ladder_state(fpar, TABLE, WALL, RIGHT, 1.0, omega, start)
    end = np.zeros(6)
    how, tau = ladder(fpar, 5, TABLE, WALL, RIGHT, 1.0, omega, 1.0, end)
    assert how == LADDER_OFF_WALL and 0.01 < tau < 0.05
    e0 = specific_energy(start, fpar)
    assert abs(specific_energy(end, fpar) - e0) < 1e-12 * e0
    assert np.all(np.abs(energies(fpar, 1.0, omega, tau) - e0) < 1e-12 * e0)
    sampled = np.zeros(6)
    ladder_at(fpar, 5, TABLE, WALL, RIGHT, 1.0, omega, tau, sampled)
    assert np.allclose(sampled, end, rtol=0.0, atol=1e-12)


def test_friction_only_takes_energy():
    """mu 0.3, turning at -10 rad/s: the energy falls at every sample until the side is decided."""
    fpar = pentagon(0.3)
    end = np.zeros(6)
    how, tau = ladder(fpar, 5, TABLE, WALL, RIGHT, 1.0, -10.0, 1.0, end)
    assert how == LADDER_DECIDED and tau > 0.005
    e = energies(fpar, 1.0, -10.0, tau)
    assert np.all(np.diff(e) < 0.0)
    assert e[-1] < 0.99 * e[0]


def test_friction_holds_a_slow_ladder_still_and_none_does_not():
    """Turning at 1e-3 rad/s at 0.989 rad: mu 1.5 stops it within microseconds and holds it
    (at rest leaning on the wall); without friction it slides on until its side is decided."""
    held = np.zeros(6)
    how, tau = ladder(pentagon(1.5), 5, TABLE, WALL, RIGHT, 0.989, -1e-3, 1.0, held)
    assert how == LADDER_AT_REST and tau < 1e-5 and held[5] == 0.0
    slid = np.zeros(6)
    how, tau = ladder(pentagon(0.0), 5, TABLE, WALL, RIGHT, 0.989, -1e-3, 1.0, slid)
    assert how == LADDER_DECIDED and slid[5] != 0.0
