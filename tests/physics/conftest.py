"""Shared builders for kernel tests: parameters without going through TOML."""

import math
from types import SimpleNamespace

import numpy as np
import pytest

from dice_sweep.physics import COUNT_COLUMNS, pack_params, roll_batch
from dice_sweep.physics.kernel import REC_WIDTH, roll_one

TABLE1_RADIUS = 0.019 / math.sqrt(2)  # m, Smith 2014 Table I


def make_config(sides=4, radius=TABLE1_RADIUS, beta_n=0.2, beta_t=-0.35, separation=None,
                method="event", dt=1e-3, t_max=30.0, max_events=100_000, g=9.81, model="paper",
                friction=math.inf, window=1e-6, air_drag=0.0, com_offset=(0.0, 0.0), speed_restitution=0.0, contact_time=0.0):
    """A config-like object for the kernel without going through TOML."""
    return SimpleNamespace(
        die=SimpleNamespace(sides=sides, circumradius=radius),
        contact=SimpleNamespace(model=model, beta_normal=beta_n, beta_tangential=beta_t, friction=friction, window=window),
        walls=SimpleNamespace(separation=separation),
        world=SimpleNamespace(g=g),
        integrator=SimpleNamespace(method=method, dt=dt, t_max=t_max, max_events=max_events),
        effects=SimpleNamespace(air_drag=air_drag, com_offset=com_offset,
                                speed_restitution=speed_restitution, contact_time=contact_time),
    )


def make_params(**kwargs):
    return pack_params(make_config(**kwargs))


def run_batch(params, states):
    fpar, ipar = params
    states = np.ascontiguousarray(states, dtype=float)
    n = states.shape[0]
    outcome = np.empty(n, np.int8)
    status = np.empty(n, np.uint8)
    counts = np.empty((n, len(COUNT_COLUMNS)), np.int32)
    t = np.empty(n)
    roll_batch(fpar, ipar, states, outcome, status, counts, t)
    return outcome, status, counts, t


def run_one(params, state, max_records=20_000):
    fpar, ipar = params
    rec = np.zeros((max_records, REC_WIDTH))
    counts = np.zeros(len(COUNT_COLUMNS), np.int32)
    outcome, status, t_dec, t_end, n_rec = roll_one(fpar, ipar, np.asarray(state, float), rec, counts)
    return outcome, status, t_dec, t_end, rec[:n_rec], counts


def random_states(rng, count, radius=TABLE1_RADIUS, y_range=(0.03, 0.2), omega_max=40.0, v_max=1.0):
    states = np.zeros((count, 6))
    states[:, 1] = rng.uniform(*y_range, count)
    states[:, 2] = rng.uniform(-math.pi, math.pi, count)
    states[:, 3] = rng.uniform(-v_max, v_max, count)
    states[:, 4] = rng.uniform(-v_max, v_max, count)
    states[:, 5] = rng.uniform(-omega_max, omega_max, count)
    return states


@pytest.fixture
def rng():
    return np.random.default_rng(20141)
