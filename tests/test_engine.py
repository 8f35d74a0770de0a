"""The plain engine (the kernels' source run uncompiled) and the choice between it and numba.

The plain engine must give the compiled kernel's results bit for bit: it is checked against
the golden files (written by the compiled kernel) and against the compiled kernel itself on
random starts of every physics path (walls, friction, drag, loaded die, two contacts, flat
landing, the fixed-step method). The choice is checked without timing: the probe's estimate
is replaced by a fixed one.
"""

import os
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from dice_sweep import engine
from dice_sweep.config import load_config
from dice_sweep.errors import DiceSweepError
from dice_sweep.golden import CASES, golden_config
from dice_sweep.physics.kernel import REC_WIDTH, roll_batch, roll_one, sample_records
from dice_sweep.roll import initial_state
from dice_sweep.physics import COUNT_COLUMNS, pack_params
from dice_sweep.storage import read_sweep
from dice_sweep.mapper import Mapper, initial_states
from dice_sweep.sweep import axis_values, run_sweep

ROOT = Path(__file__).resolve().parent.parent
CONFIGS = ROOT / "configs"
GOLDEN_STRIDE = 7  # every 7th cell of each 32 x 32 golden map: 147 rolls a case


def _bits(values):
    values = np.asarray(values)
    unsigned = {np.dtype(np.float64): np.uint64, np.dtype(np.float32): np.uint32}
    return values.view(unsigned[values.dtype]) if values.dtype in unsigned else values


@pytest.mark.parametrize("case", CASES, ids=lambda case: case.name)
def test_plain_engine_reproduces_the_golden_maps(case):
    cfg = golden_config(case, CONFIGS)
    cells = np.arange(0, cfg.grid.x.num * cfg.grid.y.num, GOLDEN_STRIDE)
    states = initial_states(cfg, axis_values(cfg.grid.x), axis_values(cfg.grid.y))[cells]
    outcome, status, counts, t_decided = Mapper.from_config(cfg).roll(states, engine.ENGINE_PLAIN)
    golden = read_sweep(ROOT / "tests" / "golden" / f"{case.name}.h5")
    np.testing.assert_array_equal(outcome, golden.outcome.ravel()[cells])
    np.testing.assert_array_equal(status, golden.status.ravel()[cells])
    np.testing.assert_array_equal(counts[:, COUNT_COLUMNS.index("impacts")], golden.impacts.ravel()[cells])
    stored = golden.t_decided.ravel()[cells]  # float32 in the file
    np.testing.assert_array_equal(_bits(t_decided.astype(stored.dtype)), _bits(stored))


# Every physics path: walls, friction and the pivot ODE, drag, a loaded die, the flat-landing
# effect (two contacts), the speed-dependent restitution, the fixed-step method.
PATHS = {
    "paper": ("table1.toml", ()),
    "walls_rigid": ("fig09.toml", ()),
    "friction": ("fig08_rigid.toml", ("contact.friction=0.3",)),
    "drag": ("fig08.toml", ("effects.air_drag=0.5", "contact.model=rigid", "contact.friction=0.3")),
    "loaded": ("loaded_die.toml", ()),
    "flat_landing": ("fig08_rigid.toml", ("effects.contact_time=3e-4", "contact.friction=0.5")),
    "fixed_step": ("table1.toml", ("integrator.method=fixed_step",)),
    "sliding_rule": ("fig08_rigid.toml", ("contact.friction=0.2", "contact.friction_rule=sliding")),
    "friction_02": ("fig08_rigid.toml", ("contact.friction=0.2",)),
    "exact_rule": ("fig09.toml", ("contact.model=rigid", "contact.friction=0.3", "contact.friction_rule=exact",
                                  "contact.restitution=energetic")),
    "rounded_inertia": ("fig08_rigid.toml", ("contact.friction=0.4", "effects.corner_radius=0.002", "effects.inertia=0.8")),
}


@pytest.mark.parametrize("path", sorted(PATHS))
def test_plain_and_compiled_rolls_agree_bit_for_bit(path):
    name, overrides = PATHS[path]
    cfg = load_config(CONFIGS / name, overrides)
    fpar, ipar = pack_params(cfg)
    rng = np.random.default_rng(7)
    base = initial_state(cfg)
    for trial in range(12):
        state = base.copy()
        state[1] = rng.uniform(0.03, 0.3)  # y0, m
        state[2] = rng.uniform(-np.pi, np.pi) if trial % 3 else 0.0  # phi0: some flat-cornered
        state[5] = rng.uniform(-60.0, 60.0)  # omega0, rad/s
        results = {}
        for which in engine.ENGINES:
            rec = np.zeros((4000, REC_WIDTH))
            counts = np.zeros(len(COUNT_COLUMNS), np.int32)
            head = engine.run(roll_one, which, fpar, ipar, state, rec, counts)
            times = np.linspace(0.0, head[3], 50)
            path_out = np.zeros((50, 6))
            engine.run(sample_records, which, fpar, ipar, rec, head[4], times, path_out)
            results[which] = (head, rec, counts, path_out)
        (head_c, rec_c, counts_c, path_c), (head_p, rec_p, counts_p, path_p) = (results[e] for e in engine.ENGINES)
        assert [_bits(float(v)) for v in head_c] == [_bits(float(v)) for v in head_p], (path, trial)
        np.testing.assert_array_equal(_bits(rec_c), _bits(rec_p))
        np.testing.assert_array_equal(counts_c, counts_p)
        np.testing.assert_array_equal(_bits(path_c), _bits(path_p))


