"""Hypothesis profiles: `make test` (and CI) draws the same examples on every run; `make
test-explore` draws new ones.

Random draws found a real search defect once (hypothesis seed 25, docs/dev/profile.md change 4),
but a rare failing example must show up in an exploration run, not first in somebody's CI.
"""

import os

import pytest
from hypothesis import settings

# deadline=None: hypothesis fails an example slower than 200 ms by default, a wall-clock limit
# that a loaded machine breaks (tests/test_no_wall_clock.py)
settings.register_profile("deterministic", derandomize=True, database=None, deadline=None)
settings.register_profile("explore", derandomize=False, print_blob=True, deadline=None)
settings.load_profile(os.environ.get("HYPOTHESIS_PROFILE", "deterministic"))

# The CLI's "compiling the kernel" note would add a line to stderr in whichever test first
# compiles a kernel (CI starts with an empty numba cache); tests/test_cli.py checks the note.
os.environ.setdefault("DICE_SWEEP_COMPILE_NOTE", "0")

# The compiled kernel everywhere, as before dice_sweep.engine: which engine runs small cold work
# depends on the numba cache and a timing probe, and tests must not. tests/test_engine.py
# covers the plain engine and the choice, with this variable set per test.
os.environ.setdefault("DICE_SWEEP_ENGINE", "numba")


@pytest.fixture(scope="session")
def fig08_file(tmp_path_factory):
    """fig08 at 128 x 128, the physical ranges of the paper's figure: a sweep file that
    tests/chaos/test_control.py and tests/app/test_chaos.py share (about 6 s to roll)."""
    from dice_sweep.config import load_config
    from tests.helpers import CONFIGS, small_sweep

    cfg = load_config(CONFIGS / "fig08.toml", ["grid.x.num=128", "grid.y.num=128"])
    path = tmp_path_factory.mktemp("fig08") / "fig08.h5"
    small_sweep(cfg, path)
    return path
