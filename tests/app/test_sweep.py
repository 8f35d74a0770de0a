"""Tests of dice_sweep.app.sweep: the sweep and merge commands' own checks (made here, once,
before any work), and that they join compute, storage and pictures."""

import pytest

from dice_sweep.app.sweep import merge, sweep
from dice_sweep.config import parse_config
from dice_sweep.errors import ConfigError, DiceSweepError
from dice_sweep.storage import read_sweep
from tests.helpers import assert_same_maps
from tests.test_sweep import CONFIG_TEXT


@pytest.fixture(scope="module")
def cfg():
    """test_sweep's grid at 8 x 8 cells: refinement needs an even count."""
    return parse_config(CONFIG_TEXT, "test.toml", overrides=["grid.x.num=8", "grid.y.num=8"])


def quiet(cfg, path, **options):
    return sweep(cfg, path, **{"workers": 1, "progress": False, **options})


def test_config_without_grid_is_refused(tmp_path):
    with pytest.raises(ConfigError, match="grid: missing; sweep needs a \\[grid\\]"):
        quiet(parse_config("", "single.toml"), tmp_path / "out.h5")
    assert not (tmp_path / "out.h5").exists()


@pytest.mark.parametrize(
    ("options", "message"),
    [
        ({"executor": "spark"}, "--executor 'spark': allowed values are local, dask"),
        ({"scheduler": "tcp://h:8786"}, "--scheduler: only with --executor dask"),
        ({"executor": "dask", "scheduler": "tcp://h:8786", "workers": 2}, "--workers: not with --scheduler"),
        ({"refine_levels": 1, "shard": (0, 2)}, "--refine: cannot be combined with --shard"),
        ({"refine_levels": 1, "resume": True}, "--refine: cannot be combined"),
        ({"refine_levels": 4}, r"--refine 4: grid.y.num = 8 is not divisible by 2\^4 = 16"),
        ({"refine_levels": -1}, "--refine -1: outside the allowed range"),
    ],
)
def test_bad_options_are_refused_before_any_work(cfg, tmp_path, options, message):
    with pytest.raises(DiceSweepError, match=message):
        quiet(cfg, tmp_path / "x.h5", **options)
    assert not (tmp_path / "x.h5").exists()


def test_sweep_writes_the_file_and_its_picture(cfg, tmp_path):
    summary, written = quiet(cfg, tmp_path / "s.h5", png_path=tmp_path / "s.png")
    assert summary.complete and summary.rolls_computed == 64
    assert read_sweep(tmp_path / "s.h5").complete
    assert written == [tmp_path / "s.png"] and (tmp_path / "s.png").stat().st_size > 0


def test_refined_sweep_writes_a_complete_file_of_the_grid(cfg, tmp_path):
    full, _ = quiet(cfg, tmp_path / "full.h5")
    refined, _ = quiet(cfg, tmp_path / "refined.h5", refine_levels=2)
    assert refined.levels == 2 and refined.shape == full.shape
    assert read_sweep(tmp_path / "refined.h5").complete


def test_merge_joins_shards_into_the_unsharded_maps(cfg, tmp_path):
    quiet(cfg, tmp_path / "whole.h5")
    parts = [tmp_path / f"part{i}.h5" for i in range(2)]
    for i, part in enumerate(parts):
        quiet(cfg, part, shard=(i, 2))
    summary = merge(parts, tmp_path / "merged.h5")
    assert summary.complete and summary.merged_parts == 2
    assert_same_maps(read_sweep(tmp_path / "merged.h5"), read_sweep(tmp_path / "whole.h5"))


def test_merge_refuses_an_output_that_is_not_a_sweep_file(cfg, tmp_path):
    quiet(cfg, tmp_path / "part.h5")
    with pytest.raises(DiceSweepError, match="--output: .*merged.png"):
        merge([tmp_path / "part.h5"], tmp_path / "merged.png")
    assert not (tmp_path / "merged.png").exists()
    with pytest.raises(DiceSweepError, match="--output: .: wrong file extension"):
        merge([tmp_path / "part.h5"], "")
