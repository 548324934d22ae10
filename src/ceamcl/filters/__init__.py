"""Localisation filters behind one interface (:class:`LocalisationFilter`), built by name
through the registry (:mod:`ceamcl.filters.registry`)."""

from __future__ import annotations

from ceamcl.filters.base import (
    Algorithm,
    Hypothesis,
    LocalisationFilter,
    ParticleSnapshot,
    PoseEstimate,
    SpeciesDiagnostics,
    StepDiagnostics,
)
from ceamcl.filters.ceamcl import CEAMCL, CEAMCLConfig
from ceamcl.filters.gmcl import GMCL, GMCLConfig
from ceamcl.filters.kld_amcl import KLDAMCL, KLDAMCLConfig
from ceamcl.filters.mcl import MCL, MCLConfig
from ceamcl.filters.registry import ALGORITHMS, SENSOR_MODELS, make_filter, make_sensor

__all__ = [
    "ALGORITHMS",
    "CEAMCL",
    "GMCL",
    "KLDAMCL",
    "MCL",
    "SENSOR_MODELS",
    "Algorithm",
    "CEAMCLConfig",
    "GMCLConfig",
    "Hypothesis",
    "KLDAMCLConfig",
    "LocalisationFilter",
    "MCLConfig",
    "ParticleSnapshot",
    "PoseEstimate",
    "SpeciesDiagnostics",
    "StepDiagnostics",
    "make_filter",
    "make_sensor",
]
