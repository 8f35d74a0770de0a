"""Outcome maps of the kernel's rigid model against pymunk (Chipmunk2D), issues 4 and 15.

A Table-I-sized square (R = 1.9/sqrt(2) cm), beta_normal = 0.2, beta_tangential = 0 (pymunk has
no tangential restitution), Coulomb friction mu = 0.5, dropped with phi0 = 0, vx0 = 0 from
y0 in [0.02, 0.08] m with omega0 in [0, 30] rad/s. Prints the share of pixels on which the two
agree, overall and away from basin boundaries, and pymunk's rolls/s; writes the maps side by
side. With --explain, sorts the disagreeing pixels by the impact at which the two paths part.

With --flat, the maps of issue 15 where flat impacts (two corners at once) dominate instead:
a pentagon thrown flat at a wall, and a hexagon and a square dropped flat on a side
(dice_sweep.reference.pymunk_die.flat_impact_configs), y0 against vx0 on 32 x 32. Prints a
table of the agreement overall, on the pixels with and without a flat impact, on pymunk's
settled pixels, and pymunk's map against itself at half the step; writes the maps.
docs/validation.md reports and explains the numbers.

    python scripts/compare_pymunk.py [--num 48] [--set contact.friction=0.3] [--explain 4] [--png PATH]
        [--dt 1e-4] [--iterations 30] [--collision-slop 1e-5] [--overlap-fixed-per-step 0.01]
    python scripts/compare_pymunk.py --flat [--num 32] [--maps wall hexagon square] [--check-dt 2.5e-5]
        [--dt 5e-5] [--iterations 100] [--png PATH] [--set KEY=VALUE]
"""

import argparse
import math
from pathlib import Path

import numpy as np

from dice_sweep.config import PARAM_UNITS
from dice_sweep.physics.kernel import EVENT_IMPACT, REC_EVENT, REC_STATE, REC_T
from dice_sweep.plotting import axis_label, draw_outcome_map, outcome_figure
from dice_sweep.reference.pymunk_die import (
    FLAT_DT,
    FLAT_SETTINGS,
    PymunkDie,
    PymunkSettings,
    compare_with_kernel,
    comparison_config,
    first_contact_is_flat,
    flat_impact_configs,
    grid_states,
    kernel_flat_impacts,
    map_agreement,
    pymunk_map,
    settled_mask,
)
from dice_sweep.roll import initial_state, roll_config, sample_path

NEIGHBOURHOODS = (3, 5)  # widths of the "away from boundaries" masks
FIGURES = Path(__file__).resolve().parent.parent / "docs" / "figures"
DEFAULT_PNG = FIGURES / "pymunk_vs_rigid.png"
FLAT_PNG = FIGURES / "pymunk_flat_impacts.png"
DEFAULT_NUM = 48  # cells per axis of issue 4's map
FLAT_NUM = 32  # and of issue 15's maps
# --explain: a jump of the velocity beyond what gravity gives in one step is an impulse
IMPULSE_JUMP = 10.0  # x g dt
DIVERGED_ANGLE = 0.1  # rad: the two paths count as apart once their angles differ this much
SAMPLE_EVERY = 10  # pymunk steps between compared samples of the two paths
EVENTS_SHOWN = 6
# --explain: paired impacts are alike within these
IMPACT_MATCH = 0.05  # share of the die's speed |v| + R |omega| before the impact
IMPACT_TIME_MATCH = 2  # pymunk steps
FIRST_IMPACT_STRIDE = 4  # --explain: first impacts compared on every 4th pixel of each axis


def print_agreement(comparison):
    share, count = comparison.agreement()
    print(f"all pixels: {share:.2%} agree ({count} pixels)")
    for width in NEIGHBOURHOODS:
        share, count = comparison.agreement(width)
        print(f"away from boundaries ({width} x {width} one side in the kernel's map): "
              f"{share:.2%} agree ({count} pixels)")
    undecided = int((comparison.pymunk < 0).sum()), int((comparison.kernel < 0).sum())
    print(f"undecided pixels: pymunk {undecided[0]}, kernel {undecided[1]}")
    print(f"pymunk: {comparison.rolls_per_second():.1f} rolls per CPU second (one core, dt = {comparison.dt:g} s)")


