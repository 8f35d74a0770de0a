"""Side-by-side speed of the kernels, a physics engine and the CLI (issue 7's benchmark).

On the same initial conditions (the fig08 grid of the Table I die):
1. the event kernel, paper and rigid models, one process;
2. the fixed_step kernel at the paper's dt = 1e-3 s;
3. pymunk (Chipmunk2D) with the same die, Newton restitution and Coulomb friction, stepped at
   1e-4 s and stopped by the same energy rule (rolls per CPU second, one core);
4. the CLI sweep of configs/fig08.toml at 1 and 2 workers (at --sweep-num, and at --long-num
   where the fixed start of a command is a few per cent of it), the rigid law of 1 (pymunk's
   physics) swept by the CLI on 2 workers at --sweep-num against pymunk's rolls/s per core
   (issue 33; ``--rigid-cli`` runs only this), and `dice-sweep roll` with an empty numba cache:
   see 5.
Prints a Markdown table; ``--write`` puts it into docs/performance.md. Public API only.
5. the cold start (issue 16): a new user's first commands and a CI job's, each a fresh process
   with an empty NUMBA_CACHE_DIR, on the engine the tool chooses and with the compile forced,
   then warm; ``--write`` puts it into docs/cold_start.md. ``--cold`` runs this part only.

    python scripts/bench.py [--num 128] [--sweep-num 1024] [--long-num 4096] [--pymunk-rolls 200] [--skip-cold] [--write]
    python scripts/bench.py --cold [--write]
    python scripts/bench.py --rigid-cli [--sweep-num 1024] [--pymunk-rolls 200]   # issue 33's rows, printed only

Every timed row gives min / median / max of its runs (the kernel rows in CPU time of the
process, the commands in wall time), and the page ends with the machine's load average
before and after (``os.getloadavg``): on a shared machine the numbers move with it.
"""

import argparse
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

from dice_sweep.config import load_config
from dice_sweep.mapper import initial_states
from dice_sweep.physics import COUNT_COLUMNS, pack_params, roll_batch
from dice_sweep.sweep import SweepJob, axis_values, run_sweep

from _docs import publish  # scripts/_docs.py: the script's folder is on sys.path

ROOT = Path(__file__).resolve().parent.parent
CLI = [sys.executable, "-m", "dice_sweep"]


def spread(values):
    """(min, median, max) of a list of numbers."""
    return min(values), float(np.median(values)), max(values)


def kernel_rate(cfg, states, repeat=3):
    """(rolls/s as (min, median, max) over ``repeat`` runs, impacts per roll) of roll_batch in
    this process; CPU time of the process (wall time on a shared machine counts the waits)."""
    fpar, ipar = pack_params(cfg)
    n = states.shape[0]
    outcome = np.empty(n, np.int8)
    status = np.empty(n, np.uint8)
    counts = np.empty((n, len(COUNT_COLUMNS)), np.int32)
    t_decided = np.empty(n)
    roll_batch(fpar, ipar, states[:2], outcome[:2], status[:2], counts[:2], t_decided[:2])  # compile/load
    rates = []
    for _ in range(repeat):
        start = time.process_time()
        roll_batch(fpar, ipar, states, outcome, status, counts, t_decided)
        rates.append(n / (time.process_time() - start))
    return spread(rates), counts[:, 0].mean()


def pymunk_rate(cfg, states, rolls, seed=0, repeat=3):
    """Rolls per CPU second of the pymunk reference die on a random subset of ``states``, best
    of ``repeat`` (one pass read 48 and 77 rolls/s in two runs on this shared machine)."""
    from dice_sweep.reference.pymunk_die import pymunk_outcomes

    chosen = states[np.random.default_rng(seed).choice(states.shape[0], size=min(rolls, states.shape[0]), replace=False)]
    best = float("inf")
    for _ in range(repeat):
        start = time.process_time()
        pymunk_outcomes(cfg, chosen)
        best = min(best, time.process_time() - start)
    return chosen.shape[0] / best


def sweep_command(config, num, out, workers, overrides=()):
    sets = [arg for override in (f"grid.x.num={num}", f"grid.y.num={num}", *overrides) for arg in ("--set", override)]
    return CLI + ["sweep", str(config), "-o", str(out), "--workers", str(workers), "--quiet", *sets]


RIGID_LAW = ("contact.model=rigid", "contact.friction=0.5", "contact.beta_tangential=0")
RIGID_CLI_WORKERS = 2


