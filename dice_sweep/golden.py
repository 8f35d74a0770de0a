"""Golden regression cases: small sweeps of the ready-to-run configs, stored as HDF5.

Every change to the physics kernels is checked against these files
(``tests/test_golden.py``). A change that is meant to move results regenerates them with
``python scripts/make_golden.py`` and says why in its commit.
"""

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from .config import load_config
from .storage import read_sweep
from .sweep import run_sweep

GOLDEN_NUM = 32  # pixels per axis: about 1 s per case, enough to cross many boundaries
MAPS = ("outcome", "status", "impacts")


@dataclass(frozen=True)
class GoldenCase:
    """One golden sweep: a config of configs/ with overrides (``section.key=value``)."""

    name: str
    config: str
    overrides: tuple[str, ...] = ()


CASES = (
    GoldenCase("fig08", "fig08.toml"),
    GoldenCase("fig08_rigid", "fig08_rigid.toml"),
    GoldenCase("fig08_rigid_friction", "fig08_rigid.toml", ("contact.friction=0.5",)),
    # issue 33's rigid law (the one the measured drops choose), pinned before its kernel was made faster
    GoldenCase("fig08_rigid_mu05_bt0", "fig08.toml", ("contact.model=rigid", "contact.friction=0.5", "contact.beta_tangential=0")),
    GoldenCase("fig08_air_drag", "fig08.toml", ("effects.air_drag=0.5", "contact.model=rigid", "contact.friction=0.3")),
    GoldenCase("fig09", "fig09.toml"),
    GoldenCase("fig11", "fig11.toml"),
    GoldenCase("fig13", "fig13.toml"),
    GoldenCase("loaded_die", "loaded_die.toml"),
)


def golden_config(case: GoldenCase, config_dir):
    """The case's config at GOLDEN_NUM x GOLDEN_NUM pixels."""
    grid = (f"grid.x.num={GOLDEN_NUM}", f"grid.y.num={GOLDEN_NUM}")
    return load_config(Path(config_dir) / case.config, case.overrides + grid)


def sweep_case(case: GoldenCase, config_dir, out_path) -> None:
    """Sweep one case in-process into ``out_path`` (HDF5)."""
    run_sweep(golden_config(case, config_dir), out_path, workers=1, progress=False)


def compare_with_golden(new_path, golden_path) -> dict[str, int]:
    """Pixels whose maps differ between a new sweep and the golden one, per map.

    ``t_decided`` counts as differing beyond a relative 1e-9 (NaN equals NaN).
    """
    new = read_sweep(new_path)
    old = read_sweep(golden_path)
    diff = {name: int(np.count_nonzero(getattr(new, name) != getattr(old, name))) for name in MAPS}
    a, b = new.t_decided, old.t_decided
    same = np.isclose(a, b, rtol=1e-9, atol=0.0) | (np.isnan(a) & np.isnan(b))
    diff["t_decided"] = int(np.count_nonzero(~same))
    diff["pixels"] = int(a.size)
    return diff
