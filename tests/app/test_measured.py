"""Tests of dice_sweep.app.measured: `dice-sweep calibrate`, `fit` and `diagnose` end to end on
small CSVs from the independent generator - the JSON contract, --json alone, Markdown with few
tracks, the residual picture, and bad input (one line, before the work)."""
import json

import numpy as np
import pytest
from matplotlib.colors import to_rgb

from dice_sweep.app.measured import run_calibrate
from dice_sweep.config import parse_config
from dice_sweep.errors import DiceSweepError
from dice_sweep.measured.calibrate import calibrate
from dice_sweep.measured.tracks import load_tracks
from tests.helpers import figure_pixels, invoke, near, png_size, read_png, run_cli
from tests.measured.cases import DECLARED_RIGID
from tests.measured.cases import TRUTH as CASE_TRUTH
from tests.measured.independent import Truth, simulate_drops, write_csv

CONFIG = DECLARED_RIGID
TRUTH = Truth(**CASE_TRUTH)


@pytest.fixture(scope="module")
def files(tmp_path_factory):
    folder = tmp_path_factory.mktemp("cli")
    data = folder / "drops.csv"
    write_csv(data, simulate_drops(TRUTH, 30, 5, rate=500.0, noise=(2e-4, 4e-3)))
    config = folder / "die.toml"
    config.write_text(CONFIG)
    return data, config


@pytest.fixture(scope="module")
def few_tracks(tmp_path_factory):
    """Fourteen drops (ten usable tracks): the least the loop runs on, and the cheapest diagnose."""
    few = tmp_path_factory.mktemp("few") / "few.csv"
    write_csv(few, simulate_drops(TRUTH, 14, 6, rate=500.0, noise=(2e-4, 4e-3)))
    return few


def test_diagnose_with_json_alone_keeps_the_contract(files, few_tracks, tmp_path):
    _, config = files
    # the contract, not the verdict: on the fewest tracks (30 cost 54 s of the suite's time)
    result = invoke("diagnose", few_tracks, "--config", config, "--quiet", "--json", tmp_path / "r.json")
    assert result.exit_code == 0, result.output
    report = json.loads((tmp_path / "r.json").read_text())
    for key in ("verdict", "effects_added", "baseline", "after", "noise_floor", "params", "angle_reading"):
        assert key in report
    assert report["verdict"] in ("explained", "improved", "unexplained")
    for part in ("baseline", "after"):
        low, high = report[part]["ci95"]
        assert low <= report[part]["test_error"] <= high
    assert set(report["params"]["friction"]) >= {"value", "ci95", "at_bound"}
    assert "as-is" in report["angle_reading"]
    assert not list(tmp_path.glob("*.partial"))


def test_fit_and_markdown_with_few_tracks(files, few_tracks, tmp_path):
    data, config = files
    result = invoke("fit", data, "--config", config, "--json", tmp_path / "fit.json")
    assert result.exit_code == 0, result.output
    fit = json.loads((tmp_path / "fit.json").read_text())
    low, high = fit["params"]["beta_normal"]["ci95"]
    assert low <= 0.4 <= high
    # ten tracks: every writer still works
    result = invoke("diagnose", few_tracks, "--config", config, "--quiet", "--json", tmp_path / "f.json", "--md", tmp_path / "f.md",
                    "--png", tmp_path / "png")
    assert result.exit_code == 0, result.output
    markdown = (tmp_path / "f.md").read_text()
    assert "Verdict" in markdown
    at_bound = [name for name, p in json.loads((tmp_path / "f.json").read_text())["params"].items() if p["at_bound"]]
    assert [line.split()[3] for line in markdown.splitlines() if line.startswith("**At a bound:**")] == at_bound
    # the same report with beta_normal at a bound says so on its own line
    from dice_sweep.measured.report import markdown_report

    report = json.loads((tmp_path / "f.json").read_text())
    report["after"]["params"]["beta_normal"]["at_bound"] = True
    assert "**At a bound:** beta_normal = " in markdown_report(report)
    # 7 x 4 inches at 100 dpi: the two fits' curves (baseline in C0, after in C1, drawn last)
    # across the time axis, and the grey line at the first impact across the plot's height
    png = tmp_path / "png" / "residual_error_vs_time.png"
    width, height = png_size(png)
    assert (width, height) == figure_pixels((7, 4), 100)
    image = read_png(png)
    assert near(image, to_rgb("C0"), tol=0.1).sum() > 50  # its legend entries at least
    _, columns = np.nonzero(near(image, to_rgb("C1"), tol=0.1))
    assert columns.size > 1000 and np.ptp(columns) > 0.6 * width
    assert near(image, to_rgb("grey"), tol=0.1).sum(axis=0).max() > 0.7 * height


