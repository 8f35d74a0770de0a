"""The block algebra of multiple shooting: sums and normal-equation blocks per segment.

Rows (one per described frame, three residual components each) are grouped by segment, each
segment with its own 6-component state; the fit (:mod:`dice_sweep.measured.fit`), the reduced
problem of the loop (:mod:`dice_sweep.measured.reduced`) and the forecast's flight states
(:mod:`dice_sweep.measured.forecast`) all work on per-segment blocks of J^T W J and J^T W r,
so a step costs a product per segment whatever the number of tracks.
"""

from dataclasses import dataclass

import numpy as np

STATE = 6  # components of a segment's state (x, y, phi, vx, vy, omega)


@dataclass
class Linearisation:
    """Jacobians and weights of a fit at its solution (for intervals and cross-validation)."""

    residual: np.ndarray  # (rows, 3)
    weight: np.ndarray  # (rows,)
    jac_params: np.ndarray  # (rows, 3, p)
    jac_states: np.ndarray  # (rows, 3, 6)

    def joint_jacobian(self):
        """(rows, 3, 6 + p): the state columns first, then the parameters'."""
        return np.concatenate([self.jac_states, self.jac_params], axis=2)


def segment_sums(values, starts):
    """Sums over each segment's rows of ``values`` (rows, ...) -> (segments, ...).

    Parameters
    ----------
    values : numpy.ndarray
        (rows, ...) per-row values.
    starts : numpy.ndarray
        Row offsets of the segments and the end (segments + 1,); a segment may be empty.
    """
    if values.shape[0] == 0:
        return np.zeros((len(starts) - 1,) + values.shape[1:])
    sums = np.add.reduceat(values, starts[:-1], axis=0)
    sums[starts[:-1] == starts[1:]] = 0.0  # empty segments (reduceat repeats the next row)
    return sums


def segment_products(jac, weight, residual, starts, hessian=True):
    """Per segment, J^T W J (segments, q, q; None unless ``hessian``) and J^T W r (segments, q)
    or, for a batch of residuals (rows, 3, S), (segments, q, S); ``jac`` is (rows, 3, q)."""
    q = jac.shape[2]
    flat = jac.reshape(-1, q)  # one row per pose component
    weighted = (jac * weight[:, None, None]).reshape(-1, q)
    tail = residual.shape[2:]
    residual = residual.reshape(flat.shape[0], -1)
    segments = len(starts) - 1
    products = np.zeros((segments, q, q)) if hessian else None
    gradient = np.zeros((segments, q, residual.shape[1]))
    # a product per segment: 10x faster than a per-row einsum and reduceat (46 ms -> 5 ms on
    # the 1800 flights of the real drops, scripts/bench_measured.py)
    for s in range(segments):
        a, b = 3 * starts[s], 3 * starts[s + 1]
        if hessian:
            products[s] = weighted[a:b].T @ flat[a:b]
        gradient[s] = weighted[a:b].T @ residual[a:b]
    return products, gradient.reshape((segments, q) + tail)


def normal_blocks(lin, starts):
    """Per-segment blocks of the weighted normal equations of a :class:`Linearisation`:
    (hss, hsp, hpp, gs, gp), s the segment's state and p the parameters."""
    hessian, gradient = segment_products(lin.joint_jacobian(), lin.weight, lin.residual, starts)
    return (hessian[:, :STATE, :STATE], hessian[:, :STATE, STATE:], hessian[:, STATE:, STATE:],
            gradient[:, :STATE], gradient[:, STATE:])


def damped_inverse(hss, damping):
    """Inverse of each segment's state block with Marquardt damping (and a floor for states
    that the frames do not pin, e.g. a spin nothing depends on)."""
    diag = np.einsum("sii->si", hss)
    floor = 1e-12 * np.maximum(diag.max(axis=1, keepdims=True), 1e-30)
    damped = hss + np.einsum("si,ij->sij", damping * diag + floor, np.eye(STATE))
    return np.linalg.inv(damped)
