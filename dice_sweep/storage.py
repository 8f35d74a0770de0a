"""The HDF5 layout of a sweep (docs/hdf5.md); the only module that imports h5py.

A sweep file holds one (ny, nx) final-state map per quantity, chunked by tile, plus the axis
values as dimension scales and root attributes describing the run. Tiles are written one at a
time and recorded in ``/done_tiles`` only after their data, so a killed run loses at most the
tiles it was computing, and ``complete`` turns true only once every tile of the shard is in.

Layout 2 is also a netCDF-4 file as xarray reads it (``xarray.open_dataset(path,
engine="h5netcdf")``): the axes are named after the swept parameters, every variable has CF
``long_name`` (and ``units`` where it is a quantity), and every map has a ``_FillValue`` no
computed cell holds, so cells not computed yet decode to NaN. Layout 1 files are still read,
resumed and merged.
"""

from __future__ import annotations

import contextlib
import dataclasses
import datetime
import errno
import io
import os
import zlib
from collections.abc import Mapping

import h5py
import numpy as np

from dice_sweep import __version__
from dice_sweep.config import MAX_SIDES, PARAM_LONG_NAMES
from dice_sweep.errors import DiceSweepError
from dice_sweep.inputs import not_a_file
from dice_sweep.outputs import check_space, written

LAYOUT_VERSION = 2  # bump when a dataset or attribute changes meaning
READ_LAYOUTS = (1, LAYOUT_VERSION)  # layouts this version reads, resumes and merges; it writes LAYOUT_VERSION
NOT_COMPUTED = 255  # /status of a cell no tile has written yet
UNDECIDED = -1  # /outcome of a roll without an answer (layout 1: also of a cell not computed yet)
# Layout 2 fills the other maps with values no roll gives either (docs/hdf5.md, "Fill values"):
OUTCOME_NOT_COMPUTED = -128  # /outcome of a cell not computed yet: no side, and not UNDECIDED
COUNT_NOT_COMPUTED = np.iinfo(np.uint16).max  # a counter of a cell not computed yet
COUNT_MAX = COUNT_NOT_COMPUTED - 1  # counters are clipped here (layout 1: at 65535, fill 0)
PROBABILITY_PREFIX = "probability_"  # /probability_k: share of a cell's draws ending on side k
NO_ANSWER = "no_answer"  # its share of draws without a side; the shares of a cell sum to 1
COUNTS_GROUP = "counts"  # layout 1 kept the counters other than impacts in /counts/<name>
TILE_DIM = "tile"  # the dimension (and coordinate: tile index) of /done_tiles
CONVENTIONS = "CF-1.8"
SHARD_RULE = "tile_index % N == I"
COUNT_LONG_NAMES = {  # long_name of each kernel counter (dice_sweep.physics.COUNT_COLUMNS)
    "impacts": "impacts of the roll (table and walls)",
    "wall_impacts": "impacts on the walls",
    "corner_fallbacks": "impacts resolved at the corner",
    "pivots": "pivot phases",
    "energy_clips": "impulses moved so that the impact gains no energy",
    "multi_contacts": "impacts of two contacts at once",
}

_GZIP_LEVEL = 4
_COMPRESSION = {"compression": "gzip", "compression_opts": _GZIP_LEVEL, "shuffle": True}


@dataclasses.dataclass(frozen=True)
class SweepAxis:
    """One axis of the map: the swept parameter and its cell centres.

    Attributes
    ----------
    param : str
        Name of the swept initial-condition parameter (``y0``, ``omega0``, ...).
    unit : str
        Its SI unit (``m``, ``m/s``, ``rad``, ``rad/s``).
    values : numpy.ndarray
        Cell centres, float64, in the parameter's SI unit.
    lo, hi : float
        The range [lo, hi] the cells cover (the image extent).
    """

    param: str
    unit: str
    values: np.ndarray
    lo: float
    hi: float

    @property
    def cell_width(self) -> float:
        """Width of a cell along the axis, in its unit: (hi - lo) / cells."""
        return (self.hi - self.lo) / len(self.values)


@dataclasses.dataclass(frozen=True)
class SweepHeader:
    """Everything fixed when a sweep file is created.

    Attributes
    ----------
    config_toml : str
        The resolved config (``dice_sweep.config.config_to_toml``).
    sides : int
        Number of sides n of the die; outcomes are 0..n-1.
    x, y : SweepAxis
        The fast (column) and slow (row) axes.
    tile_shape : tuple of int
        (rows, columns) of a tile; edge tiles are clipped.
    shard : tuple of int
        (I, N): the file holds the tiles with ``tile_index % N == I``.
    count_columns : tuple of str
        Names of the kernel counters; ``impacts`` goes to ``/impacts``, others to ``/counts``.
    status_names : tuple of str
        Meaning of the kernel status codes (index = code).
    dice_sweep_version : str
        Version of the package that created the file.
    draws : int
        Rolls per cell (``[scatter] draws``); above 1 the file also holds the share of the
        draws ending on each side (docs/hdf5.md, "Probability sweeps").
    """

    config_toml: str
    sides: int
    x: SweepAxis
    y: SweepAxis
    tile_shape: tuple[int, int]
    shard: tuple[int, int]
    count_columns: tuple[str, ...]
    status_names: tuple[str, ...]
    dice_sweep_version: str = __version__
    draws: int = 1

    @property
    def shape(self) -> tuple[int, int]:
        """(ny, nx) of the maps."""
        return (len(self.y.values), len(self.x.values))

    @property
    def probability_sides(self) -> int:
        """Sides with a probability map: n for a sweep of ``draws`` > 1 rolls per cell, else 0."""
        return self.sides if self.draws > 1 else 0


