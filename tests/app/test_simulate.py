"""dice_sweep.app.simulate: the files of ``simulate-drops`` (the drops themselves:
tests/measured/test_simulate.py)."""

import gzip
import json
import math

import pytest

from dice_sweep.app import simulate as app
from dice_sweep.config import parse_config
from dice_sweep.errors import DiceSweepError
from dice_sweep.measured import simulate

SQUARE = (f'[die]\nsides = 4\ncircumradius = {0.06 / math.sqrt(2)!r}\n[contact]\nmodel = "paper"\nbeta_normal = 0.2\n'
          'beta_tangential = -0.35\n')


@pytest.fixture(scope="module")
def drops():
    cfg = parse_config(SQUARE, "die.toml")
    return cfg, simulate.simulate_drops(cfg, 3, seed=2)


@pytest.mark.parametrize("name", ["d.csv", "d.csv.gz"])
def test_the_file_holds_the_domains_text_and_the_sidecar_its_provenance(drops, tmp_path, name):
    cfg, made = drops
    path = tmp_path / name
    assert app.write_drops(made, cfg, path) == path
    data = path.read_bytes()
    assert (gzip.decompress(data) if name.endswith(".gz") else data) == b"".join(simulate.csv_chunks(made))
    assert json.loads((tmp_path / f"{name}.json").read_text()) == json.loads(json.dumps(simulate.provenance(made, cfg, path)))
    assert sorted(p.name for p in tmp_path.iterdir()) == [name, f"{name}.json"]


def test_the_same_drops_give_the_same_gzip_bytes(drops, tmp_path):
    cfg, made = drops
    first, second = app.write_drops(made, cfg, tmp_path / "a.csv.gz"), app.write_drops(made, cfg, tmp_path / "b.csv.gz")
    assert first.read_bytes() == second.read_bytes()


def test_a_failure_while_writing_leaves_no_data_file(drops, tmp_path, monkeypatch):
    cfg, made = drops

    def broken(_):
        yield b"traj,t,x,y,phi\n"
        raise OSError("disk full")

    monkeypatch.setattr(app, "csv_chunks", broken)
    with pytest.raises(DiceSweepError, match=r"d.csv: cannot be written: disk full; nothing was written to it$"):  # issue 32: named
        app.write_drops(made, cfg, tmp_path / "d.csv")
    assert list(tmp_path.iterdir()) == []


def test_a_track_file_it_did_not_write_is_never_replaced(drops, tmp_path):
    cfg, _ = drops
    tracked = tmp_path / "tracked.csv"
    tracked.write_text("traj,t,x,y,phi\n1,0,0,0.1,0\n")
    with pytest.raises(DiceSweepError, match="not written by simulate-drops"):
        app.run_simulate_drops(cfg, tracked, 2, seed=1)
    assert tracked.read_text() == "traj,t,x,y,phi\n1,0,0,0.1,0\n"
    # one it wrote (its sidecar says synthetic) is replaced
    app.run_simulate_drops(cfg, tmp_path / "made.csv", 2, seed=1)
    again = app.run_simulate_drops(cfg, tmp_path / "made.csv", 3, seed=1)
    assert json.loads((tmp_path / "made.csv.json").read_text())["options"]["tracks"] == 3 == len(again.ending)
