"""The stochastic impact law: its random numbers, its jump and its streams in a batch."""

import math

import numpy as np
import pytest
from scipy import stats

from dice_sweep.config import parse_config
from dice_sweep.engine import ENGINE_PLAIN
from dice_sweep.mapper import Mapper, roll_states
from dice_sweep.measured.impacts import landing_tilt as measured_tilt
from dice_sweep.physics.params import (FP_G, FP_INERTIA, FP_R, FP_SCATTER_CORNER, FP_SCATTER_CORNER_FLOOR, FP_SCATTER_FLAT, FP_SCATTER_FLAT_FLOOR,
                                       FP_SCATTER_POWER, FP_SCATTER_SPIN, FP_SCATTER_TAIL_FACTOR, FP_SCATTER_TAIL_SHARE, FP_STREAM_DRAW, FP_STREAM_PIXEL, FP_STREAM_SEED, pack_params)
from dice_sweep.physics.scatter import TRIES, VARIATES, landing_tilt, normal, scatter_impact, stream_key, uniform
from tests.physics.conftest import make_params


def test_uniforms_are_uniform_and_streams_differ():
    key = np.uint64(stream_key(7, 12, 3))  # as a Python int above 2^63 numba would refuse it
    u = np.array([uniform(key, c) for c in range(20000)])
    assert stats.kstest(u, "uniform").pvalue > 1e-3
    other = np.array([uniform(np.uint64(stream_key(7, 13, 3)), c) for c in range(20000)])
    assert abs(np.corrcoef(u, other)[0, 1]) < 0.03
    assert stream_key(7, 12, 3) == key  # a pure function of (seed, pixel, draw)
    assert len({int(stream_key(s, p, d)) for s in range(3) for p in range(3) for d in range(3)}) == 27


def test_normals_are_standard_normal():
    key = np.uint64(stream_key(1, 2, 3))
    z = np.array([normal(key, 2 * c) for c in range(20000)])
    assert stats.kstest(z, "norm").pvalue > 1e-3


def test_landing_tilt_on_the_table_is_calibrates():
    """The kernel's tilt (corner k, table normal) is measured/impacts.landing_tilt of the lowest
    corner: the same rule tells flat from corner landings in the estimator and the kernel."""
    rng = np.random.default_rng(0)
    for phi in rng.uniform(-10, 10, 200):
        n = int(rng.integers(3, 9))
        lowest = int(np.argmin(np.sin(phi + 2 * np.pi * np.arange(n) / n)))
        assert landing_tilt(phi, n, 0.0, 1.0, lowest) == pytest.approx(measured_tilt(n, phi), abs=1e-12)


def _jumps(sigma, count, vy=-2.0, w=3.0, floor=0.0, power=1.0, tail=(0.0, 1.0), spin=1.0):
    """Velocity jumps of ``count`` impacts of corner 0 (tilted 30 deg: a corner landing);
    ``tail``: (tail_share, tail_factor)."""
    fpar, ipar = make_params(sides=4, radius=0.02)
    fpar[FP_SCATTER_CORNER] = sigma
    fpar[FP_SCATTER_POWER] = power
    fpar[FP_SCATTER_TAIL_SHARE], fpar[FP_SCATTER_TAIL_FACTOR] = tail
    fpar[FP_SCATTER_SPIN] = spin
    fpar[FP_SCATTER_CORNER_FLOOR] = floor
    fpar[FP_SCATTER_FLAT] = 9.0  # must not be used
    fpar[FP_SCATTER_FLAT_FLOOR] = 9.0
    out = []
    phi = -math.pi / 2 + math.radians(15.0)  # corner 0 down, its sides 30 and 60 deg from the table
    rx, ry = 0.02 * math.cos(phi), 0.02 * math.sin(phi)
    after = np.array([0.0, 0.02, phi, 0.1, 0.8, -2.0])  # a deterministic outcome, leaving, losing energy
    approach = -(vy + w * rx)
    for index in range(count):
        s = after.copy()
        tried = scatter_impact(s, fpar, ipar, rx, ry, 0.0, 1.0, 0, 0.2, vy, w, approach, index, False)
        out.append((tried, *(s[3:] - after[3:])))
    return np.array(out), approach, fpar[FP_INERTIA], after, rx, ry, (0.2, vy, w)


