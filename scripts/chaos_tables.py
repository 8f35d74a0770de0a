"""The measured tables of docs/chaos.md: one table per subcommand, written in place.

Each subcommand sweeps what it needs into out/chaos/ (files are named by a hash of the
resolved config, so a complete file of the same config is reused), measures it with dice_sweep.chaos or
dice_sweep.refine, prints the table and writes it into docs/chaos.md between the markers
``<!-- table:NAME -->`` and ``<!-- /table:NAME -->``. Figures go to docs/figures/chaos_*.png.
Public API only. ``make chaos`` runs them all.

    python scripts/chaos_tables.py validation|sides|walls|time_step|contact|refine|control|scatter [--workers N] [--num N]

``scatter`` reads the law of real bounces from configs/scatter_real.toml ([scatter] law keys
of the effect registry, draws, seed) and sweeps Figs 8, 9 and 11 with it (probability
maps, docs/chaos.md).
"""

import argparse
import hashlib
import math
import os
import re
import time
from pathlib import Path

import numpy as np

from dice_sweep import effects as effect_registry
from dice_sweep.chaos import (
    SMOOTH_BOUNDARY_SBB,
    basin_entropy,
    cantor_map,
    checkerboard_map,
    compare_control,
    control_map,
    measure_map,
    measure_probability,
    monte_carlo_indices,
    outcome_fractions,
    random_map_entropy,
    straight_boundary_map,
    uncertainty_curve,
    weierstrass_map,
)
from dice_sweep.app.sweep import draw_sweep_file, draw_sweep_files
from dice_sweep.config import config_to_toml, load_config
from dice_sweep.plotting import (
    axis_label,
    box_entropy_panel,
    plot_control_map,
    plot_refinement,
    plot_scalar_maps,
    plot_uncertainty_curves,
)
from dice_sweep.refine import compare_with_full, run_refined_sweep
from dice_sweep.storage import read_refinement_maps, read_sweep
from dice_sweep.executor import default_workers
from dice_sweep.sweep import SweepJob, run_sweep

ROOT = Path(__file__).resolve().parent.parent
DATA = ROOT / "out" / "chaos"
FIGURES = ROOT / "docs" / "figures"
DOC = ROOT / "docs" / "chaos.md"
SIDES = (4, 5, 6, 8, 12, 20)
FIXED_STEPS = (1e-3, 1e-4, 1e-5)  # s
DT_SMALL_NUM = 128  # grid of the time-step table with every dt (dt = 1e-5 s is slow)
DT_LARGE = (1e-3, 1e-4)  # also on the full grid
REFINE_LEVELS = 3
# the paper's figures; those refinement gives up on for the full grid (chaotic almost
# everywhere) last, as they take most of the time and do not depend on refine.THIN_BUFFER
FULL_GRID_LAST = ("fig09", "fig10")
PAPER_CONFIGS = tuple(sorted((path.stem for path in (ROOT / "configs").glob("fig*.toml")), key=lambda name: (name in FULL_GRID_LAST, name)))


CONTROL_SIGMAS = {"fig08": {"y0": 0.002, "omega0": 0.5}, "fig11": {"y0": 0.002, "vx0": 0.02}}
CONTROL_SCALES = (0.5, 1.0, 2.0, 4.0)  # thrower precision: multiples of the sigmas above
CONTROL_SAMPLES, CONTROL_POINTS = 256, 64
WALL_BANDS = 4  # vx0 bands for "where" the walls change the sensitivity
SCATTER_CONFIG = ROOT / "configs" / "scatter_real.toml"  # the spreads of real bounces
SCATTER_FIGURES = ("fig08", "fig09", "fig11")
SCATTER_SCALES = (0.5, 2.0)  # the spreads' multiples also swept, at half the resolution
SLOW_FIGURES = {"fig09": 2}  # n = 20: ~130 impacts a roll, 30 times slower; its grid divided by this


# --- sweeps and the document -------------------------------------------------------------


