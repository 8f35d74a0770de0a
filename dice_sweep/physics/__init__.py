"""numba kernels of the die: flight, contact, impact laws, pivot phase, outcome rule."""

from dice_sweep.physics._cache_guard import install_locator

install_locator()  # before any kernel is defined: numba picks a locator per function then

from dice_sweep.physics.params import pack_params  # noqa: E402
from dice_sweep.physics.kernel import (  # noqa: E402
    COUNT_COLUMNS,
    STATE_COLUMNS,
    STATUS_NAMES,
    roll_batch,
)

__all__ = ["pack_params", "roll_batch", "STATE_COLUMNS", "STATUS_NAMES", "COUNT_COLUMNS"]
