"""The chaos of a final-state map (issue 6, docs/chaos.md), in three parts:

- :mod:`dice_sweep.chaos.measures`: outcome fractions, basin entropy Sb and boundary basin
  entropy Sbb, the uncertainty exponent, all measures of a map at once;
- :mod:`dice_sweep.chaos.control`: control maps, the probability of each side for a thrower
  of given precision (a blur of the map, or Monte Carlo rolls);
- :mod:`dice_sweep.chaos.known_maps`: maps with known answers, to check the measures.

They compute on arrays and dataclasses; reading files and drawing is the application
layer's (dice_sweep.app.chaos).
"""

from dice_sweep.chaos.control import (  # noqa: F401
    BLUR_MIN_PIXELS,
    CONTROLLED_PROBABILITY,
    DEFAULT_MC_POINTS,
    DEFAULT_SAMPLES,
    MAX_MC_ROLLS,
    MAX_SIGMA,
    METHODS,
    ControlAgreement,
    ControlMap,
    blur_probabilities,
    choose_method,
    compare_control,
    control_map,
    monte_carlo_indices,
    monte_carlo_probabilities,
    parse_sigma,
    scattered_starts,
)
from dice_sweep.chaos.known_maps import (  # noqa: F401
    cantor_map,
    checkerboard_map,
    random_map_entropy,
    straight_boundary_map,
    weierstrass_map,
)
from dice_sweep.chaos.measures import (  # noqa: F401
    DEFAULT_BOX_SIZE,
    LOG2,
    PREDICTABLE_PROBABILITY,
    SMOOTH_BOUNDARY_SBB,
    UNDECIDED,
    BasinEntropy,
    ChaosMeasures,
    PowerLawFit,
    ProbabilityMeasures,
    UncertaintyCurve,
    basin_entropy,
    default_perturbations,
    fit_power_law,
    measure_map,
    measure_probability,
    outcome_fractions,
    shannon_entropy,
    uncertain_pixels,
    uncertainty_curve,
    wilson_bounds,
)
