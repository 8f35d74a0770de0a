"""Tests of dice_sweep.chaos.known_maps: the maps whose answers tests/chaos/test_measures.py and
docs/chaos.md check the measures on are the maps their docstrings say, pixel by pixel."""

import math

import numpy as np
import pytest

from dice_sweep.chaos import cantor_map, checkerboard_map, random_map_entropy, straight_boundary_map, weierstrass_map


def test_straight_boundary_is_1_above_the_line_through_pixel_centres():
    flat = straight_boundary_map((4, 6), 0.0, 1.5)  # row centres 0.5, 1.5, 2.5, 3.5
    assert flat.dtype == np.int8
    np.testing.assert_array_equal(flat, [[0] * 6, [0] * 6, [1] * 6, [1] * 6])  # 1.5 is not above 1.5
    diagonal = straight_boundary_map((5, 5), 1.0, 0.0)  # y = x: 1 strictly above the diagonal
    np.testing.assert_array_equal(diagonal, np.tril(np.ones((5, 5), np.int8), -1))


def test_checkerboard_alternates_blocks_with_edges_shift_pixels_in():
    board = checkerboard_map((4, 6), 2)
    assert board.dtype == np.int8
    np.testing.assert_array_equal(board[0], [0, 0, 1, 1, 0, 0])
    np.testing.assert_array_equal(board[:, 0], [0, 0, 1, 1])
    np.testing.assert_array_equal(board[2:, :2], np.ones((2, 2)))  # diagonal blocks alike
    shifted = checkerboard_map((4, 6), 2, shift=1)  # edges between pixels 0|1, 2|3, ...
    np.testing.assert_array_equal(shifted[0], [0, 1, 1, 0, 0, 1])
    np.testing.assert_array_equal(shifted[:, 0], [0, 1, 1, 0])


def test_cantor_map_is_the_middle_thirds_construction():
    row = [9, 1, 11, 3, 3, 3, 15, 7, 17]  # by hand for 2 levels: the middle third 3-5, then pixels 1 and 7
    np.testing.assert_array_equal(cantor_map(2, 3), np.tile(row, (3, 1)))
    for levels in (3, 5):
        basins = cantor_map(levels, 1)[0]
        removed = np.unique(basins[basins < 3**levels])
        assert len(removed) == 2**levels - 1  # one interval removed per node of the construction
        assert np.sum(basins >= 3**levels) == 2**levels  # the points of the set left at this resolution
        # the boundary (neighbours in different basins) touches every pixel of the set
        boundary = np.flatnonzero(np.diff(basins) != 0)
        kept = np.flatnonzero(basins >= 3**levels)
        assert set(kept) <= set(boundary) | set(boundary + 1)


@pytest.mark.parametrize(("a", "b", "terms"), [(0.0, 4.0, 1), (0.5, 3.0, 2)])
def test_weierstrass_map_is_1_above_the_graph(a, b, terms):
    pixels = 64
    image = weierstrass_map(pixels, a, b, terms)
    x = (np.arange(pixels) + 0.5) / pixels
    w = np.cos(2 * np.pi * x) + (a * np.cos(2 * np.pi * b * x + 1) if terms == 2 else 0.0)  # the sum by hand
    y = (np.arange(pixels) + 0.5) / pixels * 4 - 2
    assert image.dtype == np.int8 and image.shape == (pixels, pixels)
    assert np.all(np.diff(image, axis=0) >= 0)  # each column: 0 below the graph, 1 above, one step
    np.testing.assert_array_equal(image.argmax(axis=0), np.searchsorted(y, w, side="right"))


def test_random_map_entropy_is_the_multinomial_mean_by_hand():
    assert random_map_entropy(1, 3) == 0.0  # one pixel: one outcome per box
    assert random_map_entropy(2, 2) == pytest.approx(math.log(2) / 2, rel=1e-15)  # half the boxes split 1:1
    third = -(1 / 3 * math.log(1 / 3) + 2 / 3 * math.log(2 / 3))
    assert random_map_entropy(3, 2) == pytest.approx(6 / 8 * third, rel=1e-15)  # 6 of 8 boxes split 1:2
    # below ln(outcomes) by about (outcomes - 1) / (2 box_pixels)
    assert math.log(4) - random_map_entropy(25, 4) == pytest.approx(3 / 50, rel=0.15)
