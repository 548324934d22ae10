"""ceamcl: coevolution-based adaptive Monte Carlo localisation for 2D laser robots."""

__version__ = "0.1.0"
