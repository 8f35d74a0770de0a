"""The batch pipelines of docs/scaling.md: `make -j shards` and the SLURM job-array scripts.

Each runs the real commands (SLURM's sbatch is faked: the array tasks are run one by one with
the environment SLURM would give them) and must give the maps of one unsharded sweep, bitwise.
"""

import os
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

from dice_sweep.config import load_config
from dice_sweep.storage import read_sweep
from tests.helpers import ROOT, assert_same_maps, small_sweep

BIN = Path(sys.executable).parent
OVERRIDES = ["grid.x.num=128", "grid.y.num=96"]  # 2 x 2 tiles of 64 x 64
SET = " ".join(f"--set {item}" for item in OVERRIDES)


@pytest.fixture(scope="module")
def reference(tmp_path_factory):
    path = tmp_path_factory.mktemp("reference") / "fig08.h5"
    small_sweep(load_config(ROOT / "configs" / "fig08.toml", OVERRIDES), path)
    return read_sweep(path)


def make(*args):
    command = ["make", "-C", str(ROOT), f"BIN={BIN}", "STAMP=", *args]
    return subprocess.run(command, capture_output=True, text=True, timeout=300)


@pytest.mark.skipif(shutil.which("make") is None, reason="needs make")
def test_make_j_shards_then_merge_equals_one_sweep(reference, tmp_path):
    result = make("-j2", "shards", "CONFIG=configs/fig08.toml", "SHARDS=3", f"SET={SET}", f"SHARD_OUT={tmp_path}")
    assert result.returncode == 0, result.stderr
    parts = sorted((tmp_path / "shards" / "fig08").glob("part-*"))
    assert [part.name for part in parts] == [f"part-{i}-of-3.h5" for i in range(3)]
    assert_same_maps(read_sweep(tmp_path / "fig08.h5"), reference)
    again = make("shards", "CONFIG=configs/fig08.toml", "SHARDS=3", f"SET={SET}", f"SHARD_OUT={tmp_path}")
    assert again.returncode == 0 and "dice-sweep" not in again.stdout  # nothing left to do


@pytest.mark.skipif(shutil.which("make") is None, reason="needs make")
def test_make_shards_with_a_bad_override_leaves_nothing_that_looks_done(tmp_path):
    result = make("shards", "CONFIG=configs/fig08.toml", "SHARDS=2", "SET=--set grid.x.nmu=8", f"SHARD_OUT={tmp_path}")
    assert result.returncode != 0
    assert "grid.x.nmu" in result.stderr and "did you mean" in result.stderr
    done = [path.name for path in tmp_path.rglob("*.h5")]
    assert done == []


@pytest.mark.skipif(shutil.which("make") is None, reason="needs make")
def test_make_shards_follows_a_change_of_set(tmp_path):
    """Issue 16: `make shards` kept the parts and merged file of the previous SET."""
    args = ["shards", "CONFIG=configs/fig08.toml", "SHARDS=2", f"SHARD_OUT={tmp_path}"]
    small = "SET=--set grid.x.num=16 --set grid.y.num=8"
    assert make(*args, small).returncode == 0
    stale = tmp_path / "shards" / "fig08" / "part-0-of-2.h5.partial"
    stale.write_bytes(b"an interrupted part of the previous SET")
    result = make(*args, "SET=--set grid.x.num=32 --set grid.y.num=8")
    assert result.returncode == 0, result.stderr
    assert read_sweep(tmp_path / "fig08.h5").outcome.shape == (8, 32) and not stale.exists()
    again = make(*args, "SET=--set grid.x.num=32 --set grid.y.num=8")
    assert again.returncode == 0 and "dice-sweep" not in again.stdout  # the same SET: nothing to do
    back = make(*args, small)
    assert back.returncode == 0 and read_sweep(tmp_path / "fig08.h5").outcome.shape == (8, 16)


def run_script(name, env, *args):
    full_env = {**os.environ, "DICE_SWEEP": str(BIN / "dice-sweep"), **env}
    return subprocess.run(["bash", str(ROOT / "scripts" / "slurm" / name), *args], env=full_env,
                          capture_output=True, text=True, timeout=300, cwd=ROOT)


def test_slurm_array_tasks_then_merge_equal_one_sweep(reference, tmp_path):
    out = tmp_path / "fig08"
    common = {"CONFIG": "configs/fig08.toml", "OUT": str(out), "SET": SET, "SLURM_ARRAY_TASK_COUNT": "3"}
    for task in range(3):
        result = run_script("sweep_array.sbatch", {**common, "SLURM_ARRAY_TASK_ID": str(task)})
        assert result.returncode == 0, result.stderr
    merged = tmp_path / "fig08.h5"
    result = run_script("merge.sbatch", {"OUT": str(out), "MERGED": str(merged)})
    assert result.returncode == 0, result.stderr
    assert_same_maps(read_sweep(merged), reference)


def test_slurm_merge_refuses_a_missing_shard(tmp_path):
    out = tmp_path / "fig08"
    env = {"CONFIG": "configs/fig08.toml", "OUT": str(out), "SET": SET, "SLURM_ARRAY_TASK_COUNT": "2",
           "SLURM_ARRAY_TASK_ID": "0"}
    assert run_script("sweep_array.sbatch", env).returncode == 0
    result = run_script("merge.sbatch", {"OUT": str(out), "MERGED": str(tmp_path / "m.h5")})
    assert result.returncode == 2 and "shards missing: 1/2" in result.stderr
    assert not (tmp_path / "m.h5").exists()


def test_slurm_submit_chains_the_merge_after_the_array(tmp_path):
    """submit.sh with a fake sbatch that records its arguments and prints job ids."""
    fake = tmp_path / "sbatch"
    log = tmp_path / "calls"
    fake.write_text(f'#!/bin/bash\necho "$@" >> {log}\necho $((41 + $(wc -l < {log})))\n')
    fake.chmod(0o755)
    env = {"PATH": f"{tmp_path}:{os.environ['PATH']}"}
    result = run_script("submit.sh", env, "configs/fig10.toml", "16", "out/fig10", "--set", "grid.x.num=4096")
    assert result.returncode == 0, result.stderr
    array_call, merge_call = log.read_text().splitlines()
    assert "--array=0-15" in array_call and "CONFIG=configs/fig10.toml" in array_call
    assert "SET=--set grid.x.num=4096" in array_call and array_call.endswith("sweep_array.sbatch")
    assert "--dependency=afterok:42" in merge_call and "MERGED=out/fig10.h5" in merge_call
    assert run_script("submit.sh", env, "configs/fig10.toml").returncode == 2
