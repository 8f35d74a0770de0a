"""numba kernels of the die: flight, contact, impact laws, pivot phase, outcome rule."""

from dice_sweep.physics.params import pack_params
from dice_sweep.physics.kernel import (
    COUNT_COLUMNS,
    STATE_COLUMNS,
    STATUS_NAMES,
    roll_batch,
)

__all__ = ["pack_params", "roll_batch", "STATE_COLUMNS", "STATUS_NAMES", "COUNT_COLUMNS"]
