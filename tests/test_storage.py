"""Tests of dice_sweep.storage: the HDF5 layout of docs/hdf5.md, read back with plain h5py."""

import os
import pathlib
import re
import subprocess
import sys

import h5py
import numpy as np
import pytest

from dice_sweep.errors import DiceSweepError
from dice_sweep.storage import (
    COUNT_MAX,
    COUNT_NOT_COMPUTED,
    LAYOUT_VERSION,
    NOT_COMPUTED,
    OUTCOME_NOT_COMPUTED,
    EncodedTile,
    SweepAxis,
    SweepFile,
    SweepHeader,
    create_whole,
    decode_tile,
    encode_tile,
    exists_error,
    read_sweep,
    rolls_to_maps,
)
from tests.helpers import corrupt_first_chunk, replace_dataset, set_first

DOCS = pathlib.Path(__file__).resolve().parent.parent / "docs" / "hdf5.md"
GOLDEN = pathlib.Path(__file__).resolve().parent / "golden"
COUNT_COLUMNS = ("impacts", "wall_impacts", "pivots")
TILE = (2, 3)
# a 3 x 5 map in tiles of 2 x 3: tiles 0 1 (rows 0-1), 2 3 (row 2, clipped)
TILE_BOUNDS = {
    0: (slice(0, 2), slice(0, 3)),
    1: (slice(0, 2), slice(3, 5)),
    2: (slice(2, 3), slice(0, 3)),
    3: (slice(2, 3), slice(3, 5)),
}


def make_header(**changes):
    fields = dict(
        config_toml='[die]\nsides = 5\n',
        sides=5,
        x=SweepAxis("vx0", "m/s", np.array([-0.8, -0.4, 0.0, 0.4, 0.8]), -1.0, 1.0),
        y=SweepAxis("y0", "m", np.array([0.05, 0.15, 0.25]), 0.0, 0.3),
        tile_shape=TILE,
        shard=(0, 1),
        count_columns=COUNT_COLUMNS,
        status_names=("decided", "t_max"),
    )
    fields.update(changes)
    return SweepHeader(**fields)


def tile_maps(index):
    """Distinct synthetic kernel outputs for tile ``index``, as the stored maps."""
    rows, cols = TILE_BOUNDS[index]
    shape = (rows.stop - rows.start, cols.stop - cols.start)
    n = shape[0] * shape[1]
    rng = np.random.default_rng(index)
    outcome = rng.integers(-1, 5, n).astype(np.int8)
    status = (outcome < 0).astype(np.uint8)
    counts = rng.integers(0, 100, (n, len(COUNT_COLUMNS))).astype(np.int32)
    t_decided = np.where(outcome < 0, np.nan, rng.uniform(0.1, 3.0, n))
    return rolls_to_maps(COUNT_COLUMNS, shape, outcome, status, counts, t_decided)


def write_file(path, tiles=TILE_BOUNDS, complete=True):
    with SweepFile.create(path, make_header(), n_tiles=len(TILE_BOUNDS)) as sweep_file:
        for index in tiles:
            sweep_file.write_tile(index, *TILE_BOUNDS[index], tile_maps(index))
        if complete:
            sweep_file.mark_complete()


def test_round_trip_gives_back_every_map_axis_and_attribute(tmp_path):
    path = tmp_path / "sweep.h5"
    write_file(path)
    data = read_sweep(path)
    for index, (rows, cols) in TILE_BOUNDS.items():
        maps = tile_maps(index)
        assert np.array_equal(data.outcome[rows, cols], maps["outcome"])
        assert np.array_equal(data.status[rows, cols], maps["status"])
        assert np.array_equal(data.impacts[rows, cols], maps["impacts"])
        assert np.array_equal(data.t_decided[rows, cols], maps["t_decided"], equal_nan=True)
        assert np.array_equal(data.counts["pivots"][rows, cols], maps["pivots"])
    assert data.outcome.dtype == np.int8 and data.status.dtype == np.uint8
    assert data.impacts.dtype == np.uint16 and data.t_decided.dtype == np.float32
    assert sorted(data.counts) == ["pivots", "wall_impacts"]
    assert data.complete and data.computed.all()
    assert data.sides == 5 and data.shard == (0, 1)
    assert data.config_toml == make_header().config_toml
    assert data.status_names == ("decided", "t_max")
    assert (data.x.param, data.x.unit, data.y.param, data.y.unit) == ("vx0", "m/s", "y0", "m")
    assert np.array_equal(data.y.values, [0.05, 0.15, 0.25])
    assert data.extent == (-1.0, 1.0, 0.0, 0.3)
    assert re.fullmatch(r"\d{4}-\d\d-\d\dT\d\d:\d\d:\d\d\+00:00", data.created)


