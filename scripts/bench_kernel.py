"""Rolls per second of the batch kernel on one core (issue 2's report, issue 33's cases).

Table I die (n = 4, R = 1.9/sqrt(2) cm, beta_normal = 0.2, beta_tangential = -0.35) over a
grid of y0 in [0.02, 0.30] m by omega0 in [0, 60] rad/s (cell centres), event integrator
unless --method says otherwise. Three cases on that grid, timed in interleaved rounds so that
all see the same machine load: the paper law; the rigid law of the measured drops
(``contact.model=rigid``, ``contact.friction=0.5``, ``contact.beta_tangential=0``); the
paper law with n = 20 (``die.sides=20``, fig09's die). Times are CPU times of this process
(``time.process_time``: on a shared machine wall time also counts the waits for a core).
Prints min / median / max of the rounds, the ratios of the medians to the paper law's, and the machine's load average
(``os.getloadavg``). Public API only.

    python scripts/bench_kernel.py [--num 64] [--repeat 5] [--config configs/table1.toml] [--only paper]
"""

import argparse
import os
import time

import numpy as np

from dice_sweep.config import load_config
from dice_sweep.physics import COUNT_COLUMNS, pack_params, roll_batch

RIGID = ("contact.model=rigid", "contact.friction=0.5", "contact.beta_tangential=0")
CASES = {
    "paper": (),
    "rigid": RIGID,
    "n20": ("die.sides=20",),
}
N20_GRID_SHARE = 4  # the n = 20 case rolls num / 4 cells per axis: each roll costs ~35 of a square's


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


class Case:
    """One config on the grid, with its output arrays and its timings."""

    def __init__(self, name, config, overrides, num):
        self.name = name
        self.cfg = load_config(config, [*overrides])
        self.fpar, self.ipar = pack_params(self.cfg)
        self.states = grid_states(self.cfg, num)
        self.num = num
        n = self.states.shape[0]
        self.outputs = (np.empty(n, np.int8), np.empty(n, np.uint8), np.empty((n, len(COUNT_COLUMNS)), np.int32), np.empty(n))
        self.seconds = []
        t0 = time.perf_counter()
        roll_batch(self.fpar, self.ipar, self.states[:1], *(a[:1] for a in self.outputs))
        self.load_seconds = time.perf_counter() - t0

    def run(self):
        t0 = time.process_time()
        roll_batch(self.fpar, self.ipar, self.states, *self.outputs)
        self.seconds.append(time.process_time() - t0)

    def ns_per_roll(self):
        """(min, median, max) ns per roll over the rounds."""
        per = np.array(self.seconds) * 1e9 / self.states.shape[0]
        return per.min(), float(np.median(per)), per.max()

    def report(self, reference):
        outcome, _, counts, _ = self.outputs
        lo, med, hi = self.ns_per_roll()
        rolls = self.states.shape[0]
        print(f"{self.name}: grid {self.num} x {self.num}, n = {self.cfg.die.sides}, model {self.cfg.contact.model}, "
              f"{self.cfg.integrator.method} integrator; first call (compile or cache load) {self.load_seconds:.2f} s")
        print(f"  rolls/s (one core; best / median / worst of {len(self.seconds)}): {1e9 / lo:,.0f} / {1e9 / med:,.0f} / {1e9 / hi:,.0f}")
        print(f"  ns per roll (min / median / max): {lo:,.0f} / {med:,.0f} / {hi:,.0f}")
        if reference is not None and reference is not self:
            print(f"  cost per roll / the paper law's (medians, same rounds): {med / reference.ns_per_roll()[1]:.2f}")
        impacts = counts[:, 0].sum()
        print(f"  impacts per roll: {impacts / rolls:.2f}; ns per impact (median): {med * rolls / max(impacts, 1):.0f}")
        for name, column in zip(COUNT_COLUMNS[1:], counts.T[1:]):
            print(f"    {name} per roll: {column.mean():.3f}")
        print(f"  undecided: {np.mean(outcome < 0):.4%}")


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--config", default="configs/table1.toml")
    parser.add_argument("--num", type=int, default=64)
    parser.add_argument("--repeat", type=int, default=5)
    parser.add_argument("--only", action="append", choices=sorted(CASES), help="run only these cases (repeatable)")
    parser.add_argument("--set", action="append", default=[], dest="overrides")
    args = parser.parse_args()
    names = args.only or list(CASES)
    cases = [Case(name, args.config, (*args.overrides, *CASES[name]),
                  max(args.num // N20_GRID_SHARE, 1) if name == "n20" else args.num) for name in names]
    load_before = os.getloadavg()
    for _ in range(args.repeat):
        for case in cases:
            case.run()
    load_after = os.getloadavg()
    reference = next((case for case in cases if case.name == "paper"), None)
    for case in cases:
        case.report(reference)
    print("load average (1, 5, 15 min) before: {:.2f} {:.2f} {:.2f}; after: {:.2f} {:.2f} {:.2f} on {} cores".format(
        *load_before, *load_after, os.cpu_count()))


if __name__ == "__main__":
    main()
