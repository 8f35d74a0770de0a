"""The stochastic impact law: each impact's outcome scattered around the deterministic law.

After the deterministic impact (one corner, or two at once), the centre of mass's velocity
gets a random jump, Gaussian and isotropic in the kinetic-energy metric (vx, vy,
sqrt(I/M) omega), of standard deviation min(sqrt((sigma v (u / v)^p)^2 + f^2), u) per
component: u (m/s) the touching corner's approach speed before the impact, v = sqrt(g R), p
the ``power`` (1, the null value: sigma u exactly as before the key existed), sigma the
relative spread and f the floor (m/s; the config's floor times sqrt(g R)) of ``[scatter]``, ``flat`` and
``flat_floor`` for a landing with a side within FLAT_TILT of the surface (or a two-contact
impact), else ``corner`` and ``corner_floor``. A jump that would leave the die with more kinetic energy than it brought in, or
the touching corner still approaching the surface, is drawn again (at most TRIES times; then
the deterministic outcome stands). The jump's shape: with probability ``tail_share`` an impact's
sd is ``tail_factor`` times the law's (still capped at u; the choice is made once per impact,
its redraws keep it), and the spin component's sd is ``spin`` times the others'. Their null
values (0, 1, 1) multiply by 1.0 and draw no uniform: a roll stays bit for bit.
docs/physics.md, "Scattered impacts", states the model;
dice_sweep/measured/scatter.py estimates sigma from tracked drops.

The random numbers come from a counter-based hash, not a generator with a state: the normal
number of component c, try a, impact i of the roll with stream (seed, pixel, draw) is a pure
function of those six integers. A roll's answer therefore depends on its own stream only, never
on the batch, tile, shard or worker it is rolled in. The stream sits in fpar
(FP_STREAM_SEED, FP_STREAM_PIXEL, FP_STREAM_DRAW, integers below 2^53).

With the spreads and floors 0 (the null value) nothing here runs, and a roll is bit for bit the
deterministic one.
"""

import math

import numba
import numpy as np

from dice_sweep.physics.params import (
    FP_G,
    FP_INERTIA,
    FP_R,
    FP_SCATTER_CORNER,
    FP_SCATTER_CORNER_FLOOR,
    FP_SCATTER_FLAT,
    FP_SCATTER_FLAT_FLOOR,
    FP_SCATTER_POWER,
    FP_SCATTER_SPIN,
    FP_SCATTER_TAIL_FACTOR,
    FP_SCATTER_TAIL_SHARE,
    FP_STREAM_DRAW,
    FP_STREAM_PIXEL,
    FP_STREAM_SEED,
    IP_N,
)

FLAT_TILT = math.radians(15.0)  # rad: as measured/calibrate.FLAT_TILT, a landing this near flat is "flat"
TRIES = 16  # jumps drawn per impact before the deterministic outcome is kept
VARIATES = 2 * 3 * TRIES  # uniforms used per impact (Box-Muller: two per normal number)

_GOLDEN = np.uint64(0x9E3779B97F4A7C15)
_MIX1 = np.uint64(0xBF58476D1CE4E5B9)
_MIX2 = np.uint64(0x94D049BB133111EB)
_S30 = np.uint64(30)
_S27 = np.uint64(27)
_S31 = np.uint64(31)
_S11 = np.uint64(11)
_UNIT = 2.0**-53  # a 53-bit integer times this is in [0, 1)
# Stream numbers of starts off a sweep's grid lie in [2^52, 2^53): above every pixel number
# (below MAX_GRID_NUM^2 = 10^10), below the 2^53 a float64 slot holds exactly
OFF_GRID_STREAMS = 2**52
_S12 = np.uint64(12)
# The counter of impact i's tail uniform is TAIL_COUNTERS + i: clear of the jumps' counters
# (i VARIATES + ...), so a law with a tail leaves every normal number of a roll where it was
TAIL_COUNTERS = np.uint64(2**63)


@numba.njit(cache=True)
def mix64(x):
    """splitmix64's finaliser of x + golden ratio: a bijection of uint64 whose every output bit
    depends on every input bit (Steele, Lea and Flood 2014)."""
    z = np.uint64(x) + _GOLDEN
    z = (z ^ (z >> _S30)) * _MIX1
    z = (z ^ (z >> _S27)) * _MIX2
    return z ^ (z >> _S31)


@numba.njit(cache=True)
def stream_key(seed, pixel, draw):
    """The uint64 key of stream (seed, pixel, draw), each a non-negative integer below 2^53."""
    return mix64(mix64(mix64(np.uint64(seed)) ^ np.uint64(pixel)) ^ np.uint64(draw))


@numba.njit(cache=True)
def off_grid_streams(x_bits, y_bits, out):
    """Stream numbers of starts off a sweep's grid, from the float64 bits (uint64 arrays) of
    their two swept values: 2^52 plus the top 52 bits of a hash of both, into ``out`` (int64):
    a function of the start alone, whatever map it is rolled in."""
    for k in range(x_bits.size):
        out[k] = OFF_GRID_STREAMS + np.int64(mix64(mix64(x_bits[k]) ^ y_bits[k]) >> _S12)


