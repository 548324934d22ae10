"""CEAMCL: coevolution-based adaptive Monte Carlo localisation (the paper's section 3.5).

One step, in the paper's order, each phase a method:

1. ``_grow``: sample-size determination. A species with ``dN > 0`` receives ``dN`` new samples
   drawn from its living domain; ``N_t = max(N_{t-1} + dN, 0)`` (stochastic rounding keeps the
   mean of a real-valued ``dN``). A species below ``min_species_size`` dies out.
2. ``_resample``: low-variance resampling of ``N_t`` samples inside each species.
3. ``_predict``: the motion model moves every sample.
4. ``_weigh``: one likelihood call for the samples of all species together.
5. ``_evolve``: crossover and mutation inside each species (section 3.4).
6. ``_split_and_merge``: a species whose samples occupy several connected regions splits;
   two species whose living domains overlap with no fitness valley between them merge.
7. ``_compete``: living domains, resources, carrying capacities and the Lotka-Volterra
   increments ``dN`` for the next step (eqs. 9-16).
8. Summary: the fittest species gives the pose; every species is a hypothesis.

Importance factors are normalised inside each species (NOTES.md): resampling keeps a species'
size, which changes only through ``dN``.

Safeguards (docs/robustness.md): a step without a scan, or whose scan has no usable beam, only
resamples and predicts; weights are unchanged and every ``dN`` is set to 0, so sizes freeze
until the laser speaks again. NaN and +inf likelihoods count as impossible. When every species
has died out, or every particle is impossible under the scan, the filter re-initialises
globally (section 3.1 on that scan, or uniformly over free space without one) and the step's
:class:`StepDiagnostics` says ``reinitialised=True``.
"""

from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ceamcl.angles import interpolate
from ceamcl.filters.base import (
    Algorithm,
    Hypothesis,
    ParticleSnapshot,
    PoseEstimate,
    SpeciesDiagnostics,
    StepDiagnostics,
)
from ceamcl.filters.ceamcl.competition import (
    carrying_capacity,
    competition_coefficients,
    resources,
    step_increments,
)
from ceamcl.filters.ceamcl.config import CEAMCLConfig
from ceamcl.filters.ceamcl.initialisation import InitialSpecies, generate_initial_species
from ceamcl.filters.ceamcl.species import (
    SpeciesStats,
    all_species_stats,
    compact_species,
    group_members,
    overlapping_pairs,
    resample_species,
    sample_living_domain,
    split_parts,
)
from ceamcl.filters.evolution import evolve
from ceamcl.filters.mcl import check_increment, gaussian_poses
from ceamcl.filters.resampling import sanitise_log_likelihood
from ceamcl.maps.grid import OccupancyGrid
from ceamcl.motion.odometry import OdometryIncrement, OdometryMotionModel
from ceamcl.sensors.base import SensorModel, fitness
from ceamcl.sensors.scan import LaserScan, PreparedScan


@dataclass
class _Competition:
    """Per-species results of the last competition phase, keyed by species id."""

    dn: dict[int, float]
    resources: dict[int, float]
    capacity: dict[int, float]