def test_unwritten_tiles_read_as_not_computed_and_file_as_incomplete(tmp_path):
    path = tmp_path / "sweep.h5"
    write_file(path, tiles=[1, 2], complete=False)
    data = read_sweep(path)
    assert not data.complete
    assert data.computed[TILE_BOUNDS[1]].all() and data.computed[TILE_BOUNDS[2]].all()
    for index in (0, 3):
        block = TILE_BOUNDS[index]
        assert (data.status[block] == NOT_COMPUTED).all()
        assert (data.outcome[block] == -1).all() and np.isnan(data.t_decided[block]).all()
        assert (data.impacts[block] == 0).all() and (data.counts["pivots"][block] == 0).all()
    with SweepFile.open(path) as sweep_file:
        assert sweep_file.done_tiles().tolist() == [False, True, True, False]
    with h5py.File(path, "r") as h5:  # stored: fill values no computed cell holds
        assert (h5["outcome"][TILE_BOUNDS[0]] == OUTCOME_NOT_COMPUTED).all()
        assert (h5["pivots"][TILE_BOUNDS[3]] == COUNT_NOT_COMPUTED).all()


def test_counts_are_clipped_to_uint16():
    counts = np.array([[70000, -1, 5]], dtype=np.int32)
    maps = rolls_to_maps(COUNT_COLUMNS, (1, 1), np.zeros(1), np.zeros(1), counts, np.zeros(1))
    assert maps["impacts"][0, 0] == COUNT_MAX == 65534 and maps["wall_impacts"][0, 0] == 0
    assert maps["pivots"][0, 0] == 5


def test_plain_h5py_sees_documented_layout_and_dimension_scales(tmp_path):
    path = tmp_path / "sweep.h5"
    write_file(path)
    with h5py.File(path, "r") as h5:
        assert h5.attrs["complete"] and h5.attrs["shard"] == "0/1"
        assert h5.attrs["dice_sweep_layout"] == LAYOUT_VERSION == 2
        assert (h5.attrs["x_param"], h5.attrs["y_param"]) == ("vx0", "y0")
        assert list(h5.attrs["tile_shape"]) == list(TILE)
        assert h5["done_tiles"][...].tolist() == [1, 1, 1, 1]
        assert h5["done_tiles"].dims[0][0] == h5["tile"] and h5["tile"][...].tolist() == [0, 1, 2, 3]
        assert "counts" not in h5 and "x" not in h5 and "y" not in h5
        for name in ("outcome", "status", "impacts", "t_decided", "wall_impacts", "pivots"):
            dataset = h5[name]
            assert dataset.shape == (3, 5) and dataset.chunks == TILE
            assert dataset.compression == "gzip"
            assert dataset.dims[0][0] == h5["y0"] and dataset.dims[1][0] == h5["vx0"]
            assert len(dataset.dims[0]) == len(dataset.dims[1]) == 1
            assert "long_name" in dataset.attrs
        for name, unit in (("vx0", "m/s"), ("y0", "m")):
            assert h5[name].is_scale and h5[name].attrs["units"] == unit
        fills = {"outcome": OUTCOME_NOT_COMPUTED, "status": NOT_COMPUTED, "impacts": COUNT_NOT_COMPUTED,
                 "pivots": COUNT_NOT_COMPUTED}
        for name, fill in fills.items():  # the HDF5 fill value is the _FillValue xarray masks
            assert h5[name].fillvalue == fill == h5[name].attrs["_FillValue"]
            assert h5[name].attrs["_FillValue"].dtype == h5[name].dtype
        assert np.isnan(h5["t_decided"].fillvalue) and np.isnan(h5["t_decided"].attrs["_FillValue"])
        assert h5["t_decided"].attrs["units"] == "s" and h5["impacts"].attrs["units"] == "1"
        assert h5["status"].attrs["flag_meanings"] == "decided t_max"