class Runner:
    """Sweeps configs into out/chaos/, reusing complete files of the same config."""

    def __init__(self, workers, num):
        self.workers = workers
        self.num = num
        self.computed_seconds = []  # wall time of each sweep computed by this run
        self.reused = 0  # sweeps found complete in out/chaos/
        # compile (or load) the kernel now, so that no sweep's time includes it
        SweepJob.from_config(self.config("fig08", num=1)).warm_up()

    def config(self, name, overrides=(), num=None):
        num = num or self.num
        return load_config(ROOT / "configs" / f"{name}.toml", [f"grid.x.num={num}", f"grid.y.num={num}", *overrides])

    def sweep(self, name, overrides=(), num=None):
        """(SweepData, seconds of computing, 0 if reused) of configs/NAME.toml with overrides."""
        cfg = self.config(name, overrides, num)
        config_toml = config_to_toml(cfg)
        path = DATA / f"{hashlib.sha1(config_toml.encode()).hexdigest()[:16]}.h5"
        if path.exists():
            existing = read_sweep(path)
            if existing.complete and existing.config_toml == config_toml:
                self.reused += 1
                return existing, 0.0
            path.unlink()
        summary = run_sweep(cfg, path, workers=self.workers, progress=False)
        self.computed_seconds.append(summary.seconds)
        print(f"  swept {name} {' '.join(overrides)}: {summary.describe()}", flush=True)
        return read_sweep(path), summary.seconds


def write_table(name, markdown):
    """Put ``markdown`` between the table markers of ``name`` in docs/chaos.md; print it."""
    print(markdown)
    text = DOC.read_text()
    pattern = re.compile(rf"(<!-- table:{name} -->\n).*?(<!-- /table:{name} -->)", re.S)
    if not pattern.search(text):
        raise SystemExit(f"{DOC}: no markers <!-- table:{name} --> ... <!-- /table:{name} -->")
    DOC.write_text(pattern.sub(lambda match: match.group(1) + markdown + "\n" + match.group(2), text))


def table(header, rows):
    """A markdown table from a header list and rows of cells."""
    lines = ["| " + " | ".join(header) + " |", "|" + "---|" * len(header)]
    lines += ["| " + " | ".join(str(cell) for cell in row) + " |" for row in rows]
    return "\n".join(lines)


def measure(sweep):
    return measure_map(sweep.outcome, sweep.sides)


def measure_cells(measures):
    """Sb, Sbb, Sbb > ln 2, alpha, fit range: the cells every measure table shares."""
    entropy, curve = measures.entropy, measures.uncertainty
    return [
        f"{entropy.sb:.4f}", f"{entropy.sbb:.3f}", "yes" if entropy.fractal_by_log2 else "no",
        f"{curve.fraction[0]:.3f}", curve.fit.text(), f"{curve.fit.eps_lo:g}-{curve.fit.eps_hi:g}",
    ]


MEASURE_HEADER = ["Sb (nats)", "Sbb (nats)", "Sbb > ln 2", "f(1 pixel)", "alpha", "fit range (pixels)"]


def footer(command, started, extra="", runner=None):
    """The line under a table: its command, the run time and how many sweeps it computed."""
    sweeps = ""
    if runner is not None:
        sweeps = (f" ({len(runner.computed_seconds)} sweeps computed in {sum(runner.computed_seconds):.0f} s, "
                  f"{runner.reused} reused from out/chaos/; {runner.workers} workers on a shared machine)")
    return f"\nProduced by `{command}` in {time.perf_counter() - started:.0f} s{sweeps}.{extra}"


# --- the tables --------------------------------------------------------------------------


def sides_table(runner, args):
    started = time.perf_counter()
    rows, curves = [], []
    for sides in SIDES:
        sweep, _ = runner.sweep("fig08", [f"die.sides={sides}"])
        measures = measure(sweep)
        curves.append(measures.uncertainty)
        rows.append([sides, *measure_cells(measures), f"{measures.entropy.sb / math.log(sides):.4f}",
                     f"{100 * measures.entropy.boundary_boxes / measures.entropy.boxes:.1f}"])
    plot_uncertainty_curves(curves, [f"n = {n}" for n in SIDES], FIGURES / "chaos_sides_uncertainty.png",
                            title=f"f(eps) on fig08's ranges, {runner.num} x {runner.num}")
    markdown = table(["n", *MEASURE_HEADER, "Sb / ln n", "boundary boxes (%)"], rows)
    write_table("sides", markdown + footer(f"python scripts/chaos_tables.py sides --num {runner.num}", started, runner=runner))


def band_measures(sweep, bands):
    """Sb and alpha of each of ``bands`` equal bands of columns (the x axis)."""
    width = sweep.outcome.shape[1] // bands
    results = []
    for band in range(bands):
        part = sweep.outcome[:, band * width : (band + 1) * width]
        measures = measure_map(part, sweep.sides)
        results.append((measures.entropy.sb, measures.uncertainty.fit))
    return results