@dataclasses.dataclass(frozen=True)
class SweepData:
    """A sweep file read into memory (:func:`read_sweep`).

    Attributes
    ----------
    path : str
        The file read.
    outcome : numpy.ndarray
        int8 (ny, nx): side 0..n-1, -1 undecided or not computed.
    status : numpy.ndarray
        uint8 (ny, nx): kernel status code (0 decided), 255 not computed.
    impacts : numpy.ndarray
        uint16 (ny, nx): table and wall impacts of the roll, clipped at 65534 (65535 in
        layout 1 files).
    t_decided : numpy.ndarray
        float32 (ny, nx): simulated time at which the side was decided, s (NaN if not).
    counts : dict of str to numpy.ndarray
        The other kernel counters (uint16, clipped), by name.
    x, y : SweepAxis
        Column and row axes (values, parameter, unit, extent).
    config_toml : str
        The resolved config of the run.
    sides : int
        Number of sides n.
    complete : bool
        True only if every tile of the file's shard was written.
    shard : tuple of int
        (I, N) of the file; (0, 1) for a whole or merged sweep.
    status_names : tuple of str
        Meaning of the status codes below 255.
    dice_sweep_version, created : str
        Version that made the file and its creation time (ISO 8601, UTC).
    draws : int
        Rolls per cell; with more than 1, the per-roll maps above are those of draw 0.
    probability : numpy.ndarray or None
        float32 (n + 1, ny, nx) for draws > 1: row k < n the share of the draws ending on side
        k, row n the share with no answer (-1); NaN where not computed. None for one draw.

    Whatever the file's layout, a cell not computed reads as layout 1 stored it: outcome -1,
    status 255, counters 0, t_decided NaN; only ``status`` (:attr:`computed`) tells it from
    a computed one.
    """

    path: str
    outcome: np.ndarray
    status: np.ndarray
    impacts: np.ndarray
    t_decided: np.ndarray
    counts: dict[str, np.ndarray]
    x: SweepAxis
    y: SweepAxis
    config_toml: str
    sides: int
    complete: bool
    shard: tuple[int, int]
    status_names: tuple[str, ...]
    dice_sweep_version: str
    created: str
    draws: int = 1
    probability: np.ndarray | None = None

    @property
    def computed(self) -> np.ndarray:
        """bool (ny, nx): cells some tile has written."""
        return self.status != NOT_COMPUTED

    @property
    def maps(self) -> dict[str, np.ndarray]:
        """Every map by name, as :func:`rolls_to_maps` names them (``outcome``, ``status``,
        ``t_decided``, ``impacts`` and the other counters)."""
        return {"outcome": self.outcome, "status": self.status, "t_decided": self.t_decided,
                "impacts": self.impacts, **self.counts}

    @property
    def extent(self) -> tuple[float, float, float, float]:
        """(xmin, xmax, ymin, ymax) of the image, as matplotlib's ``imshow`` takes it."""
        return (self.x.lo, self.x.hi, self.y.lo, self.y.hi)


# --- user errors naming the file ----------------------------------------------------------

SWEEP_FILE_KIND = "allowed: a sweep file written by dice-sweep sweep or merge"


def _one_line(error: BaseException) -> str:
    return " ".join(str(error).split())


def _locked(error: OSError) -> bool:
    # HDF5 locks a file it opens (exclusively for writing): a sweep or merge writing it now
    return error.errno in (errno.EAGAIN, errno.EWOULDBLOCK) or "unable to lock file" in str(error)


def in_use(path) -> bool:
    """True if another process has ``path`` open for writing (HDF5's file lock): a sweep, a
    merge or a resume may be running on it."""
    try:
        h5py.File(path, "r").close()
    except OSError as error:
        return _locked(error)
    return False


def exists_error(path, advice: str) -> DiceSweepError:
    """The error for an output that exists: ``advice`` (e.g. 'use --resume or remove it'),
    unless a running process is writing it, which is then said instead."""
    if in_use(path):
        return DiceSweepError(f"{path}: exists and is being written by another process (a sweep or merge may be "
                              "running on it); wait for it to finish, or choose another output file")
    return DiceSweepError(f"{path}: exists; {advice}")


def _open_error(path, error: OSError, writable: bool) -> DiceSweepError:
    """One line saying why ``path`` cannot be opened as a sweep file, with the advice that fits."""
    if _locked(error):
        if writable:  # a reader's lock also keeps a writer out
            return DiceSweepError(f"{path}: in use by another process (a sweep or merge may be running on it, or a "
                                  "command reading it); wait for it to finish, then use --resume")
        return DiceSweepError(f"{path}: in use by another process (a sweep or merge may be running on it); "
                              "wait for it to finish, or stop it and then finish the file with --resume")
    if not os.path.exists(path):
        return DiceSweepError(f"{path}: no such file ({SWEEP_FILE_KIND})")
    if os.path.isdir(path):
        return DiceSweepError(f"{path}: is a folder ({SWEEP_FILE_KIND})")
    if error.errno == errno.EACCES:
        return DiceSweepError(f"{path}: permission denied")
    if os.path.getsize(path) == 0:
        return DiceSweepError(f"{path}: is empty, not a sweep file; if a killed sweep left it, remove it and rerun")
    if "signature not found" in str(error):
        return DiceSweepError(f"{path}: not an HDF5 file ({SWEEP_FILE_KIND})")
    return DiceSweepError(f"{path}: cannot open as HDF5 ({_one_line(error)}); if a killed sweep damaged it, "
                          "remove it and rerun")


