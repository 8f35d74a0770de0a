"""dice_sweep.measured.blocks: per-segment sums and normal blocks against plain loops."""

import numpy as np
import pytest

from dice_sweep.measured import blocks
from dice_sweep.measured.blocks import Linearisation

STARTS = np.array([0, 4, 4, 9, 15])  # four segments, the second empty


@pytest.fixture
def lin():
    rng = np.random.default_rng(5)
    rows = STARTS[-1]
    return Linearisation(rng.normal(size=(rows, 3)), rng.uniform(0.1, 1.0, rows), rng.normal(size=(rows, 3, 2)),
                         rng.normal(size=(rows, 3, 6)))


def test_segment_sums_with_an_empty_segment():
    values = np.arange(15.0).reshape(15, 1) ** 2
    got = blocks.segment_sums(values, STARTS)
    want = [values[a:b].sum(axis=0) for a, b in zip(STARTS[:-1], STARTS[1:])]
    np.testing.assert_array_equal(got, want)
    assert got[1, 0] == 0.0  # reduceat alone would give the next row
    assert blocks.segment_sums(np.zeros((0, 3)), np.array([0, 0, 0])).shape == (2, 3)


def test_segment_products_are_each_segments_weighted_normal_matrix(lin):
    jac = lin.joint_jacobian()
    assert jac.shape == (15, 3, 8)
    np.testing.assert_array_equal(jac[:, :, :6], lin.jac_states)  # the states first
    hessian, gradient = blocks.segment_products(jac, lin.weight, lin.residual, STARTS)
    for s, (a, b) in enumerate(zip(STARTS[:-1], STARTS[1:])):
        J = jac[a:b].reshape(-1, 8)
        W = np.repeat(lin.weight[a:b], 3)
        np.testing.assert_allclose(hessian[s], J.T @ (W[:, None] * J), rtol=1e-12, atol=1e-12)
        np.testing.assert_allclose(gradient[s], J.T @ (W * lin.residual[a:b].ravel()), rtol=1e-12, atol=1e-12)
    # a batch of residuals is each residual's gradient side by side
    batch = np.stack([lin.residual, 2.0 * lin.residual, -lin.residual], axis=2)
    none, batched = blocks.segment_products(jac, lin.weight, batch, STARTS, hessian=False)
    assert none is None and batched.shape == (4, 8, 3)
    np.testing.assert_allclose(batched, gradient[:, :, None] * np.array([1.0, 2.0, -1.0]), rtol=1e-12, atol=1e-12)


def test_normal_blocks_split_states_and_parameters(lin):
    hss, hsp, hpp, gs, gp = blocks.normal_blocks(lin, STARTS)
    hessian, gradient = blocks.segment_products(lin.joint_jacobian(), lin.weight, lin.residual, STARTS)
    np.testing.assert_array_equal(hss, hessian[:, :6, :6])
    np.testing.assert_array_equal(hsp, hessian[:, :6, 6:])
    np.testing.assert_array_equal(hpp, hessian[:, 6:, 6:])
    np.testing.assert_array_equal(gs, gradient[:, :6])
    np.testing.assert_array_equal(gp, gradient[:, 6:])


def test_damped_inverse_adds_marquardt_damping_and_a_floor(lin):
    hss = blocks.normal_blocks(lin, STARTS)[0][[0, 2, 3]]
    for damping in (0.0, 0.5):
        got = blocks.damped_inverse(hss, damping)
        for s in range(3):
            diag = np.diag(hss[s])
            damped = hss[s] + np.diag(damping * diag + 1e-12 * diag.max())
            np.testing.assert_allclose(got[s] @ damped, np.eye(6), atol=1e-9)
    # a state nothing pins (a zero row and column) gets the floor, not a singular matrix
    blind = hss[:1].copy()
    blind[0, 5, :] = blind[0, :, 5] = 0.0
    assert np.all(np.isfinite(blocks.damped_inverse(blind, 0.0)))
