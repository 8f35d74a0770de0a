"""Measured data checked before the work (issue 30, item 5; dice_sweep/measured/checks.py):
drops of the independent generator (tests/measured/independent.py, not the kernel), written by
its CSV writer and then transformed into degrees, mm, ms, a wrong frame rate, another die's
config and an angle zero off by half a side, each refused through the CLI with one line and
exit code 2 before any kernel runs; the clean drops pass without a warning, and so do the real
drops (when they are beside this checkout); the real drops read with their own angle (the run
that died late with "needs more than 4096 kernel records") are refused up front."""

import csv
import gzip
import json
import math

import pytest

from dice_sweep.config import parse_config
from dice_sweep.measured import checks
from dice_sweep.measured import fit as shooting
from dice_sweep.measured.tracks import load_tracks
from tests.helpers import ROOT, run_cli
from tests.measured.cases import NOISE, RADIUS, TRUE_COEFFICIENTS
from tests.measured.independent import Truth, simulate_drops, write_csv

REAL = ROOT.parent / "shared" / "data" / "mcube_square_drops" / "drops.csv.gz"
SQUARE_DROPS = ROOT / "configs" / "square_drops.toml"
RATE = 500.0


def config_text(sides, radius=RADIUS):
    return (f'[die]\nsides = {sides}\ncircumradius = {radius!r}\n[contact]\nmodel = "rigid"\n'
            f'beta_normal = 0.3\nbeta_tangential = 0.0\nfriction = 0.5\n')


def transform(src, dst, change, header=None):
    """The CSV ``src`` rewritten row by row (as floats) through ``change``."""
    with open(src, newline="") as fh:
        rows = list(csv.reader(fh))
    with open(dst, "w", newline="") as fh:
        out = csv.writer(fh)
        out.writerow(header or rows[0])
        for row in rows[1:]:
            out.writerow(change([float(v) for v in row]))
    return dst


@pytest.fixture(scope="module")
def files(tmp_path_factory):
    """Clean drops of a square and of a hexagon (R the same), their configs, and the transforms."""
    folder = tmp_path_factory.mktemp("checks")
    square, hexagon = folder / "square.csv", folder / "hexagon.csv"
    write_csv(square, simulate_drops(Truth(sides=4, circumradius=RADIUS, contact="rigid", **TRUE_COEFFICIENTS), 30, 21, rate=RATE, noise=NOISE))
    write_csv(hexagon, simulate_drops(Truth(sides=6, circumradius=RADIUS, contact="rigid", **TRUE_COEFFICIENTS), 30, 22, rate=RATE, noise=NOISE))
    out = {"square": square, "hexagon": hexagon}
    for sides, name in ((4, "square.toml"), (6, "hexagon.toml")):
        (folder / name).write_text(config_text(sides))
        out[name] = folder / name
    out["degrees"] = transform(square, folder / "degrees.csv", lambda r: [r[0], r[1], r[2], r[3], math.degrees(r[4])])
    out["mm"] = transform(square, folder / "mm.csv", lambda r: [r[0], r[1], 1e3 * r[2], 1e3 * r[3], r[4]])
    out["ms"] = transform(square, folder / "ms.csv", lambda r: [r[0], 1e3 * r[1], r[2], r[3], r[4]])
    out["frames"] = transform(square, folder / "frames.csv", lambda r: [r[0], round(RATE * r[1]), r[2], r[3], r[4]],
                              ["traj", "frame", "x", "y", "phi"])
    out["half_side"] = transform(square, folder / "half_side.csv", lambda r: [r[0], r[1], r[2], r[3], r[4] + math.pi / 4])
    out["half_side_hexagon"] = transform(hexagon, folder / "half_side_hexagon.csv", lambda r: [r[0], r[1], r[2], r[3], r[4] + math.pi / 6])
    out["wrapped"] = transform(square, folder / "wrapped.csv", lambda r: [r[0], r[1], r[2], r[3], r[4] % (math.pi / 2)])
    return out


@pytest.fixture
def no_kernel(monkeypatch):
    """Any simulation of the kernel fails the test: the checks must come first."""
    def refuse(*args, **kwargs):
        raise AssertionError("the kernel ran before the checks refused the data")

    monkeypatch.setattr(shooting.ShootingModel, "simulate", refuse)


def one_line_error(result):
    """The stderr of a refused command: exit 2, one line, no traceback."""
    assert result.exit_code == 2, (result.exit_code, result.output, result.stderr)
    lines = result.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("error: "), result.stderr
    assert "Traceback" not in result.stderr and (result.exception is None or isinstance(result.exception, SystemExit))
    return lines[0]


# (data, config, options, the check that refuses it, what the line must say)
REFUSED = {
    "degrees": ("degrees", "square.toml", (), "angle_unit", "degrees"),
    "mm": ("mm", "square.toml", (), "gravity", "not in m"),
    "wrong_rate": ("frames", "square.toml", ("--rate", "250"), "gravity", "--rate"),
    "hexagon_as_square": ("hexagon", "square.toml", (), "contact_share", "another die"),
    "square_as_hexagon": ("square", "hexagon.toml", (), "contact_share", "another die"),
    "half_side": ("half_side", "square.toml", (), "contact_share", "--angle auto"),
    "half_side_hexagon": ("half_side_hexagon", "hexagon.toml", (), "contact_share", "--angle auto"),
    "wrapped": ("wrapped", "square.toml", (), "angle_wrap", "unwrap"),
}