def write_figure(rows, png_path):
    """One row per (cfg, comparison, name): kernel map, pymunk map, and the kernel map with the
    disagreeing pixels in black; ``name`` (None: none) heads the row's titles."""
    # outcome_figure gives an Agg-backed figure with constrained layout; refill it with 3 panels a row
    cfg, comparison, _ = rows[0]
    fig = outcome_figure(comparison.kernel, comparison.x_values, comparison.y_values, "", "", cfg.die.sides)
    fig.clear()
    fig.set_size_inches(18, 5 * len(rows))
    for axes, (cfg, comparison, name) in zip(fig.subplots(len(rows), 3, squeeze=False), rows):
        grid = cfg.grid
        labels = axis_label(grid.x.param, PARAM_UNITS[grid.x.param]), axis_label(grid.y.param, PARAM_UNITS[grid.y.param])
        differs = np.where(comparison.kernel == comparison.pymunk, comparison.kernel, -1)
        head = "" if name is None else f"{name}: "
        panels = (
            (comparison.kernel, f"{head}kernel, model {cfg.contact.model}"),
            (comparison.pymunk, f"{head}pymunk" + ("" if name is None else f", dt {comparison.dt:g} s")),
            (differs, f"{head}kernel, black where pymunk differs ({comparison.agreement()[0]:.1%} agree)"),
        )
        for ax, (outcome, title) in zip(axes, panels):
            draw_outcome_map(ax, outcome, comparison.x_values, comparison.y_values, *labels, cfg.die.sides, title=title)
    png_path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(png_path, dpi=100)
    print(f"wrote {png_path}")


def share(agreement):
    """'96.48 % (1024)' for an (share, count) pair; '-' for no pixels."""
    value, count = agreement
    return "-" if count == 0 else f"{value:.2%} ({count})"


def compare_flat(num, names, overrides, dt, check_dt, settings, png_path):
    """Issue 15's check: the kernel against pymunk on maps where flat impacts dominate."""
    configs = flat_impact_configs(num, overrides)
    rows, table = [], []
    for name in names:
        cfg = configs[name]
        print(f"\n{name}: n = {cfg.die.sides}, R = {cfg.die.circumradius:.6g} m, phi0 = {cfg.initial.phi0:.6g} rad, "
              f"walls {cfg.walls.separation} m; {cfg.grid.x.param} in [{cfg.grid.x.min:g}, {cfg.grid.x.max:g}], "
              f"{cfg.grid.y.param} in [{cfg.grid.y.min:g}, {cfg.grid.y.max:g}], {num} x {num}; model {cfg.contact.model}, "
              f"beta_normal {cfg.contact.beta_normal:g}, beta_tangential {cfg.contact.beta_tangential:g}, "
              f"friction {cfg.contact.friction:g}")
        comparison = compare_with_kernel(cfg, dt=dt, settings=settings)
        first_flat = first_contact_is_flat(cfg, grid_states(cfg)[2]).reshape(comparison.kernel.shape)
        kernel_flat, criterion = kernel_flat_impacts(cfg, comparison)
        settled = settled_mask(comparison.pymunk, 3)
        print(f"  kernel flat impact: {criterion}")
        print(f"  undecided pixels: pymunk {int((comparison.pymunk < 0).sum())}, kernel {int((comparison.kernel < 0).sum())}; "
              f"pymunk {comparison.rolls_per_second():.1f} rolls per CPU second (dt {dt:g} s, {settings.iterations} passes)")
        if check_dt:
            check = pymunk_map(cfg, dt=check_dt, settings=settings)
            itself = share(map_agreement(comparison.pymunk, check.outcome))
            print(f"  pymunk at dt {check_dt:g} s against dt {dt:g} s: {itself} agree ({check.seconds:.0f} s CPU)")
        else:
            itself = "-"
        table.append((
            name,
            share(comparison.agreement_on()),
            share(comparison.agreement_on(first_flat)),
            share(comparison.agreement_on(kernel_flat)),
            share(comparison.agreement_on(~kernel_flat)),
            f"{settled.mean():.1%}",
            share(comparison.agreement_on(settled)),
            itself,
        ))
        rows.append((cfg, comparison, name))
    print(f"\nkernel against pymunk (dt {dt:g} s, {settings.iterations} passes): share of pixels that agree (pixels)")
    header = ("map", "all", "flat first contact", "kernel flat impact", "no kernel flat impact",
              "pymunk settled (3 x 3)", "on pymunk's settled", f"pymunk dt {check_dt:g} vs {dt:g}")
    print("| " + " | ".join(header) + " |")
    print("|" + "---|" * len(header))
    for row in table:
        print("| " + " | ".join(row) + " |")
    write_figure(rows, png_path)