@contextlib.contextmanager
def _naming(path, failure: str, advice: str):
    """Turn an HDF5 failure inside the block into one line: ``PATH: failure (why)advice``."""
    try:
        yield
    except (OSError, RuntimeError) as error:
        raise DiceSweepError(f"{path}: {failure} ({_one_line(error)}){advice}") from None


def _reading(path, what: str):
    """Read failures (a damaged chunk, a cut file) as one line naming the file.

    Only a file this process could open is read, so no other process is writing it: the
    advice to remove it cannot hit a running sweep's file."""
    return _naming(path, f"cannot read its {what}", ": the file is damaged; remove it and rerun the sweep or merge that wrote it")


def probability_names(sides: int) -> list[str]:
    """Map names of a probability sweep's shares: ``probability_0`` .. ``probability_{n-1}``,
    then ``no_answer`` (docs/hdf5.md, "Probability sweeps")."""
    return [f"{PROBABILITY_PREFIX}{k}" for k in range(sides)] + [NO_ANSWER] if sides else []


def _map_datasets(count_columns, probability_sides: int = 0) -> dict[str, tuple[np.dtype, object]]:
    """Name -> (dtype, fill value) of every (ny, nx) map, as layout 2 stores them.

    The name is the map's dataset path in a layout 2 file (:func:`_dataset_paths` gives a
    layout 1 file's) and the key of the dicts of maps this module takes and gives.
    ``probability_sides`` > 0 adds the shares of a probability sweep of that many sides.
    """
    maps = {
        "outcome": (np.dtype(np.int8), OUTCOME_NOT_COMPUTED),
        "status": (np.dtype(np.uint8), NOT_COMPUTED),
        "t_decided": (np.dtype(np.float32), np.nan),
    }
    for name in count_columns:
        maps[name] = (np.dtype(np.uint16), COUNT_NOT_COMPUTED)
    for name in probability_names(probability_sides):
        maps[name] = (np.dtype(np.float32), np.nan)
    return maps


def _dataset_paths(count_columns, layout: int, probability_sides: int = 0) -> dict[str, str]:
    """Map name -> its dataset path in a file of ``layout``."""
    paths = {name: name for name in _map_datasets(count_columns, probability_sides)}
    if layout == 1:
        paths.update({name: f"{COUNTS_GROUP}/{name}" for name in count_columns if name != "impacts"})
    return paths


def _flags(values, meanings) -> dict:
    """CF attributes of a map of codes: ``flag_values`` and the space-separated ``flag_meanings``."""
    if any(len(meaning.split()) != 1 for meaning in meanings):
        raise ValueError(f"flag meanings must be single words: {list(meanings)}")
    return {"flag_values": np.asarray(values), "flag_meanings": " ".join(meanings)}


def _map_attributes(header: "SweepHeader") -> dict[str, dict]:
    """CF attributes of the maps of a layout 2 file, by name, ``_FillValue`` included.

    Codes (outcome, status) carry no ``units`` (CF: they are not quantities); t_decided is
    in s and the counters in 1 (dimensionless counts).
    """
    maps = _map_datasets(header.count_columns, header.probability_sides)
    draw0 = f" (of draw 0 of the {header.draws} rolls of the cell)" if header.draws > 1 else ""
    attrs = {
        "outcome": {
            "long_name": "side the die came to rest on" + draw0,
            "comment": "0 .. n-1 (n = root attribute sides), numbered as in Smith 2014 Fig. 7; "
            "-1 = undecided: the roll ended without a side, status says why",
            "undecided": np.int8(UNDECIDED),
        },
        "status": {
            "long_name": "kernel status code of the roll",
            **_flags(np.arange(len(header.status_names), dtype=np.uint8), header.status_names),
        },
        "t_decided": {"long_name": "simulated time at which the side was decided", "units": "s"},
    }
    for name in header.count_columns:
        attrs[name] = {
            "long_name": COUNT_LONG_NAMES.get(name, name.replace("_", " ")),
            "units": "1",
            "valid_range": np.array([0, COUNT_MAX], dtype=np.uint16),
        }
    names = probability_names(header.probability_sides)
    for k, name in enumerate(names):
        what = f"side {k}" if name != NO_ANSWER else "no side (outcome -1: the roll ended undecided)"
        attrs[name] = {"long_name": f"share of the {header.draws} draws of the stochastic impact law ending on {what}",
                       "units": "1", "valid_range": np.array([0.0, 1.0], dtype=np.float32)}
    for name, (dtype, fill) in maps.items():
        attrs[name]["_FillValue"] = dtype.type(fill)
    return attrs


