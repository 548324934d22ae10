"""GMCL: genetic Monte Carlo localisation, the paper's second baseline (section 4).

MCL plus the genetic operators of CEAMCL (section 3.4), applied to the whole particle set
after weighting: crossover of random disjoint pairs with probability ``p_c`` (eq. 17) and
mutation of each particle with probability ``p_m`` (eq. 18, corrected). No species, no
competition, a fixed sample size. An evolved particle keeps its slot's prior weight times its
new likelihood. The operators run only on a step whose scan has a usable beam (with no
information they would only stir the particles at random).
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace

import numpy as np
from numpy.typing import NDArray

from ceamcl.filters.base import Algorithm, StepRecord
from ceamcl.filters.evolution import EvolutionConfig
from ceamcl.filters.headings import HeadingPrior
from ceamcl.filters.mcl import MCL, MCLConfig
from ceamcl.filters.particles import evolve, importance_weights
from ceamcl.sensors.scan import PreparedScan


@dataclass(frozen=True)
class GMCLConfig(MCLConfig):
    """MCL settings plus the genetic operators' (paper defaults p_c = 0.85, p_m = 0.15)."""

    evolution: EvolutionConfig = field(default_factory=EvolutionConfig)


class GMCL(MCL):
    """MCL with crossover and mutation after each weighting."""

    name = "gmcl"
    config: GMCLConfig

    def correct(self, prepared: PreparedScan | None) -> StepRecord:
        """MCL's correction with the genetic operators between weighting and resampling."""
        prior = self.particle_set.log_weights
        evaluations, reinitialised = self.reweight(prepared)
        if prepared is not None and not reinitialised:
            evaluations += self.evolve(prepared, prior)
        return StepRecord(self.resample_if_due(), evaluations, reinitialised)

    def evolve(self, prepared: PreparedScan, prior_log_weights: NDArray[np.float64]) -> int:
        """Crossover and mutation over the whole set (eqs. 17-18); each particle's weight
        becomes its prior weight times its (new) likelihood. Returns the evaluations."""
        ps = self.particle_set
        everyone = [np.arange(ps.n, dtype=np.intp)]
        evaluations = evolve(ps, everyone, self.config.evolution, self.sensor, prepared, self.rng)
        importance_weights(ps, prior_log_weights)
        return evaluations


ALGORITHM = Algorithm(
    "gmcl",
    GMCLConfig,
    GMCL,
    with_particles=lambda cfg, n: replace(cfg, n_particles=n),
    summary="MCL plus CEAMCL's genetic operators, no species (the paper's second baseline)",
)
#: GMCL as the tuning sweep found it best on the symmetric hall (docs/tuning.md; a test holds
#: it to the best row of docs/tuning.csv).
TUNED_ALGORITHM = Algorithm(
    "gmcl-tuned",
    GMCLConfig,
    GMCL,
    default_config=lambda: GMCLConfig(
        n_particles=1000, init_test_poses=1_000_000, init_headings=HeadingPrior()
    ),
    with_particles=lambda cfg, n: replace(cfg, n_particles=n),
    sensor_settings={"max_beams": 30, "temper": 0.1},
    summary="GMCL with the tuning sweep's best particles, start and sensor settings "
    "(docs/tuning.md)",
)
