"""load_tracks: formats, dropped frames, glitches and the angle convention, on drops simulated by
the kernel and written in a tracker's conventions (tests/measured/drops.py), and on the shared
real data when it is there."""

import functools
import gzip
import math
from pathlib import Path

import numpy as np
import pytest

from dice_sweep.errors import DiceSweepError
from dice_sweep.measured.tracks import load_tracks
from tests.measured import drops

REAL_DATA = Path(__file__).resolve().parents[3] / "shared" / "data" / "mcube_square_drops" / "drops.csv.gz"
DROPS = 30
GLITCH_DROPS = range(0, DROPS, 3)
MISSING_DROPS = range(1, DROPS, 4)
DROPPED = {5: [4, 5, 6], 8: [5]}  # frames lost in the first fall; the file numbers on without them
OFFSET_TOLERANCE = math.radians(0.3)  # the median of ~15 resting angles, each with 0.3 deg noise


@pytest.fixture(scope="module")
def simulated():
    """Times and true states of 30 drops like the shared data's (paper model, to rest)."""
    return drops.simulate(drops.die_config(), drops.real_like_states(DROPS, seed=1))


@pytest.fixture(scope="module")
def file_tracks(simulated):
    glitches = drops.first_fall_glitches(GLITCH_DROPS, seed=2)
    return drops.to_file(*simulated, seed=2, glitches=glitches, missing_drops=MISSING_DROPS)


def load(path, **options):
    options.setdefault("angle", "auto")  # these tests are about finding the convention
    return load_tracks(path, sides=4, circumradius=drops.RADIUS, **options)


def test_convention_glitches_and_missing_frames_are_recovered(file_tracks, tmp_path):
    path = drops.write_csv(tmp_path / "drops.csv.gz", file_tracks, columns=("traj", "t", "x", "z", "theta", "note"))
    loaded = load(path)
    assert loaded.angle_sign == drops.FILE_SIGN and "clear" in loaded.angle_note
    assert drops.angle_error(loaded.angle_offset, drops.model_offset()) < OFFSET_TOLERANCE
    flagged = {(i, int(frame)) for i, track in enumerate(loaded.tracks) for frame in np.flatnonzero(track.glitch)}
    assert flagged == file_tracks.glitches  # every injected glitch, and nothing on the clean frames
    assert (loaded.glitch_count, loaded.glitch_tracks) == (len(GLITCH_DROPS), len(GLITCH_DROPS))
    assert (loaded.gap_frames, loaded.relabels, loaded.unpaired_jumps) == (0, 0, 0)
    for i, track in enumerate(loaded.tracks):
        missing = np.isnan(file_tracks.measured[i, :, 0])
        assert np.array_equal(np.isnan(track.x), missing) and np.array_equal(track.t, file_tracks.times)
        good = track.usable
        # the model's angle comes back up to the noise, modulo a quarter turn (corner labels)
        assert np.median(drops.angle_error(track.phi[good], file_tracks.truth[i, good, 2])) < 2 * drops.NOISE[1]


def test_dropped_frames_are_put_back_as_missing_frames(simulated, tmp_path):
    lossy = drops.to_file(*simulated, seed=3, dropped_frames=DROPPED)
    loaded = load(drops.write_csv(tmp_path / "drops.csv", lossy))
    assert (loaded.gap_frames, loaded.gap_tracks) == (sum(map(len, DROPPED.values())), len(DROPPED))
    for i, track in enumerate(loaded.tracks):
        assert np.allclose(track.t, lossy.times)  # every track back on the true time grid
        assert np.array_equal(np.isnan(track.x), np.isin(np.arange(lossy.times.size), DROPPED.get(i, [])))
    as_is = load(tmp_path / "drops.csv", gaps="as-is")
    assert as_is.gap_frames == 0 and as_is.tracks[5].t.size == lossy.times.size - 3


@pytest.mark.parametrize("compress", [False, True], ids=["csv", "csv.gz"])
def test_a_byte_order_mark_and_crlf_lines_read_as_the_plain_file(file_tracks, tmp_path, compress):
    """Spreadsheet programs write a UTF-8 byte order mark and CRLF line ends: the header's
    first name was read as '\ufefftraj' and the file refused ("column 'traj': missing")."""
    plain = load(drops.write_csv(tmp_path / "plain.csv", file_tracks))
    text = (tmp_path / "plain.csv").read_bytes()
    assert text.startswith(b"traj,") and b"\r\n" not in text
    spreadsheet = b"\xef\xbb\xbf" + text.replace(b"\n", b"\r\n")
    path = tmp_path / ("excel.csv.gz" if compress else "excel.csv")
    path.write_bytes(gzip.compress(spreadsheet) if compress else spreadsheet)
    loaded = load(path)
    assert len(loaded.tracks) == len(plain.tracks) > 0
    for mine, theirs in zip(loaded.tracks, plain.tracks):
        assert np.array_equal(mine.t, theirs.t) and np.array_equal(mine.x, theirs.x, equal_nan=True)
        assert np.array_equal(mine.phi, theirs.phi, equal_nan=True)