def walls_table(runner, args):
    started = time.perf_counter()
    cases = [("no walls (fig11)", "fig11"), ("walls 0.20 m apart (fig13)", "fig13")]
    sweeps = [runner.sweep(name)[0] for _, name in cases]
    all_measures = [measure(sweep) for sweep in sweeps]
    rows = [[label, *measure_cells(m), f"{m.fractions[-1]:.4f}"] for (label, _), m in zip(cases, all_measures)]
    whole = table(["case", *MEASURE_HEADER, "undecided share"], rows)
    bands = [band_measures(sweep, WALL_BANDS) for sweep in sweeps]
    x = sweeps[0].x
    edges = np.linspace(x.lo, x.hi, WALL_BANDS + 1)
    walled = np.array_split(sweeps[1].counts["wall_impacts"] > 0, WALL_BANDS, axis=1)
    band_rows = [
        [f"{edges[b]:.3g}-{edges[b + 1]:.3g}", f"{100 * walled[b].mean():.1f} %", f"{bands[0][b][0]:.4f}",
         f"{bands[1][b][0]:.4f}", bands[0][b][1].text(), bands[1][b][1].text()]
        for b in range(WALL_BANDS)
    ]
    where = table([f"{x.param} band ({x.unit})", "rolls that hit a wall (fig13)", "Sb no walls", "Sb walls",
                   "alpha no walls", "alpha walls"], band_rows)
    plot_uncertainty_curves([m.uncertainty for m in all_measures], [label for label, _ in cases],
                            FIGURES / "chaos_walls_uncertainty.png", title="fig11 (no walls) vs fig13 (walls)")
    panels = [box_entropy_panel(sweep, m.entropy, f"{label}: box entropy, Sb = {m.entropy.sb:.3f}")
              for (label, _), sweep, m in zip(cases, sweeps, all_measures)]
    plot_scalar_maps(panels, FIGURES / "chaos_walls_entropy.png")
    markdown = whole + "\n\nBy band of the horizontal speed (whole height; alpha of a band: its own f(eps)):\n\n" + where
    write_table("walls", markdown + footer(f"python scripts/chaos_tables.py walls --num {runner.num}", started, runner=runner))


def time_step_table(runner, args):
    started = time.perf_counter()
    rows = []
    for name in ("fig08", "fig11"):
        for num, steps in ((DT_SMALL_NUM, FIXED_STEPS), (runner.num, DT_LARGE)):
            exact, _ = runner.sweep(name, num=num)
            cells = []
            for dt in FIXED_STEPS:
                if dt not in steps:
                    cells.append("not run (slow)")
                    continue
                overrides = ["integrator.method=fixed_step", f"integrator.dt={dt:g}"]
                fixed, _ = runner.sweep(name, overrides, num=num)
                differ = np.mean(fixed.outcome != exact.outcome)
                cells.append(f"{100 * differ:.2f} %")
            rows.append([name, f"{num} x {num}", *cells])
    markdown = table(["map", "grid", *[f"dt = {dt:g} s" for dt in FIXED_STEPS]], rows)
    extra = f" dt = 1e-05 s is run on the {DT_SMALL_NUM} x {DT_SMALL_NUM} grid only: it is the slowest integrator by far."
    write_table("time_step", markdown + footer(f"python scripts/chaos_tables.py time_step --num {runner.num}", started, extra, runner))
    exact, _ = runner.sweep("fig08")
    paper, _ = runner.sweep("fig08", ["integrator.method=fixed_step", "integrator.dt=0.001"])
    draw_sweep_files([exact.path, paper.path],
                    FIGURES / "chaos_fig08_time_step.png",
                    titles=["fig08, event integrator (exact)", "fig08, fixed_step dt = 1e-3 s (the paper's)"])