def kernel_impacts(cfg, report):
    """(t, state before, state after) of the kernel's impacts."""
    rows = report.records[report.records[:, REC_EVENT] == EVENT_IMPACT]
    before = sample_path(cfg, report, np.nextafter(rows[:, REC_T], -np.inf))
    return [(row[REC_T], pre, row[REC_STATE:REC_STATE + 6]) for row, pre in zip(rows, before)]


def pymunk_path(cfg, state, comparison, t_end):
    """pymunk's states every SAMPLE_EVERY steps and its impulses (t, before, after).

    It runs past t_end (s) until its own side is decided, or until the config's t_max.
    """
    die = PymunkDie.from_config(cfg, state, dt=comparison.dt, settings=comparison.settings)
    jump = IMPULSE_JUMP * cfg.world.g * comparison.dt
    times, path, impulses = [], [], []
    while die.time < cfg.integrator.t_max and (die.time <= t_end or not die.is_decided()):
        before = die.state()
        die.step()
        after = die.state()
        change = after[3:] - before[3:] + [0.0, cfg.world.g * comparison.dt, 0.0]
        if math.hypot(change[0], change[1]) + cfg.die.circumradius * abs(change[2]) > jump:
            impulses.append((die.time, before, after))
        if die.steps % SAMPLE_EVERY == 0:
            times.append(die.time)
            path.append(after)
    return np.array(times), np.array(path), impulses


def print_events(name, events):
    print(f"  {name}: {len(events)} impacts; first ones as t (s): vx, vy (m/s), omega (rad/s) before -> after")
    for t, before, after in events[:EVENTS_SHOWN]:
        print(f"    {t:.5f}: {before[3]:+.4f} {before[4]:+.4f} {before[5]:+8.3f} -> "
              f"{after[3]:+.4f} {after[4]:+.4f} {after[5]:+8.3f}")


def parting_impact(kernel_events, pymunk_events, radius, dt):
    """The first impact at which the two paths part, and how: (number from 1, kind).

    Impacts are paired in order. A pair is alike when the times differ by at most
    IMPACT_TIME_MATCH steps and the states before and the velocity changes agree within
    IMPACT_MATCH of the die's speed |v| + R |omega| before it.
    """
    scale = np.array([1.0, 1.0, radius])  # (vx, vy, omega) -> m/s
    for number, (ours, theirs) in enumerate(zip(kernel_events, pymunk_events), start=1):
        (t_ours, before, after), (t_theirs, their_before, their_after) = ours, theirs
        tolerance = IMPACT_MATCH * (math.hypot(before[3], before[4]) + radius * abs(before[5]))
        if abs(t_ours - t_theirs) > IMPACT_TIME_MATCH * dt or np.abs((before - their_before)[3:] * scale).max() > tolerance:
            return number, "impact times or states before it differ"
        change, their_change = (after - before)[3:] * scale, (their_after - their_before)[3:] * scale
        if np.abs(change - their_change).max() > tolerance:
            opposite = change[0] * their_change[0] < 0.0
            return number, "friction impulses of opposite sign" if opposite else "velocity changes differ"
    return min(len(kernel_events), len(pymunk_events)) + 1, "one has more impacts"


