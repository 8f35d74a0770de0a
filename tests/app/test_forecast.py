"""Tests of dice_sweep.app.forecast: `dice-sweep forecast` end to end on drops from simulate-drops
and fits written by hand or by `fit --json` - the JSON contract, Markdown and pictures, bad
options and bad fit files (one line, before the work), and the real drops where they are."""

import json
import math
from pathlib import Path

import numpy as np
import pytest

from dice_sweep.app.forecast import parse_map_axes, read_fit_file
from dice_sweep.config import load_config
from dice_sweep.errors import DiceSweepError
from tests.helpers import run_cli as invoke

ROOT = Path(__file__).resolve().parents[2]
SQUARE = ROOT / "configs" / "square_drops.toml"
REAL = ROOT.parent / "shared" / "data" / "mcube_square_drops" / "drops.csv.gz"


# --- the command ------------------------------------------------------------------------------------

PAPER = {"beta_normal": 0.2, "beta_tangential": -0.35}  # configs/square_drops.toml's, which simulate-drops uses


def fit_json(path, draws=True, **changes):
    """A fit JSON as dice-sweep fit writes it, for the square of configs/square_drops.toml."""
    rng = np.random.default_rng(0)
    data = {"effects": [], "params": {k: {"value": v, "ci95": [v - 0.01, v + 0.01], "unit": "1", "at_bound": False} for k, v in PAPER.items()},
            "angle_reading": "as-is: the file's angle is used unchanged (sign +1, offset 0)",
            "die": {"sides": 4, "circumradius": 0.042426406871192854}, "split": {"confirm_fraction": 0.3, "seed": 0}}
    if draws:
        data["bootstrap_draws"] = {"names": list(PAPER), "values": (np.array(list(PAPER.values())) + 0.005 * rng.normal(size=(200, 2))).tolist()}
    data.update(changes)
    path.write_text(json.dumps(data))
    return path


@pytest.fixture(scope="module")
def drops(tmp_path_factory):
    folder = tmp_path_factory.mktemp("forecast_cli")
    data = folder / "drops.csv"
    result = invoke("simulate-drops", SQUARE, "-o", data, "--tracks", 30, "--seed", 4)
    assert result.exit_code == 0, result.output
    return data, fit_json(folder / "fit.json")


def test_forecast_command_writes_the_contract(drops, tmp_path):
    data, fit = drops
    out = tmp_path / "f.json"
    result = invoke("forecast", data, "--config", SQUARE, "--fit", fit, "--members", 1000, "--map-size", 32, "--workers", 2, "--json", out,
                    "--md", tmp_path / "f.md", "--png", tmp_path / "png", "--quiet")
    assert result.exit_code == 0, result.output
    assert "held-out tracks, ensemble" in result.stdout and ": log score" in result.stdout  # the forecast to read first, named
    report = json.loads(out.read_text())
    assert report["headline"] in result.stdout
    # any warning is one stderr line, and the Markdown report's first paragraph
    assert result.output.count("warning: ") == (1 if report["warnings"] else 0)
    assert ("**Warning:**" in (tmp_path / "f.md").read_text().split("\n\n")[1]) == bool(report["warnings"])
    scores = report["scores"]
    for key in ("log_score", "log_score_uniform", "brier", "brier_uniform"):
        low, high = scores[key]["ci95"]
        assert low <= scores[key]["value"] <= high, key
    assert scores["log_score_uniform"]["value"] == pytest.approx(-math.log(4))
    assert scores["from_bounce"] == 0 and scores["by_bounce"][0]["from_bounce"] == 0
    assert [b["from_bounce"] for b in scores["by_bounce"]] == sorted(b["from_bounce"] for b in scores["by_bounce"])
    for block in scores["by_bounce"]:
        assert {"log_score", "log_score_uniform", "brier", "brier_uniform", "tracks"} <= set(block)
    tracks = scores["tracks"]
    assert len(tracks) == scores["n_tracks"] > 0
    assert all(abs(sum(t["probabilities"]) - 1) < 1e-9 and sum(t["counts"]) >= 1000 for t in tracks)
    assert report["ensemble"]["members"] >= 1000 and "bootstrap draws" in report["fit"]["parameter_uncertainty"]
    assert report["map"]["size"] == [32, 32] and len(report["map"]["axes"]) == 2
    assert "recalibrated" in scores
    assert "## By forecast point" in (tmp_path / "f.md").read_text()
    assert sorted(p.name for p in (tmp_path / "png").iterdir()) == ["release_map.png", "reliability.png", "skill_by_bounce.png"]
    assert not list(tmp_path.glob("*.partial"))