def contact_table(runner, args):
    started = time.perf_counter()
    sweeps = [runner.sweep("fig08")[0], runner.sweep("fig08_rigid")[0]]
    rows = []
    for label, sweep in zip(("paper (eqs 9-13)", "rigid (impulse at the corner)"), sweeps):
        m = measure(sweep)
        fractions = ", ".join(f"{m.fractions[k]:.3f}" for k in range(sweep.sides))
        rows.append([label, *measure_cells(m), fractions])
    same = np.mean(sweeps[0].outcome == sweeps[1].outcome)
    shares = [list(outcome_fractions(sweep.outcome, sweep.sides).values()) for sweep in sweeps]
    chance = float(np.dot(*shares))  # two unrelated maps with these shares agree this often
    markdown = table(["contact law (fig08)", *MEASURE_HEADER, "share of sides 0, 1, 2, 3"], rows)
    markdown += (f"\n\nPixels with the same side under both laws: {100 * same:.1f} % "
                 f"(two unrelated maps with these side shares: {100 * chance:.1f} %).")
    write_table("contact", markdown + footer(f"python scripts/chaos_tables.py contact --num {runner.num}", started, runner=runner))


def refine_table(runner, args):
    """Every paper config at twice --num per axis: the full sweep and the refined one, both
    computed in this run, one after the other, on the same workers (the load is in the footer)."""
    started = time.perf_counter()
    load_before = os.getloadavg()
    num, levels = 2 * runner.num, REFINE_LEVELS
    rows = []
    for name in PAPER_CONFIGS:
        cfg = runner.config(name, num=num)
        full_path, path = DATA / f"{name}_full_{num}.h5", DATA / f"{name}_refine{levels}_{num}.h5"
        full_path.unlink(missing_ok=True)
        path.unlink(missing_ok=True)
        full_summary = run_sweep(cfg, full_path, workers=runner.workers, progress=False)
        summary = run_refined_sweep(cfg, path, levels, workers=runner.workers, progress=False)
        runner.computed_seconds += [full_summary.seconds, summary.seconds]  # the footer's count
        full, refined = read_sweep(full_path), read_sweep(path)
        simulated, level, _ = read_refinement_maps(path)
        differ = compare_with_full(refined.outcome, full.outcome)
        rows.append([name, f"{num} x {num}", levels, f"{100 * summary.rolls / full.outcome.size:.1f} %",
                     f"{100 * (1 - summary.rolls / full.outcome.size):.1f} %", f"{100 * simulated.mean():.1f} %",
                     f"{100 * differ:.4f} %", int(round(differ * full.outcome.size)), f"{full_summary.seconds:.1f} s",
                     f"{summary.seconds:.1f} s", f"{100 * (1 - summary.seconds / full_summary.seconds):.0f} %"])
        if name == "fig12":  # the chaotic zoom
            plot_refinement(refined, level, levels, FIGURES / f"chaos_refine_{name}_{num}.png")
        # written after every row: the last two configs take most of the time
        header = ["map", "grid", "levels", "rolls (of a full sweep)", "rolls saved", "pixels rolled at their centre",
                  "pixels differing from the full sweep", "differing pixels", f"full sweep ({runner.workers} workers)",
                  "refined", "time saved"]
        load = (f" {len(rows)} of the {len(PAPER_CONFIGS)} paper configs. Load averages (1, 5, 15 min) before: "
                f"{', '.join(f'{v:.1f}' for v in load_before)}; after: {', '.join(f'{v:.1f}' for v in os.getloadavg())} (2 cores).")
        write_table("refine", table(header, rows) + footer(f"python scripts/chaos_tables.py refine --num {runner.num}", started, load, runner=runner))


def control_rows(runner, name, sweep, sigmas):
    rows = []
    for scale in CONTROL_SCALES:
        scaled = {param: scale * sigma for param, sigma in sigmas.items()}
        result = control_map(sweep, scaled, samples=CONTROL_SAMPLES, max_points=CONTROL_POINTS, workers=runner.workers)
        summary = result.summary()
        sigma_text = ", ".join(f"{param} {value:g}" for param, value in scaled.items())
        rows.append([name, sigma_text, result.method.replace("_", " "), f"{summary['mean_p_max']:.3f}",
                     f"{100 * summary['share_p_max_at_least_0.9']:.1f} %", f"{summary['mean_entropy_nats']:.3f}"])
    return rows