def test_the_plain_twin_calls_no_compiled_kernel():
    """Every jitted function of dice_sweep.physics has a plain twin on its own code, whose
    globals hold no numba dispatcher (a call would compile)."""
    import importlib
    import pkgutil

    from numba.core.dispatcher import Dispatcher

    import dice_sweep.physics

    twin = engine.plain(roll_batch)
    assert twin is not roll_batch and twin.__code__ is roll_batch.py_func.__code__
    kernels = {value for info in pkgutil.iter_modules(dice_sweep.physics.__path__)
               for value in vars(importlib.import_module(f"dice_sweep.physics.{info.name}")).values() if isinstance(value, Dispatcher)}
    assert len(kernels) > 20
    for kernel in kernels:
        function = engine.plain(kernel)
        assert function.__code__ is kernel.py_func.__code__, kernel
        assert not any(isinstance(value, Dispatcher) for value in function.__globals__.values()), kernel


def test_a_domain_error_of_the_plain_engine_falls_back_to_the_compiled_kernel(monkeypatch):
    cfg = load_config(CONFIGS / "table1.toml")
    fpar, ipar = pack_params(cfg)

    def failing(*args):
        raise ValueError("math domain error")

    monkeypatch.setattr(engine, "plain", lambda kernel: failing)
    args = (fpar, ipar, initial_state(cfg), np.zeros((100, REC_WIDTH)), np.zeros(len(COUNT_COLUMNS), np.int32))
    assert engine.run(roll_one, engine.ENGINE_PLAIN, *args)[0] == roll_one(*args)[0]


def _probe_says(monkeypatch, seconds_per_roll):
    monkeypatch.setattr(engine, "probe_seconds_per_roll", lambda roll, states: seconds_per_roll)
    monkeypatch.setattr(engine, "compiled_ready", lambda kernel, args: False)


def test_small_cold_work_runs_plain_and_large_cold_work_compiles(monkeypatch):
    monkeypatch.delenv(engine.ENGINE_VARIABLE, raising=False)
    states = np.zeros((4, 6))
    _probe_says(monkeypatch, 1e-3)
    below = int(engine.COMPILE_SECONDS / 1e-3) - 1
    assert engine.sweep_engine(roll_batch, (), None, states, below, 1) == engine.ENGINE_PLAIN
    assert engine.sweep_engine(roll_batch, (), None, states, below + 2, 1) == engine.ENGINE_NUMBA
    assert engine.sweep_engine(roll_batch, (), None, states, 2 * below, 2) == engine.ENGINE_PLAIN  # two workers


def test_compiled_or_cached_kernels_always_run_compiled(monkeypatch):
    monkeypatch.delenv(engine.ENGINE_VARIABLE, raising=False)
    monkeypatch.setattr(engine, "probe_seconds_per_roll", lambda roll, states: 0.0)
    cfg = load_config(CONFIGS / "demo.toml", ("grid.x.num=2", "grid.y.num=2"))
    mapper, start = Mapper.from_config(cfg), initial_state(cfg)[np.newaxis, :]
    mapper.roll(start, engine.ENGINE_NUMBA)  # compiled in this process
    assert mapper.with_engine_for(start, 10**9, 1).engine == engine.ENGINE_NUMBA
    args = (pack_params(cfg)[0], pack_params(cfg)[1], initial_state(cfg), np.zeros((1, REC_WIDTH)),
            np.zeros(len(COUNT_COLUMNS), np.int32))
    roll_one(*args)
    assert engine.call_engine(roll_one, args) == engine.ENGINE_NUMBA


def test_a_probe_that_fails_means_compiling(monkeypatch):
    monkeypatch.delenv(engine.ENGINE_VARIABLE, raising=False)
    monkeypatch.setattr(engine, "compiled_ready", lambda kernel, args: False)

    def failing(states):
        raise ZeroDivisionError

    assert engine.sweep_engine(roll_batch, (), failing, np.zeros((3, 6)), 10, 1) == engine.ENGINE_NUMBA


def test_the_engine_variable_forces_an_engine_or_is_a_one_line_error(monkeypatch):
    _probe_says(monkeypatch, 1.0)  # plain would be slow: only the variable can choose it
    monkeypatch.setenv(engine.ENGINE_VARIABLE, "plain")
    assert engine.sweep_engine(roll_batch, (), None, np.zeros((1, 6)), 10**6, 1) == engine.ENGINE_PLAIN
    monkeypatch.setenv(engine.ENGINE_VARIABLE, "jit")
    with pytest.raises(DiceSweepError, match=r"DICE_SWEEP_ENGINE='jit': allowed values are numba, plain"):
        engine.forced_engine()


