"""The reports of the measured-data commands: the --effects list, JSON-ready values, the residual
by bounce and by landing tilt, the residual curves and the Markdown report (text, no files)."""

import math

import numpy as np

from dice_sweep import effects as registry
from dice_sweep.errors import DiceSweepError


def parse_effects(text):
    """``a,b`` -> ('a', 'b'), each an effect of the registry (DiceSweepError naming --effects)."""
    names = tuple(name.strip() for name in text.split(",") if name.strip()) if text else ()
    unknown = [name for name in names if name not in registry.names()]
    if unknown:
        raise DiceSweepError(f"--effects: unknown effect {unknown[0]!r} (allowed: {', '.join(registry.names())})")
    return names


def jsonable(value):
    if isinstance(value, dict):
        return {str(k): jsonable(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [jsonable(v) for v in value]
    if isinstance(value, (np.floating, float)):
        return None if not math.isfinite(float(value)) else float(value)
    if isinstance(value, (np.integer,)):
        return int(value)
    if isinstance(value, np.bool_):
        return bool(value)
    return value


def residual_by_bounce(cfg, fits):
    """RMS error (m) of the held-out tracks' frames predicted through impact k (k = 1, 2, ...),
    before and after, with the number of tracks; and the same by landing tilt."""
    seg_confirm = fits["segments"][1]
    out = []
    residuals = fits["confirm_residuals"]
    # segment index within its track = which impact its prediction crosses
    bounce_of_row = _flight_index(seg_confirm)[seg_confirm.segment_rows] + 1
    tilt = _landing_tilts(cfg, seg_confirm, fits["prepared"][1])
    by_tilt = []
    edges = np.linspace(0.0, math.pi / cfg.die.sides, TILT_BINS + 1)
    for low, high in zip(edges[:-1], edges[1:]):
        rows = seg_confirm.predicted & (tilt[seg_confirm.segment_rows] >= low) & (tilt[seg_confirm.segment_rows] < high + 1e-12)
        if not rows.any():
            continue
        entry = {"tilt_deg": [math.degrees(low), math.degrees(high)], "tracks": int(np.unique(seg_confirm.track_rows[rows]).size),
                 "impacts": int(np.unique(seg_confirm.segment_rows[rows]).size)}
        for label, residual in residuals.items():
            entry[label] = float(np.sqrt(np.mean(np.sum(residual[rows] ** 2, axis=1))))
        by_tilt.append(entry)
    for k in range(1, int(bounce_of_row.max(initial=0)) + 1):
        rows = seg_confirm.predicted & (bounce_of_row == k)
        if not rows.any():
            continue
        entry = {"impact": k, "tracks": int(np.unique(seg_confirm.track_rows[rows]).size)}
        for label, residual in residuals.items():
            entry[label] = float(np.sqrt(np.mean(np.sum(residual[rows] ** 2, axis=1))))
        out.append(entry)
    return out, by_tilt


TILT_BINS = 3  # landing tilt bins from flat (0) to corner down (pi / n)


def _landing_tilts(cfg, segments, prepared):
    """Tilt (rad) of the lower side at each segment's impact: 0 flat, pi/n corner down, from
    the tracked angle at the last frame of the segment's own flight."""
    from dice_sweep.measured.impacts import landing_tilt

    tilt = np.full(segments.count, np.nan)
    for j in range(segments.count):
        rows = np.arange(segments.starts[j], segments.starts[j + 1])
        own = rows[~segments.predicted[rows]]
        if own.size:
            tilt[j] = landing_tilt(cfg.die.sides, segments.measured[own[-1], 2])
    return tilt


def residual_curves(residuals, prepared, segments):
    """(label, time from the first impact in s, pose error in m) per frame, one entry per
    residual (label -> (rows, 3) m, on ``segments``): what the residual picture draws."""
    t_impact = np.array([p.t_impact for p in prepared])
    seg_t0 = np.array([prepared[segments.track[j]].t[prepared[segments.track[j]].flights[k][0]]
                       for j, k in zip(range(segments.count), _flight_index(segments))])
    since = segments.times + seg_t0[segments.segment_rows] - t_impact[segments.track_rows]
    return [(label, since, np.sqrt(np.sum(residual**2, axis=1))) for label, residual in residuals.items()]


def _flight_index(segments):
    index = np.zeros(segments.count, dtype=np.int64)
    for i in range(segments.tracks):
        mine = np.flatnonzero(segments.track == i)
        index[mine] = np.arange(mine.size)
    return index


def _mm(value):
    return "n/a" if value is None or not math.isfinite(value) else f"{value * 1000:.3f} mm"


def _interval(entry, scale=1000.0, unit="mm"):
    low, high = entry
    if low is None or high is None:
        return "n/a"
    return f"[{low * scale:.3f}, {high * scale:.3f}] {unit}"


def _params_table(params):
    lines = ["| parameter | value | 95 % interval | unit | at a bound | largest one-track share of its information |",
             "|---|---|---|---|---|---|"]
    for name, p in params.items():
        ci = p["ci95"]
        ci_text = "n/a" if ci[0] is None else f"[{ci[0]:.4g}, {ci[1]:.4g}]"
        share = p.get("top_track_share")
        share_text = "-" if share is None else f"{share:.0%}" + (" (one track decides: interval not to be trusted)" if p.get("one_track_decides") else "")
        lines.append(f"| {name} | {p['value']:.4g} | {ci_text} | {p['unit']} | {'yes' if p['at_bound'] else 'no'} | {share_text} |")
    return lines


def _round_table(label, results):
    lines = [f"| {label} | held-out error | median held-out | z | share of excess | null excluded | at bound | added |",
             "|---|---|---|---|---|---|---|---|"]
    for c in results:  # (the tracks each makes worse and better are in the JSON: worse_tracks, better_tracks)
        lines.append(f"| {c['effect']} | {_mm(c['test_error'])} | {_mm(c['median_error'])} | {c['z']:.2f} | {c['excess_share']:.0%} | "
                     f"{'yes' if c['null_excluded'] else 'no'} | {', '.join(c['at_bound']) or '-'} | {'yes' if c['accepted'] else 'no'} |")
    return lines


def _presence(signature):
    state = {True: "present", False: "absent", None: "not measured"}[signature["present_before"]]
    return state + ("" if signature["counts"] else " (does not count)")


def _z(value):
    return "n/a" if value is None or not math.isfinite(value) else f"z = {value:.2f}"


def _proposal_lines(report):
    proposals = report.get("proposals") or []
    if not proposals:
        return []
    lines = ["## Proposals: formulas for what the final model leaves", "",
             "Sparse formulas fitted to the residual the final model leaves (terms, not effects of the library; "
             f"{report.get('proposals_note', '')}).", "",
             "| target | terms [95 % interval] | held-out gain |", "|---|---|---|"]
    for p in proposals:
        terms = ", ".join(f"`{t}` {v:+.4g} [{p['ci95'][t][0]:+.4g}, {p['ci95'][t][1]:+.4g}]" for t, v in p["terms"].items())
        lines.append(f"| `{p['target']}` ({p.get('unit', '')}) | {terms} | {p['heldout_gain']:.2f} |")
    return lines + [""]


def markdown_report(report):
    """A readable summary of a diagnose report (works for any number of tracks)."""
    floor = report["noise_floor"]
    lines = ["# Diagnosis of tracked drops", "",
             f"**Verdict: {report['verdict']}.** Effects added: {', '.join(report['effects_added']) or 'none'}."
             + "".join(f" Removed at the end: {r['effect']} ({r['reason']})." for r in report.get("effects_removed", []))
             + "".join(f" No motion can tell {name} from {', '.join(others)} (the same data, another parameter)."
                       for name, others in report.get("equivalent_effects", {}).items()), "",
             f"Metric: {report['metric']}.", "", f"Selection: {report['selection']}.", ""]
    data = report["data"]
    noise = report["noise"]
    spread = report.get("verdict_spread", {})
    if "usable_tracks" in data:
        used = f"{data['usable_tracks']} usable ({data['flights']} flights) in {data['cross_folds']} cross-fitting folds"
    else:  # a report of the loop before cross-fitting (issue 30)
        used = (f"{data['selection_tracks']} selection tracks ({data['selection_flights']} flights) and {data['confirmation_tracks']} "
                f"confirmation tracks ({data['confirmation_flights']} flights) usable")
    lines += [f"Data: {data['path']}: {data['tracks']} tracks at {data['rate_hz']:g} Hz; {used}; "
              f"{data['glitch_frames']} glitch frames excluded, {data['gap_frames']} dropped frames re-inserted.", "",
              f"Angle: {report['angle_reading']}", "",
              f"Tracking noise (free flights): sigma x {noise['sigma_x'] * 1e3:.4f} mm, y {noise['sigma_y'] * 1e3:.4f} mm, "
              f"phi {noise['sigma_phi'] * 1e3:.3f} mrad; noise floor {_mm(floor)} (95 % {_interval(noise['pose_ci95'])}).", ""]
    if spread:
        lines += [f"Verdict over re-splits: {', '.join(spread['verdicts'])} ({'all agree' if spread['agree'] else 'they differ'}; "
                  f"{spread['method']}).", ""]
    effects = report.get("effects", {})
    if effects:
        lines += ["## Cause or stand-in", "", "| effect | called | failed | comparisons (split: parameter z) | signature before |",
                  "|---|---|---|---|---|"]
        for name, entry in effects.items():
            c = entry["consistency"]
            tests = "; ".join(f"{x['split']}: {x['param']} {_z(x['z'])}" for x in c["comparisons"]) or "no parameter"
            sig = c["signature"]
            lines.append(f"| {name} | {entry['cause']} | {'; '.join(c['failed']) or '-'} | {tests} | "
                         f"{sig['name'] or 'none'}: {_presence(sig)} |")
        lines.append("")
    lines += ["## Before and after, every track held out (cross-fitting)", "",
              "| model | effects | RMS over tracks | 95 % interval | x floor | median track | 95 % interval | x floor |",
              "|---|---|---|---|---|---|---|---|"]
    for label in ("baseline", "after"):
        entry = report[label]
        lines.append(f"| {label} | {', '.join(entry['effects']) or 'none'} | {_mm(entry['test_error'])} | {_interval(entry['ci95'])} | "
                     f"{entry['multiple_of_floor']:.1f} | {_mm(entry['median_error'])} | {_interval(entry['median_ci95'])} | "
                     f"{entry['median_multiple_of_floor']:.1f} |")
    lines += ["", f"Verdict rule: {report['verdict_rule']}."]
    worst = report.get("worst_tracks")
    if worst:
        lines += ["", "Worst tracks (held-out error):", "", "| before: track | before | after | | after: track | after | before |",
                  "|---|---|---|---|---|---|---|"]
        for b, a in zip(worst["before"], worst["after"]):
            lines.append(f"| {b['traj']} | {_mm(b['before'])} | {_mm(b['after'])} | | {a['traj']} | {_mm(a['after'])} | {_mm(a['before'])} |")
    lines += ["", "## Parameters after", ""] + _params_table(report["after"]["params"])
    lines += ["", "## Rounds", ""]
    for fold in report.get("folds", []):
        lines.append(f"Fold {fold['fold'] + 1}: chosen on {fold['chosen_on_tracks']} tracks, predicts {fold['held_out_tracks']}; added "
                     f"{', '.join(fold['effects_added']) or 'nothing'}; its held-out median {_mm(fold['held_out']['baseline']['median_error'])} "
                     f"-> {_mm(fold['held_out']['after']['median_error'])}.")
    lines.append("")
    numbers = {}
    for rnd in report["rounds"]:
        k = numbers[rnd.get("fold")] = numbers.get(rnd.get("fold"), 0) + 1
        where = f"Fold {rnd['fold'] + 1}, round {k}" if rnd.get("fold") is not None else f"Round {k}"
        lines += [f"{where}: threshold z = {rnd['threshold_z']:.2f} (Sidak bound {rnd['sidak_z']:.2f}, {rnd['null_simulations']} null simulations).", ""]
        lines += _round_table("effect", rnd["candidates"])
        if rnd.get("pairs"):
            lines += ["", f"No single effect passed; pairs fitted together (threshold z = {rnd['pair_threshold_z']:.2f}):", ""]
            lines += _round_table("effects", rnd["pairs"])
        lines.append("")
    if report.get("by_bounce"):
        lines += ["## Error by impact (held-out tracks, frames predicted through impact k)", "",
                  "| impact | tracks | before | after |", "|---|---|---|---|"]
        lines += [f"| {b['impact']} | {b['tracks']} | {_mm(b['baseline'])} | {_mm(b['after'])} |" for b in report["by_bounce"]]
        lines.append("")
    if report.get("by_tilt"):
        lines += ["## Error by landing tilt (held-out tracks, frames predicted through an impact; 0 deg = flat)", "",
                  "| tilt | impacts | tracks | before | after |", "|---|---|---|---|---|"]
        lines += [f"| {b['tilt_deg'][0]:.0f}-{b['tilt_deg'][1]:.0f} deg | {b['impacts']} | {b['tracks']} | {_mm(b['baseline'])} | {_mm(b['after'])} |"
                  for b in report["by_tilt"]]
        lines.append("")
    lines += _proposal_lines(report)
    lines += ["## Residual signatures after", "", "| signature | value | 95 % interval | unit | points to | meaning |", "|---|---|---|---|---|---|"]
    for s in report["signatures"]:
        value = "n/a" if s["value"] is None else f"{s['value']:.4g}"
        ci = "n/a" if s["ci95"][0] is None else f"[{s['ci95'][0]:.4g}, {s['ci95'][1]:.4g}]"
        lines.append(f"| {s['signature']} | {value} | {ci} | {s['unit']} | {', '.join(s['points_to'])} | {s['note']} |")
    if report["verdict"] != "explained":
        remaining = report.get("signatures_remaining") or []
        lines += ["", f"**Not explained:** the median track error after is {report['after']['median_multiple_of_floor']:.1f} times the noise floor. "
                  + (f"Signatures left (interval excludes 0): {', '.join(remaining)}." if remaining else "No flight signature is left; the misfit is at the impacts.")]
    return "\n".join(lines) + "\n"
