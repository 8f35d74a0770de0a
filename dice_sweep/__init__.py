"""dice_sweep: final-state diagrams of a two-dimensional die roll (Smith 2014)."""

__version__ = "0.1.0"