def test_frame_column_needs_a_rate_and_t_wins_over_it(file_tracks, tmp_path):
    by_frame = drops.write_csv(tmp_path / "frames.csv", file_tracks, columns=("traj", "frame", "x", "y", "phi"))
    with pytest.raises(DiceSweepError, match="frame.*--rate"):
        load(by_frame)
    loaded = load(by_frame, rate=drops.RATE)
    assert loaded.rate == drops.RATE and np.allclose(loaded.tracks[0].t, file_tracks.times)
    both = drops.write_csv(tmp_path / "both.csv", file_tracks, columns=("traj", "frame", "t", "x", "y", "phi"), frame_offset=1000)
    assert np.allclose(load(both, rate=1.0).tracks[0].t, file_tracks.times)  # frame and rate ignored


def test_marker_tracks_become_poses(file_tracks, tmp_path):
    markers = load(drops.write_csv(tmp_path / "markers.csv", file_tracks, columns=("traj", "t", "cx", "cy", "kx", "ky")), angle="as-is")
    poses = load(drops.write_csv(tmp_path / "poses.csv", file_tracks), angle="as-is")
    for marker, pose in zip(markers.tracks, poses.tracks):
        assert np.allclose(marker.x, pose.x, equal_nan=True) and np.allclose(marker.y, pose.y, equal_nan=True)
        turns = (marker.phi - pose.phi) / (2 * math.pi)  # atan2 unwrapped: whole turns apart at most
        turns = turns[np.isfinite(turns)]
        assert np.allclose(turns, np.round(turns[0]), atol=1e-5)
    assert load(tmp_path / "markers.csv").angle_sign == drops.FILE_SIGN


@pytest.mark.parametrize(
    "text, column",
    [
        ("traj,t,x,y\n1,0,0,0.1\n", "'phi' or 'theta'"),
        ("traj,t,x,y,phi\n", "file"),
        ("", "file"),
        ("traj,t,x,y,phi\n1,0,0,0.1,0\n1,0.004,abc,0.1,0\n", "column 'x': line 3"),
        ("traj,t,x,y,phi\n1,0,0,0.1,0\n1,0,0,0.1,0\n", "column 't': line 3"),
        ("traj,x,y,phi\n1,0,0.1,0\n", "column 't'"),
        ("traj,t,x,y,phi\n1.5,0,0,0.1,0\n", "column 'traj'"),
    ],
)
def test_bad_files_give_one_line_naming_the_file_and_column(tmp_path, text, column):
    path = tmp_path / "bad.csv"
    path.write_text(text)
    with pytest.raises(DiceSweepError) as error:
        load(path)
    message = str(error.value)
    assert "\n" not in message and message.startswith(str(path)) and column in message and "allowed" in message


def test_split_is_deterministic_disjoint_and_complete(file_tracks, tmp_path):
    loaded = load(drops.write_csv(tmp_path / "drops.csv", file_tracks))
    train, test = loaded.split(0.3, seed=0)
    ids = lambda part: [track.traj for track in part.tracks]  # noqa: E731
    assert len(ids(test)) == 9 and sorted(ids(train) + ids(test)) == ids(loaded)
    assert (ids(train), ids(test)) == tuple(map(ids, loaded.split(0.3, seed=0)))
    assert ids(loaded.split(0.3, seed=1)[1]) != ids(test)
    assert test.glitch_count == sum(int(track.glitch.sum()) for track in test.tracks)


@functools.cache
def real_tracks():
    """The shared real drops, loaded once per test run (test_calibrate uses them too)."""
    if not REAL_DATA.exists():
        pytest.skip(f"{REAL_DATA} is not here")
    return load_tracks(REAL_DATA, sides=4, circumradius=0.06 / math.sqrt(2), angle="auto")


def file_jumps(path, limit=math.radians(45.0)):
    """Trajectory ids with a frame-to-frame angle jump over ``limit`` in the file (the README's count)."""
    data = np.loadtxt(gzip.open(path, "rt"), delimiter=",", skiprows=1, usecols=(0, 5))
    steps = np.abs(np.diff(data[:, 1])) > limit
    return set(data[1:, 0][steps & (data[1:, 0] == data[:-1, 0])].astype(int))


def test_real_drops_convention_and_glitches():
    real = real_tracks()
    assert len(real.tracks) == 500 and real.rate == pytest.approx(250.0)
    # the README: dice rest about -2.0 deg off a multiple of 90 deg; the impacts say sign +1
    assert real.angle_sign == 1 and "clear" in real.angle_note
    assert drops.angle_error(real.angle_offset, math.pi / 4 + math.radians(1.9)) < math.radians(0.3)
    jumped = file_jumps(REAL_DATA)
    assert 30 <= len(jumped) <= 60  # "about 42 trajectories"
    # most of those jumps are now glitch frames, dropped frames put back, or corners relabelled
    fixed = [track for track in real.tracks if track.traj in jumped]
    no_jump = [t for t in fixed if np.nanmax(np.abs(np.diff(t.phi[t.usable]))) < math.radians(45.0)]
    assert len(no_jump) >= 0.6 * len(jumped)
    assert 20 <= real.glitch_tracks <= 80 and real.relabels >= 5 and real.gap_tracks >= 50