def control_table(runner, args):
    started = time.perf_counter()
    rows, checks = [], []
    for name, sigmas in CONTROL_SIGMAS.items():
        sweep, _ = runner.sweep(name)
        rows += control_rows(runner, name, sweep, sigmas)
        blurred = control_map(sweep, sigmas, method="blur")
        rolled = control_map(sweep, sigmas, method="monte_carlo", samples=CONTROL_SAMPLES,
                             max_points=CONTROL_POINTS, workers=runner.workers)
        x_index = monte_carlo_indices(len(sweep.x.values), CONTROL_POINTS)
        y_index = monte_carlo_indices(len(sweep.y.values), CONTROL_POINTS)
        agreement = compare_control(blurred, rolled, x_index, y_index)
        checks.append([name, ", ".join(f"{k} {v:g}" for k, v in sigmas.items()), agreement.points,
                       f"{agreement.mean_abs_difference:.4f}", f"{agreement.max_abs_difference:.3f}",
                       f"{agreement.mean_mc_standard_error:.4f}", f"{100 * agreement.share_within_3_se:.1f} %",
                       f"{100 * agreement.same_most_likely:.1f} %", f"{agreement.median_gap_where_different:.3f}"])
        labels = (axis_label(sweep.x.param, sweep.x.unit), axis_label(sweep.y.param, sweep.y.unit))
        plot_control_map(blurred, FIGURES / f"chaos_control_{name}_blur.png", *labels)
        plot_control_map(rolled, FIGURES / f"chaos_control_{name}_monte_carlo.png", *labels)
    header = ["map", "sigma (SI)", "method", "mean p(most likely)", "points with p >= 0.9", "mean entropy (nats)"]
    check_header = ["map", "sigma (SI)", "points compared", "mean abs difference", "max abs difference",
                    "mean MC standard error", "within 3 standard errors", "same most likely side",
                    "median gap of the two most likely (blur) where not"]
    markdown = (table(header, rows) + "\n\nBlur against Monte Carlo "
                f"({CONTROL_SAMPLES} rolls at each of {CONTROL_POINTS} x {CONTROL_POINTS} points):\n\n" + table(check_header, checks))
    write_table("control", markdown + footer(f"python scripts/chaos_tables.py control --num {runner.num}", started, runner=runner))


SCATTER_SCALED = effect_registry.scatter_spread_keys()  # the keys a scale multiplies, kind by kind: spread, floor


def scatter_overrides(scatter, scale=1.0):
    """--set lines of the law at ``scale`` times its spreads and floors, its form (power) as it is."""
    return [*(f"scatter.{key}={scale * getattr(scatter, key)!r}" for key in SCATTER_SCALED),
            *(f"scatter.{key}={getattr(scatter, key)!r}" for key in effect_registry.scatter_law_keys() if key not in SCATTER_SCALED),
            f"scatter.draws={scatter.draws}", f"scatter.seed={scatter.seed}"]


