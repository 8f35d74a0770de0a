"""Tests of dice_sweep.startup: the CLI's skipping of numba's BLAS probe and cffi support.

Each runs in a fresh interpreter: the probe happens once per process.
"""

import subprocess
import sys
from pathlib import Path

import numpy as np

from dice_sweep.config import load_config
from dice_sweep.roll import roll_config

ROOT = Path(__file__).resolve().parents[1]
CHILD = """
import sys, json
from dice_sweep.startup import skip_numba_blas_probe
took = skip_numba_blas_probe()
from dice_sweep.config import load_config
from dice_sweep.roll import roll_config
report = roll_config(load_config("configs/table1.toml", ["initial.omega0=20"]))
linalg_during_roll = "scipy" in sys.modules or "cffi" in sys.modules
from scipy.optimize import least_squares  # scipy.linalg still imports afterwards
fit = least_squares(lambda p: p - 3.0, [0.0])
print(json.dumps([took, linalg_during_roll, report.outcome, report.impacts, report.t_decided, float(fit.x[0])]))
"""


def test_kernel_runs_without_scipy_linalg_and_gives_the_same_roll():
    import json

    child = subprocess.run([sys.executable, "-c", CHILD], capture_output=True, text=True, check=True, cwd=ROOT)
    took, linalg_during_roll, outcome, impacts, t_decided, fitted = json.loads(child.stdout)
    assert took and not linalg_during_roll
    here = roll_config(load_config(ROOT / "configs" / "table1.toml", ["initial.omega0=20"]))
    assert (outcome, impacts) == (here.outcome, here.impacts)
    assert t_decided == here.t_decided  # bitwise: the probe changes nothing in the kernel
    assert np.isclose(fitted, 3.0)


def test_probe_is_not_skipped_once_numba_has_loaded_its_registry():
    code = "import numba.np.arraymath\nfrom dice_sweep.startup import skip_numba_blas_probe\nprint(skip_numba_blas_probe())"
    child = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert child.stdout.strip() == "False"


def test_the_cache_key_covers_the_registrys_kernel_slots(monkeypatch):
    """A new registry slot renumbers the slots after it without touching a physics file; the
    kernels' cache must not be reused across that (it would index the old layout)."""
    from dice_sweep import effects, startup

    before = startup.source_digest()
    specs = effects.config_key_specs()
    extra = effects.ConfigKey("effects", "angular_drag", 0.0, "1", slot="FP_ANGULAR_DRAG")
    monkeypatch.setattr(effects, "config_key_specs", lambda: {**specs, "effects": {"angular_drag": extra, **specs["effects"]}})
    assert startup.source_digest() != before


SWEEP_CHILD = """
import sys
from dice_sweep.cli import main
try:
    main(["sweep", "configs/fig08.toml", "-o", sys.argv[1], "--set", "grid.x.num=2", "--set", "grid.y.num=2",
          "--workers", "1", "--quiet"])
except SystemExit as ended:
    assert not ended.code, ended.code
print(" ".join(sorted(name for name in ("scipy", "tqdm", "dice_sweep.refine", "dice_sweep.chaos") if name in sys.modules)))
"""


def test_a_quiet_sweep_imports_neither_scipy_nor_the_progress_bar_nor_refinement(tmp_path):
    """What the sweep command does not use stays out of its start-up (docs/dev/speed_issue33.md):
    tqdm without a terminal, scipy (numba's version check), --refine's and the chaos measures'
    modules."""
    out = tmp_path / "s.h5"
    child = subprocess.run([sys.executable, "-c", SWEEP_CHILD, str(out)], capture_output=True, text=True, check=True, cwd=ROOT)
    assert child.stdout.strip() == ""
    assert out.exists()
