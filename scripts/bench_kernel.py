"""Rolls per second of the batch kernel on one core (issue 2's report).

Table I die (n = 4, R = 1.9/sqrt(2) cm, beta_normal = 0.2, beta_tangential = -0.35) over a
grid of y0 in [0.02, 0.30] m by omega0 in [0, 60] rad/s (cell centres), event integrator
unless --method says otherwise. Public API only.

    python scripts/bench_kernel.py [--num 64] [--repeat 5] [--config configs/table1.toml]
"""

import argparse
import time

import numpy as np

from dice_sweep.config import load_config
from dice_sweep.physics import COUNT_COLUMNS, pack_params, roll_batch


def grid_states(cfg, num):
    omega = (np.arange(num) + 0.5) * 60.0 / num
    height = 0.02 + (np.arange(num) + 0.5) * 0.28 / num
    w, h = np.meshgrid(omega, height)
    states = np.zeros((num * num, 6))
    states[:, 0] = cfg.initial.x0
    states[:, 2] = cfg.initial.phi0
    states[:, 3] = cfg.initial.vx0
    states[:, 4] = cfg.initial.vy0
    states[:, 1] = h.ravel()
    states[:, 5] = w.ravel()
    return states


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--config", default="configs/table1.toml")
    parser.add_argument("--num", type=int, default=64)
    parser.add_argument("--repeat", type=int, default=5)
    parser.add_argument("--set", action="append", default=[], dest="overrides")
    args = parser.parse_args()
    cfg = load_config(args.config, args.overrides)
    fpar, ipar = pack_params(cfg)
    states = grid_states(cfg, args.num)
    n = states.shape[0]
    outcome = np.empty(n, np.int8)
    status = np.empty(n, np.uint8)
    counts = np.empty((n, len(COUNT_COLUMNS)), np.int32)
    t_decided = np.empty(n)
    t0 = time.perf_counter()
    roll_batch(fpar, ipar, states[:1], outcome[:1], status[:1], counts[:1], t_decided[:1])
    load_seconds = time.perf_counter() - t0
    best = float("inf")
    for _ in range(args.repeat):
        t0 = time.perf_counter()
        roll_batch(fpar, ipar, states, outcome, status, counts, t_decided)
        best = min(best, time.perf_counter() - t0)
    impacts = counts[:, 0].mean()
    print(f"grid {args.num} x {args.num}, {cfg.integrator.method} integrator, model {cfg.contact.model}")
    print(f"first call (compile or cache load): {load_seconds:.2f} s")
    print(f"rolls/s (one core, best of {args.repeat}): {n / best:,.0f}")
    print(f"impacts per roll: {impacts:.2f}; ns per impact: {best / counts[:, 0].sum() * 1e9:.0f}")
    for name, column in zip(COUNT_COLUMNS[1:], counts.T[1:]):
        print(f"  {name} per roll: {column.mean():.3f}")
    print(f"undecided: {np.mean(outcome < 0):.4%}")


if __name__ == "__main__":
    main()
