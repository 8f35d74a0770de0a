"""`dice-sweep simulate-drops` and dice_sweep.measured.simulate: synthetic drops from the kernel
(the files: dice_sweep.app.simulate, tests/app/test_simulate.py).

The poses are checked against the kernel's path computed another way (roll_one with a large
record buffer, then dice_sweep.roll.sample_path, instead of sample_batch); the noise, the
dropped frames and the glitches against what was asked, with stated tolerances; the file against
load_tracks and `dice-sweep calibrate`.
"""

import gzip
import inspect
import json
import math

import numpy as np
import pytest

from dice_sweep.app.simulate import run_simulate_drops
from dice_sweep.cli import simulate_drops_command
from dice_sweep.config import parse_config
from dice_sweep.measured import simulate
from dice_sweep.physics import layout
from dice_sweep.measured.flights import estimate_noise
from dice_sweep.measured.simulate import DROP_RANGES, REST_TAIL, simulate_drops
from dice_sweep.measured.tracks import load_tracks
from dice_sweep.physics import COUNT_COLUMNS, pack_params
from dice_sweep.physics.kernel import REC_WIDTH, roll_one, sample_batch
from dice_sweep.physics.params import FP_TMAX, IP_CONTINUE
from dice_sweep.roll import RollReport, sample_path
from tests.helpers import invoke

RADIUS = 0.06 / math.sqrt(2)  # m, the square of configs/square_drops.toml
SQUARE = f'[die]\nsides = 4\ncircumradius = {RADIUS!r}\n[contact]\nmodel = "paper"\nbeta_normal = 0.2\nbeta_tangential = -0.35\n'
# a rigid die with friction, drag and a loaded centre: the config's [effects] reach the kernel
LOADED = (f'[die]\nsides = 5\ncircumradius = 0.03\n[contact]\nmodel = "rigid"\nbeta_normal = 0.3\nbeta_tangential = -0.2\n'
          f'friction = 0.4\n[effects]\nair_drag = 0.3\ncom_offset = [0.002, -0.001]\n')
CLEAN = {"noise": (0.0, 0.0, 0.0), "drop_prob": 0.0, "glitch_prob": 0.0}


def config(text=SQUARE, overrides=()):
    return parse_config(text, "die.toml", overrides)


def reference_path(cfg, state, times, duration):
    """The kernel's path of one drop by another route: roll_one to rest with 100,000 records,
    then dice_sweep.roll.sample_path (sample_records over them)."""
    fpar, ipar = pack_params(cfg)
    ipar[IP_CONTINUE] = 1
    fpar[FP_TMAX] = duration
    rec = np.zeros((100_000, REC_WIDTH))
    counts = np.zeros(len(COUNT_COLUMNS), dtype=np.int32)
    outcome, status, t_decided, t_end, n_rec = roll_one(fpar, ipar, np.array(state, dtype=float), rec, counts)
    report = RollReport(int(outcome), int(status), float(t_decided), float(t_end), {}, rec[:n_rec].copy())
    return sample_path(cfg, report, times), float(t_end)


def tracks_of(drops):
    """Row slices of each track."""
    bounds = np.flatnonzero(np.diff(drops.traj)) + 1
    return np.split(np.arange(drops.traj.size), bounds)


# --- the kernel's path --------------------------------------------------------------------


@pytest.mark.parametrize("text", [SQUARE, LOADED], ids=["paper_square", "rigid_loaded_pentagon"])
def test_without_noise_the_poses_are_the_kernels_path(text):
    cfg = config(text)
    drops = simulate_drops(cfg, 6, seed=3, rate=400.0, duration=1.5, **CLEAN)
    assert drops.traj.size == drops.frames.sum()  # nothing dropped
    for i, rows in enumerate(tracks_of(drops)):
        state = drops.states[i]
        for name, value in zip(("x0", "y0", "phi0", "vx0", "vy0", "omega0"), state):
            low, high = DROP_RANGES[name]
            assert low <= value <= high
        np.testing.assert_allclose(drops.t[rows], np.arange(rows.size) / 400.0, rtol=0, atol=1e-12)
        path, t_end = reference_path(cfg, state, drops.t[rows], 1.5)
        np.testing.assert_allclose(drops.pose[rows, :2], path[:, :2], rtol=0, atol=1e-9)
        np.testing.assert_allclose(drops.pose[rows, 2], np.unwrap(path[:, 2]), rtol=0, atol=1e-9)
        # the track ends REST_TAIL after the die comes to rest (to within a frame)
        assert drops.ending[i] == "rest"
        assert t_end + REST_TAIL - 1 / 400 < drops.t[rows[-1]] <= t_end + REST_TAIL
        np.testing.assert_array_equal(path[-1, 3:], 0.0)  # at rest: no velocity, no spin


