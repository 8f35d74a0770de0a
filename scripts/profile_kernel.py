"""Where a roll's time goes in the event kernel (paper law, no drag): a breakdown per roll.

Three cases: fig08's config at 128 x 128, the Table I die at 64 x 64 (scripts/bench_kernel.py's
grid, fig08's ranges) and fig11's pentagon thrown sideways on fig11's own grid (vx0 against y0)
at 64 x 64, the case of change 4 below. For each case, on one core, these parts are timed:

* batch: ``roll_batch`` on the whole grid (the public API);
* contact search: the drag-free search (``search_free``, what ``next_contact`` runs without
  drag) replayed from every recorded start of a flight;
* impact law: ``resolve_impact`` replayed on every recorded pre-impact state (the contact
  states the search found and the states at the end of pivots that land a corner);
* outcome checks: what the roll loop does with a state after each impact (``_flat_side`` on
  table impacts, ``specific_energy``, ``decided_side``);
* pivots: ``pivot_next`` replayed from every recorded closed-form pivot;
* fixed overhead: ``roll_batch`` on dice lying flat at rest, decided before any event (the
  per-roll allocation and set-up, one outcome check, no search or impact).

Times are CPU times of the process (``time.process_time``; on a machine shared with other
jobs, wall time also counts the time the process waits for a core), the best of --repeat
rounds in which every part runs once in turn, so that all parts see the same load.

The replays run the kernel's own functions on the states recorded by ``roll_one`` (every
segment's start state is recorded); each replay loop is a numba function of this script.
The parts are timed separately, so they need not add up exactly to the batch; "rest" is the
batch minus their sum (the roll loop's own bookkeeping and the records).

Counts come from the same replays: search steps per contact search (the number of
conservative advancement steps, counted by a copy of the drag-free search loop built on the
kernel's ``_scan``, the loop that tests/physics/test_flight.py shows the kernel's search
matches bit for bit, with that scan written out in the test), split into steps taken while the centre of mass is farther than
rho_max (1 + 1e-6) from the table (one bound, no trigonometry) and steps over the corners.
The replays carry their own loop overhead, which is why "rest" can come out negative.

Whether a search step is bound by the latency of its chain (each step's length is needed
before the next angle) or by its work: the recorded flights are searched again with the
kernel's one-step function ``flight._scan``, 1, 2 or 4 searches at a time, one step of each
in turn (``replay_interleaved``); a CPU waiting on one chain could run the others' steps
meanwhile. Beside it, the latency of the chain's longest links, timed as chains of their
own (``chain_sincos``, ``chain_sqrt_div``).

    python scripts/profile_kernel.py [--repeat 7] [--write]
    python scripts/profile_kernel.py --config configs/fig09.toml --num 24 [--repeat 3]   # one config, printed only

``--write`` regenerates docs/dev/profile.md (the text around the tables is in this script).
"""

import argparse
import math
import sys
import time
from pathlib import Path

import numba
import numpy as np

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT / "scripts"))

from bench_kernel import grid_states  # noqa: E402

from dice_sweep.config import load_config  # noqa: E402
from dice_sweep.physics import COUNT_COLUMNS, pack_params, roll_batch  # noqa: E402
from dice_sweep.physics import flight, impact, kernel, outcome, pivot  # noqa: E402
from dice_sweep.physics.params import FP_COM_X, FP_COM_Y, FP_G, FP_RHO_MAX, FP_WALL, IP_N  # noqa: E402
from dice_sweep.mapper import initial_states  # noqa: E402
from dice_sweep.sweep import axis_values  # noqa: E402

CASES = (
    ("fig08, 128 x 128", "configs/fig08.toml", 128),
    ("Table I, 64 x 64", "configs/table1.toml", 64),
    ("fig11, 64 x 64", "configs/fig11.toml", 64),
)
LANE_WIDTHS = (1, 2, 4)  # searches interleaved step by step in replay_interleaved
OWN_GRID = {"configs/fig11.toml"}  # rolled on the config's own grid (vx0 against y0), not fig08's ranges


