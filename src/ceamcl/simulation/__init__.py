"""Simulation of a robot with odometry and a 2D laser in a known map."""

from ceamcl.simulation.scenarios import Scenario, get_scenario, office_scenario, paper_scenario
from ceamcl.simulation.simulator import (
    SimulatedLog,
    SimulationConfig,
    Simulator,
    default_laser,
    drive_waypoints,
)

__all__ = [
    "Scenario",
    "SimulatedLog",
    "SimulationConfig",
    "Simulator",
    "default_laser",
    "drive_waypoints",
    "get_scenario",
    "office_scenario",
    "paper_scenario",
]