def test_the_json_of_fit_feeds_the_forecast(drops, tmp_path):
    """`fit --json` writes the bootstrap draws, the die and the split the forecast reads."""
    data, _ = drops
    fit = tmp_path / "fit.json"
    result = invoke("fit", data, "--config", SQUARE, "--json", fit)
    assert result.exit_code == 0, result.output
    written = json.loads(fit.read_text())
    assert written["die"]["sides"] == 4 and written["die"]["circumradius"] == pytest.approx(0.06 / math.sqrt(2))
    assert written["split"] == {"confirm_fraction": 0.3, "seed": 0} and written["data"]["path"] == str(data)
    draws = np.array(written["bootstrap_draws"]["values"])
    assert written["bootstrap_draws"]["names"] == list(written["params"]) and draws.shape == (1000, len(written["params"]))
    for k, name in enumerate(written["params"]):  # the draws are the ones the track intervals come from
        entry = written["params"][name]
        assert np.quantile(draws[:, k], [0.025, 0.975]) == pytest.approx(entry["ci95_tracks"])
        assert entry["ci95"][0] <= entry["ci95_tracks"][0] and entry["ci95_tracks"][1] <= entry["ci95"][1]  # the interval spans both
    out = tmp_path / "f.json"
    result = invoke("forecast", data, "--config", SQUARE, "--fit", fit, "--members", 1000, "--map-size", 16, "--json", out, "--quiet")
    assert result.exit_code == 0, result.output
    report = json.loads(out.read_text())
    assert report["fit"]["kind"] == "fit" and report["fit"]["same_data"]
    assert report["fit"]["parameter_uncertainty"].startswith("1000 bootstrap draws")


def test_forecast_without_bootstrap_draws_says_so(drops, tmp_path):
    data, _ = drops
    fit = fit_json(tmp_path / "plain.json", draws=False)
    out = tmp_path / "f.json"
    result = invoke("forecast", data, "--config", SQUARE, "--fit", fit, "--from-bounce", 1, "--members", 1000, "--map-size", 0,
                    "--json", out, "--quiet")
    assert result.exit_code == 0, result.output
    report = json.loads(out.read_text())
    assert "ci95" in report["fit"]["parameter_uncertainty"] and report["map"] is None
    assert report["scores"]["from_bounce"] == 1


def one_line_error(result, *fragments):
    assert result.exit_code == 2, result.output
    lines = result.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("error: "), result.stderr
    for fragment in fragments:
        assert fragment in lines[0], (fragment, lines[0])
    return lines[0]


BAD = [
    (["--from-bounce", "-1"], ("--from-bounce: -1", "[0, 5]")),
    (["--from-bounce", "9"], ("--from-bounce: 9", "[0, 5]")),
    (["--from-bounce", "two"], ("--from-bounce", "whole number")),
    (["--members", "100"], ("--members: 100", "[1000, 1000000]")),
    (["--map-size", "5"], ("--map-size: 5", "[16, 2048]")),
    (["--map-axes", "phi0,spin"], ("--map-axes", "phi0,omega0")),
    (["--angle", "auto"], ("--angle: auto", "as-is")),
]


@pytest.mark.parametrize(("options", "fragments"), BAD, ids=[" ".join(o) for o, _ in BAD])
def test_bad_options_are_one_line_errors_before_the_work(drops, tmp_path, options, fragments):
    data, fit = drops
    one_line_error(invoke("forecast", data, "--config", SQUARE, "--fit", fit, "--json", tmp_path / "f.json", *options), *fragments)
    assert list(tmp_path.iterdir()) == []