def case_states(cfg, config, num):
    """The rolls of a case: fig08's ranges (bench_kernel's grid) or the config's own grid."""
    if config not in OWN_GRID:
        return grid_states(cfg, num)
    own = load_config(ROOT / config, [f"grid.x.num={num}", f"grid.y.num={num}"])
    return initial_states(own, axis_values(own.grid.x), axis_values(own.grid.y))


def tolerances(fpar):
    """(tol, min_step, contact_speed, stick_speed) exactly as ``_roll_event`` derives them."""
    scale = fpar[FP_RHO_MAX]
    g = fpar[FP_G]
    return (
        kernel.GAP_TOL * scale,
        kernel.MIN_STEP * math.sqrt(scale / g),
        kernel.CONTACT_SPEED * math.sqrt(g * scale),
        math.sqrt(2.0 * g * scale * kernel.STICK_HEIGHT),
    )


def search_turn(fpar, ipar):
    """The ``turn`` of ``flight._scan`` that gives ``search_free``'s steps: its tighter bound on a
    fair die of flight.NEAR_MIN_SIDES or more without walls, else none (-1)."""
    fair = fpar[FP_COM_X] == 0.0 and fpar[FP_COM_Y] == 0.0
    return flight.NEAR_TURN if ipar[IP_N] >= flight.NEAR_MIN_SIDES and fair and math.isinf(fpar[FP_WALL]) else -1.0


@numba.njit
def count_search_steps(s0, fpar, ipar, tau_max, tol, min_step, contact_speed, turn, hit, out):
    """The drag-free search loop of ``next_contact``, counting its steps.

    Returns (tau, steps, far steps); far steps are those where the centre of mass was still
    farther than rho_max (1 + 1e-6) from every surface (one bound, no corner visited).
    """
    n = ipar[IP_N]
    g = fpar[FP_G]
    n_surf = 1 if math.isinf(fpar[FP_WALL]) else 3
    rho_max = fpar[FP_RHO_MAX]
    for i in range(6):
        out[i] = s0[i]
    tau = 0.0
    far = 0
    for it in range(flight.MAX_SEARCH_STEPS):
        near = False
        for surf in range(n_surf):
            nx, ny, d = flight.surface_frame(surf, fpar[FP_WALL])
            if not d + nx * out[0] + ny * out[1] - rho_max > 1e-6 * rho_max:
                near = True
        if not near:
            far += 1
        step = flight._scan(out, fpar, n, n_surf, g, 0.0, tol, min_step, contact_speed, turn, hit)
        if step < 0.0:
            return tau, it + 1, far
        if tau + step > tau_max:
            return flight.NO_CONTACT, it + 1, far
        tau += step
        flight.flight_state(s0, tau, g, out)
    return flight.STALLED, flight.MAX_SEARCH_STEPS, far


@numba.njit
def replay_search(starts, fpar, ipar, t_left, tol, min_step, contact_speed, pre, hits):
    """The contact search from every flight start, called as ``_roll_event`` calls it
    (``search_free`` without drag); contact states into ``pre``, (surf, corner) into ``hits``
    (-1 where no contact); returns the number of contacts."""
    n = ipar[IP_N]
    n_surf = 1 if math.isinf(fpar[FP_WALL]) else 3
    found = 0
    for i in range(starts.shape[0]):
        s = starts[i]
        tau, surf, corner, x, y, phi, vy, _, _, _, _, _, _ = flight.search_free(
            fpar, n, n_surf, t_left[i], tol, min_step, contact_speed, s[0], s[1], s[2], s[3], s[4], s[5], math.nan, 0.0, 0.0,
            math.nan, 0.0, 0.0
        )
        pre[i, 0] = x
        pre[i, 1] = y
        pre[i, 2] = phi
        pre[i, 3] = s[3]
        pre[i, 4] = vy
        pre[i, 5] = s[5]
        if tau >= 0.0:
            hits[i, 0] = surf
            hits[i, 1] = corner
            found += 1
        else:
            hits[i, 0] = -1
    return found


