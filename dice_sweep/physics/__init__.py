"""numba kernels of the die: flight, contact, impact laws, pivot phase, outcome rule.

Their data layout (state columns, codes, counters, records) is in
:mod:`dice_sweep.physics.layout`, which needs no numba.
"""

from dice_sweep.startup import install_locator

install_locator()  # before any kernel is defined: numba picks a locator per function then

from dice_sweep.physics.layout import COUNT_COLUMNS, STATE_COLUMNS, STATUS_NAMES  # noqa: E402
from dice_sweep.physics.params import pack_params  # noqa: E402
from dice_sweep.physics.kernel import roll_batch  # noqa: E402

__all__ = ["pack_params", "roll_batch", "STATE_COLUMNS", "STATUS_NAMES", "COUNT_COLUMNS"]