@numba.njit(cache=True)
def uniform(key, counter):
    """The counter-th uniform number in (0, 1) of the stream ``key``."""
    z = mix64(np.uint64(key) ^ mix64(np.uint64(counter)))  # np.uint64: a key from Python arrives as int64
    return (float(z >> _S11) + 0.5) * _UNIT


@numba.njit(cache=True)
def normal(key, counter):
    """A standard normal number from uniforms counter and counter + 1 (Box-Muller)."""
    u1 = uniform(key, counter)
    u2 = uniform(key, counter + 1)
    return math.sqrt(-2.0 * math.log(u1)) * math.cos(2.0 * math.pi * u2)


@numba.njit(cache=True)
def landing_tilt(phi, n, nx, ny, corner):
    """Angle (rad) between the surface of normal (nx, ny) and the side next to ``corner``
    nearer to it, the die at angle phi (the geometric corners): 0 flat, pi/n on the corner."""
    down = math.atan2(-ny, -nx)
    offset = (phi + 2.0 * math.pi * corner / n - down + math.pi) % (2.0 * math.pi) - math.pi
    return max(math.pi / n - abs(offset), 0.0)


@numba.njit(cache=True)
def scatter_on(fpar):
    """True when the stochastic law is on (a spread or a floor above 0)."""
    return fpar[FP_SCATTER_CORNER] > 0.0 or fpar[FP_SCATTER_FLAT] > 0.0 or fpar[FP_SCATTER_CORNER_FLOOR] > 0.0 or fpar[FP_SCATTER_FLAT_FLOOR] > 0.0


@numba.njit(cache=True)
def spread_term(fpar, sigma, approach):
    """The law's speed term (m/s): sigma u at power 1 (the same float operations as before the
    power existed, so such rolls stay bit for bit), else sigma sqrt(g R) (u / sqrt(g R))^power."""
    power = fpar[FP_SCATTER_POWER]
    if power == 1.0:
        return sigma * approach
    unit = math.sqrt(fpar[FP_G] * fpar[FP_R])
    return sigma * unit * (approach / unit) ** power


@numba.njit(cache=True)
def scatter_impact(s, fpar, ipar, rx, ry, nx, ny, corner, vx0, vy0, w0, approach, index, two_contacts):
    """Add the random velocity jump of impact ``index`` (0, 1, ... within the roll) to the COM
    state s, in place. (rx, ry): the touching contact point from the COM; (nx, ny): the
    surface normal; (vx0, vy0, w0): the velocity before the impact; ``approach`` (m/s): the
    corner's approach speed before it. Returns the try that was kept (0..TRIES-1), or -1 when
    none was admissible (s unchanged)."""
    flat = two_contacts or landing_tilt(s[2], ipar[IP_N], nx, ny, corner) < FLAT_TILT
    sigma = fpar[FP_SCATTER_FLAT] if flat else fpar[FP_SCATTER_CORNER]
    floor = fpar[FP_SCATTER_FLAT_FLOOR] if flat else fpar[FP_SCATTER_CORNER_FLOOR]
    if (sigma <= 0.0 and floor <= 0.0) or approach <= 0.0:
        return -1
    inertia = fpar[FP_INERTIA]
    lever = math.sqrt(inertia)
    energy_in = vx0 * vx0 + vy0 * vy0 + inertia * w0 * w0
    key = stream_key(fpar[FP_STREAM_SEED], fpar[FP_STREAM_PIXEL], fpar[FP_STREAM_DRAW])
    # never above the approach itself: a floor on a corner barely touching would only be redrawn
    wide = 1.0
    tail = fpar[FP_SCATTER_TAIL_SHARE]
    if tail > 0.0 and uniform(key, TAIL_COUNTERS + np.uint64(index)) < tail:
        wide = fpar[FP_SCATTER_TAIL_FACTOR]
    size = min(math.sqrt(spread_term(fpar, sigma, approach) ** 2 + floor * floor) * wide, approach)
    spun = size * fpar[FP_SCATTER_SPIN]  # the spin component's sd (times 1.0 at the null: the same float)
    base = np.uint64(index) * np.uint64(VARIATES)
    for attempt in range(TRIES):
        c = base + np.uint64(6 * attempt)
        vx = s[3] + size * normal(key, c)
        vy = s[4] + size * normal(key, c + np.uint64(2))
        w = s[5] + spun * normal(key, c + np.uint64(4)) / lever
        leaving = nx * (vx - w * ry) + ny * (vy + w * rx) >= 0.0
        if leaving and vx * vx + vy * vy + inertia * w * w <= energy_in:
            s[3] = vx
            s[4] = vy
            s[5] = w
            return attempt
    return -1