@numba.njit
def replay_counts(starts, fpar, ipar, t_left, tol, min_step, contact_speed, turn, steps, far):
    hit = np.zeros(2, np.int64)
    out = np.empty(6)
    for i in range(starts.shape[0]):
        _, steps[i], far[i] = count_search_steps(starts[i], fpar, ipar, t_left[i], tol, min_step, contact_speed, turn, hit, out)


@numba.njit
def replay_interleaved(starts, fpar, ipar, t_left, tol, min_step, contact_speed, turn, width, taus):
    """The search from every flight start, ``width`` searches at a time, one step of each in
    turn: the kernel's own step (``flight._scan``) then ``flight.flight_state``, a lane taking
    the next start when its search ends. The steps of different searches are independent, so
    if a step were bound by the latency of its chain, width 2 would run two chains at once."""
    n = ipar[IP_N]
    g = fpar[FP_G]
    n_surf = 1 if math.isinf(fpar[FP_WALL]) else 3
    hit = np.zeros(2, np.int64)
    cur = np.empty((width, 6))
    tau = np.zeros(width)
    lane_start = np.full(width, -1, np.int64)
    steps_left = np.zeros(width, np.int64)
    queued = 0
    active = 0
    for lane in range(min(width, starts.shape[0])):
        lane_start[lane] = queued
        cur[lane] = starts[queued]
        steps_left[lane] = flight.MAX_SEARCH_STEPS
        queued += 1
        active += 1
    while active > 0:
        for lane in range(width):
            i = lane_start[lane]
            if i < 0:
                continue
            step = flight._scan(cur[lane], fpar, n, n_surf, g, 0.0, tol, min_step, contact_speed, turn, hit)
            steps_left[lane] -= 1
            if step >= 0.0 and tau[lane] + step <= t_left[i] and steps_left[lane] > 0:
                tau[lane] += step
                flight.flight_state(starts[i], tau[lane], g, cur[lane])
                continue
            taus[i] = tau[lane] if step < 0.0 else flight.NO_CONTACT
            if queued < starts.shape[0]:
                lane_start[lane] = queued
                cur[lane] = starts[queued]
                tau[lane] = 0.0
                steps_left[lane] = flight.MAX_SEARCH_STEPS
                queued += 1
            else:
                lane_start[lane] = -1
                active -= 1


@numba.njit
def chain_sincos(x, m):
    """m dependent sines and cosines of one angle (the search's trigonometry, in a chain)."""
    for _ in range(m):
        x = 0.5 + 1e-3 * (math.cos(x) + math.sin(x))
    return x


@numba.njit
def chain_sqrt_div(x, m):
    """m dependent square roots each followed by a division (one corner's safe step)."""
    for _ in range(m):
        x = 1.0 + 1.0 / (math.sqrt(x) + 3.0)
    return x


def chain_latency(fn, repeat, m=2_000_000):
    """ns per link of a chain microbenchmark, best of ``repeat``."""
    fn(0.3, 10)
    best = math.inf
    for _ in range(repeat):
        t0 = time.process_time()
        fn(0.3, m)
        best = min(best, time.process_time() - t0)
    return best * 1e9 / m


@numba.njit
def replay_impacts(pre, hits, fpar, ipar, post, u_n):
    counts = np.zeros(5, np.int32)
    for i in range(pre.shape[0]):
        for j in range(6):
            post[i, j] = pre[i, j]
        u_n[i] = impact.resolve_impact(post[i], fpar, ipar, hits[i, 0], hits[i, 1], counts)
    return counts


@numba.njit
def replay_outcome(post, hits, u_n, fpar, n, stick_speed):
    """The checks ``_roll_event`` makes after every impact, as it makes them (the replayed
    impacts are single contacts: the corner that hit is the contact)."""
    acc = 0.0
    decide_bound = outcome.decision_bound(fpar)
    for i in range(post.shape[0]):
        if hits[i, 0] == flight.SURF_TABLE and not abs(u_n[i]) > stick_speed:
            acc += kernel._flat_side(post[i], fpar, n, stick_speed, hits[i, 1], math.nan, 0.0)
        energy = impact.specific_energy(post[i], fpar)
        acc += energy
        if energy < decide_bound:
            acc += outcome.decided_side(post[i], fpar, n)
    return acc