NO_USABLE_TRACK = {
    "too_short": "traj,t,x,y,phi\n1,0,0,0.1,0\n1,0.002,0,0.1,0\n2,0,0,0.1,0\n",
    "all_nan": "traj,t,x,y,phi\n" + "".join(f"{k // 50},{(k % 50) * 0.002},nan,nan,nan\n" for k in range(100)),
}


@pytest.mark.parametrize("kind", sorted(NO_USABLE_TRACK))
@pytest.mark.parametrize("command", ["fit", "diagnose", "calibrate"])
def test_no_usable_tracks_is_a_one_line_error(tmp_path, command, kind):
    config = tmp_path / "die.toml"
    config.write_text(CONFIG)
    data = tmp_path / "d.csv"
    data.write_text(NO_USABLE_TRACK[kind])
    result = invoke(command, data, "--config", config, "--json", tmp_path / "out.json")
    assert result.exit_code == 2, result.output
    assert "tracks" in result.output and "allowed" in result.output and "Traceback" not in result.output
    assert len(result.output.strip().splitlines()) == 1
    assert not (tmp_path / "out.json").exists()


def test_angle_auto_without_rest_refuses(files, tmp_path):
    data, config = files
    result = invoke("diagnose", data, "--config", config, "--angle", "auto", "--json", tmp_path / "r.json")
    assert result.exit_code == 2
    assert "--angle" in result.output and "as-is" in result.output and "Traceback" not in result.output


def test_output_folder_is_checked_before_the_work(files, tmp_path):
    data, config = files
    result = invoke("diagnose", data, "--config", config, "--json", tmp_path / "missing" / "r.json")
    assert result.exit_code == 2
    assert "--json" in result.output and "does not exist" in result.output


def test_unknown_effect_is_a_one_line_error(tmp_path):
    config = tmp_path / "die.toml"
    config.write_text(CONFIG)
    data = tmp_path / "d.csv"
    data.write_text("traj,t,x,y,phi\n1,0,0,0.1,0\n")
    result = invoke("fit", data, "--config", config, "--effects", "magic")
    assert result.exit_code == 2
    assert "--effects: unknown effect 'magic'" in result.output and "Traceback" not in result.output


