"""Maps with known answers: straight and checkerboard boundaries, Cantor and Weierstrass
boundaries of known dimension, and the mean box entropy of a random map. The tests and
docs/chaos.md check the measures on them (scripts/chaos_tables.py).
"""

from __future__ import annotations

import math

import numpy as np


def straight_boundary_map(shape, slope, offset) -> np.ndarray:
    """int8 map: 1 above the line y = slope x + offset (pixel units, through pixel centres), else 0."""
    rows, cols = np.mgrid[0 : shape[0], 0 : shape[1]]
    return (rows + 0.5 > slope * (cols + 0.5) + offset).astype(np.int8)


def checkerboard_map(shape, block, shift=0) -> np.ndarray:
    """int8 checkerboard of ``block`` x ``block`` pixel squares, its edges ``shift`` pixels in."""
    rows, cols = np.mgrid[0 : shape[0], 0 : shape[1]]
    return (((rows + block - shift) // block + (cols + block - shift) // block) % 2).astype(np.int8)


def cantor_map(levels, rows) -> np.ndarray:
    """A middle-thirds Cantor boundary times a line: ``rows`` x 3^levels pixels.

    Every interval removed by the construction is a basin of its own, and so is every pixel
    never removed (a point of the set at this resolution), so the boundary is exactly the
    Cantor set, of dimension ln 2 / ln 3: alpha = 1 - ln 2 / ln 3 along the columns.
    """
    pixel = np.arange(3**levels)
    basin = 3**levels + pixel
    removed = np.zeros(pixel.shape, dtype=bool)
    for stage in range(levels):
        width = 3 ** (levels - 1 - stage)
        middle = ((pixel // width) % 3 == 1) & ~removed
        basin[middle] = (pixel[middle] // width) * width  # first pixel of the removed interval
        removed |= middle
    return np.tile(basin, (rows, 1))


def weierstrass_map(pixels, a, b, terms=20) -> np.ndarray:
    """int8 map, 1 above the graph of W(x) = sum_k a^k cos(2 pi b^k x + k), x in [0, 1].

    The graph has box-counting dimension 2 + ln a / ln b, so alpha = -ln a / ln b; the
    pixels resolve only about log_b(pixels) octaves of W.
    """
    x = (np.arange(pixels) + 0.5) / pixels
    w = sum(a**k * np.cos(2 * np.pi * b**k * x + k) for k in range(terms))
    y = (np.arange(pixels) + 0.5) / pixels * 4 - 2  # W stays within +-2 for a <= 1/2
    return (y[:, np.newaxis] > w[np.newaxis, :]).astype(np.int8)


def random_map_entropy(box_pixels, outcomes) -> float:
    """Expected Sb (= Sbb) of a map of independent, equally likely outcomes.

    The exact mean entropy of the shares of ``box_pixels`` uniform draws among ``outcomes``
    (a sum over the multinomial distribution); it is below ln(outcomes) by about
    (outcomes - 1) / (2 box_pixels).
    """

    def compositions(total, parts):
        if parts == 1:
            yield (total,)
            return
        for first in range(total + 1):
            for rest in compositions(total - first, parts - 1):
                yield (first, *rest)

    mean = 0.0
    for counts in compositions(box_pixels, outcomes):
        ways = math.factorial(box_pixels)
        for count in counts:
            ways //= math.factorial(count)
        entropy = -sum(c / box_pixels * math.log(c / box_pixels) for c in counts if c)
        mean += ways * entropy / outcomes**box_pixels
    return mean