FITS = {
    "not json": ("{nope", "not JSON"),
    "not a fit": (json.dumps({"verdict": "explained"}), "no key 'params'"),
    "another die": (None, "a fit of a die with n = 5"),
    "another model": (None, "a fit of another model"),
    "bad draws": (None, "bootstrap_draws"),
    # issue 32: fits edited by hand
    "beta_normal 5": (None, "params: beta_normal = 5 is outside its bounds [0, 1]"),
    "a draw out of bounds": (None, "bootstrap_draws.values[1]: beta_normal = 1.7 is outside its bounds [0, 1]"),
    "unknown model": (None, "model: 'no_such_model' is not a contact model"),
    "confirm_fraction 1": (None, "split.confirm_fraction: 1 leaves no track to fit on"),
    "a split of other data": (None, "train_tracks: 28 tracks, but its split"),
}
EDITED = {
    "beta_normal 5": {"params": {"beta_normal": {"value": 5.0}, "beta_tangential": {"value": -0.35}}},
    "a draw out of bounds": {"bootstrap_draws": {"names": list(PAPER), "values": [[0.2, -0.35], [1.7, -0.35]]}},
    "unknown model": {"model": "no_such_model"},
    "confirm_fraction 1": {"split": {"confirm_fraction": 1.0, "seed": 0}, "train_tracks": 28, "test_tracks": 39},
    "a split of other data": {"train_tracks": 28, "test_tracks": 12},  # 30 tracks: 0.3 of them cannot have fitted 28
}


@pytest.mark.parametrize("case", sorted(FITS))
def test_bad_fit_json_is_a_one_line_error(drops, tmp_path, case):
    data, _ = drops
    text, fragment = FITS[case]
    fit = tmp_path / "fit.json"
    if text is not None:
        fit.write_text(text)
    elif case == "another die":
        fit_json(fit, die={"sides": 5, "circumradius": 0.04})
    elif case == "another model":
        fit_json(fit, effects=["coulomb_friction"])
    elif case in EDITED:
        fit_json(fit, **EDITED[case])
    else:
        fit_json(fit, bootstrap_draws={"names": ["beta_normal"], "values": [[0.2]]})
    one_line_error(invoke("forecast", data, "--config", SQUARE, "--fit", fit, "--json", tmp_path / "f.json"), "--fit", str(fit), fragment)
    assert not (tmp_path / "f.json").exists()


def test_the_fit_as_fit_writes_it_passes_the_checks_of_an_edited_one(drops):
    """The control of the cases above: the counts and model a real fit of these drops gives."""
    from dice_sweep.app.forecast import fit_source
    from dice_sweep.measured.forecast import check_split
    from dice_sweep.measured.tracks import load_tracks

    data, fit = drops
    cfg = load_config(SQUARE)
    written = json.loads(fit.read_text())
    trackset = load_tracks(data, sides=4, circumradius=cfg.die.circumradius)
    select_set, confirm_set = trackset.split(0.3, 0)
    written.update(model="paper", train_tracks=len(select_set.tracks), test_tracks=len(confirm_set.tracks))
    check_split(written, fit_source(written, fit, cfg), trackset, fit)


def test_a_missing_fit_file_and_a_bounce_no_track_has(drops, tmp_path):
    data, fit = drops
    one_line_error(invoke("forecast", data, "--config", SQUARE, "--fit", tmp_path / "none.json", "--json", tmp_path / "f.json"),
                   "--fit", "cannot be read")
    one_line_error(invoke("forecast", data, "--config", SQUARE, "--fit", fit, "--from-bounce", 5, "--json", tmp_path / "f.json"),
                   "--from-bounce: 5", "no held-out track", "allowed: 0 to")
    one_line_error(invoke("forecast", data, "--config", SQUARE, "--fit", fit, "--json", tmp_path / "f.txt"), "--json", "f.txt", ".json")


