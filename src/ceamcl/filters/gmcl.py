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

from ceamcl.filters.base import Algorithm
from ceamcl.filters.evolution import EvolutionConfig, evolve
from ceamcl.filters.mcl import MCL, MCLConfig
from ceamcl.filters.resampling import normalise_log_weights, sanitise_log_likelihood
from ceamcl.sensors.base import fitness


@dataclass(frozen=True)
class GMCLConfig(MCLConfig):
    """MCL settings plus the genetic operators' (paper defaults p_c = 0.85, p_m = 0.15)."""

    evolution: EvolutionConfig = field(default_factory=EvolutionConfig)


class GMCL(MCL):
    """MCL with crossover and mutation after each weighting."""

    name = "gmcl"
    config: GMCLConfig

    def _evolve(self) -> None:
        prepared = self._prepared
        assert prepared is not None

        def evaluate(poses: NDArray[np.float64]) -> NDArray[np.float64]:
            return self.sensor.log_likelihood(poses, prepared)

        everyone = [np.arange(self.poses.shape[0], dtype=np.intp)]
        self._evaluations += evolve(
            self.poses, self.loglik, everyone, self.config.evolution, evaluate, self.rng
        )
        self.loglik = sanitise_log_likelihood(self.loglik)
        self.fitness = fitness(self.loglik, prepared, self.sensor)
        log_w, _, ok = normalise_log_weights(self._prior_log_weights + self.loglik)
        if ok:
            self.log_weights = log_w


ALGORITHM = Algorithm(
    "gmcl",
    GMCLConfig,
    GMCL,
    with_particles=lambda cfg, n: replace(cfg, n_particles=n),
    summary="MCL plus CEAMCL's genetic operators, no species (the paper's second baseline)",
)
