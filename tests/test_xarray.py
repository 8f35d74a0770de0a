"""Sweep files as xarray reads them (issue 16): docs/hdf5.md, "Reading with xarray".

Real sweeps of configs/demo.toml at 8 x 6, opened with ``xarray.open_dataset`` through
h5netcdf, against :func:`dice_sweep.storage.read_sweep` of the same file: dimensions named by
the swept parameters, CF ``units``/``long_name``, cells not computed masked (and only those:
a computed undecided roll stays -1), the counters at the root. Also: files of layout 1 (a
golden file, and one written as layout 1 was) still resume and merge, a merge giving layout 2.
"""

import re
import shutil

import h5py
import numpy as np
import pytest
import xarray as xr

from dice_sweep.config import load_config
from dice_sweep.storage import (
    NOT_COMPUTED,
    SweepAxis,
    SweepFile,
    SweepHeader,
    read_refinement_maps,
    read_sweep,
    rolls_to_maps,
    write_refinement_maps,
)
from dice_sweep.sweep import SweepInterrupted, merge_parts
from tests.helpers import ROOT, small_sweep

# t_max = 0.2 s: the low drops are decided, the high ones not (computed undecided rolls)
OVERRIDES = ("grid.x.num=8", "grid.y.num=6", "integrator.t_max=0.2")
TILE = (6, 4)  # two tiles: the left and right halves of the map
UNITS = {"omega0": "rad/s", "y0": "m", "t_decided": "s", "impacts": "1", "wall_impacts": "1", "pivots": "1"}


@pytest.fixture(scope="module")
def demo_cfg():
    return load_config(ROOT / "configs" / "demo.toml", OVERRIDES)


@pytest.fixture(scope="module")
def complete_path(demo_cfg, tmp_path_factory):
    path = tmp_path_factory.mktemp("complete") / "demo.h5"
    small_sweep(demo_cfg, path, tile_shape=TILE)
    return path


@pytest.fixture(scope="module")
def partial_path(demo_cfg, tmp_path_factory):
    """The same sweep, Ctrl-C after its first tile: half of the map not computed."""

    def stop(index, rolls):
        raise KeyboardInterrupt

    path = tmp_path_factory.mktemp("partial") / "demo.h5"
    with pytest.raises(SweepInterrupted):
        small_sweep(demo_cfg, path, tile_shape=TILE, on_tile=stop)
    return path


def open_xr(path, engine="h5netcdf"):
    with xr.open_dataset(path, engine=engine) as ds:
        return ds.load()


@pytest.mark.parametrize("engine", ["h5netcdf", None])  # None: xarray's choice (h5netcdf without netCDF4)
def test_dimensions_are_the_swept_parameters_with_their_values(complete_path, engine):
    data = read_sweep(complete_path)
    ds = open_xr(complete_path, engine)
    assert (data.x.param, data.y.param) == ("omega0", "y0")
    assert dict(ds.sizes) == {"y0": 6, "omega0": 8, "tile": 2}
    for name in data.maps:
        assert ds[name].dims == ("y0", "omega0"), name
    assert ds.done_tiles.dims == ("tile",) and ds.done_tiles.values.tolist() == [1, 1]
    np.testing.assert_array_equal(ds.omega0.values, data.x.values)
    np.testing.assert_array_equal(ds.y0.values, data.y.values)
    near = ds.outcome.sel(omega0=32, method="nearest")
    column = int(np.argmin(np.abs(data.x.values - 32)))
    assert near.dims == ("y0",) and float(near.omega0) == data.x.values[column]
    np.testing.assert_array_equal(near.values, data.outcome[:, column])
    row = ds.sel(y0=data.y.values[2])  # exact selection of a whole row of every map
    np.testing.assert_array_equal(row.impacts.values, data.impacts[2])
    assert ds.attrs["complete"] == 1 and ds.attrs["sides"] == 4 and ds.attrs["x_param"] == "omega0"