@pytest.mark.slow
@pytest.mark.skipif(not REAL.exists(), reason="../shared/data/mcube_square_drops is not beside this checkout")
def test_real_drops_from_the_release(tmp_path):
    """The 500 real drops: fit, then forecast from the release (a few minutes)."""
    fit = tmp_path / "fit.json"
    result = invoke("fit", REAL, "--config", SQUARE, "--angle", "auto", "--effects", "corner_impulse,coulomb_friction", "--json", fit)
    assert result.exit_code == 0, result.output
    out = tmp_path / "f.json"
    result = invoke("forecast", REAL, "--config", SQUARE, "--angle", "auto", "--fit", fit, "--map-size", 64, "--json", out, "--quiet")
    assert result.exit_code == 0, result.output
    scores = json.loads(out.read_text())["scores"]
    assert scores["n_tracks"] > 140
    assert scores["share_correct_deterministic"]["ci95"][0] > 0.25  # better than chance from the release ...
    assert scores["by_bounce"][-1]["log_skill"]["ci95"][0] > 0.5  # ... and nearly sure a few bounces later


# --- called directly -------------------------------------------------------------------------------


def test_map_axes_are_two_different_initial_values():
    assert parse_map_axes("phi0, omega0") == ("phi0", "omega0")
    assert parse_map_axes(None) is None
    for bad in ("phi0", "phi0,phi0", "phi0,spin", "phi0,omega0,y0"):
        with pytest.raises(DiceSweepError, match=f"^--map-axes: {bad!r} is not two different initial values"):
            parse_map_axes(bad)


def test_a_fit_file_is_read_with_one_line_errors(tmp_path):
    cfg = load_config(SQUARE)
    source = read_fit_file(fit_json(tmp_path / "fit.json"), cfg)
    assert source.params == PAPER and source.draws.shape == (200, 2)
    (tmp_path / "bad.json").write_text("{nope")
    with pytest.raises(DiceSweepError, match=f"^--fit: {tmp_path / 'bad.json'}: not JSON"):
        read_fit_file(tmp_path / "bad.json", cfg)
    with pytest.raises(DiceSweepError, match="cannot be read"):
        read_fit_file(tmp_path, cfg)  # a folder


@pytest.mark.parametrize("content", [b"\xff\xfe", b"\x80\x81{}", b"{\"a\": \"\xe9\"}"])
def test_a_fit_file_that_is_not_text_is_a_one_line_error(tmp_path, content):
    (tmp_path / "binary.json").write_bytes(content)
    with pytest.raises(DiceSweepError, match=f"^--fit: {tmp_path / 'binary.json'}: not JSON"):
        read_fit_file(tmp_path / "binary.json", load_config(SQUARE))



def test_a_parameter_at_a_bound_and_a_scatter_law_are_reported(drops, tmp_path):
    """Issue 31: a fitted parameter at its bound is one stderr warning line and the report's
    first paragraph; the fit's [scatter] law is read and named."""
    data, _ = drops
    params = {"beta_normal": {"value": 0.2, "ci95": [0.19, 0.21]}, "beta_tangential": {"value": -1.0, "ci95": [-1.0, -0.99]}}
    scatter = {"corner": {"value": 0.05, "floor": 0.1}, "flat": {"value": 0.08, "floor": 0.0}}
    fit = fit_json(tmp_path / "bound.json", draws=False, params=params, scatter=scatter)
    out = tmp_path / "f.json"
    result = invoke("forecast", data, "--config", SQUARE, "--fit", fit, "--members", 1000, "--map-size", 0, "--workers", 2, "--json", out,
                    "--md", tmp_path / "f.md", "--quiet")
    assert result.exit_code == 0, result.output
    lines = [line for line in result.output.splitlines() if line.startswith("warning: ")]
    assert len(lines) == 1 and "beta_tangential = -1 at its lower bound" in lines[0], result.output
    report = json.loads(out.read_text())
    # a JSON from before the law's power and shape existed: the law it was estimated with, power 1, Gaussian, isotropic
    assert report["fit"]["scatter"] == {"corner": 0.05, "corner_floor": 0.1, "flat": 0.08, "flat_floor": 0.0, "power": 1.0,
                                        "tail_share": 0.0, "tail_factor": 1.0, "spin": 1.0}
    first = (tmp_path / "f.md").read_text().split("\n\n")[1]
    assert first.startswith("**Warning:**") and "at its lower bound" in first


