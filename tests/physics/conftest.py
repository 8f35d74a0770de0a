"""Shared builders for kernel tests: parameters without going through TOML."""

import math
import dataclasses

import numpy as np
import pytest

from dice_sweep.config import Die, Integrator, Walls, World, default_config
from dice_sweep.effects import config_key_specs, set_key
from dice_sweep.physics import COUNT_COLUMNS, pack_params, roll_batch
from dice_sweep.physics.kernel import REC_WIDTH, roll_one

TABLE1_RADIUS = 0.019 / math.sqrt(2)  # m, Smith 2014 Table I


def make_config(sides=4, radius=TABLE1_RADIUS, beta_n=0.2, beta_t=-0.35, separation=None,
                method="event", dt=1e-3, t_max=30.0, max_events=100_000, g=9.81, model="paper",
                friction=math.inf, window=1e-6, **registry_keys):
    """A validated config for the kernel without going through TOML.

    Any other keyword is a key the effect registry declares, by its name (``air_drag=0.1``,
    ``com_offset=(0.002, 0)``, ``friction_rule="exact"``): a new effect needs nothing here.
    """
    by_name = {key.name: key for keys in config_key_specs().values() for key in keys.values()}
    cfg = dataclasses.replace(
        default_config(),
        die=Die(sides=sides, circumradius=radius),
        walls=Walls(separation=separation),
        world=World(g=g),
        integrator=Integrator(method=method, dt=dt, t_max=t_max, max_events=max_events),
    )
    cfg = dataclasses.replace(cfg, contact=dataclasses.replace(
        cfg.contact, model=model, beta_normal=beta_n, beta_tangential=beta_t, friction=friction, window=window))
    for name, value in registry_keys.items():
        cfg = set_key(cfg, by_name[name].dotted, tuple(value) if by_name[name].length else value)
    return cfg


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


def follow_to_rest(params, states, until=3.0):
    """Roll ``states`` to their decision (roll_batch), then follow them past it to ``until``
    seconds (sample_batch with IP_CONTINUE): (decided sides, geometric-centre states at
    ``until``)."""
    from dice_sweep.physics.kernel import sample_batch
    from dice_sweep.physics.params import IP_CONTINUE

    fpar, ipar = params
    stopped, _, _, _ = run_batch((fpar, ipar), states)
    ipar = ipar.copy()
    ipar[IP_CONTINUE] = 1
    times = np.tile([until - 0.1, until], len(states))
    starts = np.arange(0, times.size + 1, 2)
    out = np.zeros((times.size, 6))
    outcome = np.zeros(len(states), np.int8)
    sample_batch(fpar, ipar, states, times, starts, out, outcome)
    assert np.array_equal(outcome, stopped)
    return stopped, out[1::2]


def corner_impacts(rng, count, radius=TABLE1_RADIUS):
    """Random single-corner table impacts: (state, rx, ry) of a corner below the centre that
    approaches the table, the state's velocities uniform (m/s, rad/s)."""
    from dice_sweep.physics.impact import corner_normal_velocity

    for _ in range(count):
        ang = rng.uniform(-math.pi + 0.2, -0.2)
        rx, ry = radius * math.cos(ang), radius * math.sin(ang)
        s = np.array([0.0, 0.1, 0.0, *rng.uniform(-1, 1, 2), rng.uniform(-40, 40)])
        if corner_normal_velocity(s, rx, ry, 0.0, 1.0) < 0.0:
            yield s, rx, ry
