"""Pictures; the only package that imports matplotlib.

It uses the object API only (``Figure`` drawn on an Agg canvas, never pyplot), so it keeps no
global state and needs no display. It draws arrays and dataclasses it is given; reading sweep
files, parsing configs and rolling dice are the application layer's (dice_sweep.app).

Colours follow Smith 2014: for n = 4 sides 0-3 are red, green, cyan and violet (Fig. 8); for
any other n a rainbow runs from red (side 0) to violet (side n - 1) (Figs 9, 11); undecided
rolls (outcome -1) are black; cells of an incomplete sweep not computed yet are grey.

By domain: :mod:`~dice_sweep.plotting.common` (colours, sizes, formats, labels),
:mod:`~dice_sweep.plotting.maps` (final-state diagrams), :mod:`~dice_sweep.plotting.roll`
(one roll), :mod:`~dice_sweep.plotting.chaos` (measures and control maps) and
:mod:`~dice_sweep.plotting.measured` (the measured-data loop) and
:mod:`~dice_sweep.plotting.forecast` (side forecasts of tracked drops).
"""

from dice_sweep.plotting.common import (  # noqa: F401
    ANIMATION_DPI,
    ANIMATION_FIGSIZE,
    BOX_COLOR,
    DPI_RANGE,
    FOUR_SIDE_COLORS,
    MAX_ANIMATION_FRAMES,
    MAX_SIDE_LABELS,
    NOT_COMPUTED_COLOR,
    OUTCOME_FIGSIZE,
    PANEL_FIGSIZE,
    PATH_POINTS_PER_FRAME,
    ROLL_FIGSIZE,
    UNDECIDED_COLOR,
    VIOLET_HUE,
    axis_label,
    axis_labels,
    cell_extent,
    check_dpi,
    draw_scalar_map,
    image_formats,
    outcome_colors,
    panel_figure,
    save_figure,
)
from dice_sweep.plotting.maps import (  # noqa: F401
    check_box,
    draw_box,
    draw_outcome_map,
    draw_probability_map,
    outcome_figure,
    outcome_title,
    parse_box,
    plot_comparison,
    plot_refinement,
    probability_figure,
    shaded_sides,
    sweep_figure,
)
from dice_sweep.plotting.roll import (  # noqa: F401
    animate_roll,
    plot_roll,
)
from dice_sweep.plotting.chaos import (  # noqa: F401
    curve_colors,
    box_entropy_panel,
    plot_control_map,
    plot_scalar_maps,
    plot_uncertainty_curves,
)
from dice_sweep.plotting.measured import (  # noqa: F401
    CALIBRATION_FIGSIZE,
    CALIBRATION_RANGE,
    plot_calibration,
    plot_residual_curves,
)
from dice_sweep.plotting.forecast import (  # noqa: F401
    FORECAST_FIGSIZE,
    plot_release_map,
    plot_reliability,
    plot_skill_by_bounce,
)
