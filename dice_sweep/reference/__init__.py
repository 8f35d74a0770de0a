"""Independent reference simulators used only to check the kernel (issue 4).

They need test-only dependencies (``pip install -e '.[test]'``), imported lazily inside the
functions, so importing this package never requires them.
"""

from dice_sweep.reference.pymunk_die import (
    MapComparison,
    PymunkBatch,
    PymunkDie,
    PymunkSettings,
    compare_with_kernel,
    comparison_config,
    pymunk_batch,
    pymunk_outcomes,
    pymunk_roll,
    settled_mask,
)

__all__ = [
    "MapComparison",
    "PymunkBatch",
    "PymunkDie",
    "PymunkSettings",
    "compare_with_kernel",
    "comparison_config",
    "pymunk_batch",
    "pymunk_outcomes",
    "pymunk_roll",
    "settled_mask",
]
