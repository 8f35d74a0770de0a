"""Golden regression: small sweeps of the ready-to-run configs against tests/golden/*.h5.

On this machine every map is bitwise equal (0 differing pixels). A CPU that contracts
floating-point operations differently (FMA) may flip pixels on the chaotic boundaries, so
up to MAX_DIFFERING of the 1024 pixels may differ; a real regression moves far more.
Regenerate with ``python scripts/make_golden.py`` only for a change meant to move results.
"""

from pathlib import Path

import pytest

from dice_sweep.golden import CASES, compare_with_golden, sweep_case

ROOT = Path(__file__).resolve().parent.parent
MAX_DIFFERING = 5  # of 1024 pixels (0.5 %)


@pytest.mark.parametrize("case", CASES, ids=[case.name for case in CASES])
def test_sweep_matches_golden_file(case, tmp_path):
    new = tmp_path / f"{case.name}.h5"
    sweep_case(case, ROOT / "configs", new)
    diff = compare_with_golden(new, ROOT / "tests" / "golden" / f"{case.name}.h5")
    assert diff["pixels"] == 1024
    for name in ("outcome", "status", "impacts", "t_decided"):
        assert diff[name] <= MAX_DIFFERING, (name, diff)


def test_golden_comparison_sees_a_changed_parameter(tmp_path):
    """The check can fail: beta_normal moved from 0.2 to 0.21 changes many pixels of fig08."""
    case = CASES[0]
    moved = type(case)(case.name, case.config, ("contact.beta_normal=0.21",))
    new = tmp_path / "moved.h5"
    sweep_case(moved, ROOT / "configs", new)
    diff = compare_with_golden(new, ROOT / "tests" / "golden" / f"{case.name}.h5")
    assert diff["outcome"] > 10 * MAX_DIFFERING