def test_units_and_long_names_are_cf_attributes(complete_path):
    ds = open_xr(complete_path)
    for name, unit in UNITS.items():
        assert ds[name].attrs["units"] == unit, name
    for name in ds.variables:
        assert isinstance(ds[name].attrs.get("long_name"), str) and ds[name].attrs["long_name"], name
        assert "unit" not in ds[name].attrs and "DIMENSION_LABELS" not in ds[name].attrs, name
    assert ds.omega0.attrs["long_name"] == "initial angular velocity"
    assert (ds.omega0.attrs["min"], ds.omega0.attrs["max"]) == (0.0, 60.0)  # the image extent
    # codes, not quantities: CF flags, no units
    assert "units" not in ds.outcome.attrs and "units" not in ds.status.attrs
    assert ds.status.attrs["flag_meanings"].split()[:3] == ["decided", "t_max", "event_budget"]
    assert ds.status.attrs["flag_values"].tolist()[:3] == [0, 1, 2]
    assert ds.attrs["Conventions"] == "CF-1.8"


def test_a_complete_file_decodes_to_read_sweeps_maps_with_nothing_masked(complete_path):
    data = read_sweep(complete_path)
    ds = open_xr(complete_path)
    assert data.complete and data.computed.all()
    undecided = data.outcome == -1
    assert undecided.any() and (~undecided).any()  # the test sees both kinds of computed roll
    for name, values in data.maps.items():
        decoded = ds[name].values
        if name != "t_decided":
            assert not np.isnan(decoded).any(), name
        np.testing.assert_array_equal(decoded, values, err_msg=name)  # t_decided: NaN where undecided
    assert (ds.outcome.values[undecided] == -1).all() and (ds.status.values[undecided] == 1).all()
    raw = xr.open_dataset(complete_path, engine="h5netcdf", mask_and_scale=False)
    with raw:
        assert raw.outcome.dtype == np.int8 and raw.impacts.dtype == np.uint16
        np.testing.assert_array_equal(raw.outcome.values, data.outcome)


def test_cells_not_computed_are_nan_and_undecided_rolls_are_not(partial_path):
    data = read_sweep(partial_path)
    ds = open_xr(partial_path)
    computed = data.computed
    assert not data.complete and computed.any() and (~computed).any()
    assert ds.attrs["complete"] == 0 and ds.done_tiles.values.sum() == 1
    undecided = computed & (data.outcome == -1)
    assert undecided.any() and (computed & (data.outcome >= 0)).any()
    for name, values in data.maps.items():
        decoded = ds[name].values
        if name == "t_decided":  # NaN also for a computed roll not decided
            assert np.isnan(decoded[~computed]).all()
            np.testing.assert_array_equal(decoded[computed], values[computed])
        else:
            np.testing.assert_array_equal(np.isnan(decoded), ~computed, err_msg=name)
            np.testing.assert_array_equal(decoded[computed], values[computed], err_msg=name)
    assert (ds.outcome.values[undecided] == -1).all()
    assert ds.outcome.where(ds.status.notnull()).count() == computed.sum()
    assert int(ds.outcome.isnull().sum()) == int((~computed).sum())


def test_a_refined_file_has_its_maps_on_the_same_dimensions(tmp_path):
    axes = dict(x=SweepAxis("omega0", "rad/s", np.array([10.0, 30.0, 50.0]), 0.0, 60.0),
                y=SweepAxis("y0", "m", np.array([0.1, 0.2]), 0.05, 0.25))
    header = SweepHeader("", 4, tile_shape=(2, 3), shard=(0, 1), count_columns=("impacts", "pivots"),
                         status_names=("decided", "t_max"), **axes)
    n = 6
    maps = rolls_to_maps(header.count_columns, (2, 3), np.arange(n) % 4, np.zeros(n), np.ones((n, 2)), np.ones(n))
    path = tmp_path / "refined.h5"
    with SweepFile.create(path, header, n_tiles=1) as sweep_file:
        sweep_file.write_tile(0, slice(0, 2), slice(0, 3), maps)
        sweep_file.mark_complete()
        write_refinement_maps(sweep_file, np.array([[0, 1, 1], [1, 1, 0]], dtype=np.uint8), 1)
    ds = open_xr(path)
    assert ds.simulated.dims == ds.refine_level.dims == ("y0", "omega0")
    assert ds.simulated.values.tolist() == [[0, 1, 1], [1, 1, 0]]
    assert ds.refine_level.attrs["long_name"] and ds.simulated.attrs["flag_values"].tolist() == [0, 1]
    assert read_refinement_maps(path)[2] == 1 and (read_sweep(path).status != NOT_COMPUTED).all()


