"""The ``simulate-drops`` command: a config in; synthetic tracked drops (CSV, or gzip) and their
provenance (``OUT.csv.json``) out. The drops are dice_sweep.measured.simulate's.
"""

import gzip
import json
from pathlib import Path

from dice_sweep.config import check_computable
from dice_sweep.errors import DiceSweepError
from dice_sweep.measured.simulate import csv_chunks, parse_noise, parse_range, provenance, sidecar_path, simulate_drops
from dice_sweep.outputs import CSV, JSON, check_outputs, replace_atomically, write_json

__all__ = ["run_simulate_drops", "write_drops", "parse_noise", "parse_range"]  # the command's option parsers too


def _write_data(drops, path, file):
    """The CSV into a binary file object, gzip-compressed when ``path`` ends in .gz."""
    if not str(path).lower().endswith(".gz"):
        file.writelines(csv_chunks(drops))
        return
    # mtime 0 and no name: the same bytes every run
    with gzip.GzipFile(filename="", mode="wb", fileobj=file, mtime=0, compresslevel=6) as packed:
        packed.writelines(csv_chunks(drops))


def write_drops(drops, cfg, path):
    """Write the drops as CSV (gzip when ``path`` ends in .gz) and the provenance as
    ``path + ".json"``; each whole or not at all (a ``.partial`` file renamed), the data's
    partial file complete before the sidecar is renamed, so that no data file stands without
    its sidecar. Returns ``path``."""
    record = provenance(drops, cfg, path)

    def write(file):
        _write_data(drops, path, file)
        file.flush()
        write_json(sidecar_path(path), record, indent=1)

    replace_atomically(path, write)
    return path


def _check_not_data(path):
    """Refuse to replace a track file that simulate-drops did not write (tracked data, say):
    one it wrote has its sidecar, which says ``"synthetic": true``."""
    if not Path(path).exists():
        return
    try:
        synthetic = json.loads(sidecar_path(path).read_text(encoding="utf-8")).get("synthetic") is True
    except (OSError, ValueError, AttributeError):
        synthetic = False
    if not synthetic:
        raise DiceSweepError(f"--output: {path}: exists and was not written by simulate-drops (no {sidecar_path(path).name} "
                             "saying it is synthetic); remove it or choose another name (allowed: a new file, or one "
                             "simulate-drops wrote)")


def run_simulate_drops(cfg, out_path, tracks, **options):
    """The ``simulate-drops`` command: check everything, simulate, write the CSV and its
    sidecar JSON; returns the :class:`~dice_sweep.measured.simulate.SimulatedDrops`
    (``describe(out_path)`` for the user)."""
    check_outputs(("--output", out_path, CSV), ("--output", sidecar_path(out_path), JSON))
    _check_not_data(out_path)
    check_computable(cfg)
    drops = simulate_drops(cfg, tracks, **options)  # checks every option before any work
    write_drops(drops, cfg, out_path)
    return drops
