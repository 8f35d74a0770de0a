"""The ``measure`` and ``control`` commands: a sweep file in, numbers, JSON and pictures out.

The application layer joins what the lower layers keep apart: storage reads the file,
dice_sweep.chaos computes, dice_sweep.plotting draws, dice_sweep.outputs checks and writes.
"""

from __future__ import annotations

import pathlib

from dice_sweep.chaos.control import ControlMap, control_map
from dice_sweep.chaos.measures import DEFAULT_BOX_SIZE, ChaosMeasures, measure_map
from dice_sweep.errors import DiceSweepError
from dice_sweep.outputs import FOLDER, JSON, NPZ, check_outputs, make_folder, write_json
from dice_sweep.plotting import axis_labels, box_entropy_panel, plot_control_map, plot_scalar_maps, plot_uncertainty_curves
from dice_sweep.storage import read_sweep


def _png_folder(png_dir) -> pathlib.Path:
    check_outputs(("--png", png_dir, FOLDER))
    folder = pathlib.Path(png_dir)
    return make_folder(folder)


def read_complete_sweep(path):
    """:func:`dice_sweep.storage.read_sweep`, refusing a file with cells not computed.

    Raises
    ------
    DiceSweepError
        If some cell was never computed (an interrupted sweep).
    """
    sweep = read_sweep(path)
    missing = int((~sweep.computed).sum())
    if missing:
        raise DiceSweepError(f"{path}: {missing} cells not computed; finish the sweep with --resume first")
    return sweep


def measure_file(path, box_size=DEFAULT_BOX_SIZE) -> ChaosMeasures:
    """:func:`measure_map` of a complete sweep file (docs/hdf5.md).

    Parameters
    ----------
    path : str or os.PathLike
        Sweep file.
    box_size : int
        Box side for Sb and Sbb, pixels.

    Returns
    -------
    ChaosMeasures
    """
    return measure_sweep(read_complete_sweep(path), box_size)


def measure_sweep(sweep, box_size=DEFAULT_BOX_SIZE) -> ChaosMeasures:
    """:func:`measure_map` of a sweep read into memory, with its probability maps if it has them."""
    return measure_map(sweep.outcome, sweep.sides, box_size, x_step=sweep.x.cell_width, y_step=sweep.y.cell_width,
                       probability=sweep.probability, draws=sweep.draws)


def measure_pictures(sweep, measures: ChaosMeasures, png_dir) -> list[pathlib.Path]:
    """Draw f(eps) with its fit and the map of box entropies into ``png_dir``.

    Returns
    -------
    list of pathlib.Path
        ``uncertainty.png`` and ``box_entropy.png``.
    """
    folder = _png_folder(png_dir)
    return [
        plot_uncertainty_curves([measures.uncertainty], [pathlib.Path(sweep.path).name], folder / "uncertainty.png"),
        plot_scalar_maps([box_entropy_panel(sweep, measures.entropy)], folder / "box_entropy.png"),
    ]


def run_measure(path, *, box_size=DEFAULT_BOX_SIZE, json_path=None, png_dir=None) -> ChaosMeasures:
    """The ``measure`` command: measure a sweep file, optionally write JSON and pictures.

    Parameters
    ----------
    path : str or os.PathLike
        Complete sweep file.
    box_size : int
        Box side for Sb and Sbb, pixels.
    json_path : str or os.PathLike, optional
        Write every number (:meth:`ChaosMeasures.to_dict`) here.
    png_dir : str or os.PathLike, optional
        Folder (created if missing) for ``uncertainty.png`` and ``box_entropy.png``.

    Returns
    -------
    ChaosMeasures
    """
    check_outputs(("--json", json_path, JSON), ("--png", png_dir, FOLDER))
    sweep = read_complete_sweep(path)
    measures = measure_sweep(sweep, box_size)
    if json_path:
        write_json(json_path, {"file": str(path), **measures.to_dict()})
    if png_dir:
        measure_pictures(sweep, measures, png_dir)
    return measures


def run_control(path, sigmas, *, json_path=None, png_dir=None, npz_path=None, **options) -> ControlMap:
    """The ``control`` command: a control map of a sweep file, optionally JSON, pictures, arrays.

    Parameters
    ----------
    path : str or os.PathLike
        Complete sweep file.
    sigmas : dict of str to float
        Standard deviations of the scattered initial values, SI units.
    json_path : str or os.PathLike, optional
        Write :meth:`ControlMap.summary` here.
    png_dir : str or os.PathLike, optional
        Folder (created if missing) for ``control.png``.
    npz_path : str or os.PathLike, optional
        Save the maps here (:meth:`ControlMap.to_npz`).
    **options
        As :func:`control_map` (method, samples, max_points, seed, workers).

    Returns
    -------
    ControlMap
    """
    check_outputs(("--json", json_path, JSON), ("--png", png_dir, FOLDER), ("--output", npz_path, NPZ))
    sweep = read_complete_sweep(path)
    control = control_map(sweep, sigmas, **options)
    if json_path:
        write_json(json_path, {"file": str(path), **control.summary()})
    if png_dir:
        plot_control_map(control, _png_folder(png_dir) / "control.png", *axis_labels(sweep))
    if npz_path:
        control.to_npz(npz_path)
    return control