def scatter_table(runner, args):
    started = time.perf_counter()
    scatter = load_config(SCATTER_CONFIG).scatter
    rows = []
    for name in SCATTER_FIGURES:
        num = runner.num // SLOW_FIGURES.get(name, 1)
        deterministic, _ = runner.sweep(name, num=num)
        for scale, scale_num in ((1.0, num), *((k, num // 2) for k in SCATTER_SCALES)):
            sweep, _ = runner.sweep(name, scatter_overrides(scatter, scale), num=scale_num)
            p = measure_probability(sweep.probability, sweep.draws)
            low, high = p.predictable_range
            best = np.argmax(sweep.probability, axis=0)
            if scale_num == num:
                same = np.mean(best == np.where(deterministic.outcome < 0, sweep.sides, deterministic.outcome))
                draw_sweep_file(sweep.path, FIGURES / f"chaos_scatter_{name}.png", dpi=80)
            rows.append([
                f"{name} (n = {sweep.sides})", f"{scale_num} x {scale_num}", sweep.draws,
                ", ".join([f"{scale * getattr(scatter, key):.4f}" for key in SCATTER_SCALED]
                          + [f"{getattr(scatter, key):g}" for key in effect_registry.scatter_law_keys() if key not in SCATTER_SCALED]),
                f"{100 * p.predictable:.1f} % [{100 * low:.1f}, {100 * high:.1f}]",
                f"{sweep.probability[:-1].max(axis=0).mean():.3f}",
                f"{p.basin_entropy:.3f} ({p.basin_entropy_corrected:.3f})", f"{math.log(sweep.sides):.3f}",
                f"{100 * p.no_answer:.2f} %", f"{100 * same:.1f} %" if scale_num == num else "",
            ])
    header = ["map", "pixels", "draws M", "corner: spread, floor; flat: spread, floor; power; tail share, tail factor, spin", "predictable: p >= 0.9 [range from the M draws]",
              "mean p(most likely)", "basin entropy, nats (Miller-Madow)", "fair die ln n", "no answer",
              "most likely side = deterministic side"]
    keys = ", ".join(f"{key} = {getattr(scatter, key):.4g}" for key in effect_registry.scatter_law_keys())
    source = (f"\n\nThe law from `{SCATTER_CONFIG.relative_to(ROOT)}` ([scatter] {keys}; draws = {scatter.draws}, "
              f"seed = {scatter.seed}; floors in sqrt(g R) of each die); rows at "
              f"{' and '.join(f'{k:g}' for k in SCATTER_SCALES)} times the spreads and floors at half the resolution.")
    write_table("scatter", table(header, rows) + source
                + footer(f"python scripts/chaos_tables.py scatter --num {runner.num}", started, runner=runner))


def binary_entropy(p):
    return -(p * math.log(p) + (1 - p) * math.log(1 - p))


def validation_table(runner, args):
    started = time.perf_counter()
    h_corner, h_edge = binary_entropy(12 / 25), binary_entropy(0.4)
    random4 = np.random.default_rng(1).integers(0, 4, (400, 400))
    golden = (math.sqrt(5) - 1) / 2
    entropy_cases = [
        ("horizontal line at row 252, 500 x 500", straight_boundary_map((500, 500), 0.0, 252), "Sbb", h_edge, "h(2/5)"),
        ("line of slope 0.1, 500 x 500", straight_boundary_map((500, 500), 0.1, 100.3), "Sbb", SMOOTH_BOUNDARY_SBB, "about 1/2"),
        ("line of slope 0.618, 500 x 500", straight_boundary_map((500, 500), golden, 100.3), "Sbb", SMOOTH_BOUNDARY_SBB, "about 1/2"),
        ("pixel checkerboard, 100 x 100", checkerboard_map((100, 100), 1), "Sbb", h_corner, "h(12/25)"),
        ("10-pixel checkerboard, edges at 7 mod 10", checkerboard_map((500, 500), 10, 7), "Sb", (h_corner + 2 * h_edge) / 4, "(h(12/25) + 2 h(2/5)) / 4"),
        ("random, 4 outcomes, 400 x 400", random4, "Sb", random_map_entropy(25, 4), "multinomial mean"),
    ]
    rows = []
    for label, outcome, name, expected, formula in entropy_cases:
        entropy = basin_entropy(outcome)
        measured = entropy.sb if name == "Sb" else entropy.sbb
        rows.append([label, name, f"{expected:.4f} ({formula})", f"{measured:.4f}"])
    alpha_cases = [
        ("line of slope 0.3, 500 x 500", straight_boundary_map((500, 500), 0.3, 180.3), None, 1.0, "1"),
        ("128-pixel checkerboard, 1024 x 1024, eps 1-8", checkerboard_map((1024, 1024), 128), [1, 2, 3, 4, 6, 8], 1.0, "1 (eps << 128)"),
        ("random, 4 outcomes, 400 x 400", random4, None, 0.0, "0"),
        ("Cantor set x line, 243 x 6561, eps = 3^k", cantor_map(8, 3**5), 3 ** np.arange(5), 1 - math.log(2) / math.log(3), "1 - ln 2/ln 3"),
        ("Weierstrass graph a = 1/2, b = 4, 1024 x 1024", weierstrass_map(1024, 0.5, 4.0), None, 0.5, "-ln a/ln b"),
    ]
    for label, outcome, eps, expected, formula in alpha_cases:
        fit = uncertainty_curve(outcome, eps).fit
        rows.append([label, "alpha", f"{expected:.4f} ({formula})", f"{fit.text()}, eps {fit.eps_lo:g}-{fit.eps_hi:g}"])
    markdown = table(["map", "measure", "expected", "measured"], rows)
    write_table("validation", markdown + footer("python scripts/chaos_tables.py validation", started))


TABLES = {
    "validation": validation_table,
    "sides": sides_table,
    "walls": walls_table,
    "time_step": time_step_table,
    "contact": contact_table,
    "refine": refine_table,
    "control": control_table,
    "scatter": scatter_table,
}


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("table", choices=sorted(TABLES))
    parser.add_argument("--workers", type=int, default=None, help="worker processes (default: all cores)")
    parser.add_argument("--num", type=int, default=512, help="cells per axis of the sweeps (default 512)")
    args = parser.parse_args()
    DATA.mkdir(parents=True, exist_ok=True)
    runner = Runner(args.workers or default_workers(), args.num)
    TABLES[args.table](runner, args)


if __name__ == "__main__":
    main()