def test_a_pivot_running_past_the_duration_is_not_a_kernel_that_stopped_early():
    """This drop chatters on the table past 1.5 s, in a pivot that a time limit of 1.5 s ends
    at its start (t_end 1.4987 s): the track must still run to 1.5 s, on the kernel's path."""
    state = (0.0, 0.20551489315058943, 2.3101900754682756, -0.05209880847211895, -0.3619084749005347, -5.38826401424894)
    fixed = {name: (value, value) for name, value in zip(("x0", "y0", "phi0", "vx0", "vy0", "omega0"), state)}
    cfg = config(text=f"{SQUARE}[initial]\ny0 = 0.2\n")
    drops = simulate_drops(cfg, 1, initial="config", ranges=fixed, duration=1.5, **CLEAN)
    assert drops.ending == ["duration"] and drops.traj.size == 376
    path, _ = reference_path(cfg, state, drops.t, 2.5)
    np.testing.assert_allclose(drops.pose[:, :2], path[:, :2], rtol=0, atol=1e-9)


def test_sample_batch_record_buffer_is_the_size_simulate_assumes():
    source = inspect.getsource(sample_batch.py_func)
    assert "np.empty((SAMPLE_RECORDS, REC_WIDTH))" in source  # the layout's constant, not a number
    assert simulate.SAMPLE_RECORDS is layout.SAMPLE_RECORDS


def test_a_drop_with_more_records_than_sample_batch_keeps_is_cut_not_extrapolated(monkeypatch):
    cfg = config()
    full = simulate_drops(cfg, 4, seed=5, **CLEAN)
    monkeypatch.setattr(simulate, "SAMPLE_RECORDS", 3)  # as if the buffer held 3 segments
    cut = simulate_drops(cfg, 4, seed=5, **CLEAN)
    assert cut.ending == ["records"] * 4
    for rows_cut, rows_full in zip(tracks_of(cut), tracks_of(full)):
        assert 0 < rows_cut.size < rows_full.size
        np.testing.assert_array_equal(cut.pose[rows_cut], full.pose[rows_full[: rows_cut.size]])


# --- what the tracker adds ------------------------------------------------------------------


def test_noise_has_the_requested_sigmas():
    """Noisy minus noise-free drops of the same seed (same states, frames and glitches): the
    difference is the noise alone, on every frame that is not a glitch (in flight or at rest);
    each sigma within 6 % (~3.5 standard errors at ~3000 frames)."""
    cfg = config()
    sigmas = (3e-4, 1e-4, 0.01)
    options = {"seed": 11, "drop_prob": 0.01, "glitch_prob": 0.01}
    noisy = simulate_drops(cfg, 16, noise=sigmas, **options)
    clean = simulate_drops(cfg, 16, noise=(0.0, 0.0, 0.0), **options)
    np.testing.assert_array_equal(noisy.t, clean.t)
    np.testing.assert_array_equal(noisy.glitch, clean.glitch)
    error = (noisy.pose - clean.pose)[~noisy.glitch]
    assert error.shape[0] > 2500
    np.testing.assert_allclose(error.std(axis=0), sigmas, rtol=0.06)
    assert np.all(np.abs(error.mean(axis=0)) < 4 * np.array(sigmas) / math.sqrt(error.shape[0]))
    np.testing.assert_array_equal(noisy.true_pose, clean.true_pose)


def test_the_loops_noise_estimate_from_flights_finds_the_requested_sigmas(tmp_path):
    """flights.estimate_noise (quadratic fits over the free flights, as fit and diagnose measure
    the noise floor): within 10 % of each sigma (~1000 flight frames: ~4.5 standard errors)."""
    sigmas = (3e-4, 1e-4, 0.01)
    path = tmp_path / "noisy.csv"
    run_simulate_drops(config(), path, 20, seed=0, noise=sigmas)
    trackset = load_tracks(path, sides=4, circumradius=RADIUS)
    estimate = estimate_noise(trackset.tracks, sides=4, circumradius=RADIUS, g=9.81)
    assert estimate.frames > 800
    np.testing.assert_allclose(estimate.sigma, sigmas, rtol=0.10)


def _within_binomial(count, trials, p):
    return abs(count - trials * p) <= 4.0 * math.sqrt(trials * p * (1 - p))