# --- layout 1 files (tests/golden) ----------------------------------------------------------


def create_layout_1(path, header, n_tiles):
    """An empty sweep file of layout 1, as SweepFile.create wrote it before layout 2."""
    with h5py.File(path, "w-") as h5:
        h5.attrs.update({
            "dice_sweep_layout": 1, "config_toml": header.config_toml, "complete": False,
            "dice_sweep_version": header.dice_sweep_version, "created": "2025-01-31T12:00:00+00:00",
            "sides": header.sides, "shard": "0/1", "shard_rule": "tile_index % N == I",
            "tile_shape": np.asarray(header.tile_shape, dtype=np.int64), "count_columns": list(header.count_columns),
        })
        for name, axis in (("y", header.y), ("x", header.x)):
            scale = h5.create_dataset(name, data=axis.values)
            scale.attrs.update({"param": axis.param, "unit": axis.unit, "min": axis.lo, "max": axis.hi})
            scale.make_scale(axis.param)
        maps = {"outcome": (np.int8, -1), "status": (np.uint8, 255), "t_decided": (np.float32, np.nan)}
        maps.update({name if name == "impacts" else f"counts/{name}": (np.uint16, 0) for name in header.count_columns})
        for name, (dtype, fill) in maps.items():
            dataset = h5.create_dataset(name, shape=header.shape, dtype=dtype, chunks=header.tile_shape,
                                        fillvalue=fill, compression="gzip", compression_opts=4, shuffle=True)
            for dim, axis_name in enumerate(("y", "x")):
                dataset.dims[dim].label = axis_name
                dataset.dims[dim].attach_scale(h5[axis_name])
        h5["outcome"].attrs["undecided"] = -1
        h5["status"].attrs.update({"names": list(header.status_names), "not_computed": 255})
        h5["t_decided"].attrs["unit"] = "s"
        h5.create_dataset("done_tiles", shape=(n_tiles,), dtype=np.uint8, fillvalue=0)


def test_a_layout_1_file_resumes_in_its_own_layout_and_merges_into_layout_2(demo_cfg, complete_path, tmp_path):
    """A sweep interrupted before the upgrade: resumed in layout 1, then merged into layout 2."""
    first = (slice(0, 6), slice(0, 4))  # tile 0 of TILE
    with SweepFile.open(complete_path) as done:
        header, tile = done.header, done.read_block(*first)
    path = tmp_path / "old.h5"
    create_layout_1(path, header, n_tiles=2)
    with SweepFile.open(path, writable=True) as old:
        assert old.layout == 1 and old._copies_chunks(*first)  # chunks copied as they are
        old.write_tile(0, *first, tile)
    partial = read_sweep(path)
    assert partial.computed[first].all() and not partial.computed.all() and (partial.outcome[~partial.computed] == -1).all()
    summary = small_sweep(demo_cfg, path, tile_shape=TILE, resume=True)
    assert summary.complete and summary.rolls_computed == 24
    with h5py.File(path, "r") as h5:
        assert h5.attrs["dice_sweep_layout"] == 1 and "counts/pivots" in h5 and "x" in h5 and "pivots" not in h5
    reference = read_sweep(complete_path).maps
    merged = tmp_path / "merged.h5"
    merge_parts([path], merged)
    for data in (read_sweep(path), read_sweep(merged)):
        assert data.complete and (data.x.param, data.y.param, data.x.unit) == ("omega0", "y0", "rad/s")
        for name, values in reference.items():
            np.testing.assert_array_equal(data.maps[name], values, err_msg=name)
    ds = open_xr(merged)
    assert ds.outcome.dims == ("y0", "omega0") and ds.attrs["dice_sweep_layout"] == 2
    np.testing.assert_array_equal(ds.pivots.values, reference["pivots"])