def test_jump_size_and_admissibility():
    jumps, approach, inertia, after, rx, ry, before = _jumps(0.05, 4000)
    kept = jumps[:, 0] >= 0
    assert kept.mean() > 0.99
    d = jumps[kept, 1:]
    d[:, 2] *= math.sqrt(inertia)
    # each component's sd is sigma times the approach speed (truncation removes almost nothing here)
    assert np.std(d, axis=0) == pytest.approx(0.05 * approach * np.ones(3), rel=0.06)
    new = after[3:] + jumps[kept, 1:]
    assert np.all(new[:, 1] + new[:, 2] * rx >= 0.0)  # the corner leaves the table
    energy_in = before[0] ** 2 + before[1] ** 2 + inertia * before[2] ** 2
    assert np.all(new[:, 0] ** 2 + new[:, 1] ** 2 + inertia * new[:, 2] ** 2 <= energy_in)


def test_the_floor_adds_in_quadrature():
    jumps, approach, inertia, *_ = _jumps(0.03, 4000, floor=0.05)
    d = jumps[jumps[:, 0] >= 0, 1:]
    d[:, 2] *= math.sqrt(inertia)
    assert np.std(d, axis=0) == pytest.approx(math.hypot(0.03 * approach, 0.05) * np.ones(3), rel=0.06)


@pytest.mark.parametrize("power", [0.0, 0.5, 2.0])
def test_the_spread_term_follows_the_power_of_the_approach(power):
    """sd = sigma sqrt(g R) (u / sqrt(g R))^power: at power 2 this corner, approaching at 4.5
    sqrt(g R), scatters 4.5 times what power 1 gives it, at 0 1/4.5 of it."""
    jumps, approach, inertia, *_ = _jumps(0.03, 4000, power=power)
    fpar, _ = make_params(sides=4, radius=0.02)
    unit = math.sqrt(fpar[FP_G] * fpar[FP_R])
    d = jumps[jumps[:, 0] >= 0, 1:]
    d[:, 2] *= math.sqrt(inertia)
    assert np.std(d, axis=0) == pytest.approx(0.03 * unit * (approach / unit) ** power * np.ones(3), rel=0.06)


def test_power_one_is_todays_law_bit_for_bit():
    """At the power's null value each kept jump is the old law's, to the bit: size
    min(sqrt((sigma u)^2 + f^2), u) times the stream's normal numbers (recomputed here in plain
    Python floats); a power a hair off 1 gives other bits."""
    sigma, floor = 0.05, 0.02
    jumps, approach, inertia, after, *_ = _jumps(sigma, 200, floor=floor)
    fpar, _ = make_params(sides=4, radius=0.02)
    key = stream_key(fpar[FP_STREAM_SEED], fpar[FP_STREAM_PIXEL], fpar[FP_STREAM_DRAW])
    size = min(math.sqrt((sigma * approach) ** 2 + floor * floor), approach)
    for index, (tried, dvx, *_) in enumerate(jumps):
        if tried >= 0:
            counter = np.uint64(index) * np.uint64(VARIATES) + np.uint64(6 * int(tried))
            assert after[3] + dvx == after[3] + size * normal(key, counter)
    off, *_ = _jumps(sigma, 200, floor=floor, power=1.0 + 1e-12)
    assert not np.array_equal(jumps, off) and np.allclose(jumps, off, atol=1e-9)


def test_a_share_of_impacts_jumps_wider():
    """tail_share 0.2, tail_factor 3: a fifth of the impacts jump with three times the sd
    (the same factor on all three components of an impact), the rest with the law's."""
    jumps, approach, inertia, *_ = _jumps(0.02, 4000, tail=(0.2, 3.0))
    d = jumps[jumps[:, 0] >= 0, 1:]
    d[:, 2] *= math.sqrt(inertia)
    size = 0.02 * approach
    # |jump|^2 beyond 12 sd^2: chi-square(3) > 12 for 0.74 % of narrow impacts, > 12 / 9 for 72 % of wide ones
    far = np.sum(d**2, axis=1) > 12.0 * size**2
    assert 0.150 - 0.025 < far.mean() < 0.150 + 0.025  # 0.8 * 0.0074 + 0.2 * 0.721 = 0.150; a Gaussian of the same variance: 0.20
    assert np.std(d, axis=0) == pytest.approx(size * math.sqrt(0.8 + 0.2 * 9.0) * np.ones(3), rel=0.08)
    assert stats.kurtosis(d[:, 0]) > 2.0  # a Gaussian's is 0; this mixture's 3 (1 - w + w k^4) / (1 - w + w k^2)^2 - 3 = 4.5


def test_the_spin_component_scales_alone():
    jumps, approach, inertia, *_ = _jumps(0.05, 4000, spin=1.8)
    d = jumps[jumps[:, 0] >= 0, 1:]
    d[:, 2] *= math.sqrt(inertia)
    assert np.std(d, axis=0) == pytest.approx(0.05 * approach * np.array([1.0, 1.0, 1.8]), rel=0.06)