def test_a_layout_1_file_is_read_with_the_meaning_it_had():
    """tests/golden holds files of layout 1 (/x, /y, /counts/<name>, outcome filled with -1)."""
    path = GOLDEN / "fig08.h5"
    with h5py.File(path, "r") as h5:
        assert h5.attrs["dice_sweep_layout"] == 1 and "counts/pivots" in h5
        pivots = h5["counts/pivots"][...]
    data = read_sweep(path)
    assert (data.x.param, data.x.unit, data.y.param, data.y.unit) == ("omega0", "rad/s", "y0", "m")
    assert data.status_names[:2] == ("decided", "t_max") and data.complete
    assert np.array_equal(data.counts["pivots"], pivots) and data.outcome.shape == (32, 32)
    with SweepFile.open(path) as sweep_file:
        assert sweep_file.layout == 1
        block = sweep_file.read_tile(slice(0, 32), slice(0, 32))  # as layout 2 stores it, for merge
        assert isinstance(block, dict) and np.array_equal(block["pivots"], pivots)


def test_create_refuses_an_existing_file(tmp_path):
    path = tmp_path / "sweep.h5"
    path.write_bytes(b"precious")
    with pytest.raises(DiceSweepError, match="cannot create"):
        SweepFile.create(path, make_header(), n_tiles=4)
    assert path.read_bytes() == b"precious"


def test_open_refuses_files_that_are_not_sweeps(tmp_path):
    text_file = tmp_path / "notes.h5"
    text_file.write_text("not HDF5")
    with pytest.raises(DiceSweepError, match="not an HDF5 file"):
        read_sweep(text_file)
    other_hdf5 = tmp_path / "other.h5"
    with h5py.File(other_hdf5, "w") as h5:
        h5["data"] = np.zeros(3)
    with pytest.raises(DiceSweepError, match="not a dice_sweep sweep file"):
        read_sweep(other_hdf5)


def open_error(path, writable=False):
    with pytest.raises(DiceSweepError) as caught:
        SweepFile.open(path, writable=writable)
    message = str(caught.value)
    assert message.startswith(f"{path}: ") and "\n" not in message
    return message


def test_a_missing_file_a_folder_and_an_empty_file_each_get_their_own_message(tmp_path):
    """Issue 16: all three got 'if a kill damaged it, remove it and rerun' (the folder's on two lines)."""
    assert "no such file" in open_error(tmp_path / "missing.h5")
    (tmp_path / "folder.h5").mkdir()
    assert "is a folder" in open_error(tmp_path / "folder.h5")
    (tmp_path / "empty.h5").write_bytes(b"")
    assert "is empty" in open_error(tmp_path / "empty.h5")
    for name in ("missing.h5", "folder.h5"):
        assert "remove" not in open_error(tmp_path / name)


HOLD_OPEN = """
import sys, time, h5py
h5 = h5py.File(sys.argv[1], sys.argv[2])
print("open", flush=True)
time.sleep(60)
"""


@pytest.fixture
def held_open(tmp_path):
    """Open a sweep file in another process (as a running sweep holds its file); yield its path."""
    path = tmp_path / "running.h5"
    write_file(path, tiles=[0, 1], complete=False)
    holders = []

    def hold(mode):
        holder = subprocess.Popen([sys.executable, "-c", HOLD_OPEN, str(path), mode], stdout=subprocess.PIPE, text=True)
        holders.append(holder)
        assert holder.stdout.readline().strip() == "open"
        return path

    yield hold
    for holder in holders:
        holder.kill()
        holder.wait()


def test_a_file_a_running_sweep_writes_is_never_called_damaged(held_open):
    """Issue 16: a file locked by a running sweep got 'if a kill damaged it, remove it and rerun'."""
    path = held_open("r+")
    for writable in (False, True):
        message = open_error(path, writable)
        assert "a sweep or merge may be running on it" in message and "remove" not in message
    message = str(exists_error(path, "use --resume or remove it"))
    assert "being written by another process" in message and "remove" not in message