def test_dropped_frames_and_glitches_at_the_requested_rates():
    cfg = config()
    drops = simulate_drops(cfg, 24, seed=2, noise=(0.0, 0.0, 0.0), drop_prob=0.05, glitch_prob=0.03)
    frames = int(drops.frames.sum())
    assert _within_binomial(drops.dropped, frames, 0.05)
    assert _within_binomial(int(drops.glitch.sum()), frames, 0.03 * (1 - 0.05))
    # rows removed: the kept frames of a track are a subset of its clock, in order
    for i, rows in enumerate(tracks_of(drops)):
        frame = np.round(drops.t[rows] * 250.0).astype(int)
        assert np.all(np.diff(frame) >= 1) and frame[-1] < drops.frames[i]
    # a glitch moves the pose by GLITCH_SIZE R in (x, y, R phi); other frames are the truth
    jump = (drops.pose - drops.true_pose) * [1.0, 1.0, RADIUS]
    np.testing.assert_allclose(np.linalg.norm(jump[drops.glitch], axis=1), simulate.GLITCH_SIZE * RADIUS, rtol=1e-9)
    assert np.all(jump[~drops.glitch] == 0)


def test_neighbouring_glitch_frames_are_one_glitch():
    drops = simulate_drops(config(), 4, seed=3, noise=(0.0, 0.0, 0.0), drop_prob=0.0, glitch_prob=0.3)
    jump = drops.pose - drops.true_pose
    same_track = drops.traj[1:] == drops.traj[:-1]
    pairs = np.flatnonzero(drops.glitch[1:] & drops.glitch[:-1] & same_track)
    assert pairs.size > 10
    np.testing.assert_allclose(jump[pairs + 1], jump[pairs], rtol=0, atol=1e-12)
    starts = np.flatnonzero(drops.glitch[1:] & ~drops.glitch[:-1]) + 1
    assert np.unique(np.round(jump[starts], 9), axis=0).shape[0] == starts.size  # each glitch its own jump


def test_renumbered_rows_hide_the_gaps_and_the_loader_finds_some(tmp_path):
    cfg = config()
    path = tmp_path / "renumbered.csv"
    drops = run_simulate_drops(cfg, path, 10, seed=4, drop_prob=0.03, renumber=True)
    for rows in tracks_of(drops):
        np.testing.assert_allclose(np.diff(drops.t[rows]), 1 / 250.0, rtol=1e-12)
    assert drops.dropped > 20
    # gaps in flight show in the motion (docs/calibration.md); gaps at rest cannot
    assert 0 < load_tracks(path, sides=4, circumradius=RADIUS).gap_frames <= drops.dropped


def test_the_loader_flags_the_glitches(tmp_path):
    """At the default noise, the loader's glitch frames are the injected ones (90 % both ways)."""
    path = tmp_path / "glitchy.csv"
    drops = run_simulate_drops(config(), path, 10, seed=6, glitch_prob=0.01)
    trackset = load_tracks(path, sides=4, circumradius=RADIUS)
    injected = {(int(traj), round(float(t) * 250)) for traj, t in zip(drops.traj[drops.glitch], drops.t[drops.glitch])}
    flagged = {(track.traj, round(float(t) * 250)) for track in trackset.tracks for t in track.t[track.glitch]}
    assert len(injected) >= 10
    assert len(injected & flagged) >= 0.9 * len(injected) and len(injected & flagged) >= 0.9 * len(flagged)


def test_frame_rate_of_the_file(tmp_path):
    cfg = config()
    path = tmp_path / "d.csv"
    drops = run_simulate_drops(cfg, path, 5, seed=1, rate=500.0, drop_prob=0.02)
    steps = np.concatenate([np.diff(drops.t[rows]) for rows in tracks_of(drops)])
    assert steps.min() == pytest.approx(1 / 500.0, rel=1e-9)
    np.testing.assert_allclose(steps * 500.0, np.round(steps * 500.0), atol=1e-6)  # whole frames
    assert load_tracks(path, sides=4, circumradius=RADIUS).rate == pytest.approx(500.0, rel=1e-9)


