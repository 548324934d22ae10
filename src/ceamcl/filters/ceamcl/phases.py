"""CEAMCL's phases (paper section 3.5) as functions on the particle core's container.

The particle set's labels are the species ids. Each phase takes only its own settings (a
sub-config: ``CEAMCLConfig.growth``, ``.split_merge`` and ``.competition`` give them with the
paper's defaults, which live in :class:`~ceamcl.filters.ceamcl.config.CEAMCLConfig` alone),
changes the set in place where it acts on particles, and counts what it did into an
:class:`~ceamcl.filters.ceamcl.records.Events` record. The filter
(:class:`~ceamcl.filters.ceamcl.filter.CEAMCL`) calls them in the paper's order; initial
species generation (section 3.1) lives in :mod:`~ceamcl.filters.ceamcl.initialisation`.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray

from ceamcl.angles import interpolate
from ceamcl.filters.ceamcl.competition import (
    carrying_capacity,
    competition_coefficients,
    resources,
    step_increments,
)
from ceamcl.filters.ceamcl.records import Events
from ceamcl.filters.ceamcl.species import (
    SpeciesStats,
    all_species_stats,
    compact_species,
    overlapping_pairs,
    sample_living_domain,
    split_parts,
)
from ceamcl.filters.particles import ParticleSet
from ceamcl.filters.resampling import label_groups, sanitise_log_likelihood
from ceamcl.sensors.base import SensorModel, fitness
from ceamcl.sensors.scan import PreparedScan


@dataclass(frozen=True)
class GrowthConfig:
    """Sample-size determination: species below ``min_species_size`` die out; the total
    sample size never exceeds ``max_samples``."""

    min_species_size: int
    max_samples: int


@dataclass(frozen=True)
class SplitMergeConfig:
    """Split on the connected regions of ``split_cell_m x split_cell_m x split_cell_rad``
    cells (fragments below ``min_species_size`` dropped); merge two overlapping species
    unless the fitness at ``merge_probe_points`` points between their means falls below
    ``merge_valley_ratio`` of the smaller end."""

    min_species_size: int
    split_cell_m: float
    split_cell_rad: float
    merge_valley_ratio: float
    merge_probe_points: int


@dataclass(frozen=True)
class CompetitionConfig:
    """Eqs. 9-16: growth rate ``r`` per step, minimum living domain ``epsilon_m2`` and
    resources ``delta_per_m2`` per square metre of living domain; ``tracking_epsilon_m2``
    replaces ``epsilon_m2`` while a single species lives (docs/ceamcl.md, "epsilon")."""

    growth_rate: float
    epsilon_m2: float
    delta_per_m2: float
    tracking_epsilon_m2: float | None = None
    #: a lone species below the tracking floor (``delta * tracking_epsilon_m2``) grows to it at
    #: once instead of logistically (docs/ceamcl.md, departure 8)
    fill_tracking_floor: bool = False


@dataclass
class Competition:
    """Per-species results of the last competition phase, keyed by species id: the increments
    ``dN`` for the next step, resources and carrying capacities."""

    dn: dict[int, float] = field(default_factory=dict)
    resources: dict[int, float] = field(default_factory=dict)
    capacity: dict[int, float] = field(default_factory=dict)


def species_stats(ps: ParticleSet) -> dict[int, SpeciesStats]:
    """:class:`SpeciesStats` of every species of the set, in ascending id order."""
    return all_species_stats(ps.labels, ps.poses, ps.loglik, ps.fitness)


def _stochastic_round(x: float, rng: np.random.Generator) -> int:
    """``floor(x)`` plus 1 with probability ``x - floor(x)`` (keeps the mean of ``x``)."""
    if not np.isfinite(x):
        return 0
    lo = float(np.floor(x))
    return int(lo) + int(rng.random() < (x - lo))


def grow(
    ps: ParticleSet,
    stats: dict[int, SpeciesStats],
    dn: dict[int, float],
    config: GrowthConfig,
    sensor: SensorModel,
    prepared: PreparedScan | None,
    events: Events,
    rng: np.random.Generator,
) -> tuple[dict[int, int], int]:
    """Phase 1, sample-size determination: ``N_t = max(N_{t-1} + dN, 0)`` per species, ``dN``
    rounded stochastically and positive ones scaled down to stay within ``max_samples``. A
    species with ``dN > 0`` receives that many samples from its living domain, scored with
    the last scan (``prepared``; none yet: as likely as the rest); one whose size, rounded or
    real-valued, falls below ``min_species_size`` dies out. Returns the target size of every
    surviving species and the evaluations spent."""
    new_poses, new_species, dead = [], [], []
    targets: dict[int, int] = {}
    positive = sum(max(d, 0.0) for d in dn.values())
    room = max(config.max_samples - ps.n, 0)
    scale = min(1.0, room / positive) if positive > 0 else 1.0
    for sid, s in stats.items():
        d = dn.get(sid, 0.0)
        if d > 0:
            d *= scale
        change = _stochastic_round(d, rng)
        if change > 0:  # rounding up must not break the cap on the total sample size
            change = min(change, room)
            room -= change
        target = max(s.n + change, 0)
        # the real-valued size decides extinction: a species at the floor that keeps shrinking
        # (dN < 0) dies now, instead of lingering until stochastic rounding lets it go
        if target < config.min_species_size or s.n + d < config.min_species_size:
            dead.append(sid)
            events.extinctions += 1
            continue
        targets[sid] = target
        if change > 0:
            new_poses.append(sample_living_domain(s, change, rng))
            new_species.append(np.full(change, sid, dtype=np.int64))
    if dead:
        ps.take(~np.isin(ps.labels, dead))
    evaluations = 0
    if new_poses:
        added = ParticleSet.from_poses(np.vstack(new_poses), np.concatenate(new_species))
        if prepared is not None:
            added.loglik = sanitise_log_likelihood(sensor.log_likelihood(added.poses, prepared))
            added.fitness = fitness(added.loglik, prepared, sensor)
            evaluations = added.n
        ps.extend(added)
        events.new_samples = added.n
    return targets, evaluations


def fit_budget(
    ps: ParticleSet, max_samples: int, min_species_size: int, rank: dict[int, float]
) -> int:
    """Keep the total sample size within ``max_samples`` where a step added species beside
    the living ones (a recovery's search, departure 19's start): species in order of
    ``rank`` (their log-weights, the highest first; ties by id) keep their samples while room
    lasts, one cut short keeps its best-scoring samples, and one left fewer than
    ``min_species_size`` goes. Returns how many samples went (0: within the budget)."""
    if ps.n <= max_samples:
        return 0
    members = label_groups(ps.labels)
    order = sorted(members, key=lambda sid: (-rank.get(sid, -np.inf), sid))
    keep: list[NDArray[np.intp]] = []
    room = max_samples
    for sid in order:
        idx = members[sid]
        take = min(idx.size, room)
        if take < min_species_size:
            continue
        if take < idx.size:
            idx = np.sort(idx[np.argsort(-ps.loglik[idx], kind="stable")[:take]])
        keep.append(idx)
        room -= take
    sel = np.sort(np.concatenate(keep)) if keep else np.zeros(0, dtype=np.intp)
    dropped = ps.n - sel.size
    ps.take(sel)
    return dropped


def split(
    ps: ParticleSet,
    members: dict[int, NDArray[np.intp]],
    config: SplitMergeConfig,
    next_id: int,
    events: Events,
    scores: NDArray[np.float64] | None = None,
) -> tuple[dict[int, int], dict[int, float]]:
    """Phase 6a: a species whose particles occupy several connected regions of cells splits,
    one species per region (the first keeps the id, the others get ids from ``next_id``);
    fragments smaller than a viable species are dropped (resampling refills the parent next
    step). ``members``: the particles of each species (:func:`label_groups`). Returns each new
    id's parent and, with ``scores`` (each particle's log-likelihood for the step's scan),
    the shortfall of every part of a split species, the kept first one included: the best
    score in the part minus the best in the whole species, 0 for the part that holds it
    (docs/ceamcl.md, "a split part's own evidence")."""
    keep = np.ones(ps.n, dtype=bool)
    new_ids: dict[int, int] = {}
    shortfall: dict[int, float] = {}
    compact = compact_species(members, ps.poses, config.split_cell_m, config.split_cell_rad)
    for sid, idx in members.items():
        if idx.size < 2 * config.min_species_size or sid in compact:
            continue
        parts = split_parts(idx, ps.poses, config.split_cell_m, config.split_cell_rad)
        tops = [float(np.max(scores[p])) for p in parts] if scores is not None else []
        whole = max(tops, default=-np.inf)  # the species' best, fragments included
        if np.isfinite(whole) and len(parts) > 1:
            shortfall[sid] = tops[0] - whole
        for k, part in enumerate(parts[1:], start=1):
            if part.size >= config.min_species_size:
                ps.labels[part] = next_id
                new_ids[next_id] = sid
                if np.isfinite(whole):
                    shortfall[next_id] = tops[k] - whole  # <= 0; -inf when nothing fits
                next_id += 1
                events.splits += 1
            else:
                keep[part] = False
    if not keep.all():
        ps.take(keep)
    return new_ids, shortfall


def merge(
    ps: ParticleSet,
    stats: dict[int, SpeciesStats],
    dn: dict[int, float],
    config: SplitMergeConfig,
    sensor: SensorModel,
    prepared: PreparedScan,
    events: Events,
    log_weight: dict[int, float] | None = None,
    log_prior: dict[int, float] | None = None,
) -> tuple[bool, int]:
    """Phase 6b: two species whose living domains overlap merge (the less fit joins the
    fitter, adding its ``dN`` and, when given, its weight to ``log_weight``; of their
    unfaded priors in ``log_prior`` the larger stays) unless the
    fitness along the segment between their means dips below ``merge_valley_ratio`` of the
    smaller end value. Returns whether any merged and the evaluations spent on the probes."""
    ids = sorted(stats, key=lambda s: -stats[s].fitness)
    pairs = [(ids[i], ids[j]) for i, j in overlapping_pairs([stats[sid] for sid in ids])]
    if not pairs:
        return False, 0
    k = config.merge_probe_points
    fractions = np.linspace(0.0, 1.0, k + 2)
    probes = []
    for a, b in pairs:
        ma, mb = stats[a].mean, stats[b].mean
        xy = ma[None, :2] + fractions[:, None] * (mb[:2] - ma[:2])[None, :]
        th = interpolate(ma[2], mb[2], fractions)
        probes.append(np.column_stack([xy, th]))
    ll = sensor.log_likelihood(np.vstack(probes), prepared).reshape(len(pairs), k + 2)
    fit = fitness(ll, prepared, sensor)
    merged: set[int] = set()
    for (a, b), f in zip(pairs, fit, strict=True):
        if a in merged or b in merged:
            continue
        ends = min(f[0], f[-1])
        if f[1:-1].min() >= config.merge_valley_ratio * ends:
            ps.labels[ps.labels == b] = a  # b (the less fit) joins a
            merged.add(b)
            dn[a] = dn.get(a, 0.0) + dn.get(b, 0.0)
            if log_weight is not None and b in log_weight:
                log_weight[a] = float(np.logaddexp(log_weight.get(a, -np.inf), log_weight.pop(b)))
            if log_prior is not None and (a in log_prior or b in log_prior):
                held = max(log_prior.pop(a, 0.0), log_prior.pop(b, 0.0))
                if held < 0.0:
                    log_prior[a] = held
            events.merges += 1
    return bool(merged), int(ll.size)


def allocate_resources(
    stats: dict[int, SpeciesStats],
    config: CompetitionConfig,
    competition: Competition,
    fitness: dict[int, float] | None = None,
) -> None:
    """Eqs. 15-16: each species' resources from its living domain and its carrying capacity
    from its fitness (``fitness``, by species id; default: the species' mean fitness), into
    ``competition``."""
    ids = list(stats)
    area = np.array([stats[s].area_m2 for s in ids])
    tracking = _tracking_epsilon(config, len(ids))
    eps = config.epsilon_m2 if tracking is None else tracking
    res = resources(area, config.delta_per_m2, eps)
    fit = np.array([_fitness_of(stats, fitness, s) for s in ids])
    cap = carrying_capacity(fit, float(res.sum()))
    competition.resources = dict(zip(ids, res.tolist(), strict=True))
    competition.capacity = dict(zip(ids, cap.tolist(), strict=True))


def _tracking_epsilon(config: CompetitionConfig, n_species: int) -> float | None:
    """``tracking_epsilon_m2`` while a single species tracks the robot (docs/ceamcl.md,
    "epsilon"), else None."""
    return config.tracking_epsilon_m2 if n_species == 1 else None


def _fitness_of(
    stats: dict[int, SpeciesStats], fitness: dict[int, float] | None, sid: int
) -> float:
    if fitness is None or sid not in fitness:
        return stats[sid].fitness
    return fitness[sid]


def compete(
    stats: dict[int, SpeciesStats],
    config: CompetitionConfig,
    fitness: dict[int, float] | None = None,
    floors: dict[int, int] | None = None,
) -> Competition:
    """Phase 7, eqs. 9-16: resources, carrying capacities and every species' ``dN`` for the
    next step (Lotka-Volterra competition, integrated exactly over a step). ``fitness`` is the
    ``w`` of eqs. 9 and 16 by species id, in (0, 1] (default: each species' mean fitness).
    ``floors``: a size some species keep whatever eq. 9 says (their ``dN`` raised to reach
    it; docs/ceamcl.md, departure 13), as a lone species keeps the tracking floor."""
    ids = list(stats)
    out = Competition()
    if not ids:
        return out
    allocate_resources(stats, config, out, fitness)
    n = np.array([stats[s].n for s in ids], dtype=np.float64)
    fit = np.array([max(_fitness_of(stats, fitness, s), 1e-12) for s in ids])
    cap = np.array([out.capacity[s] for s in ids])
    dn = step_increments(n, cap, competition_coefficients(fit), config.growth_rate)
    tracking = _tracking_epsilon(config, len(ids))
    if config.fill_tracking_floor and tracking is not None:
        # the competition is over: the floor tracking needs holds from now, not in 10-25 steps
        dn = np.maximum(dn, config.delta_per_m2 * tracking - n)
    out.dn = dict(zip(ids, dn.tolist(), strict=True))
    raise_to_floors(out.dn, stats, floors or {})
    return out


def raise_to_floors(
    dn: dict[int, float], stats: dict[int, SpeciesStats], floors: dict[int, int]
) -> None:
    """Raise the ``dN`` of each species of ``floors`` (by id) so that it reaches that many
    samples, whatever eq. 9 says: departure 13's viable species (:func:`compete`) and
    departure 36's species at the anchor (docs/ceamcl.md)."""
    for sid, floor in floors.items():
        dn[sid] = max(dn.get(sid, 0.0), float(floor - stats[sid].n))


__all__ = [
    "Competition",
    "CompetitionConfig",
    "GrowthConfig",
    "SplitMergeConfig",
    "allocate_resources",
    "compete",
    "fit_budget",
    "grow",
    "merge",
    "raise_to_floors",
    "species_stats",
    "split",
]