def test_a_file_another_process_reads_cannot_be_resumed_now(held_open):
    path = held_open("r")
    assert read_sweep(path).computed.any()  # readers share the file
    message = open_error(path, writable=True)
    assert "wait for it to finish" in message and "remove" not in message
    assert str(exists_error(path, "remove it")) == f"{path}: exists; remove it"


def test_a_corrupt_chunk_is_an_error_naming_the_file(tmp_path):
    """Issue 16: 'error: Can't synchronously read data (filter returned failure during read)'."""
    path = tmp_path / "sweep.h5"
    write_file(path)
    corrupt_first_chunk(path)
    with pytest.raises(DiceSweepError, match=f"^{re.escape(str(path))}: cannot read its maps .*damaged"):
        read_sweep(path)
    with SweepFile.open(path) as sweep_file, pytest.raises(DiceSweepError, match=re.escape(str(path))):
        sweep_file.read_block(*TILE_BOUNDS[0])


def test_a_file_written_whole_is_removed_when_writing_fails_and_no_other_file_is(tmp_path):
    """A failed merge or refined sweep leaves no half-written file to block or mislead the next run."""
    path = tmp_path / "merged.h5"
    with pytest.raises(ZeroDivisionError), create_whole(path, make_header(), n_tiles=4) as sweep_file:
        sweep_file.write_tile(0, *TILE_BOUNDS[0], tile_maps(0))
        1 / 0
    assert not path.exists()
    path.write_bytes(b"precious")
    with pytest.raises(DiceSweepError, match="cannot create"), create_whole(path, make_header(), n_tiles=4):
        pass
    assert path.read_bytes() == b"precious"


def test_reading_example_of_the_docs_runs(tmp_path, monkeypatch, capsys):
    write_file(tmp_path / "sweep.h5")
    example = re.search(r"```python\n(.*?)```", DOCS.read_text(), re.S).group(1)
    monkeypatch.chdir(tmp_path)
    exec(compile(example, str(DOCS), "exec"), {})
    assert "vx0" in capsys.readouterr().out


# --- encoded tiles (compressed where computed, copied as chunks by the writer) -------------


@pytest.mark.parametrize("index", sorted(TILE_BOUNDS))
def test_encode_then_decode_gives_the_maps_back_bitwise(index):
    maps = tile_maps(index)
    decoded = decode_tile(encode_tile(maps, TILE, COUNT_COLUMNS), TILE, COUNT_COLUMNS)
    assert decoded.keys() == maps.keys()
    for name, values in maps.items():
        assert decoded[name].dtype == values.dtype and decoded[name].tobytes() == values.tobytes(), name


def test_encoded_tiles_written_as_chunks_read_back_like_arrays(tmp_path):
    """Edge tiles padded, NaNs and negative outcomes kept: plain h5py reads the same maps."""
    write_file(tmp_path / "arrays.h5")
    with SweepFile.create(tmp_path / "chunks.h5", make_header(), n_tiles=len(TILE_BOUNDS)) as sweep_file:
        assert sweep_file._direct  # the fast path is the one tested here
        for index in TILE_BOUNDS:
            sweep_file.write_tile(index, *TILE_BOUNDS[index], encode_tile(tile_maps(index), TILE, COUNT_COLUMNS))
        sweep_file.mark_complete()
    with h5py.File(tmp_path / "arrays.h5") as a, h5py.File(tmp_path / "chunks.h5") as b:
        names = []
        a.visit(names.append)
        for name in names:
            if isinstance(a[name], h5py.Dataset):
                assert a[name][...].tobytes() == b[name][...].tobytes(), name