@numba.njit
def replay_pivots(pivots, fpar, n, kinds, pre, hits):
    """The closed-form pivot from every recorded one (columns: corner, px, chi, state), as the
    roll loop makes it (flat angles from the batch's table); the state where each landing
    pivot puts its next corner down goes to ``pre``."""
    out = np.zeros(5)
    hit = np.zeros(2, np.int64)
    flats = np.full((n, 3), math.nan)  # kernel._flat_table: NaN until a corner first pivots
    for i in range(pivots.shape[0]):
        corner = int(pivots[i, 0])
        chi_right, chi_left = kernel._flat_pair(fpar, n, corner, flats)
        kinds[i] = pivot.pivot_next_flat(fpar, n, corner, pivots[i, 1], pivots[i, 2], pivots[i, 8], chi_right, chi_left,
                                         out, hit)
        for j in range(6):
            pre[i, j] = pivots[i, 3 + j]
        kernel._set_pivot_state(pre[i], fpar, pivots[i, 1] + out[3], out[0], out[1], corner, flats[corner, 2])
        hits[i, 0] = hit[0]
        hits[i, 1] = hit[1]


def record_rolls(fpar, ipar, states):
    """Flight starts (with the time left) and closed-form pivots of every roll."""
    t_max = fpar[kernel.FP_TMAX]
    flights, t_left, pivots = [], [], []
    rec = np.zeros((4096, kernel.REC_WIDTH))
    counts = np.zeros(len(COUNT_COLUMNS), np.int32)
    for state in states:
        n_rec = kernel.roll_one(fpar, ipar, state, rec, counts)[4]
        for row in rec[:n_rec]:
            seg_state = row[kernel.REC_STATE:kernel.REC_STATE + 6]
            if row[kernel.REC_KIND] == kernel.SEG_FLIGHT:
                flights.append(seg_state.copy())
                t_left.append(t_max - row[kernel.REC_T])
            elif row[kernel.REC_KIND] == kernel.SEG_PIVOT:
                pivots.append(np.concatenate(([row[kernel.REC_CORNER], row[kernel.REC_PX], row[kernel.REC_CHI]], seg_state)))
    return np.array(flights), np.array(t_left), np.array(pivots).reshape(-1, 9)