def test_layout_1_parts_merge_into_a_layout_2_file_with_the_same_maps(tmp_path):
    golden = ROOT / "tests" / "golden" / "fig08.h5"  # a whole sweep: shard 0/1
    merged = tmp_path / "merged.h5"
    merge_parts([golden], merged)
    old, new = read_sweep(golden), read_sweep(merged)
    assert new.complete
    assert (new.x.param, new.y.param, new.x.unit) == (old.x.param, old.y.param, old.x.unit)
    for name, values in old.maps.items():
        np.testing.assert_array_equal(new.maps[name], values, err_msg=name)
    ds = open_xr(merged)
    assert ds.outcome.dims == ("y0", "omega0") and ds.attrs["dice_sweep_layout"] == 2
    np.testing.assert_array_equal(ds.pivots.values, old.counts["pivots"])


def test_xarray_example_of_the_docs_runs(partial_path, tmp_path, monkeypatch, capsys):
    docs = ROOT / "docs" / "hdf5.md"
    blocks = re.findall(r"```python\n(.*?)```", docs.read_text(), re.S)
    example = next(block for block in blocks if "import xarray" in block)
    shutil.copyfile(partial_path, tmp_path / "sweep.h5")
    monkeypatch.chdir(tmp_path)
    exec(compile(example, str(docs), "exec"), {})
    lines = capsys.readouterr().out.splitlines()
    assert lines[0] == "('y0', 'omega0') rad/s m"
    assert re.fullmatch(r"omega0 = (26\.25|33\.75) rad/s: (6|0) of 6 computed", lines[1])  # 30: a tie
    assert lines[2].startswith("computed 24 of 48 - undecided ")


def test_the_docs_install_line_installs_an_h5py_backend():
    """docs/hdf5.md's `pip install ...` line gave, in an environment without dice_sweep, an
    h5netcdf without h5py (an optional backend of recent releases), so engine="h5netcdf" failed:
    the line must install h5py, by name or by h5netcdf's [h5py] extra, whenever the installed
    h5netcdf does not require it unconditionally."""
    from importlib.metadata import requires

    line = re.search(r"`(pip install [^`]*)`", (ROOT / "docs" / "hdf5.md").read_text()).group(1)
    words = line.replace("'", "").replace('"', "").split()[2:]
    assert "xarray" in words and any(word.startswith("h5netcdf") for word in words)
    unconditional = [r.split(";")[0].strip() for r in requires("h5netcdf") or [] if ";" not in r]
    if not any(r.startswith("h5py") for r in unconditional):
        assert "h5netcdf[h5py]" in words or "h5py" in words, line


def test_a_probability_sweep_has_one_share_map_per_side_on_the_same_dimensions(demo_cfg, tmp_path):
    """[scatter] draws 4: /probability_0 .. /probability_3 and /no_answer as (y0, omega0) maps
    in 1, summing to 1 where computed, NaN where not (Ctrl-C after the first tile)."""
    from dice_sweep.config import load_config

    cfg = load_config(ROOT / "configs" / "demo.toml", (*OVERRIDES, "scatter.corner=0.1", "scatter.draws=4"))
    path = tmp_path / "p.h5"

    def stop(index, rolls):
        raise KeyboardInterrupt

    with pytest.raises(SweepInterrupted):
        small_sweep(cfg, path, tile_shape=TILE, on_tile=stop)
    ds = open_xr(path)
    names = [f"probability_{k}" for k in range(4)] + ["no_answer"]
    computed = read_sweep(path).computed
    total = sum(ds[name] for name in names)
    for name in names:
        assert ds[name].dims == ("y0", "omega0") and ds[name].attrs["units"] == "1", name
        assert "draws" in ds[name].attrs["long_name"], name
        np.testing.assert_array_equal(np.isnan(ds[name].values), ~computed, err_msg=name)
    np.testing.assert_allclose(total.values[computed], 1.0, atol=1e-6)
    assert ds.attrs["draws"] == 4 and ds.no_answer.values[computed].max() > 0  # t_max 0.2 s: some draws undecided


def test_a_sweep_of_one_draw_has_no_share_maps_and_no_draws_attribute(complete_path):
    ds = open_xr(complete_path)
    assert "draws" not in ds.attrs and not [name for name in ds.variables if name.startswith("probability")]