@pytest.mark.parametrize("command", ["calibrate", "fit", "diagnose"])
@pytest.mark.parametrize("damage", ["not gzip", "corrupt deflate", "cut short"])
def test_a_damaged_gzip_file_is_a_one_line_error(files, tmp_path, command, damage):
    """Caught: a deflate stream with bad data raised zlib.error through the CLI (a traceback)."""
    import gzip

    body = bytearray(gzip.compress(files[0].read_bytes()))
    if damage == "not gzip":
        body = bytearray(b"\x1f\x8bnot really gzip")
    elif damage == "corrupt deflate":
        body[100:200] = bytes(100)
    else:
        body = body[: len(body) // 2]
    data = tmp_path / "drops.csv.gz"
    data.write_bytes(bytes(body))
    extra = [] if command == "calibrate" else ["--json", tmp_path / "out.json"]
    result = invoke(command, data, "--config", files[1], *extra)
    assert result.exit_code == 2, result.output
    assert str(data) in result.output and "Traceback" not in result.output
    assert len(result.output.strip().splitlines()) == 1
    assert not (tmp_path / "out.json").exists()


def test_calibrate_writes_the_json_and_picture_of_the_result_it_returns(files, tmp_path):
    data, config = files
    cfg = parse_config(config.read_text(), str(config))
    result, written = run_calibrate(data, cfg, json_path=tmp_path / "c.json", png_path=tmp_path / "c.png")
    assert written == [tmp_path / "c.json", tmp_path / "c.png"]
    expected = calibrate(load_tracks(data, sides=cfg.die.sides, circumradius=cfg.die.circumradius), cfg)
    assert json.loads((tmp_path / "c.json").read_text()) == json.loads(json.dumps(expected.to_dict()))
    assert result.to_dict() == expected.to_dict()
    assert png_size(tmp_path / "c.png")[0] > 100


def test_calibrate_checks_its_outputs_before_reading_the_data(tmp_path):
    cfg = parse_config(CONFIG)
    with pytest.raises(DiceSweepError, match="^--png: .*wrong file extension"):
        run_calibrate(tmp_path / "no_such.csv", cfg, png_path=tmp_path / "c.txt")  # the data is never opened


@pytest.fixture(scope="module")
def paper_drops(tmp_path_factory):
    """Drops of the paper's law with Table I's coefficients from the independent generator (the
    README's synthetic drops, made without this project's kernel), at g = 9.81 and at g = 16
    m/s^2, beyond the gravity effect's fit range of 0.5 to 1.5 times the declared 9.81; and the
    square with that law declared."""
    from tests.measured.cases import DECLARED_PAPER

    folder = tmp_path_factory.mktemp("paper")
    paths = {}
    for g in (9.81, 16.0):
        paths[g] = folder / f"drops_g{g:g}.csv"
        truth = Truth(contact="paper", beta_normal=0.2, beta_tangential=-0.35, g=g)
        write_csv(paths[g], simulate_drops(truth, 20, 7, rate=500.0, noise=(2e-4, 4e-3)))
    config = folder / "die.toml"
    config.write_text(DECLARED_PAPER)
    return paths, config


@pytest.mark.parametrize("g", [9.81, 16.0], ids=["control", "g beyond the range"])
def test_fit_says_on_stderr_when_a_parameter_sits_at_a_bound(paper_drops, tmp_path, g):
    """Issue 32: the README's `fit` line ended with beta_tangential at its bound -1 and nothing
    said so. A warning line names each parameter the JSON marks at a bound: g, when the drops'
    gravity lies beyond the range the fit may use; none on the control, where the declared law
    and g are the truth."""
    paths, config = paper_drops
    result = run_cli("fit", paths[g], "--config", config, "--effects", "gravity", "--no-check-units", "--json", tmp_path / "fit.json")
    assert result.exit_code == 0, result.stderr
    fit = json.loads((tmp_path / "fit.json").read_text())
    at_bound = sorted(name for name, p in fit["params"].items() if p["at_bound"])
    warnings = [line for line in result.stderr.splitlines() if "sits at a bound" in line]
    assert sorted(line.split()[1] for line in warnings) == at_bound
    assert all(line.startswith("warning: ") for line in warnings)
    if g > 9.81:
        assert "g" in at_bound and fit["params"]["g"]["value"] == pytest.approx(1.5 * 9.81, rel=1e-3)
    else:
        assert at_bound == [] and result.stderr == ""
        assert fit["params"]["g"]["value"] == pytest.approx(9.81, rel=0.01)
        assert fit["params"]["beta_tangential"]["value"] == pytest.approx(-0.35, abs=0.03)


def test_the_at_a_bound_lines_name_each_parameter_at_a_bound_and_no_other():
    from dice_sweep.measured.report import at_bound_lines

    params = {"beta_normal": {"value": 0.2, "at_bound": False}, "beta_tangential": {"value": -1.0, "at_bound": True}}
    lines = at_bound_lines(params)
    assert len(lines) == 1 and lines[0].startswith("beta_tangential = -1 sits at a bound")
    assert at_bound_lines({"beta_normal": {"value": 0.2, "at_bound": False}}) == []