def profile_case(config, num, repeat):
    cfg = load_config(ROOT / config, [])
    fpar, ipar = pack_params(cfg)
    n = ipar[IP_N]
    states = case_states(cfg, config, num)
    rolls = states.shape[0]
    tol, min_step, contact_speed, stick_speed = tolerances(fpar)
    out_o = np.empty(rolls, np.int8)
    out_s = np.empty(rolls, np.uint8)
    out_c = np.empty((rolls, len(COUNT_COLUMNS)), np.int32)
    out_t = np.empty(rolls)
    roll_batch(fpar, ipar, states, out_o, out_s, out_c, out_t)
    impacts_per_roll = out_c[:, 0].mean()
    pivots_per_roll = out_c[:, 3].mean()

    # the inputs of every part, recorded once (each replay below also runs once here)
    flights, t_left, pivots = record_rolls(fpar, ipar, states)
    pre = np.empty_like(flights)
    hits = np.empty((len(flights), 2), np.int64)
    replay_search(flights, fpar, ipar, t_left, tol, min_step, contact_speed, pre, hits)
    steps = np.empty(len(flights), np.int64)
    far = np.empty(len(flights), np.int64)
    turn = search_turn(fpar, ipar)
    replay_counts(flights, fpar, ipar, t_left, tol, min_step, contact_speed, turn, steps, far)
    kinds = np.empty(len(pivots), np.int64)
    piv_pre = np.empty((len(pivots), 6))
    piv_hits = np.empty((len(pivots), 2), np.int64)
    replay_pivots(pivots, fpar, n, kinds, piv_pre, piv_hits)
    landed = kinds == pivot.PIVOT_FLAT
    imp_pre = np.ascontiguousarray(np.concatenate((pre[hits[:, 0] >= 0], piv_pre[landed])))
    imp_hits = np.ascontiguousarray(np.concatenate((hits[hits[:, 0] >= 0], piv_hits[landed])))
    post = np.empty_like(imp_pre)
    u_n = np.empty(len(imp_pre))
    replay_impacts(imp_pre, imp_hits, fpar, ipar, post, u_n)
    rest = np.zeros((rolls, 6))
    rest[:, 1] = outcome.rest_height(fpar, n, n - 1)
    rest[:, 2] = -0.5 * math.pi + math.pi / n  # side n-1 flat on the table

    # every part timed in turn, repeat rounds, so that all see the same machine load
    timed = {
        "batch": (roll_batch, (fpar, ipar, states, out_o, out_s, out_c, out_t)),
        "contact search": (replay_search, (flights, fpar, ipar, t_left, tol, min_step, contact_speed, pre, hits)),
        "impact law": (replay_impacts, (imp_pre, imp_hits, fpar, ipar, post, u_n)),
        "outcome checks": (replay_outcome, (post, imp_hits, u_n, fpar, n, stick_speed)),
        "pivots (closed form)": (replay_pivots, (pivots, fpar, n, kinds, piv_pre, piv_hits)),
        "fixed overhead": (roll_batch, (fpar, ipar, rest, out_o, out_s, out_c, out_t)),
    }
    taus = {width: np.empty(len(flights)) for width in LANE_WIDTHS}
    for width, out in taus.items():
        replay_interleaved(flights, fpar, ipar, t_left, tol, min_step, contact_speed, turn, width, out)
        if not np.array_equal(out, taus[LANE_WIDTHS[0]]):
            raise AssertionError(f"interleaving {width} searches changed their contact times")
    for width, out in taus.items():
        timed[("lanes", width)] = (replay_interleaved, (flights, fpar, ipar, t_left, tol, min_step, contact_speed, turn, width, out))
    best = {name: math.inf for name in timed}
    for _ in range(repeat):
        for name, (fn, args) in timed.items():
            t0 = time.process_time()
            fn(*args)
            best[name] = min(best[name], time.process_time() - t0)
    t_batch = best.pop("batch")
    lanes = {width: best.pop(("lanes", width)) * 1e9 / len(flights) for width in LANE_WIDTHS}

    ns = 1e9 / rolls
    parts = {name: seconds * ns for name, seconds in best.items()}
    return {
        "rolls": rolls,
        "batch": t_batch * ns,
        "rolls_per_s": rolls / t_batch,
        "lanes": lanes,
        "parts": parts,
        "impacts": impacts_per_roll,
        "replayed_impacts": len(imp_pre) / rolls,
        "pivots": pivots_per_roll,
        "flights": len(flights) / rolls,
        "steps": steps.mean(),
        "far_steps": far.mean(),
        "steps_p90": float(np.percentile(steps, 90)),
        "steps_max": int(steps.max()),
        "pivot_kinds": {name: int(np.count_nonzero(kinds == code)) / rolls for name, code in (
            ("lift-off", pivot.PIVOT_LIFTOFF), ("next corner", pivot.PIVOT_FLAT))},
    }