@pytest.mark.parametrize("case", sorted(REFUSED))
def test_a_wrong_unit_or_convention_is_one_line_and_exit_2(files, case, no_kernel, tmp_path):
    data, config, options, check, hint = REFUSED[case]
    result = run_cli("diagnose", files[data], "--config", files[config], *options, "--quiet", "--json", tmp_path / "r.json")
    line = one_line_error(result)
    assert line.startswith(f"error: {files[data]}: check {check}: "), line
    assert "95 % interval" in line and "expected" in line and hint in line and "--no-check-units" in line
    assert not (tmp_path / "r.json").exists()


def test_time_in_ms_is_one_line_and_exit_2(files, no_kernel, tmp_path):
    """The loader refuses a clock in ms at 500 Hz (a 0.5 Hz frame rate) before the checks."""
    line = one_line_error(run_cli("fit", files["ms"], "--config", files["square.toml"]))
    assert "not a frame rate (are the times in s?)" in line


def fit_file(path, cfg):
    """A fit JSON of the config's own model at its values (enough for forecast to get to the data)."""
    spec = shooting.ModelSpec.of(cfg)
    path.write_text(json.dumps({"effects": [], "params": {k: {"value": v} for k, v in shooting.start_values(cfg, spec).items()}}))
    return path


@pytest.mark.parametrize("command", ["fit", "diagnose", "calibrate", "forecast"])
def test_every_command_on_tracked_data_checks_it(files, command, no_kernel, tmp_path):
    extra = {"diagnose": ("--json", tmp_path / "r.json"), "fit": (), "calibrate": (),
             "forecast": ("--fit", fit_file(tmp_path / "fit.json", parse_config(config_text(4))), "--json", tmp_path / "f.json")}[command]
    line = one_line_error(run_cli(command, files["degrees"], "--config", files["square.toml"], *extra))
    assert "check angle_unit" in line


def test_the_checks_can_be_skipped(files):
    result = run_cli("calibrate", files["degrees"], "--config", files["square.toml"], "--no-check-units")
    assert result.exit_code == 0, result.output
    assert "check" not in result.stderr


@pytest.mark.parametrize("data,config", [("square", "square.toml"), ("hexagon", "hexagon.toml")])
def test_clean_drops_pass_without_a_warning(files, data, config):
    result = run_cli("calibrate", files[data], "--config", files[config])
    assert result.exit_code == 0, result.output
    assert "warning" not in result.stderr and "error" not in result.stderr, result.stderr
    cfg = parse_config(files[config].read_text())
    tracks = load_tracks(files[data], sides=cfg.die.sides, circumradius=cfg.die.circumradius)
    findings = {f.name: f for f in checks.judge(checks.measure(tracks, cfg), cfg)}
    assert all(f.status in ("ok", "skipped") for f in findings.values()), [f.message for f in findings.values()]
    low, high = findings["gravity"].interval
    assert 0.97 * 9.81 < low <= high < 1.01 * 9.81
    assert findings["angle_unit"].interval[1] < 0.5  # the physical bound is 1
    assert findings["contact_share"].value < 0.05


def test_a_frame_rate_a_little_off_warns(files):
    """600 Hz for 500 Hz frames: g seen 1.44 times too large, within the gravity effect's range
    (0.5 to 1.5 g): a warning line, and the command goes on."""
    result = run_cli("calibrate", files["frames"], "--rate", "600", "--config", files["square.toml"])
    assert result.exit_code == 0, result.output
    warnings = [line for line in result.stderr.splitlines() if line.startswith("warning:")]
    assert len(warnings) == 1 and "check gravity" in warnings[0] and "--rate" in warnings[0], result.stderr


def test_too_few_impacts_warn_that_the_die_was_not_checked(files, tmp_path):
    few = tmp_path / "few.csv"
    with open(files["square"]) as src, open(few, "w") as dst:
        dst.writelines(line for line in src if line.startswith(("traj", "1,", "2,")))
    cfg = parse_config(files["square.toml"].read_text())
    tracks = load_tracks(few, sides=4, circumradius=RADIUS)
    lines = []
    with checks.settings(warn=lines.append):
        checks.check_measured(tracks, cfg)
    assert any("not checked: too little evidence" in line for line in lines), lines


needs_real = pytest.mark.skipif(not REAL.exists(), reason=f"{REAL} is not beside this checkout")


@needs_real
def test_the_real_drops_pass():
    result = run_cli("calibrate", REAL, "--config", SQUARE_DROPS, "--angle", "auto")
    assert result.exit_code == 0, result.output
    assert "warning" not in result.stderr, result.stderr


@needs_real
def test_the_record_limit_run_is_refused_up_front(tmp_path, no_kernel):
    """diagnose on 60 real drops with the file's own angle (--angle as-is: a side flat on the
    table reads as a corner straight down) ran for minutes, then died with "needs more than
    4096 kernel records" (dice_sweep/measured/fit.py, ShootingModel.simulate). It is refused
    now before the kernel runs, by the dice at rest."""
    sixty = tmp_path / "sixty.csv"
    with gzip.open(REAL, "rt") as src, open(sixty, "w") as dst:
        dst.writelines(line for k, line in enumerate(src) if k == 0 or int(line.split(",", 1)[0]) <= 60)
    line = one_line_error(run_cli("diagnose", sixty, "--config", SQUARE_DROPS, "--quiet", "--json", tmp_path / "r.json"))
    assert "check rest_angle" in line and "--angle auto" in line
    value = float(line.split("pi/n, ")[1].split(" ")[0])
    assert value > 0.9  # 45 deg off the flat pose: one pi/n of the square