def rolls_to_maps(count_columns, shape, outcome, status, counts, t_decided) -> dict:
    """Kernel outputs of a tile (flat, row-major) -> the stored (rows, cols) arrays by map name.

    Parameters
    ----------
    count_columns : sequence of str
        Names of the columns of ``counts``.
    shape : tuple of int
        (rows, cols) of the tile.
    outcome, status, counts, t_decided : numpy.ndarray
        ``roll_batch`` outputs for the tile's rolls.

    Returns
    -------
    dict of str to numpy.ndarray
        Map name (``outcome``, ``status``, ``t_decided``, the counters by name) -> array in
        the stored dtype (counters clipped at COUNT_MAX = 65534, time float32).
    """
    maps = {
        "outcome": outcome.reshape(shape).astype(np.int8, copy=False),
        "status": status.reshape(shape).astype(np.uint8, copy=False),
        "t_decided": t_decided.reshape(shape).astype(np.float32),
    }
    for column, name in enumerate(count_columns):
        clipped = np.clip(counts[:, column], 0, COUNT_MAX).astype(np.uint16)
        maps[name] = clipped.reshape(shape)
    return maps


def draws_to_maps(count_columns, shape, sides, draws, outcome, status, counts, t_decided) -> dict:
    """Kernel outputs of a tile of ``draws`` rolls per cell (cell-major: the draws of a cell
    are consecutive) -> the stored maps: those of draw 0 (:func:`rolls_to_maps`) and the
    share of each side and of no answer (:func:`probability_names`), float32."""
    first = slice(None, None, draws)
    maps = rolls_to_maps(count_columns, shape, outcome[first], status[first], counts[first], t_decided[first])
    codes = np.where(outcome < 0, sides, outcome).astype(np.int64)  # no answer counted as code n
    cells = len(codes) // draws
    tally = np.bincount(np.arange(len(codes)) // draws * (sides + 1) + codes, minlength=cells * (sides + 1))
    tally = tally.reshape(cells, sides + 1)
    for k, name in enumerate(probability_names(sides)):
        maps[name] = (tally[:, k] / draws).astype(np.float32).reshape(shape)
    return maps


def _as_layout_2(block: dict, count_columns) -> dict:
    """A block of a layout 1 file with layout 2's values: the fill values of the cells not
    computed, and counters clipped at COUNT_MAX (layout 1's 65535 would read as a fill)."""
    not_computed = block["status"] == NOT_COMPUTED
    block["outcome"] = np.where(not_computed, OUTCOME_NOT_COMPUTED, block["outcome"]).astype(np.int8)
    for name in count_columns:
        clipped = np.minimum(block[name], COUNT_MAX)
        block[name] = np.where(not_computed, COUNT_NOT_COMPUTED, clipped).astype(np.uint16)
    return block


def chunk_shape(tile_shape, shape) -> tuple[int, int]:
    """HDF5 chunk of the maps: one tile, clipped to a grid smaller than a tile."""
    return (min(tile_shape[0], shape[0]), min(tile_shape[1], shape[1]))


@dataclasses.dataclass(frozen=True)
class EncodedTile:
    """A tile's maps as the bytes of their HDF5 chunks (shuffle, then deflate), by map name.

    Made by :func:`encode_rolls` where the tile is computed (the sweep's task, in a worker),
    so that the process writing the file only copies bytes (``write_direct_chunk``) instead of compressing. In a
    development timing (h5py, fig08's 64 x 64 tiles, with the per-tile flush) a tile cost the
    writer 3.1 ms as arrays and 0.4 ms as copied chunks; scripts/bench_scaling.py measures
    the current path.
    """

    shape: tuple[int, int]
    chunks: dict[str, bytes]


def _shuffle(values: np.ndarray) -> bytes:
    # HDF5's shuffle filter: byte k of every element, for k = 0 .. itemsize - 1
    flat = np.ascontiguousarray(values).reshape(-1)
    return flat.view(np.uint8).reshape(-1, flat.itemsize).T.tobytes()


def encode_tile(maps: Mapping, chunk: tuple[int, int], count_columns, probability_sides: int = 0) -> EncodedTile:
    """The chunks of a tile's maps (from :func:`rolls_to_maps`, or :func:`draws_to_maps` with
    its ``probability_sides``) as the file stores them.

    A tile at the grid's edge is padded to the full chunk with the fill value; HDF5 ignores
    what lies outside the dataset.
    """
    shape = next(iter(maps.values())).shape
    chunks = {}
    for name, (dtype, fill) in _map_datasets(count_columns, probability_sides).items():
        padded = np.full(chunk, fill, dtype=dtype)
        padded[: shape[0], : shape[1]] = maps[name]
        chunks[name] = zlib.compress(_shuffle(padded), _GZIP_LEVEL)
    return EncodedTile(tuple(shape), chunks)


def encode_rolls(rolls, shape: tuple[int, int], chunk: tuple[int, int], count_columns) -> EncodedTile:
    """A tile's kernel outputs (flat, row-major: outcome, status, counts, t_decided) as the
    file stores them: :func:`rolls_to_maps`, then :func:`encode_tile`."""
    return encode_tile(rolls_to_maps(count_columns, shape, *rolls), chunk, count_columns)


def decode_tile(encoded: EncodedTile, chunk: tuple[int, int], count_columns, probability_sides: int = 0) -> dict[str, np.ndarray]:
    """The maps of an :class:`EncodedTile` (the inverse of :func:`encode_tile`)."""
    maps = {}
    rows, cols = encoded.shape
    for name, (dtype, _) in _map_datasets(count_columns, probability_sides).items():
        raw = np.frombuffer(zlib.decompress(encoded.chunks[name]), dtype=np.uint8)
        values = raw.reshape(dtype.itemsize, -1).T.copy().view(dtype).reshape(chunk)
        maps[name] = values[:rows, :cols]
    return maps


def _utc_now() -> str:
    return datetime.datetime.now(datetime.timezone.utc).isoformat(timespec="seconds")


def _str_tuple(values) -> tuple[str, ...]:
    return tuple(v.decode() if isinstance(v, bytes) else str(v) for v in values)


def _empty_file_image(header: SweepHeader, n_tiles: int) -> bytes:
    """The bytes of a new, empty sweep file, built in memory: written by Python, a full disk
    is one clean error, where HDF5 meeting it leaves a file it cannot close (a segfault)."""
    maps = _map_datasets(header.count_columns, header.probability_sides)
    axis_paths = (header.y.param, header.x.param)  # the axes are named after their parameters
    if axis_paths[0] == axis_paths[1] or {*maps, "done_tiles", TILE_DIM, SIMULATED, REFINE_LEVEL} & {*axis_paths}:
        raise ValueError(f"swept parameters {axis_paths} are not two names free in the layout")
    attributes = _map_attributes(header)
    image = io.BytesIO()
    with h5py.File(image, "w") as h5:
        ny, nx = header.shape
        chunks = chunk_shape(header.tile_shape, header.shape)
        h5.attrs.update(
            {
                "dice_sweep_layout": LAYOUT_VERSION,
                "Conventions": CONVENTIONS,
                "x_param": header.x.param,
                "y_param": header.y.param,
                "config_toml": header.config_toml,
                "dice_sweep_version": header.dice_sweep_version,
                "created": _utc_now(),
                "complete": np.int8(0),  # not a bool: netCDF-C does not read h5py's bool (an HDF5 enum)
                "sides": header.sides,
                "shard": f"{header.shard[0]}/{header.shard[1]}",
                "shard_rule": SHARD_RULE,
                "tile_shape": np.asarray(header.tile_shape, dtype=np.int64),
                "count_columns": list(header.count_columns),
                # only a probability sweep has it: the files of one roll per cell are as before
                **({"draws": np.int64(header.draws)} if header.draws > 1 else {}),
            }
        )
        for axis in (header.y, header.x):
            scale = h5.create_dataset(axis.param, data=np.asarray(axis.values, dtype=np.float64))
            scale.attrs.update({"long_name": PARAM_LONG_NAMES.get(axis.param, axis.param), "units": axis.unit,
                                "min": axis.lo, "max": axis.hi})
            scale.make_scale(axis.param)
        for name, (dtype, fill) in maps.items():
            dataset = h5.create_dataset(
                name, shape=(ny, nx), dtype=dtype, chunks=chunks, fillvalue=fill, **_COMPRESSION
            )
            dataset.attrs.update(attributes[name])
            _attach_axes(h5, dataset, axis_paths)
        tiles = h5.create_dataset(TILE_DIM, data=np.arange(n_tiles, dtype=np.int64))
        tiles.attrs["long_name"] = "tile index (row-major, docs/hdf5.md)"
        tiles.make_scale(TILE_DIM)
        done = h5.create_dataset("done_tiles", shape=(n_tiles,), dtype=np.uint8, fillvalue=0)
        done.attrs.update({"long_name": "1 once the tile's data are in the file",
                           **_flags(np.array([0, 1], dtype=np.uint8), ("not_written", "written"))})
        done.dims[0].attach_scale(tiles)
    return image.getvalue()


@contextlib.contextmanager
def _new_file(path, header: SweepHeader, n_tiles: int):
    """An empty sweep file at a temporary name (yielded), renamed to ``path`` when the block
    ends; an existing ``path`` is refused, never replaced."""
    if os.path.lexists(path):
        raise DiceSweepError(f"{path}: cannot create (it exists)")
    image = _empty_file_image(header, n_tiles)
    with written(path, replace=False, defer=False) as temporary:  # read back at once: never held back
        temporary.write_bytes(image)
        yield temporary


class SweepFile:
    """An open sweep file: create it, write tiles, read blocks back, mark it complete.

    Use :meth:`create` or :meth:`open`, preferably in a ``with`` block.
    """

    def __init__(self, h5file: h5py.File, header: SweepHeader):
        self._h5 = h5file
        self.header = header
        self.path = h5file.filename
        self.layout = int(h5file.attrs["dice_sweep_layout"])
        self._axis_paths = _axis_paths(h5file, self.layout)
        # looking a dataset up by name costs as much as writing a tile's worth of it
        self._maps = _map_datasets(header.count_columns, header.probability_sides)
        paths = {**_dataset_paths(header.count_columns, self.layout, header.probability_sides), "done_tiles": "done_tiles"}
        self._datasets = {name: h5file[path] for name, path in paths.items()}
        self._chunk = chunk_shape(header.tile_shape, header.shape)
        self._one_space = h5py.h5s.create_simple((1,))  # the memory side of _mark_done's write
        # encoded tiles are copied as they are only into datasets filtered as encode_tile does
        self._direct = all(
            self._datasets[name].chunks == self._chunk
            and self._datasets[name].compression == _COMPRESSION["compression"]
            and self._datasets[name].compression_opts == _GZIP_LEVEL
            and self._datasets[name].shuffle
            for name in self._maps
        )

    # --- opening -------------------------------------------------------------------------

    @classmethod
    def create(cls, path, header: SweepHeader, n_tiles: int) -> "SweepFile":
        """Create a new, empty sweep file; refuse to replace an existing one.

        Parameters
        ----------
        path : str or os.PathLike
            File to create.
        header : SweepHeader
            The run's fixed description.
        n_tiles : int
            Number of tiles of the whole grid (length of ``/done_tiles``).
        """
        with _new_file(path, header, n_tiles):  # a full disk here: one line, nothing left
            pass
        return cls.open(path, writable=True)

    @classmethod
    def open(cls, path, writable: bool = False) -> "SweepFile":
        """Open an existing sweep file for reading, or for resuming when ``writable``.

        Raises
        ------
        DiceSweepError
            If the file is missing, damaged or not a dice_sweep sweep file.
        """
        problem = not_a_file(path)  # HDF5 would block on a FIFO
        if problem:
            raise DiceSweepError(f"{path}: {problem}")
        try:
            h5 = h5py.File(path, "r+" if writable else "r")
        except OSError as error:
            raise _open_error(path, error, writable) from None
        try:
            with _reading(path, "header"):
                sweep_file = cls(h5, _read_header(h5))
                sweep_file._check_layout()
                return sweep_file
        except (KeyError, ValueError) as error:
            h5.close()
            raise DiceSweepError(f"{path}: not a dice_sweep sweep file ({_one_line(error)}; {SWEEP_FILE_KIND})") from None
        except DiceSweepError:
            h5.close()
            raise

    def _invalid(self, key: str, problem: str, allowed: str) -> DiceSweepError:
        return DiceSweepError(f"{self.path}: {key}: {problem} (allowed: {allowed}; docs/hdf5.md)")

    def _check_layout(self) -> None:
        """Refuse a file whose description does not fit docs/hdf5.md (forged or damaged): sides,
        axes, tile and shard, and the shape and dtype of every map, before anything reads it."""
        header = self.header
        if not 3 <= header.sides <= MAX_SIDES:
            raise self._invalid("sides", f"{header.sides} sides", f"an integer 3 to {MAX_SIDES}")
        if header.x.param == header.y.param:
            raise self._invalid("y_param", f"{header.y.param!r} is also the x axis", "two different swept parameters")
        for axis in (header.x, header.y):
            values = np.asarray(axis.values)
            if (values.ndim != 1 or values.size == 0 or values.dtype.kind != "f" or not np.isfinite(values).all()
                    or not np.all(np.diff(values) > 0) or not (np.isfinite(axis.lo) and np.isfinite(axis.hi) and axis.lo < axis.hi)):
                span = f" from {values.min():g} to {values.max():g}" if values.dtype.kind == "f" and values.size else ""
                raise self._invalid(f"/{axis.param}", f"{values.size} {values.dtype} values{span} in [{axis.lo:g}, {axis.hi:g}]",
                                    "finite, strictly increasing cell centres, and finite min < max")
        (shard_index, shard_count), tile_shape = header.shard, header.tile_shape
        if not 0 <= shard_index < shard_count:
            raise self._invalid("shard", f"{shard_index}/{shard_count}", "I/N with 0 <= I < N")
        if len(tile_shape) != 2 or min(tile_shape) < 1:
            raise self._invalid("tile_shape", f"{list(tile_shape)}", "two positive integers")
        for name, (dtype, _) in self._maps.items():
            dataset = self._datasets[name]
            if dataset.shape != header.shape or dataset.dtype.kind != dtype.kind:
                raise self._invalid(f"/{dataset.name.lstrip('/')}", f"{dataset.dtype} of shape {dataset.shape}",
                                    f"{dtype} of the axes' shape {header.shape}")
        n_tiles = -(-header.shape[0] // tile_shape[0]) * -(-header.shape[1] // tile_shape[1])
        if self._datasets["done_tiles"].shape != (n_tiles,):
            raise self._invalid("/done_tiles", f"shape {self._datasets['done_tiles'].shape}", f"({n_tiles},): one flag per tile")

    def _check_outcomes(self, outcome: np.ndarray, status: np.ndarray) -> None:
        """Refuse computed cells whose outcome is no side of the die and not -1 (undecided)."""
        bad = (status != NOT_COMPUTED) & ((outcome < UNDECIDED) | (outcome >= self.header.sides))
        if bad.any():
            row, col = np.argwhere(bad)[0]
            raise self._invalid("/outcome", f"{outcome[row, col]} in a computed cell (row {row}, column {col}) of a "
                                f"{self.header.sides}-sided die", f"-1 (undecided) or a side 0 .. {self.header.sides - 1}")

    def check_values(self) -> None:
        """Refuse a file whose outcome map holds a value no roll of its die gives (merge
        copies chunks without decoding them, so it checks every part first)."""
        with _reading(self.path, "maps"):
            self._check_outcomes(self._datasets["outcome"][...], self._datasets["status"][...])

    def close(self) -> None:
        """Flush and close the file."""
        if self._h5.id.valid:
            self._h5.close()

    def __enter__(self) -> "SweepFile":
        return self

    def __exit__(self, *exc_info) -> None:
        self.close()

    # --- state ---------------------------------------------------------------------------

    @property
    def complete(self) -> bool:
        """True once every tile of the shard is written."""
        return bool(self._h5.attrs["complete"])

    @property
    def created(self) -> str:
        """Creation time, ISO 8601 UTC."""
        return str(self._h5.attrs["created"])

    def done_tiles(self) -> np.ndarray:
        """bool (n_tiles,): tiles whose data are in the file."""
        with _reading(self.path, "/done_tiles"):
            return self._datasets["done_tiles"][...].astype(bool)

    def computed(self) -> np.ndarray:
        """bool (ny, nx): cells whose ``/status`` is not 255 (not computed)."""
        with _reading(self.path, "/status"):
            return self._datasets["status"][...] != NOT_COMPUTED

    # --- data ----------------------------------------------------------------------------

    def write_tile(self, tile_index: int, rows: slice, cols: slice, maps: Mapping | EncodedTile) -> None:
        """Write one tile's arrays (from :func:`rolls_to_maps`, or encoded by
        :func:`encode_tile`), then record it as done.

        The data go first and the bookkeeping last, then a flush: a kill at any point leaves
        the tile either recorded with its data or not recorded at all.
        """
        kept = "; the tiles written before it are kept, and the file is not marked complete"
        size = sum(map(len, maps.chunks.values())) if isinstance(maps, EncodedTile) else sum(v.nbytes for v in maps.values())
        check_space(self.path, size, f" for tile {tile_index}{kept}")
        with _naming(self.path, f"cannot write tile {tile_index}", kept):
            if isinstance(maps, EncodedTile) and self._copies_chunks(rows, cols):
                for name, chunk_bytes in maps.chunks.items():
                    self._datasets[name].id.write_direct_chunk((rows.start, cols.start), chunk_bytes)
            else:
                if isinstance(maps, EncodedTile):
                    maps = decode_tile(maps, self._chunk, self.header.count_columns, self.header.probability_sides)
                for name, values in maps.items():
                    self._datasets[name][rows, cols] = values
            self._mark_done(tile_index)
            self._h5.flush()

    _ONE = np.ones(1, dtype=np.uint8)

    def _mark_done(self, tile_index: int) -> None:
        # h5py's ds[i] = 1 builds a selection through Python-level machinery: about 150 us,
        # against 30 us for the same one-element write through the low-level API.
        done = self._datasets["done_tiles"].id
        file_space = done.get_space()
        file_space.select_hyperslab((tile_index,), (1,))
        done.write(self._one_space, file_space, self._ONE)

    def _copies_chunks(self, rows: slice, cols: slice) -> bool:
        """True if the block at (rows, cols) is one whole chunk, filtered as encode_tile does."""
        return self._direct and rows.start % self._chunk[0] == 0 and cols.start % self._chunk[1] == 0

    def read_tile(self, rows: slice, cols: slice) -> EncodedTile | dict[str, np.ndarray]:
        """The tile at (rows, cols) as its stored chunks when they can be copied as they are
        (:class:`EncodedTile`, no decompression: what merge copies), else as arrays.

        A layout 1 file gives arrays with the values of layout 2 (the one files are written in).
        """
        if self.layout != LAYOUT_VERSION:
            return _as_layout_2(self.read_block(rows, cols), self.header.count_columns)
        if not self._copies_chunks(rows, cols):
            return self.read_block(rows, cols)
        chunks = {}
        for name in self._maps:
            try:
                filter_mask, chunk_bytes = self._datasets[name].id.read_direct_chunk((rows.start, cols.start))
            except (OSError, RuntimeError, ValueError):  # a chunk never written
                return self.read_block(rows, cols)
            if filter_mask != 0:  # a filter was skipped when this chunk was written
                return self.read_block(rows, cols)
            chunks[name] = chunk_bytes
        return EncodedTile((rows.stop - rows.start, cols.stop - cols.start), chunks)

    def read_block(self, rows: slice, cols: slice) -> dict[str, np.ndarray]:
        """Stored arrays of a block, by map name (the form :meth:`write_tile` takes)."""
        with _reading(self.path, "maps"):
            block = {name: self._datasets[name][rows, cols] for name in self._maps}
        self._check_outcomes(block["outcome"], block["status"])
        return block

    def mark_complete(self) -> None:
        """Set the ``complete`` attribute (call only when every tile of the shard is done)."""
        check_space(self.path, 0, "; the file is not marked complete")
        self._h5.attrs["complete"] = True if self.layout == 1 else np.int8(1)
        self._h5.flush()

    def read(self) -> SweepData:
        """All maps and the description, in memory."""
        header = self.header
        extra = [name for name in header.count_columns if name != "impacts"]
        with _reading(self.path, "maps"):
            maps = {name: self._datasets[name][...] for name in ("outcome", "status", "impacts", "t_decided")}
            counts = {name: self._datasets[name][...] for name in extra}
            shares = [self._datasets[name][...] for name in probability_names(header.probability_sides)]
        self._check_outcomes(maps["outcome"], maps["status"])
        not_computed = maps["status"] == NOT_COMPUTED  # as layout 1 stored them (SweepData)
        maps["outcome"][not_computed] = UNDECIDED
        for values in (maps["impacts"], *counts.values()):
            values[not_computed] = 0
        return SweepData(
            path=str(self.path),
            **maps,
            counts=counts,
            x=header.x,
            y=header.y,
            config_toml=header.config_toml,
            sides=header.sides,
            complete=self.complete,
            shard=header.shard,
            status_names=header.status_names,
            dice_sweep_version=header.dice_sweep_version,
            created=self.created,
            draws=header.draws,
            probability=np.stack(shares) if shares else None,
        )


@contextlib.contextmanager
def create_whole(path, header: SweepHeader, n_tiles: int):
    """:meth:`SweepFile.create` for a file one call writes whole (a merge, a refined sweep;
    neither can be resumed): written under a temporary name and renamed to ``path`` once the
    block ends, so that no half-written file is left to block or mislead the next run (if the
    block fails, the temporary is removed)."""
    with _new_file(path, header, n_tiles) as temporary:
        with SweepFile.open(temporary, writable=True) as sweep_file:
            sweep_file.path = str(path)  # errors name the output, not its temporary
            yield sweep_file


def _axis_paths(h5: h5py.File, layout: int) -> tuple[str, str]:
    """Dataset paths of the (row, column) axes: ``/y``, ``/x`` in layout 1, the parameters' names after."""
    if layout == 1:
        return ("y", "x")
    return (str(h5.attrs["y_param"]), str(h5.attrs["x_param"]))


def _attach_axes(h5: h5py.File, dataset: h5py.Dataset, axis_paths) -> None:
    """Attach the (row, column) dimension scales to a map: what names its dimensions (no
    labels: netCDF does not use them, and xarray would show them as an attribute)."""
    for dim, path in enumerate(axis_paths):
        dataset.dims[dim].attach_scale(h5[path])


def _read_axis(dataset: h5py.Dataset, layout: int) -> SweepAxis:
    attrs = dataset.attrs
    return SweepAxis(
        param=str(attrs["param"]) if layout == 1 else dataset.name.rsplit("/", 1)[-1],
        unit=str(attrs["unit" if layout == 1 else "units"]),
        values=dataset[...],
        lo=float(attrs["min"]),
        hi=float(attrs["max"]),
    )


def _read_header(h5: h5py.File) -> SweepHeader:
    attrs = h5.attrs
    layout = int(attrs["dice_sweep_layout"])
    if layout not in READ_LAYOUTS:
        raise ValueError(f"layout version {layout}, this dice_sweep reads {' and '.join(map(str, READ_LAYOUTS))}")
    shard_index, shard_count = (int(part) for part in str(attrs["shard"]).split("/"))
    y_path, x_path = _axis_paths(h5, layout)
    status = h5["status"].attrs
    return SweepHeader(
        config_toml=str(attrs["config_toml"]),
        sides=int(attrs["sides"]),
        x=_read_axis(h5[x_path], layout),
        y=_read_axis(h5[y_path], layout),
        tile_shape=tuple(int(v) for v in attrs["tile_shape"]),
        shard=(shard_index, shard_count),
        count_columns=_str_tuple(attrs["count_columns"]),
        status_names=_str_tuple(status["names"]) if layout == 1 else tuple(str(status["flag_meanings"]).split()),
        dice_sweep_version=str(attrs["dice_sweep_version"]),
        draws=int(attrs.get("draws", 1)),
    )


def read_sweep(path) -> SweepData:
    """Read a sweep file (complete or not) into memory.

    Parameters
    ----------
    path : str or os.PathLike
        A file written by ``dice-sweep sweep`` or ``dice-sweep merge``.

    Returns
    -------
    SweepData
        Maps, axes with parameters and units, config, ``complete`` flag and ``sides``.
    """
    with SweepFile.open(path) as sweep_file:
        return sweep_file.read()


# --- adaptive refinement (dice_sweep.refine, issue 6) ------------------------------------

SIMULATED = "simulated"  # uint8 map: 1 where the pixel's own centre was rolled
REFINE_LEVEL = "refine_level"  # uint8 map: level whose roll gave the pixel its value


def write_refinement_maps(sweep_file: SweepFile, refine_level: np.ndarray, levels: int) -> None:
    """Add the maps of a quadtree refinement to a sweep file (docs/hdf5.md).

    Parameters
    ----------
    sweep_file : SweepFile
        A file just created for the refined sweep.
    refine_level : numpy.ndarray
        uint8 (ny, nx): level 0 .. ``levels`` whose roll gave each pixel its value.
    levels : int
        Number of refinement levels; pixels at this level were rolled at their own centre.
    """
    h5 = sweep_file._h5
    check_space(sweep_file.path, 2 * refine_level.size, " for the refinement maps")
    chunks = chunk_shape(sweep_file.header.tile_shape, sweep_file.header.shape)
    maps = {SIMULATED: (refine_level == levels).astype(np.uint8), REFINE_LEVEL: refine_level.astype(np.uint8)}
    attributes = {
        SIMULATED: {"long_name": "1 where the pixel was rolled at its own centre, 0 where it took a coarser cell's roll",
                    **_flags(np.array([0, 1], dtype=np.uint8), ("coarser_cell", "own_centre"))},
        REFINE_LEVEL: {"long_name": "refinement level whose roll gave the pixel its value (0 = coarsest)",
                       "valid_range": np.array([0, levels], dtype=np.uint8)},
    }
    for name, values in maps.items():
        dataset = h5.create_dataset(name, data=values, chunks=chunks, **_COMPRESSION)
        dataset.attrs.update(attributes[name])
        _attach_axes(h5, dataset, sweep_file._axis_paths)
    h5.attrs["refine_levels"] = int(levels)
    h5.flush()


def read_refinement_maps(path) -> tuple[np.ndarray, np.ndarray, int] | None:
    """(simulated as bool, refine_level, levels) of a refined sweep file; None for a full sweep."""
    with SweepFile.open(path) as sweep_file, _reading(path, "refinement maps"):
        h5 = sweep_file._h5
        if SIMULATED not in h5:
            return None
        return h5[SIMULATED][...].astype(bool), h5[REFINE_LEVEL][...], int(h5.attrs["refine_levels"])