class CEAMCL:
    """Coevolution-based adaptive MCL (implements :class:`LocalisationFilter`)."""

    name = "ceamcl"

    def __init__(
        self,
        grid: OccupancyGrid,
        motion: OdometryMotionModel,
        sensor: SensorModel,
        config: CEAMCLConfig | None = None,
        *,
        rng: np.random.Generator,
    ) -> None:
        self.grid = grid
        self.motion = motion
        self.sensor = sensor
        self.config = config or CEAMCLConfig()
        self.rng = rng
        self.poses: NDArray[np.float64] = np.zeros((0, 3))
        self.species: NDArray[np.int64] = np.zeros(0, dtype=np.int64)
        self.loglik: NDArray[np.float64] = np.zeros(0)
        self.fitness: NDArray[np.float64] = np.zeros(0)
        self.stats: dict[int, SpeciesStats] = {}
        self.competition = _Competition({}, {}, {})
        self.initial: InitialSpecies | None = None
        self.t = 0
        self._next_id = 0
        self._prepared: PreparedScan | None = None
        self._evaluations = 0
        self._events: dict[str, float] = {}
        self._targets: dict[int, int] = {}
        self._fit_fast: float | None = None
        self._fit_slow: float | None = None
        self._steps_since_init = 0

    # ================================================================== initialisation
    def initialise_global(self, scan: LaserScan) -> StepDiagnostics:
        """Initial species generation (section 3.1) from the first scan."""
        start = time.perf_counter()
        self.t = 0
        self._initialise_from(self.sensor.prepare(scan))
        return self._diagnostics(start, reinitialised=False)

    def _initialise_from(self, prepared: PreparedScan | None) -> None:
        """Section 3.1. Without a usable beam (``prepared`` None or empty) every test pose is
        equally fit, so the species spread uniformly over free space."""
        self._reset_events()
        self._fit_fast = self._fit_slow = None
        self._steps_since_init = 0
        cfg = self.config
        test = self.grid.sample_free_poses(cfg.n_test, self.rng)
        if prepared is None or prepared.n_beams == 0:
            ll = np.zeros(cfg.n_test)
            self._evaluations = 0
        else:
            ll = sanitise_log_likelihood(
                np.concatenate(
                    [
                        self.sensor.log_likelihood(test[i : i + cfg.test_batch], prepared)
                        for i in range(0, cfg.n_test, cfg.test_batch)
                    ]
                )
            )
            self._evaluations = cfg.n_test
        fit = np.ones(cfg.n_test) if prepared is None else fitness(ll, prepared, self.sensor)
        init = generate_initial_species(
            self.grid,
            test,
            ll,
            fit,
            cell_m=cfg.cell_m,
            mu=cfg.mu,
            eta=cfg.eta,
            cell_top_k=cfg.cell_top_k,
            fitness_exponent=cfg.cell_fitness_exponent,
            smoothing_cells=cfg.cell_smoothing,
            min_species_size=cfg.min_species_size,
            max_samples=cfg.max_samples,
        )
        self.initial = init
        self.poses = init.poses
        self.species = init.labels.astype(np.int64)
        self.loglik = init.loglik
        self.fitness = init.fitness
        self._next_id = init.n_species
        self._prepared = prepared if prepared is not None and prepared.n_beams > 0 else None
        # "for each species i, let dN_0 / dt = 0": competition starts after the first step.
        self.competition = _Competition({i: 0.0 for i in range(init.n_species)}, {}, {})
        # The paper clusters initial species in x-y only; one x-y region can hold a pose and
        # its mirror image (same place, other heading). Splitting now, before the first
        # resampling, keeps both as species instead of letting resampling pick one.
        self._split_and_merge()  # leaves self.stats fresh
        self._compute_resources_only()
        self._events["n0"] = float(init.n0)
        self._events["v_cells"] = float(init.v_size)

    def initialise_pose(self, pose: ArrayLike, covariance: ArrayLike) -> None:
        """Pose tracking: one species of ``tracking_samples`` around a known pose."""
        n = self.config.tracking_samples
        self.poses = gaussian_poses(pose, covariance, n, self.rng)
        self.species = np.zeros(n, dtype=np.int64)
        self.loglik = np.zeros(n)
        self.fitness = np.ones(n)
        self._next_id = 1
        self._prepared = None
        self.t = 0
        self._refresh_stats()
        self.competition = _Competition({0: 0.0}, {}, {})

    # ================================================================== one step
    def step(self, increment: OdometryIncrement, scan: LaserScan | None) -> StepDiagnostics:
        start = time.perf_counter()
        check_increment(increment)
        self.t += 1
        self._evaluations = 0
        self._reset_events()
        prepared = None if scan is None else self.sensor.prepare(scan)
        self._grow()
        if self.poses.shape[0] == 0:
            return self._restart(prepared, start)
        members = self._resample()
        self._predict(increment)
        if prepared is None or prepared.n_beams == 0:
            # No information: sizes freeze (dN = 0) and the particles, just resampled, keep
            # equal weights (no evidence is counted twice at the next resampling).
            self.loglik = np.zeros(self.poses.shape[0])
            self._refresh_stats()
            self.competition.dn = {sid: 0.0 for sid in self.stats}
            return self._diagnostics(start, reinitialised=False)
        self._weigh(prepared)
        if not np.any(np.isfinite(self.loglik)):
            return self._restart(prepared, start)  # every particle impossible under this scan
        self._evolve(members)
        self._split_and_merge(members)  # leaves self.stats fresh
        if self._fitness_collapsed():
            self._events["recoveries"] = 1.0
            return self._restart(prepared, start)  # kidnapped: no species explains the scans
        self._compete()
        return self._diagnostics(start, reinitialised=False)

    def _fitness_collapsed(self) -> bool:
        """Kidnap detection (docs/ceamcl.md): fast and slow running averages of the fittest
        species' fitness, as augmented MCL keeps of the mean weight; the robot is lost when
        the fast one falls below ``recovery_ratio`` times the slow one. Fitness lies in (0, 1]
        and is comparable between steps, so the test does not depend on the scan's size."""
        cfg = self.config
        best = max((s.fitness for s in self.stats.values()), default=0.0)
        self._steps_since_init += 1
        if self._fit_slow is None or self._fit_fast is None:
            self._fit_slow = self._fit_fast = best
            return False
        self._fit_fast += cfg.recovery_alpha_fast * (best - self._fit_fast)
        self._fit_slow += cfg.recovery_alpha_slow * (best - self._fit_slow)
        return (
            cfg.recovery
            and self._steps_since_init > cfg.recovery_warmup_steps
            and self._fit_fast < cfg.recovery_ratio * self._fit_slow
        )

    def _restart(self, prepared: PreparedScan | None, start: float) -> StepDiagnostics:
        """Every species died out (or every particle is impossible): global initialisation
        again, from the step's scan or, without one, uniformly over free space; recorded in the
        diagnostics as ``reinitialised`` (and ``extra["restarts"]``)."""
        t = self.t
        evaluations, events = self._evaluations, dict(self._events)
        self._initialise_from(prepared)
        self._evaluations += evaluations
        for key, value in self._events.items():
            events[key] = events.get(key, 0.0) + value
        self._events = {**events, "restarts": 1.0}
        self.t = t
        return self._diagnostics(start, reinitialised=True)

    # ------------------------------------------------------------------ 1. sample size
    def _grow(self) -> None:
        cfg = self.config
        new_poses, new_species, dead = [], [], []
        targets: dict[int, int] = {}
        total_now = self.poses.shape[0]
        positive = sum(max(dn, 0.0) for dn in self.competition.dn.values())
        room = max(cfg.max_samples - total_now, 0)
        scale = min(1.0, room / positive) if positive > 0 else 1.0
        for sid, stats in self.stats.items():
            dn = self.competition.dn.get(sid, 0.0)
            if dn > 0:
                dn *= scale
            change = self._stochastic_round(dn)
            if change > 0:  # rounding up must not break the cap on the total sample size
                change = min(change, room)
                room -= change
            target = max(stats.n + change, 0)
            if target < cfg.min_species_size:
                dead.append(sid)
                self._events["extinctions"] = self._events.get("extinctions", 0.0) + 1
                continue
            targets[sid] = target
            if change > 0:
                new_poses.append(sample_living_domain(stats, change, self.rng))
                new_species.append(np.full(change, sid, dtype=np.int64))
        if dead:
            alive = ~np.isin(self.species, dead)
            self._take(alive)
        if new_poses:
            added = np.vstack(new_poses)
            if self._prepared is None:  # no scan yet: newcomers are as likely as the rest
                ll = np.zeros(added.shape[0])
                fit_added = np.ones(added.shape[0])
            else:
                ll = sanitise_log_likelihood(self.sensor.log_likelihood(added, self._prepared))
                fit_added = fitness(ll, self._prepared, self.sensor)
                self._evaluations += added.shape[0]
            self.poses = np.vstack([self.poses, added])
            self.species = np.concatenate([self.species, *new_species])
            self.loglik = np.concatenate([self.loglik, ll])
            self.fitness = np.concatenate([self.fitness, fit_added])
            self._events["new_samples"] = float(added.shape[0])
        self._targets = targets

    def _stochastic_round(self, x: float) -> int:
        if not np.isfinite(x):
            return 0
        lo = float(np.floor(x))
        return int(lo) + int(self.rng.random() < (x - lo))

    # ------------------------------------------------------------------ 2. resampling
    def _resample(self) -> dict[int, NDArray[np.intp]]:
        """Returns the members of each species after resampling; prediction, weighting and
        evolution keep them, so evolution and splitting reuse them."""
        sel, members = resample_species(self.species, self.loglik, self._targets, self.rng)
        self._take(sel)
        return members

    # ------------------------------------------------------------------ 3. prediction
    def _predict(self, increment: OdometryIncrement) -> None:
        self.poses = self.motion.sample(self.poses, increment, self.rng)

    # ------------------------------------------------------------------ 4. weighting
    def _weigh(self, prepared: PreparedScan) -> None:
        self._prepared = prepared
        self.loglik = sanitise_log_likelihood(self.sensor.log_likelihood(self.poses, prepared))
        self._evaluations += self.poses.shape[0]

    def _evaluate(self, poses: NDArray[np.float64]) -> NDArray[np.float64]:
        assert self._prepared is not None
        return self.sensor.log_likelihood(poses, self._prepared)

    # ------------------------------------------------------------------ 5. evolution
    def _evolve(self, members: dict[int, NDArray[np.intp]]) -> None:
        groups = list(members.values())
        self._evaluations += evolve(
            self.poses, self.loglik, groups, self.config.evolution, self._evaluate, self.rng
        )
        assert self._prepared is not None
        self.loglik = sanitise_log_likelihood(self.loglik)
        self.fitness = fitness(self.loglik, self._prepared, self.sensor)

    # ------------------------------------------------------------------ 6. split and merge
    def _split_and_merge(self, members: dict[int, NDArray[np.intp]] | None = None) -> None:
        """Split, then merge (``members``: the particles of each species when already known,
        as :func:`group_members` gives them); on return ``self.stats`` describes the current
        particles."""
        cfg = self.config
        if members is None:
            members = group_members(self.species)
        # Split: one species per connected region of occupied cells; fragments smaller than a
        # viable species are dropped (resampling refills the parent next step).
        keep = np.ones(self.species.size, dtype=bool)
        compact = compact_species(members, self.poses, cfg.split_cell_m, cfg.split_cell_rad)
        for sid, idx in members.items():
            if idx.size < 2 * cfg.min_species_size or sid in compact:
                continue
            parts = split_parts(idx, self.poses, cfg.split_cell_m, cfg.split_cell_rad)
            for part in parts[1:]:
                if part.size >= cfg.min_species_size:
                    self.species[part] = self._next_id
                    self.competition.dn[self._next_id] = 0.0
                    self._next_id += 1
                    self._events["splits"] = self._events.get("splits", 0.0) + 1
                else:
                    keep[part] = False
        if not keep.all():
            self._take(keep)
        self._refresh_stats()
        self._merge()

    def _merge(self) -> None:
        if self._prepared is None:
            return  # no scan to probe the fitness between two species: no evidence to merge
        cfg = self.config
        ids = sorted(self.stats, key=lambda s: -self.stats[s].fitness)
        pairs = [(ids[i], ids[j]) for i, j in overlapping_pairs([self.stats[sid] for sid in ids])]
        if not pairs:
            return
        k = cfg.merge_probe_points
        fractions = np.linspace(0.0, 1.0, k + 2)
        probes = []
        for a, b in pairs:
            ma, mb = self.stats[a].mean, self.stats[b].mean
            xy = ma[None, :2] + fractions[:, None] * (mb[:2] - ma[:2])[None, :]
            th = interpolate(ma[2], mb[2], fractions)
            probes.append(np.column_stack([xy, th]))
        ll = self._evaluate(np.vstack(probes)).reshape(len(pairs), k + 2)
        self._evaluations += ll.size
        assert self._prepared is not None
        fit = fitness(ll, self._prepared, self.sensor)
        merged: set[int] = set()
        for (a, b), f in zip(pairs, fit, strict=True):
            if a in merged or b in merged:
                continue
            ends = min(f[0], f[-1])
            if f[1:-1].min() >= cfg.merge_valley_ratio * ends:
                # b (the less fit) joins a.
                self.species[self.species == b] = a
                merged.add(b)
                self.competition.dn[a] = self.competition.dn.get(a, 0.0) + self.competition.dn.get(
                    b, 0.0
                )
                self._events["merges"] = self._events.get("merges", 0.0) + 1
        if merged:
            self._refresh_stats()

    # ------------------------------------------------------------------ 7. competition
    def _compute_resources_only(self) -> None:
        ids = list(self.stats)
        cfg = self.config
        area = np.array([self.stats[s].area_m2 for s in ids])
        res = resources(area, cfg.delta_per_m2, cfg.epsilon_m2)
        fit = np.array([self.stats[s].fitness for s in ids])
        cap = carrying_capacity(fit, float(res.sum()))
        self.competition.resources = dict(zip(ids, res.tolist(), strict=True))
        self.competition.capacity = dict(zip(ids, cap.tolist(), strict=True))

    def _compete(self) -> None:
        """Eqs. 9-16: dN of every species for the next step."""
        ids = list(self.stats)
        if not ids:
            self.competition = _Competition({}, {}, {})
            return
        self._compute_resources_only()
        n = np.array([self.stats[s].n for s in ids], dtype=np.float64)
        fit = np.array([max(self.stats[s].fitness, 1e-12) for s in ids])
        cap = np.array([self.competition.capacity[s] for s in ids])
        dn = step_increments(n, cap, competition_coefficients(fit), self.config.growth_rate)
        self.competition.dn = dict(zip(ids, dn.tolist(), strict=True))

    # ------------------------------------------------------------------ bookkeeping
    def _take(self, mask: NDArray[np.bool_] | NDArray[np.intp]) -> None:
        """Keep the particles a boolean mask or an index array selects."""
        self.poses = self.poses[mask]
        self.species = self.species[mask]
        self.loglik = self.loglik[mask]
        self.fitness = self.fitness[mask]

    def _refresh_stats(self) -> None:
        self.stats = all_species_stats(self.species, self.poses, self.loglik, self.fitness)

    def _reset_events(self) -> None:
        self._events = {}
        self._targets = {}

    def _diagnostics(self, start: float, reinitialised: bool) -> StepDiagnostics:
        comp = self.competition
        species = tuple(
            SpeciesDiagnostics(
                species_id=sid,
                n=s.n,
                dn=comp.dn.get(sid, 0.0),
                fitness=s.fitness,
                area_m2=s.area_m2,
                resources=comp.resources.get(sid, float("nan")),
                capacity=comp.capacity.get(sid, float("nan")),
                x=float(s.mean[0]),
                y=float(s.mean[1]),
                theta=float(s.mean[2]),
            )
            for sid, s in self.stats.items()
        )
        extra = {
            "total_resources": float(sum(comp.resources.values())),
            "new_samples": 0.0,
            "extinctions": 0.0,
            "splits": 0.0,
            "merges": 0.0,
        }
        extra.update(self._events)
        return StepDiagnostics(
            step=self.t,
            n_particles=int(self.poses.shape[0]),
            ess=float("nan"),
            resampled=self.t > 0,
            likelihood_evaluations=self._evaluations,
            step_ms=(time.perf_counter() - start) * 1e3,
            reinitialised=reinitialised,
            species=species,
            extra=extra,
        )

    # ================================================================== queries
    def fittest(self) -> SpeciesStats | None:
        if not self.stats:
            return None
        return max(self.stats.values(), key=lambda s: s.fitness)

    def estimate(self) -> PoseEstimate:
        best = self.fittest()
        if best is None:
            return PoseEstimate(np.zeros(3), np.diag([1e6, 1e6, np.pi**2]))
        return PoseEstimate(best.mean.copy(), best.covariance.copy())

    def hypotheses(self) -> list[Hypothesis]:
        stats = sorted(self.stats.values(), key=lambda s: -s.fitness)
        mass = np.array([s.n * s.fitness for s in stats], dtype=np.float64)
        share = mass / mass.sum() if mass.sum() > 0 else np.full(mass.size, 1.0 / max(mass.size, 1))
        return [
            Hypothesis(
                pose=s.mean.copy(),
                covariance=s.covariance.copy(),
                n_particles=s.n,
                weight=float(w),
                fitness=s.fitness,
                label=s.species_id,
            )
            for s, w in zip(stats, share, strict=True)
        ]

    def particles(self) -> ParticleSnapshot:
        weights = np.zeros(self.poses.shape[0])
        hyps = {h.label: h.weight for h in self.hypotheses()}
        for sid, s in self.stats.items():
            weights[s.members] = s.weights * hyps.get(sid, 0.0)
        total = weights.sum()
        if total > 0:
            weights /= total
        return ParticleSnapshot(self.poses.copy(), weights, self.species.copy())


ALGORITHM = Algorithm(
    "ceamcl",
    CEAMCLConfig,
    CEAMCL,
    summary="coevolution-based adaptive MCL: species, Lotka-Volterra competition, evolution",
)
