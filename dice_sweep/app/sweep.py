"""The ``sweep``, ``merge`` and ``plot`` commands: a config in, a sweep file and its
final-state diagram out.

The application layer joins what the lower layers keep apart: dice_sweep.sweep and
dice_sweep.refine compute and write the file, storage reads it back, config turns its stored
text into a title, plotting draws. The command's inputs are checked here, once, before any
work (the config itself when it was loaded, the option values by the command line); the
layers below take them as checked.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from pathlib import Path

import numpy as np

from dice_sweep.config import check_computable, parse_config, require_grid
from dice_sweep.errors import DiceSweepError
from dice_sweep.executor import check_executor
from dice_sweep.outputs import SWEEP_FILE, check_outputs
from dice_sweep.storage import read_sweep


def sweep_config(sweep_data):
    """The config a sweep file was computed with (its stored TOML, parsed)."""
    return parse_config(sweep_data.config_toml, source=f"{sweep_data.path}: config_toml")


def diagram_title(sweep_data) -> str:
    """Title of a sweep's final-state diagram: its config, and "(incomplete)" when cells are missing."""
    from dice_sweep.plotting import outcome_title  # matplotlib: only where a picture is drawn (start-up time)

    return outcome_title(sweep_config(sweep_data), sweep_data.complete and bool(sweep_data.computed.all()))


def draw_sweep_file(h5_path, png_path, *, box=None, dpi=150, warn: Callable[[str], None] | None = None):
    """Draw the final-state diagram of a sweep file (complete or not) into ``png_path``.

    ``warn`` gets one line when some cells are not computed yet (an incomplete sweep or one
    shard); they are drawn grey as "not computed" either way. Returns ``png_path``.
    """
    from dice_sweep.plotting import check_dpi, probability_figure, save_figure, sweep_figure

    check_dpi(dpi)
    sweep_data = read_sweep(h5_path)
    missing = int(np.count_nonzero(~sweep_data.computed))
    if missing and warn is not None:
        warn(f"{h5_path}: {missing} of {sweep_data.outcome.size} cells not computed yet, drawn grey as 'not computed' "
             "(finish the sweep with --resume, or merge its shards)")
    title = diagram_title(sweep_data)
    if sweep_data.probability is None:
        figure = sweep_figure(sweep_data, title, box=box, dpi=dpi)
    else:  # a probability sweep: the most likely side shaded by its probability, and the entropy
        from dice_sweep.chaos.measures import shannon_entropy

        entropy = np.where(sweep_data.computed, shannon_entropy(np.nan_to_num(sweep_data.probability)), np.nan)
        figure = probability_figure(sweep_data, entropy, title, box=box, dpi=dpi)
    save_figure(figure, png_path, dpi)
    return png_path


def draw_sweep_files(h5_paths: Sequence, png_path, *, titles=None, dpi=100):
    """Final-state diagrams of several sweep files side by side; titles default to each
    file's config. Returns ``png_path``."""
    from dice_sweep.plotting import plot_comparison

    sweeps = [read_sweep(path) for path in h5_paths]
    return plot_comparison(sweeps, titles or [diagram_title(s) for s in sweeps], png_path, dpi=dpi)


def sweep(cfg, out_path, *, png_path=None, workers=None, shard=(0, 1), resume=False, progress=True, refine_levels=None,
          executor="local", scheduler=None, log=None, warn=None):
    """The ``sweep`` command: a full, sharded, resumed, dask or refined sweep of ``cfg`` into
    ``out_path``, then its diagram if asked. Returns (summary, pictures written).

    ``cfg`` is a loaded (validated) config, ``shard`` and ``workers`` the checked option values
    (:func:`dice_sweep.executor.parse_shard`, :func:`dice_sweep.executor.worker_count`), the
    output paths checked (:func:`dice_sweep.outputs.check_outputs`). What only this command
    asks is checked here: a grid, ``--refine``'s levels and what it combines with, the executor.
    """
    require_grid(cfg)
    check_computable(cfg)
    if refine_levels is not None:
        from dice_sweep.refine import check_levels, check_refinable, run_refined_sweep  # only here: start-up time

        if resume or shard != (0, 1) or executor != "local":
            raise DiceSweepError("--refine: cannot be combined with --shard, --resume or --executor dask (a refined sweep is written whole, at the end)")
        check_refinable(cfg)
        check_levels(cfg, refine_levels)
        summary = run_refined_sweep(cfg, out_path, refine_levels, workers=workers, progress=progress, log=log)
    else:
        from dice_sweep.sweep import run_sweep

        check_executor(executor, scheduler, workers)
        summary = run_sweep(cfg, out_path, workers=workers, shard=shard, resume=resume, progress=progress,
                            executor=executor, scheduler=scheduler)
    written = [draw_sweep_file(out_path, png_path, warn=warn)] if png_path else []
    return summary, written


def merge(part_paths: Sequence, out_path):
    """The ``merge`` command: the complete shard files of one sweep joined into ``out_path``
    (:func:`dice_sweep.sweep.merge_parts`). Returns its summary."""
    from dice_sweep.sweep import merge_parts

    check_outputs(("--output", Path(out_path), SWEEP_FILE))  # a Path: an empty name is checked too, as "."
    return merge_parts(part_paths, out_path)