def test_encoded_tile_falls_back_to_arrays_when_the_file_is_filtered_otherwise(tmp_path):
    with SweepFile.create(tmp_path / "other.h5", make_header(), n_tiles=len(TILE_BOUNDS)) as sweep_file:
        sweep_file._direct = False  # as for a file whose datasets another tool re-filtered
        for index in TILE_BOUNDS:
            sweep_file.write_tile(index, *TILE_BOUNDS[index], encode_tile(tile_maps(index), TILE, COUNT_COLUMNS))
    data = read_sweep(tmp_path / "other.h5")
    write_file(tmp_path / "arrays.h5")
    assert data.t_decided.tobytes() == read_sweep(tmp_path / "arrays.h5").t_decided.tobytes()


def test_read_tile_gives_the_stored_chunks_that_decode_to_the_block(tmp_path):
    write_file(tmp_path / "a.h5", tiles=[0, 1, 2])  # tile 3 never written
    with SweepFile.open(tmp_path / "a.h5") as sweep_file:
        for index in (0, 1, 2):
            tile = sweep_file.read_tile(*TILE_BOUNDS[index])
            assert isinstance(tile, EncodedTile)
            decoded = decode_tile(tile, TILE, COUNT_COLUMNS)
            block = sweep_file.read_block(*TILE_BOUNDS[index])
            assert all(decoded[name].tobytes() == block[name].tobytes() for name in block)
        missing = sweep_file.read_tile(*TILE_BOUNDS[3])  # no chunk: the arrays (fill values)
        assert isinstance(missing, dict) and (missing["status"] == NOT_COMPUTED).all()


# ---- a full disk and forged files (issue 32) -----------------------------------------------------


def test_a_full_disk_before_a_tile_stops_the_sweep_cleanly_and_it_resumes(tmp_path, monkeypatch):
    """HDF5 that meets a full disk in a write leaves a file it cannot close (the process
    segfaulted at exit): the space is checked before each tile, the file closed cleanly, not
    marked complete, and finished later from where it stopped."""
    import dice_sweep.outputs as outputs

    path = tmp_path / "sweep.h5"
    disk = {"free": 10**12}
    monkeypatch.setattr(outputs, "free_bytes", lambda folder: disk["free"])
    with SweepFile.create(path, make_header(), n_tiles=len(TILE_BOUNDS)) as sweep_file:
        sweep_file.write_tile(0, *TILE_BOUNDS[0], tile_maps(0))
        disk["free"] = outputs.HDF5_SPARE  # full: no room for a tile's data beside HDF5's spare
        with pytest.raises(DiceSweepError, match=rf"^{path}: no space left on the device: .* for tile 1; the tiles written "
                                                 "before it are kept, and the file is not marked complete$"):
            sweep_file.write_tile(1, *TILE_BOUNDS[1], tile_maps(1))
        disk["free"] = outputs.HDF5_SPARE - 1
        with pytest.raises(DiceSweepError, match="the file is not marked complete"):
            sweep_file.mark_complete()
    data = read_sweep(path)
    assert not data.complete and data.computed[TILE_BOUNDS[0]].all() and data.computed.sum() == 6
    disk["free"] = 10**12
    with SweepFile.open(path, writable=True) as sweep_file:
        for index in (1, 2, 3):
            sweep_file.write_tile(index, *TILE_BOUNDS[index], tile_maps(index))
        sweep_file.mark_complete()
    write_file(tmp_path / "whole.h5")
    assert_same_data(read_sweep(path), read_sweep(tmp_path / "whole.h5"))


def assert_same_data(data, reference):
    assert data.complete and reference.complete
    for name, values in reference.maps.items():
        np.testing.assert_array_equal(data.maps[name], values, err_msg=name)


def test_a_full_disk_at_creation_leaves_nothing(tmp_path, monkeypatch):
    def no_room(path):
        raise OSError(28, "No space left on device")

    monkeypatch.setattr(pathlib.Path, "write_bytes", lambda self, data: no_room(self))
    with pytest.raises(DiceSweepError, match=r"sweep.h5: cannot be written: No space left on device \(errno 28\)"):
        SweepFile.create(tmp_path / "sweep.h5", make_header(), n_tiles=4)
    with pytest.raises(DiceSweepError, match="merged.h5: cannot be written: No space left"):
        with create_whole(tmp_path / "merged.h5", make_header(), n_tiles=4):
            pass
    assert list(tmp_path.iterdir()) == []