def test_measurement_effects_of_the_tracking_section():
    plain = simulate_drops(config(), 5, seed=8, **CLEAN)
    seen = simulate_drops(config(overrides=("tracking.table_offset=0.004", "tracking.length_scale=1.02",
                                             "tracking.angle_offset=0.1")), 5, seed=8, **CLEAN)
    np.testing.assert_array_equal(seen.t, plain.t)
    np.testing.assert_allclose(seen.pose[:, 0], 1.02 * plain.pose[:, 0], rtol=0, atol=1e-15)
    np.testing.assert_allclose(seen.pose[:, 1], 1.02 * plain.pose[:, 1] + 0.004, rtol=0, atol=1e-15)  # y scaled, then offset
    np.testing.assert_allclose(seen.pose[:, 2], plain.pose[:, 2] + 0.1, rtol=0, atol=1e-15)
    # a clock running 5 % fast: file t = 1.05 true t, the poses those of the true times
    fast = simulate_drops(config(overrides=("tracking.time_scale=1.05",)), 5, seed=8, **CLEAN)
    np.testing.assert_allclose(fast.true_t, fast.t / 1.05, rtol=1e-15)
    rows = tracks_of(fast)[0]
    path, _ = reference_path(config(), fast.states[0], fast.true_t[rows], 1.5 / 1.05)
    np.testing.assert_allclose(fast.pose[rows, :2], path[:, :2], rtol=0, atol=1e-9)


def test_initial_states_from_the_config_and_ranges():
    cfg = config()
    drops = simulate_drops(cfg, 4, seed=1, initial="config", ranges={"omega0": (20.0, 30.0)}, **CLEAN)
    initial = cfg.initial
    np.testing.assert_array_equal(drops.states[:, :5], [[initial.x0, initial.y0, initial.phi0, initial.vx0, initial.vy0]] * 4)
    assert np.all((drops.states[:, 5] >= 20.0) & (drops.states[:, 5] <= 30.0)) and np.ptp(drops.states[:, 5]) > 0


# --- the file -------------------------------------------------------------------------------


def test_the_csv_text_and_the_provenance_are_the_drops(monkeypatch):
    cfg = config()
    drops = simulate_drops(cfg, 3, seed=2, glitch_prob=0.05)
    text = b"".join(simulate.csv_chunks(drops))
    lines = text.decode().splitlines()
    assert lines[0] == "traj,t,x,y,phi" and len(lines) == drops.traj.size + 1
    rows = np.loadtxt(lines[1:], delimiter=",")
    np.testing.assert_array_equal(rows[:, 0], drops.traj)
    np.testing.assert_allclose(rows[:, 1:], np.column_stack([drops.t, drops.pose]), rtol=1e-9, atol=1e-12)
    monkeypatch.setattr(simulate, "CHUNK_ROWS", 7)  # chunks change nothing in the text
    assert b"".join(simulate.csv_chunks(drops)) == text
    record = simulate.provenance(drops, cfg, "/somewhere/d.csv.gz")
    assert record["synthetic"] is True and record["data"] == "d.csv.gz" and parse_config(record["config"]) == cfg
    assert record["frames_written"] == drops.traj.size and len(record["glitch_frames"]) == int(drops.glitch.sum()) > 0
    assert [entry["side"] for entry in record["per_track"]] == drops.outcome.tolist()


@pytest.mark.parametrize("name", ["drops.csv", "drops.csv.gz"])
def test_file_is_read_back_with_its_tracks_and_a_synthetic_sidecar(tmp_path, name):
    cfg = config()
    path = tmp_path / name
    result = invoke("simulate-drops", _config_file(tmp_path), "-o", path, "--tracks", 7, "--seed", 9)
    assert result.exit_code == 0, result.output
    assert "SYNTHETIC" in result.output and f"{path}.json" in result.output
    trackset = load_tracks(path, sides=4, circumradius=RADIUS)
    assert [track.traj for track in trackset.tracks] == list(range(1, 8))
    sidecar = json.loads((tmp_path / f"{name}.json").read_text())
    assert sidecar["synthetic"] is True and "not measured" in sidecar["note"]
    assert sidecar["options"]["seed"] == 9 and sidecar["options"]["tracks"] == 7
    assert parse_config(sidecar["config"]) == cfg
    assert len(sidecar["per_track"]) == 7
    assert not list(tmp_path.glob("*.partial"))
    if name.endswith(".gz"):
        assert path.read_bytes()[:2] == b"\x1f\x8b"
        assert gzip.decompress(path.read_bytes()).decode().startswith("traj,t,x,y,phi\n")


