"""The interface every localisation filter implements, and the records it produces.

A filter is built with a map, a motion model, a sensor model, a frozen config and a
``numpy.random.Generator``; after that it is driven by three calls:

* ``initialise_global(scan)``: no idea where the robot is; the first scan is the only clue;
* ``initialise_pose(pose, covariance)``: pose tracking from a known start;
* ``step(increment, scan)``: odometry since the last step, then the new scan.

It can be asked, at any time, for ``estimate()`` (the pose it believes), ``hypotheses()`` (every
distinct pose it still entertains, best first) and ``particles()`` (for plotting). Each call
to ``initialise_global`` and ``step`` returns a :class:`StepDiagnostics` record.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Protocol

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ceamcl.motion.odometry import OdometryIncrement
from ceamcl.sensors.scan import LaserScan


@dataclass(frozen=True, eq=False)
class PoseEstimate:
    """The filter's pose ``(x, y, theta)`` and its ``3 x 3`` covariance."""

    pose: NDArray[np.float64]
    covariance: NDArray[np.float64]


@dataclass(frozen=True, eq=False)
class Hypothesis:
    """One distinct pose hypothesis: a species (CEAMCL) or a particle cluster (MCL, GMCL).

    ``weight``: its share of the probability mass (sums to 1 over hypotheses);
    ``fitness``: its mean fitness in (0, 1] for the last scan (see ``sensors.base.fitness``).
    """

    pose: NDArray[np.float64]
    covariance: NDArray[np.float64]
    n_particles: int
    weight: float
    fitness: float
    label: int


@dataclass(frozen=True, eq=False)
class ParticleSnapshot:
    """Particles for plotting: poses ``(N, 3)``, normalised weights ``(N,)``, labels ``(N,)``
    (species id for CEAMCL, cluster id otherwise)."""

    poses: NDArray[np.float64]
    weights: NDArray[np.float64]
    labels: NDArray[np.int64]


@dataclass(frozen=True)
class SpeciesDiagnostics:
    """One species at the end of a CEAMCL step (section 3.5)."""

    species_id: int
    n: int
    dn: float
    fitness: float
    area_m2: float
    resources: float
    capacity: float
    x: float
    y: float
    theta: float


@dataclass
class StepDiagnostics:
    """What one step did and cost. Filters fill the common fields; CEAMCL adds species."""

    step: int
    n_particles: int
    ess: float = float("nan")
    resampled: bool = False
    likelihood_evaluations: int = 0
    step_ms: float = 0.0
    reinitialised: bool = False
    species: tuple[SpeciesDiagnostics, ...] = ()
    extra: dict[str, float] = field(default_factory=dict)

    def row(self) -> dict[str, float | int | bool]:
        """A flat record for CSV: common fields, extra scalars and species totals."""
        out: dict[str, float | int | bool] = {
            "step": self.step,
            "n_particles": self.n_particles,
            "ess": self.ess,
            "resampled": self.resampled,
            "likelihood_evaluations": self.likelihood_evaluations,
            "step_ms": self.step_ms,
            "reinitialised": self.reinitialised,
            "n_species": len(self.species),
        }
        out.update(self.extra)
        return out


class LocalisationFilter(Protocol):
    """The one interface of MCL, GMCL, CEAMCL and KLD-AMCL."""

    name: str

    def initialise_global(self, scan: LaserScan) -> StepDiagnostics: ...

    def initialise_pose(self, pose: ArrayLike, covariance: ArrayLike) -> None: ...

    def step(self, increment: OdometryIncrement, scan: LaserScan | None) -> StepDiagnostics: ...

    def estimate(self) -> PoseEstimate: ...

    def hypotheses(self) -> list[Hypothesis]: ...

    def particles(self) -> ParticleSnapshot: ...