def rigid_cli_rows(num, repeat, munk, tmp):
    """Issue 33's like-for-like comparison: the rigid law (what pymunk's die does) swept by the
    CLI on fig08's grid at num x num with RIGID_CLI_WORKERS workers, in rolls per second per
    core (the rolls over the median wall time of the whole command over the workers), against
    ``munk``, pymunk's rolls per CPU second of this run. Table rows, then a sentence."""
    fig08 = ROOT / "configs" / "fig08.toml"
    times = []
    for attempt in range(repeat):
        out = tmp / f"rigid{num}-{attempt}.h5"
        times.append(timed(sweep_command(fig08, num, out, RIGID_CLI_WORKERS, RIGID_LAW)))
        out.unlink()
    walls = spread(times)
    per_core = num * num / (walls[1] * RIGID_CLI_WORKERS)
    sets = " ".join(f"--set {override}" for override in RIGID_LAW)
    rows = [f"| `dice-sweep sweep configs/fig08.toml {sets}` at {num} x {num}, {RIGID_CLI_WORKERS} workers "
            f"({repeat} runs) | {seconds(walls)} |"]
    sentence = (f"The rigid law through the CLI, like for like with pymunk's die (e 0.2, mu 0.5): {per_core:,.0f} rolls/s "
                f"per core ({num * num} rolls over the median wall time over {RIGID_CLI_WORKERS} workers) against pymunk's "
                f"{munk:,.1f} in this run: **{per_core / munk:,.0f} x**.")
    return rows, sentence


def cli_sweep_times(config, num, repeat, tmp):
    """{workers: (min, median, max) wall time} of the whole `sweep` command at num x num, 1 and
    2 workers alternating, so that both see the same machine."""
    times = {1: [], 2: []}
    for attempt in range(repeat):
        for workers in (1, 2):
            out = tmp / f"n{num}-w{workers}-{attempt}.h5"
            times[workers].append(timed(sweep_command(config, num, out, workers)))
            out.unlink()
    return {workers: spread(values) for workers, values in times.items()}


def seconds(values):
    return " / ".join(f"{value:.2f}" for value in values)


def sweep_rows(num, repeat, times):
    return [f"| `dice-sweep sweep configs/fig08.toml` at {num} x {num}, 1 worker ({repeat} runs) | {seconds(times[1])} |",
            f"| same, 2 workers | {seconds(times[2])} (speed-up of the medians **{times[1][1] / times[2][1]:.2f}**) |"]


def timed(command, env=None):
    start = time.perf_counter()
    subprocess.run(command, check=True, capture_output=True, env=env)
    return time.perf_counter() - start


COLD_REPEAT = 3  # cold runs per command (median): each compiles or probes from scratch