def test_a_scatter_law_out_of_range_is_a_one_line_error(drops, tmp_path):
    data, _ = drops
    fit = fit_json(tmp_path / "bad.json", scatter={"corner": {"value": 3.0}, "flat": {"value": 0.1}})
    result = invoke("forecast", data, "--config", SQUARE, "--fit", fit, "--json", tmp_path / "f.json")
    assert result.exit_code == 2 and "scatter.corner.value is not in [0, 1]" in result.output
    assert len(result.output.strip().splitlines()) == 1 and not (tmp_path / "f.json").exists()
    fit = fit_json(tmp_path / "power.json", scatter={"corner": {"value": 0.1}, "flat": {"value": 0.1}, "power": {"value": 9.0}})
    result = invoke("forecast", data, "--config", SQUARE, "--fit", fit, "--json", tmp_path / "f.json")
    assert result.exit_code == 2 and "scatter.power.value is not in [0, 4]" in result.output
    assert len(result.output.strip().splitlines()) == 1 and not (tmp_path / "f.json").exists()
    fit = fit_json(tmp_path / "tail.json", scatter={"corner": {"value": 0.1}, "flat": {"value": 0.1}, "tail_factor": {"value": 0.5}})
    result = invoke("forecast", data, "--config", SQUARE, "--fit", fit, "--json", tmp_path / "f.json")
    assert result.exit_code == 2 and "scatter.tail_factor.value is not in [1, 10]" in result.output
    assert len(result.output.strip().splitlines()) == 1 and not (tmp_path / "f.json").exists()


def test_a_fitted_scale_multiplies_the_scatter_law_and_is_reported(drops, tmp_path):
    """Issue 31: the fit JSON's scatter_scale (fit_scatter_scale's factor) multiplies every
    spread and floor, capped at 1, not the law's power or shape, and the report says so."""
    data, _ = drops
    scale = {"value": 1.5, "ci95": [1.2, 1.9], "tracks": 40, "bounces": [0, 1], "at_grid_end": False}
    scatter = {"corner": {"value": 0.05, "floor": 0.1}, "flat": {"value": 0.8, "floor": 0.0}, "power": {"value": 2.0},
               "tail_share": {"value": 0.2}, "tail_factor": {"value": 2.5}, "spin": {"value": 1.4}}
    fit = fit_json(tmp_path / "scaled.json", scatter=scatter, scatter_scale=scale)
    out = tmp_path / "f.json"
    result = invoke("forecast", data, "--config", SQUARE, "--fit", fit, "--members", 1000, "--map-size", 0, "--workers", 2, "--json", out,
                    "--md", tmp_path / "f.md", "--quiet")
    assert result.exit_code == 0, result.output
    report = json.loads(out.read_text())
    assert report["fit"]["scatter"] == pytest.approx({"corner": 0.075, "corner_floor": 0.15, "flat": 1.0, "flat_floor": 0.0, "power": 2.0,
                                                      "tail_share": 0.2, "tail_factor": 2.5, "spin": 1.4})
    assert report["fit"]["scatter_scale"]["value"] == 1.5
    assert "times 1.500 [1.200, 1.900]" in (tmp_path / "f.md").read_text()
    fit = fit_json(tmp_path / "bare.json", scatter=scatter, scatter_scale={"value": 0.5})  # a scale written by hand: its value only
    result = invoke("forecast", data, "--config", SQUARE, "--fit", fit, "--members", 1000, "--map-size", 0, "--workers", 2, "--json", out,
                    "--md", tmp_path / "f.md", "--quiet")
    assert result.exit_code == 0, result.output
    assert "times 0.500)" in (tmp_path / "f.md").read_text()


@pytest.mark.parametrize("value", [0.0, -1.0, 1e9, "2"])
def test_a_scatter_scale_out_of_range_is_a_one_line_error(drops, tmp_path, value):
    data, _ = drops
    fit = fit_json(tmp_path / "bad.json", scatter={"corner": {"value": 0.1}, "flat": {"value": 0.1}}, scatter_scale={"value": value})
    result = invoke("forecast", data, "--config", SQUARE, "--fit", fit, "--json", tmp_path / "f.json")
    assert result.exit_code == 2 and "scatter_scale.value is not in (0, 100]" in result.output
    assert len(result.output.strip().splitlines()) == 1 and not (tmp_path / "f.json").exists()
