"""Localisation filters behind one interface (:class:`LocalisationFilter`), built by name
through the registry (:mod:`ceamcl.filters.registry`)."""

from __future__ import annotations

from ceamcl.filters.base import (
    Algorithm,
    Hypothesis,
    LocalisationFilter,
    ParticleSnapshot,
    PoseEstimate,
    StepDiagnostics,
    StepRecord,
)
from ceamcl.filters.ceamcl import CEAMCL, CEAMCLConfig
from ceamcl.filters.ceamcl.records import CEAMCLRecord, SpeciesRecord, species_of
from ceamcl.filters.gmcl import GMCL, GMCLConfig
from ceamcl.filters.kld_amcl import KLDAMCL, KLDAMCLConfig, KLDAMCLRecord
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
    "CEAMCLRecord",
    "GMCLConfig",
    "Hypothesis",
    "KLDAMCLConfig",
    "KLDAMCLRecord",
    "LocalisationFilter",
    "MCLConfig",
    "ParticleSnapshot",
    "PoseEstimate",
    "SpeciesRecord",
    "StepDiagnostics",
    "StepRecord",
    "make_filter",
    "make_sensor",
    "species_of",
]