def markdown(results, repeat, names=None):
    lines = [f"Best of {repeat} runs per part, one core, ns per roll.", ""]
    names = names or [name for name, _, _ in CASES]
    lines.append("| part | " + " | ".join(names) + " |")
    lines.append("|---|" + "---:|" * len(names))
    lines.append("| whole batch (`roll_batch`) | " + " | ".join(f"{r['batch']:,.0f}" for r in results) + " |")
    for part in results[0]["parts"]:
        cells = [f"{r['parts'][part]:,.0f} ({r['parts'][part] / r['batch']:.0%})" for r in results]
        lines.append(f"| {part} | " + " | ".join(cells) + " |")
    cells = [f"{r['batch'] - sum(r['parts'].values()):,.0f}" for r in results]
    lines.append("| rest (batch minus the parts) | " + " | ".join(cells) + " |")
    lines.append("| rolls/s | " + " | ".join(f"{r['rolls_per_s']:,.0f}" for r in results) + " |")
    lines.append("")
    lines.append("| count per roll | " + " | ".join(names) + " |")
    lines.append("|---|" + "---:|" * len(names))
    rows = (
        ("impacts", lambda r: f"{r['impacts']:.2f}"),
        ("impacts replayed (flights + landing pivots)", lambda r: f"{r['replayed_impacts']:.2f}"),
        ("flights (contact searches)", lambda r: f"{r['flights']:.2f}"),
        ("closed-form pivots", lambda r: f"{r['pivots']:.3f}"),
        ("  ending in lift-off", lambda r: f"{r['pivot_kinds']['lift-off']:.3f}"),
        ("  ending on the next corner", lambda r: f"{r['pivot_kinds']['next corner']:.3f}"),
        ("search steps per contact search (mean)", lambda r: f"{r['steps']:.2f}"),
        ("  of which far from the table (no corner visited)", lambda r: f"{r['far_steps']:.2f}"),
        ("  90th percentile / max", lambda r: f"{r['steps_p90']:.0f} / {r['steps_max']}"),
    )
    for label, fmt in rows:
        lines.append(f"| {label} | " + " | ".join(fmt(r) for r in results) + " |")
    return "\n".join(lines)


DOC_HEAD = """# Where a roll's time goes (event kernel, paper law)

Generated by `python scripts/profile_kernel.py --write`; do not edit the tables by hand.
Timings are from this project's shared 2-core machine and vary by 10-30 % between runs;
compare parts within one run.

## Method

{method}
"""


def search_table(results, chains):
    """The search step: its cost, the latency of its longest operations, and interleaving."""
    names = [name for name, _, _ in CASES]
    lines = [
        (
            "The search step (ns). Interleaved: the kernel's step (`flight._scan`, three array "
            "arguments, so dearer than `search_free`'s own loop) driven over 1, 2 or 4 searches "
            "in turn by this script's `replay_interleaved`; contact times identical at every "
            "width (checked by the script)."
        ),
        "",
        "| | " + " | ".join(names) + " |",
        "|---|" + "---:|" * len(names),
    ]
    rows = [("per search step (`search_free`, the kernel)", lambda r: r["parts"]["contact search"] / (r["flights"] * r["steps"]))]
    rows += [("per search, `search_free`", lambda r: r["parts"]["contact search"] / r["flights"])]
    for width in LANE_WIDTHS:
        label = "per search, `_scan`, one search at a time" if width == 1 else f"per search, `_scan`, {width} interleaved"
        rows.append((label, lambda r, w=width: r["lanes"][w]))
    for label, value in rows:
        lines.append(f"| {label} | " + " | ".join(f"{value(r):,.0f}" for r in results) + " |")
    lines += [
        "",
        (
            f"Chains on this machine (best of the rounds, ns per link): a sine and cosine of the "
            f"previous result {chains['sincos']:.1f}; a square root then a division "
            f"{chains['sqrt_div']:.1f} (`chain_sincos`, `chain_sqrt_div`)."
        ),
    ]
    return "\n".join(lines)


def derived(results):
    """Figures computed from the tables: cost per search step and the impacts' share."""
    lines = []
    for (name, _, _), r in zip(CASES, results):
        per_step = r["parts"]["contact search"] / (r["flights"] * r["steps"])
        share = r["parts"]["impact law"] / r["batch"]
        lines.append(
            f"- {name}: {per_step:.0f} ns per search step; the impact law is {share:.0%} of a roll "
            f"({r['batch'] / r['impacts']:,.0f} ns of batch time per impact, "
            f"{r['parts']['impact law'] / r['impacts']:,.0f} ns of it in the law itself)."
        )
    for (name, _, _), r in zip(CASES, results):
        per_step = r["parts"]["contact search"] / (r["flights"] * r["steps"])
        oracle = r["batch"] - r["parts"]["contact search"] + r["flights"] * per_step
        lines.append(
            f"- {name}, bound: a search that found every contact in one step would leave a roll "
            f"at {oracle:,.0f} ns, {oracle / r['parts']['impact law']:.1f} times the impact law."
        )
    return "\n".join(lines)