def test_a_whole_file_appears_only_once_complete(tmp_path):
    path = tmp_path / "merged.h5"
    with create_whole(path, make_header(), n_tiles=len(TILE_BOUNDS)) as sweep_file:
        assert not path.exists() and sweep_file.path == str(path)  # written under a temporary name
        for index in TILE_BOUNDS:
            sweep_file.write_tile(index, *TILE_BOUNDS[index], tile_maps(index))
        sweep_file.mark_complete()
    assert read_sweep(path).complete and [p.name for p in tmp_path.iterdir()] == ["merged.h5"]


def forged(tmp_path, change):
    """A complete sweep file, then ``change(h5)`` made to it with plain h5py."""
    path = tmp_path / "forged.h5"
    write_file(path)
    with h5py.File(path, "r+") as h5:
        change(h5)
    return path


def set_axis(h5, value):
    values = h5["vx0"][...]
    values[2] = value
    h5["vx0"][...] = values


FORGED = {  # change -> (key, fragment of the one line)
    "outcome of the wrong shape": (lambda h5: replace_dataset(h5, "outcome", np.zeros((2, 5), np.int8)), "/outcome", "shape (2, 5)"),
    "float outcomes": (lambda h5: replace_dataset(h5, "outcome", np.zeros((3, 5), np.float32)), "/outcome", "float32"),
    "outcome 50 on a five-sided die": (set_first("outcome", 50), "/outcome", "50 in a computed cell (row 0, column 0)"),
    "outcome -128 in a computed cell": (lambda h5: (set_first("outcome", -128)(h5), set_first("status", 0)(h5)), "/outcome", "-128"),
    "sides 0": (lambda h5: h5.attrs.__setitem__("sides", 0), "sides", "0 sides"),
    "sides 200": (lambda h5: h5.attrs.__setitem__("sides", 200), "sides", "an integer 3 to 127"),
    "x axis equal to the y axis": (lambda h5: h5.attrs.__setitem__("x_param", "y0"), "y_param", "also the x axis"),
    "an axis value inf": (lambda h5: set_axis(h5, np.inf), "/vx0", "finite, strictly increasing"),
    "an axis not increasing": (lambda h5: set_axis(h5, -0.8), "/vx0", "finite, strictly increasing"),
    "shard 3/2": (lambda h5: h5.attrs.__setitem__("shard", "3/2"), "shard", "3/2"),
    "tile shape 0": (lambda h5: h5.attrs.__setitem__("tile_shape", np.array([0, 3])), "tile_shape", "two positive integers"),
    "status of the wrong shape": (lambda h5: replace_dataset(h5, "status", np.zeros((3, 4), np.uint8)), "/status", "shape (3, 4)"),
}


@pytest.mark.parametrize("case", sorted(FORGED))
def test_a_forged_file_is_refused_naming_the_file_and_the_key(tmp_path, case):
    change, key, fragment = FORGED[case]
    path = forged(tmp_path, change)
    with pytest.raises(DiceSweepError) as error:
        with SweepFile.open(path) as sweep_file:
            sweep_file.check_values()  # what merge asks of each part
    message = str(error.value)
    assert message.startswith(f"{path}: {key}: ") and fragment in message and "\n" not in message, message
    with pytest.raises(DiceSweepError, match=f"^{re.escape(str(path))}: {key}: "):
        read_sweep(path)


def test_the_control_file_passes_every_check(tmp_path):
    """The same file unchanged: nothing to find (the checks do not refuse good files)."""
    path = forged(tmp_path, lambda h5: None)
    with SweepFile.open(path) as sweep_file:
        sweep_file.check_values()
    assert read_sweep(path).complete
    for golden in sorted(GOLDEN.glob("*.h5")):  # files of both layouts, every die
        with SweepFile.open(golden) as sweep_file:
            sweep_file.check_values()


def test_a_fifo_is_refused_without_opening_it(tmp_path):
    fifo = tmp_path / "sweep.h5"
    os.mkfifo(fifo)
    with pytest.raises(DiceSweepError, match="sweep.h5: is a FIFO"):
        read_sweep(fifo)