def test_same_seed_same_bytes_other_seed_other_drops(tmp_path):
    cfg = config()
    a, b, c = (run_simulate_drops(cfg, tmp_path / f"{n}.csv.gz", 4, seed=s) for n, s in (("a", 5), ("b", 5), ("c", 6)))
    assert (tmp_path / "a.csv.gz").read_bytes() == (tmp_path / "b.csv.gz").read_bytes()
    assert (tmp_path / "a.csv.gz").read_bytes() != (tmp_path / "c.csv.gz").read_bytes()
    assert not np.array_equal(a.states, c.states)


def _config_file(folder, text=SQUARE):
    path = folder / "die.toml"
    path.write_text(text)
    return path


@pytest.mark.parametrize(
    "options, fragments",
    [
        (["--tracks", "0"], ["--tracks", "[1, 100000]"]),
        (["--tracks", "many"], ["--tracks", "whole number"]),
        (["--tracks", "3", "--seed", "-2"], ["--seed", "[0, inf)"]),
        (["--tracks", "3", "--rate", "0"], ["--rate", "(0, inf)"]),
        (["--tracks", "3", "--rate", "fast"], ["--rate", "> 0 Hz"]),
        (["--tracks", "3", "--noise", "1e-4,1e-4"], ["--noise", "SX,SY,SPHI"]),
        (["--tracks", "3", "--noise", "1e-4,-1e-4,0"], ["--noise", ">= 0"]),
        (["--tracks", "3", "--drop-prob", "0.7"], ["--drop-prob", "[0, 0.5]"]),
        (["--tracks", "3", "--glitch-prob", "-0.1"], ["--glitch-prob", "[0, 0.5]"]),
        (["--tracks", "3", "--duration", "0"], ["--duration", "(0, 30]"]),
        (["--tracks", "3", "--duration", "31"], ["--duration", "t_max"]),
        (["--tracks", "3", "--initial", "thrown"], ["--initial", "drops, config"]),
        (["--tracks", "3", "--range", "z0=0:1"], ["--range", "x0, y0, phi0"]),
        (["--tracks", "3", "--range", "omega0=5:1"], ["--range", "LOW <= HIGH"]),
        (["--tracks", "3", "--range", "y0=0.03:0.2"], ["--range y0", "y0 >= 0.0424264 m"]),
        (["--tracks", "3", "--set", "integrator.method=fixed_step"], ["integrator.method", "event"]),
        (["--tracks", "3", "--set", "contact.beta_normal=2"], ["contact.beta_normal", "[0, 1]"]),
    ],
)
def test_bad_options_are_one_line_errors_before_any_work(tmp_path, options, fragments):
    out = tmp_path / "out.csv"
    result = invoke("simulate-drops", _config_file(tmp_path), "-o", out, *options)
    assert result.exit_code == 2, result.output
    lines = result.output.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("error: ") and "Traceback" not in result.output, result.output
    for fragment in fragments:
        assert fragment in lines[0], lines[0]
    assert sorted(p.name for p in tmp_path.iterdir()) == ["die.toml"]


@pytest.mark.parametrize("name, fragment", [("out.txt", ".csv or .csv.gz"), ("missing/out.csv", "does not exist")])
def test_bad_output_is_a_one_line_error(tmp_path, name, fragment):
    result = invoke("simulate-drops", _config_file(tmp_path), "-o", tmp_path / name, "--tracks", 2)
    assert result.exit_code == 2 and len(result.output.strip().splitlines()) == 1
    assert "--output" in result.output and fragment in result.output


def test_cli_defaults_are_the_librarys():
    defaults = {p.name: p.default for p in simulate_drops_command.params}
    assert float(defaults["rate"]) == simulate.RATE and int(defaults["seed"]) == simulate.SEED
    assert float(defaults["drop_prob"]) == simulate.DROP_PROB and float(defaults["glitch_prob"]) == simulate.GLITCH_PROB
    assert float(defaults["duration"]) == simulate.DURATION
    assert simulate.parse_noise(defaults["noise"]) == simulate.NOISE


def test_calibrate_runs_on_a_simulated_file(tmp_path):
    """End to end: simulate-drops, then calibrate measures the config's beta_normal."""
    config_path = _config_file(tmp_path)
    data = tmp_path / "drops.csv.gz"
    assert invoke("simulate-drops", config_path, "-o", data, "--tracks", 12, "--seed", 1).exit_code == 0
    result = invoke("calibrate", data, "--config", config_path, "--json", tmp_path / "cal.json")
    assert result.exit_code == 0, result.output
    summary = json.loads((tmp_path / "cal.json").read_text())
    assert "12 tracks" in result.output
    assert summary["summary"]["first"]["beta_normal"]["median"] == pytest.approx(0.2, abs=0.01)