# Findings and changes (kept here so that --write reproduces the whole page).
NOTES = """
## Findings

- The contact search is most of a roll: about five steps per contact, each one sine and
  cosine, then for each corner a gap, its rate, a square root and a division, and the
  branches that pick the step. The steps form one chain (each step's length is needed
  before the next angle), but the step is not bound by that chain's latency: the chain's
  longest links (a sine and cosine, then one corner's square root and division; the chain
  table above) are about half of a step, and running 2 or 4 independent searches step by
  step in turn, which would overlap their chains, made no search faster (slower, with the
  lanes' own bookkeeping; the table above). A step costs its work. The number of steps is set by the conservative
  advancement itself (the quadratic lower bound and the Newton steps from the safe side);
  changing it changes the contact times in their last bits.
- Root finding, then, is most of the roll, and cannot be removed: even a search that found
  each contact in one step would leave a roll at several times the impact law (the "bound"
  lines above), because the outcome checks, the pivots and the fixed set-up together
  already cost more than the law.
- Reference counting. An array argument of a numba function costs a call to ``NRT_incref``
  and one to ``NRT_decref`` (atomic) per call, unless numba's pruning pass removes them,
  which it did here only in functions with no call or division that can raise (seen in the
  generated assembly; a 5-array function took about 30 ns per call against 7 ns without).
  The search made such a call per step (``_scan``, three arrays) below one per flight
  (``next_contact``, five arrays).
- The outcome checks after each impact cost more than the impact law: ``decided_side`` took
  the side below the centre of mass (a float modulo) and both corners' geometry (two
  ``atan2`` calls, their angles unused) even when the energy was far above any barrier, and
  ``_flat_side`` took the side below on every table impact.
- Per roll, ``roll_one`` and ``_roll_event`` allocated four small arrays.
- A corner touching a surface without approaching faster than contact_speed was passed by
  steps of min_step (3.7e-11 s for this die). On fig11 at 64 x 64 one flight took 162,122
  such steps, 42 % of all the grid's search steps: after an impact the pentagon's bottom
  corner rested on the table while it spun at 27 rad/s, where rho omega^2 (9.84 m/s^2)
  nearly cancels g, so the corner barely accelerated into the table (found by counting
  steps per flight with this script's counting loop).

## Changes (1 to 3 and 5 bit for bit: outcome, status, counts, t_decided and the segment records)

1. The drag-free search is one loop over local variables (``flight.search_free``), called by
   the roll loop with the state as scalars; no trigonometry on steps taken while the centre
   of mass is still farther than rho_max from the table.
   ``tests/physics/test_flight.py`` checks it bit for bit against the generic scan it came
   from, written out in the test.
2. ``decided_side`` first compares the energy with g rho_max (1 - margin), never below its
   barrier, and the roll loop makes that comparison before calling it; ``_flat_side``
   counts the corners that are level and still before it looks for the side below
   (``tests/physics/test_outcome.py`` checks ``decided_side`` against the full rule).
3. ``roll_batch`` and ``sample_batch`` allocate a roll's scratch arrays once.
4. Such a touching corner (fp <= 0) now steps to where the quadratic bound could reach -tol
   / 2 (``flight._touching_step``), still within the tolerance: that flight takes 165 steps,
   and fig11's mean falls from 10.68 steps per search (this script's counting loop, same
   grid, previous commit) to the value in the table above. Results, from `dice-sweep sweep`
   before and after at the sizes named, compared with ``storage.read_sweep``: no outcome,
   status or impact count changed on fig08, fig11 (512 x 512), fig09, fig13 (256 x 256),
   fig10 (128 x 128) or the golden files (``scripts/make_golden.py --check``); t_decided
   moved in 47 of fig11's 262,144 pixels and 5 of fig13's 65,536 (the other grids: none).
   ``tests/physics/test_flight.py`` (the grazing start, and no corner ever below -tol against
   the exact gap) checks it.
5. The roll loop (``_roll_event``) and its set-up (``_roll_into``) are inlined into
   ``roll_one``, ``roll_batch`` and ``sample_batch`` (numba's ``inline="always"``): as a call
   per roll the loop took eight array arguments, a reference count up and down for each.
   Fixed overhead on fig08's grid: 194 ns per roll in this page's previous version
   (commit a1087f1, when it was in docs/), the value in the table above now. Bit for bit: no outcome, status, impact count
   or t_decided changed on fig08 and fig11 at 512 x 512, fig09 and fig13 at 256 x 256 or
   fig10 at 128 x 128 (`dice-sweep sweep` on this commit and on an unpacked archive of the
   previous one) or in the golden files. A cold start compiles three copies of the loop
   instead of one: ``NUMBA_CACHE_DIR=<empty directory> dice-sweep roll configs/table1.toml``
   took 48.6 s against 47.2 s before, one run each.

Tried and dropped (no gain above the noise of interleaved runs): folding the table's normal
(0, 1) into the search's expressions; passing the contact's sine and cosine on to
``_flat_side``; ``error_model="numpy"`` (it lets numba prune the reference counts of leaf
functions only, and would turn a division by zero into a NaN instead of an error); a
third-order bound (the exact second derivative of the gap at the step's start, its third
bounded by rho |omega|^3): 24 % fewer search steps on fig08 (5.29 to 4.05, counted by
replaying the recorded flights on that commit) but each step dearer by about as much, so
rolls/s did not change (-2 %, within the noise of scripts/bench_kernel.py; commit cf0054e
and its revert 5d37201); a branch-free safe step (both of its formulas computed, one kept;
an uncommitted timing on the recorded flights, bit for bit the same contacts); skipping the
square root and division of a corner whose bound is still clearly above zero at the
shortest step so far (its root then lies beyond it: the same steps bit for bit), with the
corners visited from the last step's shortest: 2 to 7 % off a search in uncommitted
timings of the recorded flights, within their noise, for a proof obligation in the
kernel.

## Left

- Cheaper steps rather than fewer: the sine and cosine are a good part of a step's work.
  Near a contact the angle per step is tiny, so the previous sine and cosine could be
  rotated by a short polynomial instead; that moves contact times by round-off, so every
  result in its last bits (and some chaotic pixels): a change of results, to be made on
  purpose.
- Newton on the gap itself from the bound's root: at low spin the lowest corner's gap is
  concave, so it would need a bracket.
- ``pivot_next`` recomputed the flat angles (``atan2`` calls) on every pivot; the roll loop
  now keeps them per corner for the batch (issue 33, branch imp33). The corner's geometry
  (``corner_geometry``) is still read on every pivot.
"""


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeat", type=int, default=7)
    parser.add_argument("--write", action="store_true", help="write docs/dev/profile.md")
    parser.add_argument("--config", default=None,
                        help="profile only this config (fig08's ranges unless it is fig11) and print the breakdown; no --write")
    parser.add_argument("--num", type=int, default=32, help="cells per axis with --config")
    args = parser.parse_args()
    if args.config:
        result = profile_case(args.config, args.num, args.repeat)
        print(markdown([result], args.repeat, [f"{args.config}, {args.num} x {args.num}"]))
        return
    results = []
    for name, config, num in CASES:
        print(f"profiling {name} ...", file=sys.stderr)
        results.append(profile_case(config, num, args.repeat))
    chains = {"sincos": chain_latency(chain_sincos, args.repeat), "sqrt_div": chain_latency(chain_sqrt_div, args.repeat)}
    table = markdown(results, args.repeat)
    search = search_table(results, chains)
    print(table)
    print(derived(results))
    print(search)
    if args.write:
        method = __doc__.split("\n\n", 1)[1].rsplit("\n\n    python", 1)[0]
        text = DOC_HEAD.format(method=method) + "\n## Breakdown\n\n" + table + "\n\n" + derived(results) + "\n"
        text += "\n" + search + "\n"
        text += NOTES
        (ROOT / "docs" / "dev" / "profile.md").write_text(text)


if __name__ == "__main__":
    main()