def first_impacts(cfg, comparison, stride):
    """How far the first impacts agree on every stride-th pixel of each axis, disagreeing or not."""
    radius = cfg.die.circumradius
    differences, delays = [], []
    for i in range(0, len(comparison.y_values), stride):
        for j in range(0, len(comparison.x_values), stride):
            cell = cfg.with_initial(**{cfg.grid.x.param: comparison.x_values[j], cfg.grid.y.param: comparison.y_values[i]})
            report = roll_config(cell)
            (t_ours, before, after), = kernel_impacts(cell, report)[:1]
            (t_theirs, their_before, their_after), = pymunk_path(cell, initial_state(cell), comparison, t_ours)[2][:1]
            scale = np.array([1.0, 1.0, radius])
            change, their_change = (after - before)[3:] * scale, (their_after - their_before)[3:] * scale
            speed = math.hypot(before[3], before[4]) + radius * abs(before[5])
            differences.append(np.abs(change - their_change).max() / speed)
            delays.append(t_theirs - t_ours)
    differences, delays = np.array(differences), np.array(delays)
    print(f"\nfirst impacts of {differences.size} pixels (every {stride}th of each axis): velocity changes differ "
          f"by a median {np.median(differences):.2%} of the speed (90th percentile {np.quantile(differences, 0.9):.2%}, "
          f"largest {differences.max():.2%}); within {IMPACT_MATCH:.0%} on {np.mean(differences <= IMPACT_MATCH):.1%}")
    print(f"  pymunk finds the first impact later by {delays.min() / comparison.dt:.2f} to "
          f"{delays.max() / comparison.dt:.2f} steps (median {np.median(delays) / comparison.dt:.2f})")