def cold_start_markdown(tmp: Path) -> str:
    """Wall times of first commands with an empty numba cache, chosen engine and compile forced."""
    table1 = str(ROOT / "configs" / "table1.toml")
    demo = str(ROOT / "configs" / "demo.toml")
    fig09 = str(ROOT / "configs" / "fig09.toml")
    commands = [
        ("`dice-sweep roll configs/table1.toml`", lambda out: CLI + ["roll", table1]),
        ("`dice-sweep sweep configs/demo.toml` (make demo's sweep, 128 x 128, 2 workers)",
         lambda out: CLI + ["sweep", demo, "-o", str(out), "--quiet"]),
        ("`dice-sweep sweep configs/fig09.toml` at 32 x 32 (walls, rigid law, about 140 impacts a roll)",
         lambda out: CLI + ["sweep", fig09, "-o", str(out), "--quiet", "--set", "grid.x.num=32", "--set", "grid.y.num=32"]),
    ]
    runs = 0
    load_before = os.getloadavg()[0]  # a loaded machine compiles slower: the table says how loaded

    def run(command, engine, cache):
        nonlocal runs
        runs += 1
        env = dict(os.environ, NUMBA_CACHE_DIR=str(cache))
        env.pop("DICE_SWEEP_ENGINE", None)
        if engine:
            env["DICE_SWEEP_ENGINE"] = engine
        return timed(command(tmp / f"cold{runs}.h5"), env=env)

    def cold(command, engine=None):
        return float(np.median([run(command, engine, tmp / f"empty{runs}-{i}") for i in range(COLD_REPEAT)]))

    lines = ["| command | cold, engine chosen (s) | cold, compile forced (s) | warm (s) |", "|---|---|---|---|"]
    for name, command in commands:
        chosen = cold(command)
        forced = cold(command, "numba")
        warm_cache = tmp / "warm"
        run(command, "numba", warm_cache)
        warm = min(run(command, None, warm_cache) for _ in range(3))
        lines.append(f"| {name} | {chosen:.2f} | {forced:.2f} | {warm:.2f} |")
    # a new user's first two commands in one fresh environment
    fresh = tmp / "fresh-user"
    first = run(commands[0][1], None, fresh) + run(commands[1][1], None, fresh)
    lines += ["", f"A new user's first `roll` then first `sweep` (the demo), one empty cache: **{first:.2f} s** "
              f"in all. Cold = median of {COLD_REPEAT} fresh processes, each with its own empty NUMBA_CACHE_DIR; "
              "warm = best of 3 with the cache filled."]
    lines += ["", f"Load average (1 min, as `uptime` prints it) on the {os.cpu_count()} cores: {load_before:.2f} when these runs "
                  f"started, {os.getloadavg()[0]:.2f} when they ended."]
    return "\n".join(lines)


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--num", type=int, default=128, help="cells per axis of the kernel grid")
    parser.add_argument("--sweep-num", type=int, default=1024, help="cells per axis of the CLI sweep")
    parser.add_argument("--long-num", type=int, default=4096,
                        help="cells per axis of a long CLI sweep, where the fixed start matters little (0: skip)")
    parser.add_argument("--long-repeat", type=int, default=3, help="runs of the long sweep per worker count")
    parser.add_argument("--pymunk-rolls", type=int, default=200)
    parser.add_argument("--write", action="store_true", help="write docs/performance.md and docs/cold_start.md")
    parser.add_argument("--cold", action="store_true", help="only the cold-start part (docs/cold_start.md)")
    parser.add_argument("--skip-cold", action="store_true", help="leave out the cold-start part (minutes of compiling)")
    parser.add_argument("--rigid-cli", action="store_true",
                        help="only pymunk and the rigid law through the CLI (issue 33's rows), printed")
    args = parser.parse_args()
    if args.rigid_cli:
        rigid = load_config(ROOT / "configs" / "fig08.toml", [f"grid.x.num={args.num}", f"grid.y.num={args.num}", *RIGID_LAW])
        munk = pymunk_rate(rigid, initial_states(rigid, axis_values(rigid.grid.x), axis_values(rigid.grid.y)), args.pymunk_rolls)
        load_before = os.getloadavg()
        with tempfile.TemporaryDirectory() as tmp:
            rows, sentence = rigid_cli_rows(args.sweep_num, 3, munk, Path(tmp))
        print("\n".join(["| command | wall time (s), min / median / max |", "|---|---|", *rows, "", sentence, "",
                         "Load average (1, 5, 15 min) before the CLI runs: {:.2f} {:.2f} {:.2f}; after: {:.2f} {:.2f} {:.2f}; "
                         "{} cores.".format(*load_before, *os.getloadavg(), os.cpu_count())]))
        return 0
    if not args.skip_cold:
        with tempfile.TemporaryDirectory() as tmp:
            publish(cold_start_markdown(Path(tmp)), "cold_start.md", "cold_start_intro.md", args.write)
    if args.cold:
        return 0
    load_before = os.getloadavg()
    fig08 = ROOT / "configs" / "fig08.toml"
    cfg = load_config(fig08, [f"grid.x.num={args.num}", f"grid.y.num={args.num}"])
    states = initial_states(cfg, axis_values(cfg.grid.x), axis_values(cfg.grid.y))
    rigid = load_config(fig08, [f"grid.x.num={args.num}", f"grid.y.num={args.num}", *RIGID_LAW])
    rows = []
    paper_rate, paper_impacts = kernel_rate(cfg, states)
    rows.append(("event kernel, paper law", paper_rate, paper_impacts))
    rigid_rate, rigid_impacts = kernel_rate(rigid, states)
    rows.append(("event kernel, rigid law, mu = 0.5, beta_t = 0", rigid_rate, rigid_impacts))
    fixed = load_config(fig08, [f"grid.x.num={args.num}", f"grid.y.num={args.num}", "integrator.method=fixed_step"])
    fixed_rate, fixed_impacts = kernel_rate(fixed, states, repeat=1)
    rows.append(("fixed_step kernel, paper law, dt = 1e-3 s", fixed_rate, fixed_impacts))
    munk = pymunk_rate(rigid, states, args.pymunk_rolls)
    lines = [f"Grid: fig08's ranges at {args.num} x {args.num} = {states.shape[0]} rolls (pymunk: "
             f"{min(args.pymunk_rolls, states.shape[0])} of them), Table I die. One process; rolls per CPU second, "
             "worst / median / best of the runs.", "",
             "| simulator | rolls/s (one core) | impacts per roll | ns per impact (median) |", "|---|---|---|---|"]
    for name, rate, impacts in rows:
        lines.append(f"| {name} | {rate[2]:,.0f} / {rate[1]:,.0f} / {rate[0]:,.0f} | {impacts:.2f} | {1e9 / (rate[1] * impacts):,.0f} |")
    lines.append(f"| pymunk (Chipmunk2D), rigid law as above, dt = 1e-4 s (per CPU second, best of 3) | {munk:,.1f} | - | - |")
    lines += ["", f"Event kernel (rigid) / pymunk, same physics, per core (medians): **{rigid_rate[1] / munk:,.0f} x**; "
              f"the rigid law's cost per roll over the paper law's (medians): {paper_rate[1] / rigid_rate[1]:.2f}.", ""]
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        sweep_times = cli_sweep_times(fig08, args.sweep_num, 3, tmp)
        rigid_rows, rigid_sentence = rigid_cli_rows(args.sweep_num, 3, munk, tmp)
        long_times = cli_sweep_times(fig08, args.long_num, args.long_repeat, tmp) if args.long_num else None
        # the fixed start: the same command on a 2 x 2 grid (4 rolls)
        start_cost = min(timed(sweep_command(fig08, 2, tmp / f"tiny{i}.h5", 1)) for i in range(3))
        big = load_config(fig08, [f"grid.x.num={args.sweep_num}", f"grid.y.num={args.sweep_num}"])
        big_tiles = SweepJob.from_config(big).tiles.count
        in_process = {1: float("inf"), 2: float("inf")}
        parent_cpu = float("inf")  # CPU time of the process that writes, with 2 workers
        for attempt in range(3):
            for workers in (1, 2):
                begin, cpu = time.perf_counter(), time.process_time()
                run_sweep(big, tmp / f"in{workers}-{attempt}.h5", workers=workers, progress=False)
                in_process[workers] = min(in_process[workers], time.perf_counter() - begin)
                if workers == 2:
                    parent_cpu = min(parent_cpu, time.process_time() - cpu)
    lines += ["| command | wall time (s), min / median / max |", "|---|---|", *sweep_rows(args.sweep_num, 3, sweep_times)]
    if long_times:
        lines += sweep_rows(args.long_num, args.long_repeat, long_times)
    lines += [*rigid_rows, "", rigid_sentence]
    lines += ["", "Cold starts (an empty numba cache): [cold_start.md](cold_start.md).", "",
              "Amdahl split of the CLI sweeps:", "",
              "| part | 1 worker (s) | 2 workers (s) | speed-up |", "|---|---|---|---|",
              f"| fixed start: the same `sweep` command on a 2 x 2 grid (best of 3) | {start_cost:.2f} | {start_cost:.2f} | 1 |",
              f"| the sweep itself: `run_sweep` in a warm process ({args.sweep_num} x {args.sweep_num}, best of 3) | "
              f"{in_process[1]:.2f} | {in_process[2]:.2f} | {in_process[1] / in_process[2]:.2f} |", "",
              f"With 2 workers the parent, which receives, writes and records the {big_tiles} tiles, used "
              f"{parent_cpu:.2f} s of CPU (best of 3), on the same 2 cores as the workers."]
    load_after = os.getloadavg()
    if long_times:
        share = start_cost / long_times[1][1]  # of the median 1-worker command
        parallel = in_process[1] / in_process[2]
        lines += ["", f"At {args.long_num} x {args.long_num} the fixed start is {share:.1%} of the 1-worker command. "
                  f"Amdahl's law with that share predicts a whole-command speed-up of {1 / (share + (1 - share) / parallel):.2f} "
                  f"with the sweep's own speed-up measured above ({parallel:.2f}), and at most {2 / (1 + share):.2f} with a "
                  "perfect one."]
    lines += ["", "Load average of the machine (1, 5, 15 min) before the kernel rows: {:.2f} {:.2f} {:.2f}; after the last row: "
              "{:.2f} {:.2f} {:.2f}; {} cores.".format(*load_before, *load_after, os.cpu_count())]
    publish("\n".join(lines), "performance.md", "performance_intro.md", args.write)
    return 0


if __name__ == "__main__":
    sys.exit(main())