def test_a_plain_sweep_equals_a_compiled_one(tmp_path, monkeypatch):
    cfg = load_config(CONFIGS / "fig08_rigid.toml", ("grid.x.num=12", "grid.y.num=10", "contact.friction=0.5"))
    maps = {}
    for which in engine.ENGINES:
        monkeypatch.setenv(engine.ENGINE_VARIABLE, which)
        summary = run_sweep(cfg, tmp_path / f"{which}.h5", workers=2, progress=False, tile_shape=(4, 4))
        assert summary.engine == which and summary.complete
        maps[which] = read_sweep(tmp_path / f"{which}.h5")
    for name in ("outcome", "status", "impacts"):
        np.testing.assert_array_equal(getattr(maps["numba"], name), getattr(maps["plain"], name))
    np.testing.assert_array_equal(_bits(maps["numba"].t_decided), _bits(maps["plain"].t_decided))
    assert "uncompiled" in summary.describe()


def _cli(args, cache_dir, env_extra=None, cwd=ROOT):
    env = dict(os.environ, NUMBA_CACHE_DIR=str(cache_dir), DICE_SWEEP_COMPILE_NOTE="1")
    env.pop(engine.ENGINE_VARIABLE, None)
    env.update(env_extra or {})
    return subprocess.run([sys.executable, "-m", "dice_sweep", *args], capture_output=True, text=True, env=env, cwd=cwd)


def _cached_kernels(cache_dir):
    return sorted(p.name for p in Path(cache_dir).rglob("*.nbi"))


def test_a_first_roll_and_a_first_small_sweep_compile_nothing(tmp_path):
    """Issue 16: with an empty numba cache, a roll and a small sweep start at once (no
    compile note, nothing written to the cache) and say how they ran."""
    cache = tmp_path / "numba-cache"
    roll = _cli(["roll", str(CONFIGS / "table1.toml")], cache)
    assert roll.returncode == 0, roll.stderr
    assert roll.stdout.startswith("side ") and "compiling" not in roll.stderr
    out = tmp_path / "small.h5"
    sweep = _cli(["sweep", str(CONFIGS / "demo.toml"), "-o", str(out), "--set", "grid.x.num=16", "--set", "grid.y.num=16"], cache)
    assert sweep.returncode == 0, sweep.stderr
    assert "uncompiled" in sweep.stdout and "compiling" not in sweep.stderr
    assert _cached_kernels(cache) == []
    compiled = tmp_path / "compiled.h5"
    run_sweep(load_config(CONFIGS / "demo.toml", ("grid.x.num=16", "grid.y.num=16")), compiled, workers=1, progress=False)
    np.testing.assert_array_equal(read_sweep(out).outcome, read_sweep(compiled).outcome)


# --- keeping the compiled kernel between CI jobs (docs/cold_start.md) --------------------------

def _checkout(root: Path) -> Path:
    """A fresh copy of the package, as a CI job's new checkout: another path, new mtimes."""
    shutil.copytree(ROOT / "dice_sweep", root / "dice_sweep", ignore=shutil.ignore_patterns("__pycache__"))
    return root


def _compile_in(checkout: Path, cache_dir: Path) -> str:
    """Compile (or load) one small kernel in a fresh process of ``checkout``: 'compiled' or
    'loaded', from numba's own cache statistics."""
    code = ("from dice_sweep.physics.outcome import side_below; import numpy as np; "
            "from dice_sweep.physics import pack_params; from dice_sweep.config import load_config; "
            f"fpar, _ = pack_params(load_config({str(CONFIGS / 'table1.toml')!r})); side_below(0.3, fpar, 4); "
            "print('loaded' if side_below.stats.cache_hits else 'compiled')")
    env = dict(os.environ, NUMBA_CACHE_DIR=str(cache_dir), PYTHONPATH=str(checkout))
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, env=env, cwd=checkout)
    assert done.returncode == 0, done.stderr
    return done.stdout.strip()


def test_a_kept_numba_cache_serves_a_new_checkout_and_a_source_change_is_not_served(tmp_path):
    cache = tmp_path / "kept-cache"  # what the CI job saves and restores
    first = _checkout(tmp_path / "job1")
    assert _compile_in(first, cache) == "compiled"
    second = _checkout(tmp_path / "job2")
    assert _compile_in(second, cache) == "loaded"
    assert all(p.parent.name == "dice_sweep_physics" for p in Path(cache).rglob("*.nbi"))
    changed = _checkout(tmp_path / "job3")
    flight = changed / "dice_sweep" / "physics" / "flight.py"
    flight.write_text(flight.read_text() + "\n# another source\n")  # not the file of side_below
    assert _compile_in(changed, cache) == "compiled"