def test_the_shapes_null_values_are_todays_law_bit_for_bit():
    """tail_share 0 (any tail_factor) and spin 1: every jump and every roll of a probability
    sweep's streams as without the keys; a tail_share a hair above 0 moves some."""
    plain, *_ = _jumps(0.05, 300, floor=0.02)
    same, *_ = _jumps(0.05, 300, floor=0.02, tail=(0.0, 7.0), spin=1.0)
    assert np.array_equal(plain, same)
    starts = _starts(200)
    streams = np.column_stack([np.arange(200), np.full(200, 3)])
    law = "[scatter]\ncorner = 0.1\nflat = 0.2\ncorner_floor = 0.05\nseed = 4\n"
    before = Mapper.from_config(parse_config(law)).roll(starts, streams=streams)
    after = Mapper.from_config(parse_config(law + "tail_share = 0.0\ntail_factor = 5.0\nspin = 1.0\n")).roll(starts, streams=streams)
    for a, b in zip(before, after):
        assert np.array_equal(a, b, equal_nan=True)
    tailed = Mapper.from_config(parse_config(law + "tail_share = 0.3\ntail_factor = 5.0\n")).roll(starts, streams=streams)
    assert (tailed.outcome != before.outcome).mean() > 0.05


def test_config_floors_are_in_each_dies_own_speed():
    cfg = parse_config("[die]\ncircumradius = 0.04\n[scatter]\ncorner_floor = 0.1\nflat_floor = 0.2\n")
    fpar, _ = pack_params(cfg)
    speed = math.sqrt(9.81 * 0.04)
    assert fpar[FP_SCATTER_CORNER_FLOOR] == pytest.approx(0.1 * speed) and fpar[FP_SCATTER_FLAT_FLOOR] == pytest.approx(0.2 * speed)


def test_inadmissible_jumps_are_redrawn_then_dropped():
    """A huge spread: most draws gain energy; the kept ones never do, and an impact with no
    admissible draw in TRIES keeps the deterministic outcome."""
    jumps, approach, inertia, after, rx, ry, before = _jumps(1.0, 400)
    assert (jumps[:, 0] > 0).any() and (jumps[:, 0] == -1).any()
    assert np.all(jumps[jumps[:, 0] == -1, 1:] == 0.0)
    assert jumps[:, 0].max() < TRIES


def _starts(count, seed=0):
    rng = np.random.default_rng(seed)
    return np.column_stack([np.zeros(count), rng.uniform(0.05, 0.2, count), rng.uniform(-3, 3, count), rng.uniform(-0.5, 0.5, count),
                            np.zeros(count), rng.uniform(-20, 20, count)])


def test_null_spread_is_the_deterministic_kernel_bit_for_bit():
    starts = _starts(300)
    mapper = Mapper.from_config(parse_config(""))
    plain = mapper.roll(starts)
    streamed = mapper.roll(starts, streams=np.column_stack([np.arange(300), np.full(300, 5)]))
    for a, b in zip(plain, streamed):
        assert np.array_equal(a, b, equal_nan=True)


def test_a_rolls_answer_depends_on_its_stream_only():
    cfg = parse_config("[scatter]\ncorner = 0.1\nflat = 0.2\nseed = 11\n")
    mapper = Mapper.from_config(cfg)
    starts = _starts(300)
    streams = np.column_stack([np.arange(300), np.zeros(300)])
    whole = mapper.roll(starts, streams=streams)
    order = np.random.default_rng(1).permutation(300)
    shuffled = mapper.roll(starts[order], streams=streams[order])
    assert np.array_equal(shuffled.outcome, whole.outcome[order])
    assert np.array_equal(shuffled.t_decided, whole.t_decided[order], equal_nan=True)
    chunked = roll_states(mapper, starts, workers=2, streams=streams)  # chunks, two processes
    assert np.array_equal(chunked.outcome, whole.outcome)
    deterministic = Mapper.from_config(parse_config("")).roll(starts)
    assert (deterministic.outcome != whole.outcome).mean() > 0.2  # the law does scatter
    other_draw = mapper.roll(starts, streams=np.column_stack([np.arange(300), np.ones(300)]))
    assert (other_draw.outcome != whole.outcome).mean() > 0.2
    cold = mapper.roll(starts[:10], engine=ENGINE_PLAIN, streams=streams[:10])  # the uncompiled source
    assert np.array_equal(cold.outcome, whole.outcome[:10])
