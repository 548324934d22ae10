"""CEAMCL: species, competition, resources and evolution (paper section 3)."""

from ceamcl.filters.ceamcl.config import CEAMCLConfig
from ceamcl.filters.ceamcl.filter import CEAMCL

__all__ = ["CEAMCL", "CEAMCLConfig"]