def explain(cfg, comparison, count):
    """Sort the disagreeing pixels by the impact at which the paths part; print ``count`` in full.

    The most settled pixels (see ``settled_mask``) are printed first.
    """
    differs = comparison.kernel != comparison.pymunk
    settled = {width: settled_mask(comparison.kernel, width) for width in NEIGHBOURHOODS}
    order = sorted(zip(*np.nonzero(differs)), key=lambda ij: [not settled[width][ij] for width in NEIGHBOURHOODS[::-1]])
    grid = cfg.grid
    kinds = {}
    for rank, (i, j) in enumerate(order):
        cell = cfg.with_initial(**{grid.x.param: comparison.x_values[j], grid.y.param: comparison.y_values[i]})
        report = roll_config(cell)
        times, path, impulses = pymunk_path(cell, initial_state(cell), comparison, report.t_end)
        events = kernel_impacts(cell, report)
        number, kind = parting_impact(events, impulses, cfg.die.circumradius, comparison.dt)
        kind = f"kernel {report.status_name}, impact {number}: {kind}"
        kinds[kind] = kinds.get(kind, 0) + 1
        if rank >= count:
            continue
        both = times <= report.t_end
        ours = sample_path(cell, report, times[both])
        apart = np.nonzero(np.abs(ours[:, 2] - path[both, 2]) > DIVERGED_ANGLE)[0]
        print(f"\npixel ({i}, {j}): {grid.x.param} = {comparison.x_values[j]:.4g}, "
              f"{grid.y.param} = {comparison.y_values[i]:.4g}; kernel side {comparison.kernel[i, j]} "
              f"(t_decided {report.t_decided:.4f} s), pymunk side {comparison.pymunk[i, j]}; "
              f"settled 3x3: {bool(settled[3][i, j])}, 5x5: {bool(settled[5][i, j])}; {kind}")
        print(f"  angles differ by > {DIVERGED_ANGLE} rad from t = "
              + (f"{times[apart[0]]:.4f} s" if apart.size else "never (within the kernel's run)"))
        print_events("kernel", events)
        print_events("pymunk", impulses)
    print(f"\n{len(order)} disagreeing pixels by the impact at which the paths part "
          f"(alike: within {IMPACT_TIME_MATCH} steps and {IMPACT_MATCH:.0%} of the speed):")
    for kind, number in sorted(kinds.items()):
        print(f"  {kind}: {number}")


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--flat", action="store_true",
                        help="issue 15's maps where flat impacts dominate, instead of issue 4's map")
    parser.add_argument("--num", type=int, default=None,
                        help=f"cells per axis (default {DEFAULT_NUM}; {FLAT_NUM} with --flat)")
    parser.add_argument("--set", action="append", default=[], dest="overrides", metavar="KEY=VALUE",
                        help="config override, e.g. contact.friction=0.3 (repeatable)")
    parser.add_argument("--png", type=Path, default=None,
                        help=f"figure to write (default docs/figures/{DEFAULT_PNG.name}; {FLAT_PNG.name} with --flat)")
    parser.add_argument("--explain", type=int, default=None, metavar="K",
                        help="count the disagreeing pixels by the impact at which the two paths part, and "
                             "print both paths of K of them, the most settled first")
    flat_maps = tuple(flat_impact_configs(2))
    parser.add_argument("--maps", nargs="+", choices=flat_maps, default=list(flat_maps),
                        help="with --flat: which maps (default all)")
    parser.add_argument("--check-dt", type=float, default=None,
                        help="with --flat: pymunk's map again at this step, s, against its own at --dt "
                             "(default half of --dt; 0: skip)")
    defaults = PymunkSettings()
    parser.add_argument("--dt", type=float, default=None, help=f"pymunk's step, s (default 1e-4; {FLAT_DT:g} with --flat)")
    parser.add_argument("--iterations", type=int, default=None,
                        help=f"pymunk solver passes per step (default {defaults.iterations}; "
                             f"{FLAT_SETTINGS.iterations} with --flat)")
    parser.add_argument("--collision-slop", type=float, default=defaults.collision_slop,
                        help=f"overlap left uncorrected, m (default {defaults.collision_slop:g})")
    parser.add_argument("--overlap-fixed-per-step", type=float, default=defaults.overlap_fixed_per_step,
                        help=f"share of the overlap corrected per step (default {defaults.overlap_fixed_per_step:g})")
    args = parser.parse_args()
    if args.flat:
        if args.explain is not None:
            parser.error("--explain goes with issue 4's map, not with --flat")
        dt = FLAT_DT if args.dt is None else args.dt
        settings = PymunkSettings(FLAT_SETTINGS.iterations if args.iterations is None else args.iterations,
                                  args.collision_slop, args.overlap_fixed_per_step)
        check_dt = 0.5 * dt if args.check_dt is None else args.check_dt
        compare_flat(args.num or FLAT_NUM, args.maps, args.overrides, dt, check_dt, settings, args.png or FLAT_PNG)
        return
    args.num = args.num or DEFAULT_NUM
    args.dt = 1e-4 if args.dt is None else args.dt
    settings = PymunkSettings(defaults.iterations if args.iterations is None else args.iterations,
                              args.collision_slop, args.overlap_fixed_per_step)
    cfg = comparison_config(args.num, args.overrides)
    print(f"grid {args.num} x {args.num}: {cfg.grid.x.param} in [{cfg.grid.x.min:g}, {cfg.grid.x.max:g}], "
          f"{cfg.grid.y.param} in [{cfg.grid.y.min:g}, {cfg.grid.y.max:g}]; model {cfg.contact.model}, "
          f"beta_normal {cfg.contact.beta_normal:g}, beta_tangential {cfg.contact.beta_tangential:g}, "
          f"friction {cfg.contact.friction:g}")
    comparison = compare_with_kernel(cfg, dt=args.dt, settings=settings)
    print(f"pymunk: dt {args.dt:g} s, {settings}")
    print_agreement(comparison)
    write_figure([(cfg, comparison, None)], args.png or DEFAULT_PNG)
    if args.explain is not None:
        explain(cfg, comparison, args.explain)
        first_impacts(cfg, comparison, FIRST_IMPACT_STRIDE)


if __name__ == "__main__":
    main()
