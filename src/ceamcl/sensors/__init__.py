"""Laser sensor models (likelihood field, beam model), scans and ray casting."""

from ceamcl.sensors.base import SensorModel, fitness
from ceamcl.sensors.beam_model import BeamModel, BeamModelConfig
from ceamcl.sensors.likelihood_field import LikelihoodFieldConfig, LikelihoodFieldModel
from ceamcl.sensors.scan import LaserGeometry, LaserScan, PreparedScan, prepare_scan

__all__ = [
    "BeamModel",
    "BeamModelConfig",
    "LaserGeometry",
    "LaserScan",
    "LikelihoodFieldConfig",
    "LikelihoodFieldModel",
    "PreparedScan",
    "SensorModel",
    "fitness",
    "prepare_scan",
]
