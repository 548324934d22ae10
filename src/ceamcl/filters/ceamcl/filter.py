"""CEAMCL: coevolution-based adaptive Monte Carlo localisation (the paper's section 3.5).

One step, in the paper's order, each phase a public function of
:mod:`~ceamcl.filters.ceamcl.phases` or of the particle core (:mod:`ceamcl.filters.particles`)
acting on one :class:`~ceamcl.filters.particles.ParticleSet` whose labels are the species:

1. ``grow``: sample-size determination. A species with ``dN > 0`` receives ``dN`` new samples
   drawn from its living domain; ``N_t = max(N_{t-1} + dN, 0)`` (stochastic rounding keeps the
   mean of a real-valued ``dN``). A species below ``min_species_size`` dies out.
2. ``resample_within_labels``: low-variance resampling of ``N_t`` samples inside each species.
3. ``propagate``: the motion model moves every sample.
4. ``weigh``: one likelihood call for the samples of all species together.
5. ``evolve``: crossover and mutation inside each species (section 3.4).
6. ``split`` and ``merge``: a species whose samples occupy several connected regions splits;
   two species whose living domains overlap with no fitness valley between them merge.
7. ``compete``: living domains, resources, carrying capacities and the Lotka-Volterra
   increments ``dN`` for the next step (eqs. 9-16).
8. Summary: the leading species gives the pose; every species is a hypothesis.

Importance factors are normalised inside each species (NOTES.md): resampling keeps a species'
size, which changes only through ``dN``. What a species has seen is kept in its *evidence*
(docs/ceamcl.md): at each step with a scan, its log-weight grows by its marginal likelihood
(the mean likelihood of its predicted samples, before evolution), as a mixture particle filter
weighs its components. The weights, divided by the largest, are the fitness ``w`` in (0, 1] of
the competition (eqs. 9 and 16), the species' share of the posterior in :meth:`hypotheses`,
and choose the leading species. ``competition_fitness="scan"`` restores the paper's literal
reading (the current scan's mean fitness).

Safeguards (docs/robustness.md): a step without a scan, or whose scan has no usable beam, only
resamples and predicts; weights are unchanged and every ``dN`` is set to 0, so sizes freeze
until the laser speaks again. NaN and +inf likelihoods count as impossible. When every species
has died out, or every particle is impossible under the scan, the filter re-initialises
globally (section 3.1 on that scan, or uniformly over free space without one) and the step's
:class:`~ceamcl.filters.ceamcl.records.CEAMCLRecord` says ``reinitialised=True``.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import replace

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ceamcl import angles
from ceamcl.errors import ConfigError, check_rng
from ceamcl.filters.base import (
    Algorithm,
    Hypothesis,
    ParticleSnapshot,
    PoseEstimate,
    check_grid,
    check_scan,
    check_step_arguments,
    require_initialised,
)
from ceamcl.filters.ceamcl.anchor import (
    CHAIN_M,
    DRIFT_SD_M_PER_M,
    ConfidentPose,
    DriftEnvelope,
)
from ceamcl.filters.ceamcl.config import CEAMCLConfig
from ceamcl.filters.ceamcl.initialisation import (
    InitialisationConfig,
    InitialSpecies,
    heading_proposal,
    initial_species,
    polish,
)
from ceamcl.filters.ceamcl.phases import (
    Competition,
    allocate_resources,
    compete,
    fit_budget,
    grow,
    merge,
    raise_to_floors,
    species_stats,
    split,
)
from ceamcl.filters.ceamcl.records import CEAMCLRecord, Events, SpeciesRecord
from ceamcl.filters.ceamcl.species import SpeciesStats
from ceamcl.filters.headings import HeadingPrior, facing_length
from ceamcl.filters.particles import (
    ParticleSet,
    check_increment,
    evolve,
    gaussian,
    gaussian_poses,
    propagate,
    resample_within_labels,
    uniform_log_weights,
    usable,
    weigh,
)
from ceamcl.filters.resampling import (
    label_groups,
    normalise_log_weights,
    sanitise_log_likelihood,
)
from ceamcl.filters.state import (
    LocalisationState,
    MapAgreement,
    State,
    initialising,
    read_hypotheses,
    wall_crossing,
)
from ceamcl.maps.grid import OccupancyGrid
from ceamcl.motion.odometry import OdometryIncrement, OdometryMotionModel, apply_increment
from ceamcl.pose import pose_mean, position_error
from ceamcl.sensors.base import SensorModel, fitness
from ceamcl.sensors.beam_skip import skip_unexplained_beams
from ceamcl.sensors.scan import LaserScan, PreparedScan
from ceamcl.sensors.search import search_model
from ceamcl.sensors.see_through import see_through_penalty

#: A species' log-weight never falls below this (exp of it is still a positive number, so
#: shares stay well defined; the competition has long ended such a species).
LOG_WEIGHT_FLOOR = -700.0
#: the motion a climb at the scan of a start carries the last peaks by: none (departure 43)
_STANDING = OdometryIncrement(0.0, 0.0, 0.0)
#: ``CEAMCL._held`` before any update has judged the anchor: nothing held.
_NOT_HELD: tuple[int, None, None, float] = (0, None, None, float("nan"))
_NO_ESTIMATE: tuple[int, int, None] = (-1, -1, None)
#: ``CEAMCL._score_anchor``: the best pose around the anchor, its tempered log-likelihood and
#: the leader's best sample's.
_Scored = tuple[NDArray[np.float64], float, float]


class CEAMCL:
    """Coevolution-based adaptive MCL (implements :class:`LocalisationFilter`).

    ``particle_set`` holds the samples (labels: species ids; CEAMCL weighs inside each
    species from the log-likelihoods and leaves the set's log-weights unused); ``stats`` the
    species' statistics, ``competition`` the last competition phase's results.
    """

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
        check_grid(grid)
        check_rng(rng)
        self.grid = grid
        self.motion = motion
        self.sensor = sensor
        self.config = config or CEAMCLConfig()
        self.rng = rng
        #: the model that scores a search's test poses (``search_with_field``), made once
        self._search: SensorModel | None = None
        self.particle_set = ParticleSet.from_poses(np.zeros((0, 3)))
        #: set by the first initialisation; stepping or asking before it is an error
        self._initialised = False
        self.stats: dict[int, SpeciesStats] = {}
        self.competition = Competition()
        self.initial: InitialSpecies | None = None
        self.events = Events()
        self.t = 0
        self._next_id = 0
        self._prepared: PreparedScan | None = None  # the last scan with a usable beam
        self._full: PreparedScan | None = None
        self._evaluations = 0
        self._fit_fast: float | None = None
        self._fit_slow: float | None = None
        self._steps_since_init = 0
        #: consecutive updates the state has said LOST, and how many a recovery waits for
        #: (doubled after each one it fires until the state leaves LOST; departure 10)
        self._lost_streak = 0
        self._lost_wait = self.config.recovery_lost_updates or 0
        #: the hypotheses and state read during this step (departure 10), handed to callers
        #: that ask again before anything changes (the map's agreement applied when they
        #: do); cleared by every step and initialisation
        self._read: tuple[list[Hypothesis], LocalisationState] | None = None
        #: log of each species' accumulated evidence, the largest 0 (docs/ceamcl.md)
        self.log_weight: dict[int, float] = {}
        #: the part of ``log_weight`` the evidence memory does not fade: a species a recovery
        #: proposed far from every species the filter had carries ``log(recovery_prior)``
        #: here while others live (departure 11); absent means 0
        self.log_prior: dict[int, float] = {}
        #: each species' evidence peak at the last step that compared species, carried to the
        #: next by the odometry as the climb's first candidate (docs/ceamcl.md, departure 6);
        #: species ids are never reused, so a new species never meets an old peak
        self._peaks: dict[int, NDArray[np.float64]] = {}
        #: each species' fitness at the peak its evidence climb found this step, when it
        #: climbed: how well the hypothesis can fit the scan (docs/state.md)
        self._peak_fitness: dict[int, float] = {}
        #: each species' running share of the updates at which it fitted as well as the best
        #: while the filter was ambiguous (departure 13)
        self._equal_record: dict[int, float] = {}
        #: the last scan received, for the state's wall-crossing test (docs/state.md)
        self.last_scan: LaserScan | None = None
        #: the state's memory of how well the map explains the scans (docs/state.md); the
        #: recovery reads the state without it (:meth:`_lost_too_long`)
        self.map_agreement = MapAgreement(grid)
        #: the leading pose the last time the filter was LOCALISED with the map's agreement,
        #: carried on by the odometry (departure 14)
        self.confident = ConfidentPose(
            self.map_agreement, self._drift_envelope, self._anchor_fits_better
        )
        #: departure 38: the last grid scored around the anchor, keyed by the update, the
        #: pose, the leader and the particle count (a contest and a return judge one update)
        self._anchor_scored: tuple[tuple[int, bytes, int, int], _Scored] | None = None
        #: consecutive updates (up to ``self.t``) at which the state said LOST with the leader
        #: beyond the drift envelope of the last confident pose (departure 17)
        self._far_lost: tuple[int, int] = (0, 0)
        #: departure 39: the anchor as the estimate at update ``self.t`` where the coast goes
        #: on while the state says LOST with the leader back within the envelope
        self._coast: tuple[int, PoseEstimate | None] = (0, None)
        #: the anchor's travel (m) when the leader came back within the envelope (departure 39)
        self._coast_from = 0.0
        #: departure 40: the update at which a far leader was held back because it read
        #: LOCALISED for the first time after a coast
        self._unconfirmed_at = -1
        #: departure 41: the last update at which a far leader reading LOCALISED was held back
        #: (departure 40), and the odometry's travel (m) and turning (rad) when it began to
        #: read so at every update up to that one
        self._streak: tuple[int, float, float] = (-1, 0.0, 0.0)
        #: departure 41: the last update at which the estimate stayed on the anchor since a
        #: far leader was first held back (-1: none)
        self._confirm_window = -1
        #: the odometry's travel (m) and turning (rad) since the filter started
        self._moved = (0.0, 0.0)
        #: departure 44: the odometry's travel (m) at the last update that weighed a lone
        #: species (None: none yet, or several species lived since), and the travel counted
        #: since a scan last showed surfaces facing along the track
        self._track: tuple[float | None, float] = (None, 0.0)
        #: departure 18, this update: the anchor as the estimate, its place's share of the
        #: weight when it was held against a leader the species read LOCALISED (the state then
        #: says AMBIGUOUS), and the share of the scan the map explains at a leader held back
        #: because the map does not vouch for it (departure 23; NaN: not held back for that)
        self._held: tuple[int, PoseEstimate | None, float | None, float] = _NOT_HELD
        #: the update and the species whose mean was its estimate (-1: the anchor; departure
        #: 18), and that mean carried on by the odometry since (departure 25; None: the
        #: estimate was the anchor, or a species read LOST)
        self._estimate_from: tuple[int, int, NDArray[np.float64] | None] = _NO_ESTIMATE

    # ================================================================== initialisation
    def initialise_global(self, scan: LaserScan) -> CEAMCLRecord:
        """Initial species generation (section 3.1) from the first scan."""
        check_scan(scan)
        self.t = 0
        self.map_agreement.reset()
        self.last_scan = scan
        self._forget_estimates()
        self.events = Events()
        self._evaluations = 0
        self._initialise_from(usable(self.sensor, scan))
        self._initialised = True
        if self.config.init_is_a_search:  # departure 30
            self._lost_wait = 2 * (self.config.recovery_lost_updates or 0)
        return self._record(reinitialised=False)

    def _initialise_from(
        self,
        prepared: PreparedScan | None,
        *,
        kept: tuple[ParticleSet, dict[int, float], dict[int, float]] | None = None,
        prior: float = 1.0,
        settings: InitialisationConfig | None = None,
    ) -> None:
        """Section 3.1 (:func:`~ceamcl.filters.ceamcl.initialisation.initial_species`) with
        a scan's usable beams (none: the species spread uniformly over free space). ``kept``:
        particles of earlier species to keep beside the new ones, with each species' log
        evidence in the scale of the new species' log-likelihoods and the handicaps they hold
        (which they keep); the new species then start
        at ``prior`` times their own evidence, or at their own evidence when near a kept
        species, a handicap kept apart in ``log_prior`` unless ``recovery_prior_fades``
        (:meth:`_recover`, :meth:`_recovery_handicaps`). ``settings``: section 3.1's (``None``:
        the global initialisation's; a recovery passes ``recovery_initialisation``)."""
        self._fit_fast = self._fit_slow = None
        self._steps_since_init = 0
        self._lost_streak = 0
        self._read = None
        self._peak_fitness = {}
        settings = self.config.initialisation if settings is None else settings
        # a scan without usable beams spreads the species uniformly: no heading density to draw
        headings = heading_proposal(
            self.grid, self.last_scan if prepared is not None else None, settings
        )
        # Departure 29: a ray-casting filter's global search scores its test poses with the
        # field and its own model judges the best of them; a recovery (``kept``) searches with
        # its own model (searched with the field, recoveries lost fr079's track at every scan).
        search, searched, judge = self.sensor, prepared, None
        field = self._search_sensor()
        if kept is None and prepared is not None and field is not self.sensor:
            field_scan = usable(field, self.last_scan)
            if field_scan is not None:  # else no beam the field can use: our own model
                search, searched, judge = field, field_scan, (self.sensor, prepared)
        init, evaluations = initial_species(
            self.grid, search, searched, settings, self.rng, headings, judge
        )
        self.initial = init
        # Not in the paper: a few greedy moves bring each chosen test pose nearer its peak
        # (docs/ceamcl.md, "test poses"); ``self.initial`` keeps section 3.1's own choice.
        poses, loglik, spent = polish(
            init.poses,
            init.loglik,
            self.sensor,
            prepared,
            settings,
            self.rng,
        )
        self._evaluations += evaluations + spent
        # ids are never reused: after a restart the new species count on from the old ones
        first = self._next_id
        labels = init.labels.astype(np.int64) + first
        self.particle_set = ParticleSet.from_poses(poses, labels)
        self.particle_set.loglik = loglik
        self.particle_set.fitness = (
            fitness(loglik, prepared, self.sensor)
            if spent and prepared is not None
            else init.fitness
        )
        self._next_id = first + init.n_species
        self._prepared = prepared
        # "for each species i, let dN_0 / dt = 0": competition starts after the first step.
        sids = range(first, self._next_id)
        self.competition = Competition({sid: 0.0 for sid in sids})
        # each species' evidence so far: how well it can explain the first scan, its best
        # sample's likelihood raised by the climb every later update makes (departure 43)
        self.log_weight = {}
        members = label_groups(labels)
        best_seen = None
        if self.config.evidence_climb_at_start and prepared is not None and prepared.n_beams:
            best_seen = loglik.copy()
            held = self._peaks  # the climb records the new species' peaks only
            self._evaluations += self._probe_peaks(members, best_seen, prepared, _STANDING)
            # a recovery's kept species keep theirs, from which their next climb starts
            self._peaks = {**held, **self._peaks}
        self._accumulate_evidence(members, memory=0.0, best_seen=best_seen)
        self.log_prior = {}
        if kept is not None:
            old, evidence, old_priors = kept
            # one x-y region can hold a place at several headings (below): split first, so
            # that each part is near the old species or not by its own mean pose
            self._split_and_merge()
            finite = loglik[np.isfinite(loglik)]
            # back to the log-likelihoods' scale (the largest new species' evidence is 0 now)
            scale = float(np.max(finite)) if finite.size else -np.inf
            handicap = self._recovery_handicaps(old, float(np.log(prior)), old_priors)
            self.log_weight = {sid: v + scale + handicap[sid] for sid, v in self.log_weight.items()}
            if not self.config.recovery_prior_fades:
                self.log_prior = {sid: h for sid, h in handicap.items() if h < 0.0}
                self.log_prior.update(old_priors)
            self.log_weight.update(evidence)
            self.particle_set.extend(old)
            self.particle_set.log_weights = uniform_log_weights(self.particle_set.n)
            self.competition.dn.update({sid: 0.0 for sid in evidence})
            self._normalise_weights()
        self._fit_budget()
        # The paper clusters initial species in x-y only; one x-y region can hold a pose and
        # its mirror image (same place, other heading). Splitting now, before the first
        # resampling, keeps both as species instead of letting resampling pick one.
        self._split_and_merge()  # leaves self.stats fresh
        allocate_resources(
            self.stats, self.config.competition, self.competition, self._competition_fitness()
        )
        self.events.n0 += init.n0
        self.events.v_cells += init.v_size

    def _search_sensor(self) -> SensorModel:
        """The model that scores a search's test poses (``search_with_field``): the filter's
        own, or the likelihood field a ray-casting model searches with (made once)."""
        if not self.config.search_with_field:
            return self.sensor
        if self._search is None:
            self._search = search_model(self.sensor)
        return self._search

    def _recovery_handicaps(
        self, old: ParticleSet, log_prior: float, old_priors: dict[int, float]
    ) -> dict[int, float]:
        """Each new species' log prior against the species the filter had (``old``, holding
        the handicaps ``old_priors``): the smallest handicap of an old species whose mean lies
        within ``recovery_drift_m`` and ``recovery_drift_rad`` of its own (0 for one without,
        and for the anchor), ``log_prior`` where none does (docs/ceamcl.md, departures 9, 11
        and 21: a place near a far place that carried a handicap is that far place again).
        With ``recovery_drift_from_anchor`` and an anchor, an old species within reach of it
        passes its handicap on only to new species within reach of the anchor as well
        (departure 37, an option: a drift of a drift is not one)."""
        new = label_groups(self.particle_set.labels)
        reach = self.config.recovery_drift_m
        groups = label_groups(old.labels)
        olds = [pose_mean(old.poses[idx]) for idx in groups.values()]
        held = [old_priors.get(sid, 0.0) for sid in groups]
        confident = self.confident.anchor()
        if reach is None or not (olds or confident is not None):
            return {sid: log_prior for sid in new}
        b = np.array(olds).reshape(-1, 3)
        if confident is not None and not self._near(confident[0][None, :], b, reach).any():
            # where the odometry says the robot is since it was last localised, when no
            # species the filter still has stands there (departure 14)
            b = np.vstack([b, confident[0]])
            held.append(0.0)
        a = np.array([pose_mean(self.particle_set.poses[idx]) for idx in new.values()])
        close = self._close(a, b, reach)
        if confident is not None and self.config.recovery_drift_from_anchor:
            anchor = confident[0][None, :]
            anchors_own = self._near(b, anchor, reach)
            close &= ~anchors_own[None, :] | self._near(a, anchor, reach)[:, None]
        inherited = np.where(close, np.array(held)[None, :], -np.inf)
        best = inherited.max(axis=1)
        return {
            sid: float(h) if np.isfinite(h) else log_prior for sid, h in zip(new, best, strict=True)
        }

    def _close(
        self, a: NDArray[np.float64], b: NDArray[np.float64], reach: float
    ) -> NDArray[np.bool_]:
        """``(A, B)``: whether pose ``b[j]`` lies within ``reach`` metres and
        ``recovery_drift_rad`` of heading of pose ``a[i]``."""
        apart = np.hypot(a[:, None, 0] - b[None, :, 0], a[:, None, 1] - b[None, :, 1])
        turned = np.abs(angles.wrap(a[:, None, 2] - b[None, :, 2]))
        return np.asarray((apart <= reach) & (turned <= self.config.recovery_drift_rad))

    def _near(
        self, a: NDArray[np.float64], b: NDArray[np.float64], reach: float
    ) -> NDArray[np.bool_]:
        """For each pose of ``a``, whether a pose of ``b`` lies within ``reach`` metres and
        ``recovery_drift_rad`` of heading."""
        return np.asarray(self._close(a, b, reach).any(axis=1), dtype=np.bool_)

    def _forget_estimates(self) -> None:
        """A new start: no anchor, no count of updates beyond it, nothing held, no estimate
        for a leader to continue."""
        self.confident.reset()
        self._far_lost = (0, 0)
        self._coast = (0, None)
        self._unconfirmed_at = -1
        self._streak = (-1, 0.0, 0.0)
        self._confirm_window = -1
        self._held = _NOT_HELD
        self._estimate_from = _NO_ESTIMATE
        self._track = (None, 0.0)

    def initialise_pose(self, pose: ArrayLike, covariance: ArrayLike) -> None:
        """Pose tracking: one species of ``tracking_samples`` around a known pose."""
        sid = self._next_id
        self._read = None
        self._forget_estimates()
        self.particle_set = gaussian(pose, covariance, self.config.tracking_samples, self.rng)
        self.particle_set.labels[:] = sid
        self._next_id = sid + 1
        self._prepared = None
        self._full = None
        self.t = 0
        self.map_agreement.reset()
        self._refresh_stats()
        self.competition = Competition({sid: 0.0})
        self.log_weight = {sid: 0.0}
        self.log_prior = {}
        self._initialised = True

    def initialise_hypotheses(self, poses: ArrayLike, covariance: ArrayLike) -> None:
        """Several hypotheses at once (e.g. the known symmetric images of a start pose): one
        species of ``tracking_samples`` around each pose, with equal weights; fewer a species
        (not below ``min_species_size``) where that many would exceed ``max_samples``."""
        cfg = self.config
        centres = np.asarray(poses, dtype=np.float64)
        if centres.ndim not in (1, 2) or centres.shape[-1] != 3 or centres.size == 0:
            raise ConfigError(
                f"poses: expected one or more poses (x, y, theta), an array of shape (K, 3), "
                f"got shape {centres.shape}"
            )
        centres = centres.reshape(-1, 3)
        k = centres.shape[0]
        if k * cfg.min_species_size > cfg.max_samples:
            raise ConfigError(
                f"poses: {k} hypotheses of at least {cfg.min_species_size} samples exceed "
                f"max_samples {cfg.max_samples}; expected at most "
                f"{cfg.max_samples // cfg.min_species_size}"
            )
        each = max(cfg.min_species_size, min(cfg.tracking_samples, cfg.max_samples // k))
        parts = [gaussian(pose, covariance, each, self.rng) for pose in centres]  # checks first
        self._read = None
        self._forget_estimates()
        for part in parts:
            part.labels[:] = self._next_id
            self._next_id += 1
        ps = parts[0]
        for part in parts[1:]:
            ps.extend(part)
        self.particle_set = ps
        self._prepared = None
        self._full = None
        self.t = 0
        self.map_agreement.reset()
        self._refresh_stats()
        self.competition = Competition({sid: 0.0 for sid in self.stats})
        self.log_weight = {sid: 0.0 for sid in self.stats}
        self.log_prior = {}
        self._initialised = True

    # ================================================================== one step
    def step(self, increment: OdometryIncrement, scan: LaserScan | None) -> CEAMCLRecord:
        """One step of section 3.5 (see the module docstring)."""
        require_initialised(self, "step")
        check_step_arguments(increment, scan)
        check_increment(increment)  # before any phase changes the particles
        cfg = self.config
        ps = self.particle_set
        self.t += 1
        self._read = None
        if scan is not None:
            self.last_scan = scan
        self._evaluations = 0
        self.events = Events()
        self._peak_fitness = {}
        self._full = None
        prepared = usable(self.sensor, scan)
        # 1. Sample-size determination (the anchor's species kept while nothing fits).
        self._keep_anchor_species()
        targets, evaluations = grow(
            ps,
            self.stats,
            self.competition.dn,
            cfg.growth,
            self.sensor,
            self._prepared,
            self.events,
            self.rng,
        )
        self._evaluations += evaluations
        if ps.n == 0:
            return self._restart(prepared)  # every species died out
        # 2. Resampling inside each species (sizes from phase 1).
        members = resample_within_labels(ps, targets, self.rng)
        # 3. Prediction.
        propagate(ps, self.motion, increment, self.rng)
        self._moved = (
            self._moved[0] + abs(increment.trans),
            self._moved[1] + sum(increment.turns),
        )
        self.confident.carry(increment, self.config.recovery_anchor_m)
        at, source, last = self._estimate_from
        if last is not None:
            last = apply_increment(last, increment.rot1, increment.trans, increment.rot2)[0]
            self._estimate_from = (at, source, last)
        if prepared is None:
            # No information: sizes freeze (dN = 0) and the particles, just resampled, keep
            # equal weights (no evidence is counted twice at the next resampling).
            ps.loglik = np.zeros(ps.n)
            self._refresh_stats()
            self.competition.dn = {sid: 0.0 for sid in self.stats}
            return self._record(reinitialised=False)
        # 4. Weighting, all species in one likelihood call; while one species tracks the
        # robot, without the short readings it cannot explain (beam skipping, docs/ceamcl.md).
        full = prepared  # a restart generates species from every beam
        if cfg.beam_skip is not None and len(members) == 1:
            prepared, self.events.skipped_beams = skip_unexplained_beams(
                self.grid, (ps.poses[idx] for idx in members.values()), prepared, cfg.beam_skip
            )
        self._prepared = prepared
        self._full = full  # every beam: departure 18 judges the anchor on them
        self._evaluations += ps.n
        if not weigh(ps, self.sensor, prepared):
            return self._restart(full)  # every particle impossible under this scan
        best_seen = ps.loglik.copy()  # each sample's best, over its children too
        # 5. Evolution inside each species.
        groups = list(members.values())
        self._evaluations += evolve(
            ps, groups, cfg.evolution, self.sensor, prepared, self.rng, best_seen
        )
        # Evidence only compares species: a lone species' is normalised away, so it pays for
        # neither the climb nor the wall check.
        compared = len(members) > 1
        if compared:
            self._track = (None, 0.0)  # departure 44 counts a lone species' travel only
            self._evaluations += self._probe_peaks(members, best_seen, prepared, increment)
        else:
            self._peaks = {}  # no warm start for a lone species' climb
            along = self._track_reach(scan)  # departure 44, counted at every lone update
            # for the reported fitness (docs/state.md), or a track the scans could not place
            if self._fit_in_doubt(members) or along > 0.0:
                self._evaluations += self._probe_peaks(members, best_seen, prepared, increment)
                self._evaluations += self._look_around(members, full, increment)  # departure 12
                if along > 0.0 and not self.events.look_arounds:
                    self._evaluations += self._look_along(members, full, along)
        self._accumulate_evidence(
            members, self._memory_for(increment), best_seen, see_through=compared
        )
        # 6. Split and merge.
        self._split_and_merge(members, ps.loglik)  # leaves self.stats fresh
        collapsed = self._fitness_collapsed()  # both run: each keeps its own running record
        lost = self._lost_too_long()
        self._propose_anchor()
        if collapsed or lost:
            self.events.recoveries += 1
            self.confident.search()
            if cfg.recovery_prior is not None:
                return self._recover(full, increment)  # a second opinion (departure 9)
            return self._restart(full)  # kidnapped: no species explains the scans
        # 7. Competition: dN of every species for the next step.
        self.competition = compete(
            self.stats, cfg.competition, self._competition_fitness(), self._viable_floors()
        )
        return self._record(reinitialised=False)

    def _viable_floors(self) -> dict[int, int]:
        """Departure 13 (docs/ceamcl.md): the species that keep ``viable_size`` samples
        whatever eq. 9 says. While at least two species hold ``viable_weight_min`` of the
        weight each, a species qualifies when its fitness as the state reads it (fittest
        individual or climb peak) is within ``viable_fit_margin`` of the leading species'
        (not the best of any: one light species' lucky climb would strip the rest for an
        update, departure 24) and at least ``confirm_fit_below``, and has been at a running
        share of at least a half of the recent updates (``viable_memory`` an update, the
        share kept across updates in ``_equal_record``). Eq. 9 with ``alpha_ij = w_j / w_i``
        shrinks a species whose accumulated evidence fell behind a transient contest, even
        while it fits as well as its rivals again; now it lives while it does, and its weight
        is what its evidence says. Updates the record."""
        cfg = self.config
        margin = cfg.viable_fit_margin
        if margin is None or len(self.stats) < 2:
            self._equal_record = {}
            return {}
        stats, share = self._ranked_shares()
        if np.count_nonzero(share >= cfg.viable_weight_min) < 2:
            self._equal_record = {}
            return {}
        fit = {s.species_id: self._fit_read(s) for s in stats}
        bar = max(fit[stats[0].species_id] - margin, cfg.confirm_fit_below or 0.0)
        a = cfg.viable_memory
        equal = {sid: f >= bar for sid, f in fit.items()}
        self._equal_record = {
            sid: (1.0 - a) * self._equal_record.get(sid, 0.0) + a * float(ok)
            for sid, ok in equal.items()
        }
        return {
            sid: cfg.viable_size
            for sid, ok in equal.items()
            if ok and self._equal_record[sid] >= 0.5
        }

    def _propose_anchor(self) -> None:
        """Departure 14 (docs/ceamcl.md): at an update where the state (as the recovery reads
        it) says LOCALISED, the leading pose is proposed as the anchor a later recovery
        measures drift from (:meth:`_recovery_handicaps`); it becomes the anchor if the map
        explains this scan there (:class:`~ceamcl.filters.ceamcl.anchor.ConfidentPose`). A
        pose drifting in a room the map holds poorly is not one."""
        if self.config.recovery_anchor_m is None:
            return
        hyps, read = self._species_read()
        if read.state is State.LOCALISED and hyps:
            self.confident.propose(hyps[0].pose, self.last_scan, self.t)

    # ------------------------------------------------------------------ evidence
    def _probe_peaks(
        self,
        members: dict[int, NDArray[np.intp]],
        best_seen: NDArray[np.float64],
        prepared: PreparedScan,
        increment: OdometryIncrement,
    ) -> int:
        """A short greedy climb from each species' best sample, for its evidence only (the
        samples are not moved): ``evidence_rounds`` rounds of ``evidence_probes`` Gaussian
        probes (the mutation's Sigma) around the best pose so far; the best log-likelihood
        found raises ``best_seen`` at that sample; the probes' spread shrinks by
        ``evidence_shrink`` each round, so later rounds refine what the first found. Without
        it the evidence of a species would depend on how close its cloud happened to come to
        the likelihood's peak, noise that grows with the motion between updates, and a small
        species, with fewer samples near the peak, would lose to a large one at the same
        place (docs/ceamcl.md, "evidence"). With ``evidence_warm_start`` the climb starts
        from the better of the best sample and the species' last peak moved by ``increment``
        (when that lies within ``evidence_warm_gate`` mutation Sigmas of the best sample), so
        the peak found is refined from step to step instead of found again from each
        species' own samples (docs/ceamcl.md, departure 6). Returns the evaluations spent."""
        cfg = self.config
        k = cfg.evidence_probes
        if k == 0 or cfg.evidence_rounds == 0 or not members:
            return 0
        ps = self.particle_set
        sids = list(members)
        tops = np.array([int(idx[np.argmax(ps.loglik[idx])]) for idx in members.values()])
        centre = ps.poses[tops].copy()
        best = ps.loglik[tops].copy()
        ev = cfg.evolution
        sxy, sth = ev.mutation_sigma_xy_m, ev.mutation_sigma_theta_rad
        sigma = np.array([sxy, sxy, sth])
        evaluations = 0
        if cfg.evidence_warm_start:
            evaluations += self._start_from_last_peaks(
                sids, centre, best, cfg.evidence_warm_gate * sigma, increment, prepared
            )
        for _ in range(cfg.evidence_rounds):
            probes = centre[:, None, :] + self.rng.standard_normal((len(sids), k, 3)) * sigma
            probes[..., 2] = np.arctan2(np.sin(probes[..., 2]), np.cos(probes[..., 2]))
            ll = self.sensor.log_likelihood(probes.reshape(-1, 3), prepared).reshape(len(sids), k)
            ll = np.where(np.isnan(ll), -np.inf, ll)
            evaluations += ll.size
            j = np.argmax(ll, axis=1)
            rows = np.arange(len(sids))
            better = ll[rows, j] > best
            centre[better] = probes[rows[better], j[better]]
            best[better] = ll[rows[better], j[better]]
            sigma = sigma * cfg.evidence_shrink
        np.maximum.at(best_seen, tops, best)
        self._peaks = {sid: centre[r].copy() for r, sid in enumerate(sids)}
        peak_fit = fitness(best, prepared, self.sensor)
        self._peak_fitness = {sid: float(peak_fit[r]) for r, sid in enumerate(sids)}
        return evaluations

    def _look_around(
        self,
        members: dict[int, NDArray[np.intp]],
        full: PreparedScan,
        increment: OdometryIncrement,
    ) -> int:
        """Departure 12 (docs/ceamcl.md): a lone species that fits the scan poorly looks
        around its best pose before the state calls the robot lost. Every pose of a grid
        (``look_around_step_m``, ``look_around_step_rad``) within ``look_around_m`` plus
        ``look_around_gain`` times the odometry's translation (at most ``look_around_max_m``)
        and ``look_around_rad`` plus the gain times its rotation (at most
        ``look_around_max_rad``) is scored on every beam of the scan. When the best of them
        beats the species' best pose by ``look_around_margin`` in tempered log-likelihood
        (refined, also after both pay for their readings through the map's walls,
        ``see_through_margin_m``: departure 32) and fits as the state reads a lone species
        (fitness at least ``confirm_fit_below``, beam skipping at that pose), the worst
        ``look_around_share`` of the species' samples are drawn again around it (the
        mutation's Sigma) and the whole species is weighed again with the beams that pose
        keeps. The odometry can be wrong by more than the motion model's noise (a wheel slip,
        a reversing robot whose encoders report speed without sign), and the scan, which
        fits a pose nearby, says where the robot went: a local sensor reset (Lenser and
        Veloso 2000) in the neighbourhood the odometry leaves in doubt. Returns the
        evaluations spent."""
        cfg = self.config
        lone = self._lone_peak(members)
        if cfg.look_around_m is None or lone is None:
            return 0
        sid, idx, centre = lone
        radius, spread = look_around_reach(cfg, increment)
        near = min(3.0 * cfg.look_around_rad, spread)  # the first search's turn
        offsets = _look_around_offsets(
            radius, cfg.look_around_step_m, near, cfg.look_around_step_rad
        )
        found, evaluations, here = self._search_around(centre, offsets, full, None)
        if found is None and spread > near:
            # departure 42: nothing near fits clearly better; the turns beyond, out to the reach
            wide = _look_around_offsets(
                radius, cfg.look_around_step_m, spread, cfg.look_around_step_rad
            )
            wide = wide[np.abs(wide[:, 2]) > near + 0.5 * cfg.look_around_step_rad]
            if wide.size:  # none when the reach adds less than a step of turn
                found, more, _ = self._search_around(centre, wide, full, here)
                evaluations += more
        if found is None:
            return evaluations
        return evaluations + self._redraw_around(sid, idx, found)

    def _lone_peak(
        self, members: dict[int, NDArray[np.intp]]
    ) -> tuple[int, NDArray[np.intp], NDArray[np.float64]] | None:
        """The lone species' id, its samples and where a look around it starts: its last peak,
        or its fittest sample (departures 12 and 44); ``None`` when it has no samples."""
        ((sid, idx),) = members.items()
        if idx.size == 0:
            return None
        ps = self.particle_set
        top = int(idx[np.argmax(ps.loglik[idx])])
        return sid, idx, self._peaks.get(sid, ps.poses[top])

    def _redraw_around(
        self,
        sid: int,
        idx: NDArray[np.intp],
        found: tuple[NDArray[np.float64], float, PreparedScan],
    ) -> int:
        """What a look-around that found a pose does (departures 12 and 44): the worst
        ``look_around_share`` of species ``sid``'s samples (``idx``) are drawn again around it
        with the mutation's Sigma and the species is weighed again with the beams that pose
        keeps. Returns the evaluations spent."""
        ps = self.particle_set
        pose, fit, there = found
        k = max(1, round(self.config.look_around_share * idx.size))
        worst = idx[np.argsort(ps.loglik[idx], kind="stable")[:k]]
        ps.poses[worst] = self._mutation_cloud(pose, k)
        ps.loglik[idx] = sanitise_log_likelihood(self.sensor.log_likelihood(ps.poses[idx], there))
        ps.fitness[idx] = fitness(ps.loglik[idx], there, self.sensor)
        self._prepared = there
        self._peaks[sid] = pose.copy()
        self._peak_fitness[sid] = fit
        self.events.look_arounds += 1
        return int(idx.size)

    def _track_reach(self, scan: LaserScan | None) -> float:
        """Departure 44 (docs/ceamcl.md): how far a lone species should look along its track
        at this update (0: not at all). The odometry's travel is counted while fewer than
        ``track_facing_m`` metres of the scan's surfaces face along the robot's axis (a
        corridor's side walls face across it, so nothing in the scans says how far along the
        robot is and the species may have drifted along it unnoticed); the travel up to a scan
        that shows that many is not counted, the reach is then ``track_drift_sd`` standard
        deviations of the odometry's drift over the count (departure 15's drift a metre, at most
        ``track_look_max_m``), and the count falls to ``track_drift_decay`` of itself."""
        cfg = self.config
        sd = cfg.track_drift_sd
        if sd is None or scan is None:
            return 0.0
        last, unseen = self._track
        travel = self._moved[0]
        if facing_length(scan, _SURFACES, _FACING_RAD) < cfg.track_facing_m:
            # the travel up to this scan was not placed along the track
            self._track = (travel, unseen if last is None else unseen + travel - last)
            return 0.0
        self._track = (travel, cfg.track_drift_decay * unseen)
        reach = min(cfg.track_look_max_m, sd * DRIFT_SD_M_PER_M * unseen)
        return reach if reach >= cfg.track_look_min_m else 0.0

    def _look_along(
        self, members: dict[int, NDArray[np.intp]], full: PreparedScan, reach: float
    ) -> int:
        """Departure 44: the lone species scores, on every beam, poses along its best pose's
        heading within ``reach`` metres ahead and behind, ``look_around_step_m`` apart, each
        also a step to either side and ``look_around_step_rad`` either way, and moves as
        departure 12's look-around does when its test accepts one. Returns the evaluations
        spent."""
        lone = self._lone_peak(members)
        if lone is None:
            return 0
        sid, idx, centre = lone
        found, evaluations, _ = self._search_around(
            centre, _along_offsets(centre[2], reach, self.config), full, None
        )
        if found is None:
            return evaluations
        return evaluations + self._redraw_around(sid, idx, found)

    def _search_around(
        self,
        centre: NDArray[np.float64],
        offsets: NDArray[np.float64],
        full: PreparedScan,
        here: float | None,
    ) -> tuple[tuple[NDArray[np.float64], float, PreparedScan] | None, int, float]:
        """One grid of :meth:`_look_around`: the poses ``centre + offsets`` scored on every
        beam; the best, refined on a grid a quarter as fine, is found when it beats the centre
        (``here``, its tempered log-likelihood; ``None``: read from the grid, which holds the
        centre) by ``look_around_margin``, also once both pay for their readings through
        walls, and fits as the state reads a lone species. Returns the found pose with its
        fitness and the beams it keeps (or ``None``), the evaluations, and ``here``."""
        cfg = self.config
        cands = centre + offsets
        cands[:, 2] = angles.wrap(cands[:, 2])
        ll = sanitise_log_likelihood(self.sensor.log_likelihood(cands, full))
        evaluations = int(ll.size)
        if here is None:
            here = float(ll[np.flatnonzero(~offsets.any(axis=1))[0]])
        if not ll.max() - here >= cfg.look_around_margin:
            return None, evaluations, here
        # refine the best grid pose on a grid a quarter as fine, then ask that it fits
        coarse = cands[int(np.argmax(ll))]
        fine = coarse + _look_around_offsets(
            0.5 * cfg.look_around_step_m * np.sqrt(2.0),
            0.25 * cfg.look_around_step_m,
            0.5 * cfg.look_around_step_rad,
            0.25 * cfg.look_around_step_rad,
        )
        fine[:, 2] = angles.wrap(fine[:, 2])
        lf = sanitise_log_likelihood(self.sensor.log_likelihood(fine, full))
        evaluations += int(lf.size)
        found = fine[int(np.argmax(lf))]
        # departure 32: the found pose beats the species' best by the margin once both pay for
        # the readings they send through the map's walls, as the evidence weighs them
        lost = self._through_walls(np.vstack([found, centre]))
        if (float(lf.max()) + lost[0]) - (here + lost[1]) < cfg.look_around_margin:
            return None, evaluations, here
        # the found pose's fitness as the state reads a lone species': without the short
        # readings it cannot explain (beam skipping)
        there = full
        if cfg.beam_skip is not None:
            there, _ = skip_unexplained_beams(self.grid, [found[None, :]], full, cfg.beam_skip)
        lt = sanitise_log_likelihood(self.sensor.log_likelihood(found[None, :], there))
        fit = float(fitness(lt, there, self.sensor)[0])
        evaluations += 1
        bar = cfg.confirm_fit_below if cfg.confirm_fit_below is not None else 0.0
        if fit < bar:
            return None, evaluations, here
        return (found, fit, there), evaluations, here

    def _through_walls(self, poses: NDArray[np.float64]) -> NDArray[np.float64]:
        """Per pose, what the last scan's readings through the map's walls cost it in tempered
        log-likelihood (``see_through_margin_m``, ``see_through_tolerance``; departure 4): the
        evidence's penalty, 0 when the check is off or no scan was seen."""
        margin = self.config.see_through_margin_m
        if margin is None or self.last_scan is None:
            return np.zeros(len(poses))
        return see_through_penalty(
            self.grid,
            self.sensor,
            poses,
            self.last_scan,
            margin,
            self.config.see_through_tolerance,
        )

    def _mutation_cloud(self, centre: NDArray[np.float64], n: int) -> NDArray[np.float64]:
        """``n`` poses around ``centre`` with the mutation's Sigma, the first on ``centre``
        (departures 12 and 19)."""
        ev = self.config.evolution
        sigma = [ev.mutation_sigma_xy_m, ev.mutation_sigma_xy_m, ev.mutation_sigma_theta_rad]
        poses = gaussian_poses(centre, np.diag(np.square(sigma)), n, self.rng)
        poses[0] = centre
        return poses

    def _fit_in_doubt(self, members: dict[int, NDArray[np.intp]]) -> bool:
        """Whether a lone species' fittest individual scores below ``confirm_fit_below``:
        before the state calls the robot lost for it, the evidence climb looks for a pose of
        the species that fits (docs/state.md)."""
        bar = self.config.confirm_fit_below
        if bar is None or not members:
            return False
        (idx,) = members.values()
        return bool(idx.size) and float(np.max(self.particle_set.fitness[idx])) < bar

    def _start_from_last_peaks(
        self,
        sids: list[int],
        centre: NDArray[np.float64],
        best: NDArray[np.float64],
        gate: NDArray[np.float64],
        increment: OdometryIncrement,
        prepared: PreparedScan,
    ) -> int:
        """Departure 6: each species' last peak, moved by ``increment``, replaces its climb's
        start (``centre``, ``best``, updated in place) when it lies within ``gate`` of it in
        every coordinate and scores higher. Returns the evaluations spent."""
        held = np.array([r for r, sid in enumerate(sids) if sid in self._peaks], dtype=np.intp)
        if held.size == 0:
            return 0
        carried = apply_increment(
            np.array([self._peaks[sids[r]] for r in held]),
            increment.rot1,
            increment.trans,
            increment.rot2,
        )
        gap = np.abs(carried - centre[held])
        gap[:, 2] = np.abs(angles.diff(carried[:, 2], centre[held, 2]))
        near = np.all(gap <= gate, axis=1)
        rows, carried = held[near], carried[near]
        if rows.size == 0:
            return 0
        ll = self.sensor.log_likelihood(carried, prepared)
        ll = np.where(np.isnan(ll), -np.inf, ll)
        better = ll > best[rows]
        centre[rows[better]] = carried[better]
        best[rows[better]] = ll[better]
        return int(ll.size)

    def _memory_for(self, increment: OdometryIncrement) -> float:
        """``evidence_memory`` per step of up to ``evidence_memory_step_m`` of travel and
        ``evidence_memory_step_rad`` of turning; a longer step (updates paced by
        ``update_min_d``, docs/ceamcl.md departure 6) fades the past as that many steps would:
        ``memory ** max(1, trans / step_m, |turn| / step_rad)``."""
        cfg = self.config
        if cfg.evidence_memory_step_m is None or cfg.evidence_memory_step_rad is None:
            return cfg.evidence_memory
        turn = abs(float(angles.wrap(increment.rot1 + increment.rot2)))
        steps = max(
            1.0,
            abs(increment.trans) / cfg.evidence_memory_step_m,
            turn / cfg.evidence_memory_step_rad,
        )
        return float(cfg.evidence_memory**steps)

    def _accumulate_evidence(
        self,
        members: dict[int, NDArray[np.intp]],
        memory: float,
        best_seen: NDArray[np.float64] | None = None,
        *,
        see_through: bool = False,
    ) -> None:
        """Each species' log-weight becomes ``memory`` times itself plus the scan's evidence
        for it: the largest log-likelihood of any pose the step scored for it (its samples,
        and with ``best_seen`` every child evolution tried, kept or not), i.e. how well the
        species *can* explain the scan, not how well its cloud happens to sit this step
        (docs/ceamcl.md, "evidence"); then the largest is set to 0. With ``see_through`` (and
        ``see_through_margin_m`` set) that best sample also pays for the last scan's readings
        that pass through the map's walls from it (:mod:`ceamcl.sensors.see_through`)."""
        ll = self.particle_set.loglik if best_seen is None else best_seen
        living = {sid: idx for sid, idx in members.items() if idx.size}
        top = {sid: float(np.max(ll[idx])) for sid, idx in living.items()}  # never +inf
        if see_through and self.config.see_through_margin_m is not None and top:
            # the samples at each species' best (a crossover pair shares its children's)
            best = [idx[ll[idx] == top[sid]] for sid, idx in living.items()]
            penalty = self._through_walls(self.particle_set.poses[np.concatenate(best)])
            ends = np.cumsum([b.size for b in best])
            top = {
                sid: v + float(np.max(part))
                for (sid, v), part in zip(top.items(), np.split(penalty, ends[:-1]), strict=True)
            }
        for sid in members:
            gain = top.get(sid, -np.inf)
            held = self.log_prior.get(sid, 0.0)  # not faded (departure 11)
            self.log_weight[sid] = memory * (self.log_weight.get(sid, 0.0) - held) + held + gain
        self._normalise_weights()

    def _normalise_weights(self, living: bool = False) -> None:
        """The largest log-weight 0 (all 0 when none is finite); with ``living``, only the
        species in ``stats`` keep one (a species new to them starts at 0, the leader's), and
        a handicap in ``log_prior`` stays while another species lives."""
        if living:
            lw = {sid: self.log_weight.get(sid, 0.0) for sid in self.stats}
            # a prior is odds against the other species: with none left, nothing is held
            held = {sid: v for sid, v in self.log_prior.items() if sid in self.stats}
            self.log_prior = held if len(self.stats) > 1 else {}
        else:
            lw = dict(self.log_weight)
        top = max(lw.values(), default=0.0)
        if not np.isfinite(top):
            self.log_weight = {sid: 0.0 for sid in lw}
            return
        self.log_weight = {sid: max(v - top, LOG_WEIGHT_FLOOR) for sid, v in lw.items()}

    def _competition_fitness(self) -> dict[int, float] | None:
        """The ``w`` of eqs. 9 and 16 by species: the accumulated evidence relative to the
        leading species, or ``None`` for the current scan's mean fitness ("scan")."""
        if self.config.competition_fitness == "scan":
            return None
        return {sid: float(np.exp(self.log_weight.get(sid, 0.0))) for sid in self.stats}

    def _fitness_collapsed(self) -> bool:
        """Kidnap detection (docs/ceamcl.md): fast and slow running averages of the fittest
        species' fitness, as augmented MCL keeps of the mean weight; the robot is lost when
        the fast one falls below ``recovery_ratio`` times the slow one. Fitness lies in (0, 1]
        and is comparable between steps, so the test does not depend on the scan's size. A
        species' fitness is read as the state reads it (``recovery_reads="fittest"``: its
        fittest individual, or its climb's peak; departure 26), or as its mean
        (``"mean"``)."""
        cfg = self.config
        read = (lambda s: s.fitness) if cfg.recovery_reads == "mean" else self._fit_read
        best = max((read(s) for s in self.stats.values()), default=0.0)
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

    def _fit_read(self, s: SpeciesStats) -> float:
        """A species' fitness as the state reads it (:func:`_reported_fitness`, with this
        step's climb), NaN read as 0: what the viable floors and the kidnap test compare."""
        return float(np.nan_to_num(_reported_fitness(s, self._peak_fitness.get(s.species_id))))

    def _species_read(self) -> tuple[list[Hypothesis], LocalisationState]:
        """This update's hypotheses and the state the species read from them, without the
        map's agreement: read once and kept (``_read``) for what the runner (or a node) asks
        next, until the species change."""
        if self._read is None:
            hyps = self.hypotheses()
            self._read = (hyps, self._read_state(hyps))
        return self._read

    def _lost_too_long(self) -> bool:
        """Has the state said LOST at ``recovery_lost_updates`` consecutive updates (the
        wait doubled after each recovery this fired, until the state leaves LOST)?
        (docs/ceamcl.md, departure 10.) Read after split and merge, as the runner reads it."""
        cfg = self.config
        if cfg.recovery_lost_updates is None or not cfg.recovery:
            return False
        # without the map's agreement (docs/state.md): the recovery does not need it
        _, state = self._species_read()
        if state.state is not State.LOST:
            self._lost_streak = 0
            self._lost_wait = cfg.recovery_lost_updates
            return False
        self._lost_streak += 1
        if self._lost_streak < self._lost_wait:
            return False
        self._lost_wait *= 2
        return True

    def _recover(self, prepared: PreparedScan, increment: OdometryIncrement) -> CEAMCLRecord:
        """The kidnap test fired: global initialisation from the step's scan, the species the
        filter had kept beside the new ones (docs/ceamcl.md, departure 9). The old species are
        scored with the whole scan (a lone species was weighed without the beams it skipped)
        and climb from their best samples, as the new species' test poses were polished; each
        keeps its accumulated evidence, and each new species starts at ``recovery_prior``
        times the leading old species' weight before this scan's evidence, or level with it
        within ``recovery_drift_m`` / ``recovery_drift_rad`` of an old species (a drift, not
        a kidnap: departure 11). A robot that was
        carried off is found again within a few scans, as the old species keep failing; a
        scan or two that the map explains poorly no longer hands the estimate to whichever
        place of the building fits that one scan best."""
        prior = self.config.recovery_prior
        assert prior is not None
        old = self.particle_set
        members = label_groups(old.labels)
        weigh(old, self.sensor, prepared)
        old.fitness = fitness(old.loglik, prepared, self.sensor)
        spent = old.n
        best_seen = old.loglik.copy()
        spent += self._probe_peaks(members, best_seen, prepared, increment)
        gains = {sid: float(np.max(best_seen[idx])) for sid, idx in members.items() if idx.size}
        past = {sid: self.log_weight.get(sid, 0.0) for sid in gains}
        lead = max(past, key=lambda sid: past[sid], default=None)
        kept = None
        if lead is not None and np.isfinite(gains[lead]):
            # evidence in the new species' scale: the leader's relative weight is 0
            kept = (
                old,
                {sid: v + gains[lead] for sid, v in past.items()},
                {sid: h for sid, h in self.log_prior.items() if sid in past},
            )
        self._initialise_from(
            prepared,
            kept=kept,
            prior=prior,
            settings=self.config.recovery_initialisation,
        )
        self._evaluations += spent
        self.events.restarts += 1
        return self._record(reinitialised=True)

    def _restart(self, prepared: PreparedScan | None) -> CEAMCLRecord:
        """Every species died out (or every particle is impossible, or the robot was
        kidnapped): global initialisation again, from the step's scan or, without one,
        uniformly over free space; recorded as ``reinitialised`` and ``restarts``."""
        self._initialise_from(prepared)
        self.events.restarts += 1
        return self._record(reinitialised=True)

    # ------------------------------------------------------------------ 6. split and merge
    def _split_and_merge(
        self,
        members: dict[int, NDArray[np.intp]] | None = None,
        scores: NDArray[np.float64] | None = None,
    ) -> None:
        """Split, then merge (``members``: the particles of each species when already known,
        as :func:`~ceamcl.filters.resampling.label_groups` gives them); on return
        ``self.stats`` describes the current particles. Each part of a split species keeps
        the species' past evidence; with ``scores`` (each sample's log-likelihood for the
        step's scan) a part whose best sample scores below the species' best loses the
        difference from the step's evidence: the part that holds the best sample (and the
        climb from it) keeps the species' weight, the others fall behind by what their own
        samples show (docs/ceamcl.md, "a split part's own evidence")."""
        ps = self.particle_set
        if members is None:
            members = label_groups(ps.labels)
        new_ids, shortfall = split(
            ps, members, self.config.split_merge, self._next_id, self.events, scores
        )
        for sid, parent in new_ids.items():
            self.competition.dn[sid] = 0.0
            self.log_weight[sid] = self.log_weight.get(parent, 0.0)  # the parent's past
            if parent in self.log_prior:
                self.log_prior[sid] = self.log_prior[parent]
            if parent in self._equal_record:
                self._equal_record[sid] = self._equal_record[parent]
            self._peaks.pop(parent, None)  # the peak may lie in either part
        for sid, short in shortfall.items():
            self.log_weight[sid] = self.log_weight.get(sid, 0.0) + short
        if scores is not None:
            # the climb's peak belongs to the part that holds the species' best sample
            for parent in set(new_ids.values()) & set(self._peak_fitness):
                parts = [parent] + [c for c, p in new_ids.items() if p == parent]
                holder = next((p for p in parts if shortfall.get(p) == 0.0), parent)
                self._peak_fitness[holder] = self._peak_fitness.pop(parent)
        self._next_id += len(new_ids)
        self._refresh_stats()
        self._merge()
        self._normalise_weights(living=True)

    def _merge(self) -> None:
        if self._prepared is None:
            return  # no scan to probe the fitness between two species: no evidence to merge
        merged, evaluations = merge(
            self.particle_set,
            self.stats,
            self.competition.dn,
            self.config.split_merge,
            self.sensor,
            self._prepared,
            self.events,
            self.log_weight,
            self.log_prior,
        )
        self._evaluations += evaluations
        if merged:
            self._refresh_stats()

    # ------------------------------------------------------------------ bookkeeping
    def _refresh_stats(self) -> None:
        self.stats = species_stats(self.particle_set)

    def _record(self, reinitialised: bool) -> CEAMCLRecord:
        self._count_far_lost()
        # The map's agreement counts the updates it does not vouch for only where the state is
        # read; read here, at every update, so that what the filter reports next (the estimate
        # while lost, departure 17) does not depend on whether a caller asked for the state.
        # The read is kept: a caller's state() and hypotheses() reuse it.
        self._species_state()
        comp = self.competition
        ranked, shares = self._ranked_shares()
        share = {s.species_id: float(w) for s, w in zip(ranked, shares, strict=True)}
        species = tuple(
            SpeciesRecord(
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
                weight=float(share.get(sid, 0.0)),
            )
            for sid, s in self.stats.items()
        )
        return CEAMCLRecord(
            resampled=self.t > 0,
            likelihood_evaluations=self._evaluations,
            reinitialised=reinitialised,
            species=species,
            n_species=len(species),
            total_resources=float(sum(comp.resources.values())),
            events=replace(self.events),
        )

    # ================================================================== queries
    def fittest(self) -> SpeciesStats | None:
        """The leading species: the largest accumulated evidence (ties: the fitter now)."""
        if not self.stats:
            return None
        return max(self.stats.values(), key=self._rank_key)

    def _rank_key(self, s: SpeciesStats) -> tuple[float, float]:
        if self.config.competition_fitness == "scan":
            return (s.fitness, 0.0)
        return (self.log_weight.get(s.species_id, 0.0), s.fitness)

    def estimate(self) -> PoseEstimate:
        """The leading species' mean and covariance; while the state says LOST and the
        leading species has left the last confident pose carried on by the odometry (the
        anchor), that pose (``coast_when_lost``). "Left": beyond the odometry's drift envelope
        of the anchor at ``coast_after_updates`` consecutive updates with the state LOST
        (departure 17, ``anchor_envelope_sd``), a species sliding where the map holds little,
        and from then on while the state says LOST, for a while (departure 39,
        ``coast_while_lost_m``);
        without an envelope, after a recovery and beyond ``recovery_drift_m`` (or
        ``recovery_drift_rad``), another place the recovery proposed (departure 15)."""
        require_initialised(self, "estimate")
        best = self.fittest()
        if best is None:
            return PoseEstimate(np.zeros(3), np.diag([1e6, 1e6, np.pi**2]))
        cfg = self.config
        if cfg.coast_when_lost and self.t > 0:
            if cfg.anchor_envelope_sd is not None:
                # counted at the end of this update (_count_far_lost): no test repeated here
                at, run = self._far_lost
                left = (
                    self._left_anchor(best) or self._coasting_while_lost()
                    if at == self.t and run >= cfg.coast_after_updates
                    else None
                )
                if left is not None:
                    return left
                at, held, _, _ = self._held  # judged at the end of this update (_count_far_lost)
                if at == self.t and held is not None:
                    return PoseEstimate(held.pose.copy(), held.covariance.copy())
            else:  # departure 15: the state is read only when the leader has left the anchor
                left = self._left_anchor(best)
                if left is not None and self.state().state is State.LOST:
                    return left
        return self.estimate_of(best)

    def estimate_of(self, best: SpeciesStats) -> PoseEstimate:
        """The estimate a species gives when it leads (what :meth:`estimate` reports unless
        the filter coasts on its anchor): its mean, as its hypothesis has it (the default,
        ``estimate_likelihood="tempered"``), or its samples' mean weighted by the scan's
        untempered likelihood (``"full"``, departure 35); its covariance."""
        covariance = best.covariance.copy()
        temper = self.sensor.temper
        if self.config.estimate_likelihood == "tempered" or temper >= 1.0:
            return PoseEstimate(best.mean.copy(), covariance)
        ps = self.particle_set
        # the tempering undone; nothing finite to read (impossible everywhere): the mean
        _, weights, ok = normalise_log_weights(ps.loglik[best.members] / temper)
        if not ok:
            return PoseEstimate(best.mean.copy(), covariance)
        return PoseEstimate(pose_mean(ps.poses[best.members], weights), covariance)

    def _coasting_while_lost(self) -> PoseEstimate | None:
        """Departure 39's anchor as this update's estimate: set by :meth:`_count_far_lost`
        when the estimate coasted at the last update, the state still says LOST and the
        leader is back within the envelope; else ``None``."""
        at, est = self._coast
        return est if at == self.t else None

    def _left_anchor(self, best: SpeciesStats) -> PoseEstimate | None:
        """The anchor as an estimate when the leading species ``best`` stands beyond its
        reach (the drift envelope, or departure 15's ``recovery_drift_m``), else ``None``."""
        coasting = self.confident.coasting(self.config.recovery_drift_m)
        if coasting is None:
            return None
        pose, covariance, reach = coasting
        if reach is not None and self._near(best.mean[None, :], pose[None, :], reach)[0]:
            return None
        return PoseEstimate(pose, covariance)

    def _fits_as_well(self, best: SpeciesStats, near: float, lead: float) -> bool:
        """Whether the best pose near the anchor (tempered log-likelihood ``near``, every
        beam) fits within ``anchor_hold_margin`` of the leading species ``best`` (its best
        sample's ``lead``), and, when ``best`` is a recovery's far place, within its handicap
        as well (departures 18 and 19)."""
        margin = self.config.anchor_hold_margin
        if margin is None:
            return False
        return near >= lead - margin + self.log_prior.get(best.species_id, 0.0)

    def _score_anchor(self, best: SpeciesStats, anchor: NDArray[np.float64]) -> _Scored | None:
        """The pose of a grid around the anchor (:data:`HOLD_RADIUS_M`, :data:`HOLD_RAD`)
        that fits this update's scan best, on every beam, its tempered log-likelihood and the
        best of the leading species' samples; ``None`` without a scan. Scored once an update
        for a pose and a leader."""
        full = self._full
        if full is None:
            return None
        key = (self.t, anchor.tobytes(), best.species_id, self.particle_set.n)
        if self._anchor_scored is not None and self._anchor_scored[0] == key:
            return self._anchor_scored[1]
        near = anchor + _HOLD_OFFSETS
        near[:, 2] = angles.wrap(near[:, 2])
        leader = self.particle_set.poses[best.members]
        ll = sanitise_log_likelihood(self.sensor.log_likelihood(np.vstack([near, leader]), full))
        self._evaluations += int(ll.size)
        k = near.shape[0]
        i = int(np.argmax(ll[:k]))
        scored = (near[i].copy(), float(ll[i]), float(ll[k:].max()))
        self._anchor_scored = (key, scored)
        return scored

    def _anchor_fits_better(self, step: int, pose: NDArray[np.float64]) -> bool:
        """Departure 38's contest (``anchor_returns``): whether, at this update (``step``),
        the best pose around the anchor's ``pose`` fits the scan better than the leading
        species' best sample, on every beam. ``False`` at another update, without a scan or
        a leader, for a leader whose mean fitness reaches ``anchor_returns`` (it fits), or
        with the departure off."""
        best = self.fittest()
        if step != self.t or best is None or not self._in_doubt(best):
            return False
        judged = self._score_anchor(best, np.asarray(pose, dtype=np.float64))
        return judged is not None and judged[1] > judged[2]

    def _in_doubt(self, best: SpeciesStats) -> bool:
        """Departure 38's gate: whether the leader ``best`` fits below ``anchor_returns`` (its
        mean fitness; ``None``: the departure is off)."""
        below = self.config.anchor_returns
        return below is not None and best.fitness < below

    def _anchor_place_returns(
        self, best: SpeciesStats | None, moved_on: bool
    ) -> SpeciesStats | None:
        """Departure 38 (``anchor_returns``, with ``anchor_species``), at the end of an
        update: while an anchor is held, the leader that continues the estimate (departures 18
        and 19 judge the others) fits below ``anchor_returns``, stands more than
        :data:`CHAIN_M` from the anchor and no species does within ``CHAIN_M`` of it, the best
        pose around the anchor that out-fits the leader's best sample by
        ``anchor_hold_margin`` starts a species, at the leader's weight plus the difference
        of their fits (departure 19's start). The leader after it."""
        cfg = self.config
        margin = cfg.anchor_hold_margin
        if (
            best is None
            or not moved_on
            or not self._in_doubt(best)
            or margin is None
            or cfg.anchor_envelope_sd is None
        ):
            return best
        coasting = self.confident.coasting(cfg.recovery_drift_m)
        if coasting is None:
            return best
        anchor = coasting[0]
        if not float(position_error(best.mean, anchor)) > CHAIN_M:
            return best
        if not self._anchor_vacant(anchor, CHAIN_M):
            return best
        judged = self._score_anchor(best, anchor)
        if judged is None or judged[1] < judged[2] + margin:
            return best
        pose, near, lead = judged
        self._sprout(pose, self.log_weight.get(best.species_id, 0.0) + near - lead)
        return self.fittest()

    def _fit_budget(self) -> bool:
        """``max_samples`` caps the total where species were added beside the living ones (a
        recovery keeps its old species, departure 19 starts one): the species with the least
        weight give way (:func:`~ceamcl.filters.ceamcl.phases.fit_budget`), and the rest start
        with equal weights again; the statistics are refreshed and the weights and handicaps
        are then the living species' (:meth:`_normalise_weights`). Whether any went."""
        ps = self.particle_set
        cfg = self.config
        if not fit_budget(ps, cfg.max_samples, cfg.min_species_size, self.log_weight):
            return False
        ps.log_weights = uniform_log_weights(ps.n)
        self._refresh_stats()
        self._normalise_weights(living=True)
        return True

    def _sprout(self, pose: NDArray[np.float64], log_weight: float) -> None:
        """Departure 19: a new species of ``delta x epsilon`` samples around ``pose`` (the
        mutation's Sigma), weighed on every beam of this update's scan, at ``log_weight``
        against the leading species' 0 and with no handicap (where the odometry says the
        robot is, as departure 14 has it for a recovery's species)."""
        full = self._full
        assert full is not None
        cfg = self.config
        n = max(cfg.viable_size, cfg.species_floor)
        poses = self._mutation_cloud(pose, n)
        sid = self._next_id
        self._next_id += 1
        new = ParticleSet.from_poses(poses, np.full(n, sid, dtype=np.int64))
        new.loglik = sanitise_log_likelihood(self.sensor.log_likelihood(poses, full))
        new.fitness = fitness(new.loglik, full, self.sensor)
        self._evaluations += n
        ps = self.particle_set
        ps.extend(new)
        ps.log_weights = uniform_log_weights(ps.n)
        self.log_weight[sid] = log_weight
        self.competition.dn[sid] = 0.0
        self._normalise_weights()
        if not self._fit_budget():  # (which refreshes them where species went)
            self._refresh_stats()
        self._read = None  # the hypotheses and the state include it
        self.events.sprouts += 1

    def _count_far_lost(self) -> None:
        """At the end of an update: one more consecutive update at which the state says LOST
        with the leader beyond the drift envelope of the anchor, or none (departure 17; once
        that coasts, any leader while the state says LOST: departure 39), and,
        where that does not coast, whether the anchor holds against a leader that stands
        beyond it and was not the last update's estimate (departure 18; judged once an
        update; and, the update after a coast, one that reads LOCALISED for the first time:
        departure 40); where the anchor's place fits as well and no species stands there, a species
        starts there (departure 19)."""
        cfg = self.config
        if self._far_lost[0] == self.t:
            return
        best = self.fittest()
        left = (  # the anchor as an estimate, the leader beyond its envelope
            self._left_anchor(best)
            if cfg.coast_when_lost
            and cfg.anchor_envelope_sd is not None
            and self.t > 0
            and best is not None
            else None
        )
        far = left is not None and self._species_state().state is State.LOST
        last_at, last_run = self._far_lost
        # the estimate coasted at the last update (departures 39 and 40 read it)
        coasted = last_at == self.t - 1 and last_run >= cfg.coast_after_updates
        if (  # departure 39: a coast goes on while the state says LOST, for a while
            cfg.coast_when_lost
            and cfg.coast_while_lost_m is not None
            and not far
            and cfg.anchor_envelope_sd is not None
            and coasted
            and best is not None
            and self._species_state().state is State.LOST
        ):
            coasting = self.confident.coasting(cfg.recovery_drift_m)
            held_anchor = self.confident.anchor()
            if coasting is not None and held_anchor is not None:
                travel = held_anchor[1]
                if self._coast[0] != self.t - 1:  # the leader is back within the envelope
                    self._coast_from = travel
                if travel - self._coast_from <= cfg.coast_while_lost_m:
                    left = PoseEstimate(coasting[0], coasting[1])
                    far = True
                    self._coast = (self.t, left)
        run = last_run + 1 if far and last_at == self.t - 1 else int(far)
        self._far_lost = (self.t, run)
        coasts = left is not None and run >= cfg.coast_after_updates  # what estimate() reports
        # the leader moved the estimate here itself (departure 12's look-around or a wrong
        # odometry can carry it metres in an update), or it leads anew (a recovery's place)
        moved_on = best is not None and self._continues_estimate(best)
        held, share, unvouched = None, None, float("nan")
        margin = cfg.anchor_hold_margin
        if left is not None and best is not None and not moved_on and margin is not None:
            localised = self._species_state().state is State.LOCALISED
            vacant = self._anchor_vacant(left.pose)
            # departure 18's fit test while LOCALISED; departure 19's, where a species may start
            judged = self._score_anchor(best, left.pose) if localised or vacant else None
            fits = judged is not None and self._fits_as_well(best, judged[1], judged[2])
            # departure 23: nor does the leader take it where the map does not vouch for it
            doubted = localised and not fits and not coasts
            unvouched = self._far_share(best) if doubted else float("nan")
            # departure 40: nor at the first update it reads LOCALISED after a coast, and
            # (departure 41) until it has read so over a stride of motion
            unconfirmed = doubted and cfg.far_confirm and self._unconfirmed(coasted)
            if unconfirmed:
                self._unconfirmed_at = self.t
            if not coasts and (fits or not localised or np.isfinite(unvouched) or unconfirmed):
                held = left  # not LOCALISED: the far place is doubted too
                if judged is not None and localised:
                    # two places fit: the anchor's and the leader's, at odds of this scan's
                    # fit with the leader's handicap
                    odds = judged[2] + self.log_prior.get(best.species_id, 0.0) - judged[1]
                    share = float(1.0 / (1.0 + np.exp(min(odds, 700.0))))
            if (unconfirmed or self._confirm_window == self.t - 1) and (held is not None or coasts):
                self._confirm_window = self.t  # the estimate stays on the anchor
            if judged is not None and fits and vacant:
                # departure 19: the anchor's place competes, at the leader's weight less what
                # it fits worse at this scan (never ahead on the leader's handicap: a robot
                # carried off)
                pose, near, lead = judged
                self._sprout(pose, self.log_weight.get(best.species_id, 0.0) + near - lead)
                best = self.fittest()
        best = self._anchor_place_returns(best, moved_on)
        self._held = (self.t, held, share, unvouched)  # a finite unvouched was held
        own = best is not None and not coasts and held is None
        # departure 25: a species the filter believed (the species' own reading of the state,
        # made this update for the recovery, is not LOST; no reading, as with the recovery
        # off or after a sprout: not believed) that a new leader may continue
        read = self._read
        believed = read is not None and read[1].state is not State.LOST
        if own and best is not None:
            self._estimate_from = (self.t, best.species_id, best.mean.copy() if believed else None)
        else:
            self._estimate_from = (self.t, -1, None)

    def _unconfirmed(self, coasted: bool) -> bool:
        """Departures 40 and 41, for a far leader that reads LOCALISED at this update: whether
        it is held back. Departure 40: at the first such update after the estimate coasted.
        Departure 41: while the estimate has stayed on the anchor since (the window), until
        the leader has read LOCALISED at every update over ``far_confirm_m`` of travel or
        ``far_confirm_rad`` of turning (a read that is not LOCALISED starts the count again);
        both ``None``: departure 40 alone, one update. Advances the count (``_streak``): call it
        once an update."""
        cfg = self.config
        if cfg.far_confirm_m is None and cfg.far_confirm_rad is None:
            return coasted
        if not (coasted or self._confirm_window == self.t - 1):
            return False
        at, travel, turn = self._streak
        if at != self.t - 1:  # the first update of a streak
            self._streak = (self.t, *self._moved)
            return True
        moved, turned = self._moved[0] - travel, self._moved[1] - turn
        within = (cfg.far_confirm_m is None or moved < cfg.far_confirm_m) and (
            cfg.far_confirm_rad is None or turned < cfg.far_confirm_rad
        )
        if within:
            self._streak = (self.t, travel, turn)
        return within or coasted

    def _keep_anchor_species(self) -> None:
        """Departure 36 (``anchor_keep_fit``), before eq. 9's sizes are applied: when the
        last update held the estimate at the anchor and the leading species' mean fitness was
        below ``anchor_keep_fit``, each species within the anchor's reach (:meth:`_near`, its
        drift envelope) grows to at least ``delta x epsilon`` samples instead of shrinking
        (:func:`~ceamcl.filters.ceamcl.phases.raise_to_floors`, as departure 13's floors)."""
        cfg = self.config
        at, held, _, _ = self._held
        if cfg.anchor_keep_fit is None or at != self.t - 1 or held is None:
            return
        lead = self.fittest()
        if lead is None or not lead.fitness < cfg.anchor_keep_fit:
            return
        coasting = self.confident.coasting(cfg.recovery_drift_m)
        if coasting is None or coasting[2] is None:
            return
        ids = list(self.stats)
        means = np.array([self.stats[sid].mean for sid in ids])
        near = self._near(means, held.pose[None, :], coasting[2])
        kept = {sid: cfg.species_floor for sid, ok in zip(ids, near, strict=True) if ok}
        raise_to_floors(self.competition.dn, self.stats, kept)

    def _continues_estimate(self, best: SpeciesStats) -> bool:
        """Whether the leader ``best`` was the last update's estimate: the same species, or
        (departure 25, ``estimate_continues_m``) another one within that many metres and
        ``recovery_drift_rad`` of that estimate carried on by the odometry, as the tracked
        species a recovery kept under a new id, or a species started where the anchor's place
        fits (departure 19) beside it. Not after an update at which the species read the state
        LOST: a species sliding where the map holds little continues nothing. Only a leader
        that would move the estimate further (a recovery's other place) is judged against the
        anchor (departure 18)."""
        at, source, last = self._estimate_from
        if at != self.t - 1 or source < 0:
            return False
        if source == best.species_id:
            return True
        reach = self.config.estimate_continues_m
        if reach is None or last is None:
            return False
        return bool(self._near(best.mean[None, :], last[None, :], reach)[0])

    def _far_share(self, best: SpeciesStats) -> float:
        """Departure 23: the share of the scan the map explains at the far leader ``best``
        when it falls short of ``far_vouch_share`` (the map does not vouch for it as for a
        robot found again), else NaN (no test, no scan, or vouched for)."""
        floor = self.config.far_vouch_share
        if floor is None:
            return float("nan")
        share = self.map_agreement.share_at(self.t, self.last_scan, best.mean)
        return share if share < floor else float("nan")

    def _anchor_vacant(self, anchor: NDArray[np.float64], reach: float | None = None) -> bool:
        """Whether, with ``anchor_species``, no species' mean lies within ``reach`` metres
        (``None``: the anchor's drift envelope; departure 38 reads :data:`CHAIN_M`) and
        :meth:`_near`'s heading of the ``anchor`` pose."""
        cfg = self.config
        if not cfg.anchor_species:
            return False
        if reach is None:
            coasting = self.confident.coasting(cfg.recovery_drift_m)
            reach = None if coasting is None else coasting[2]
            if reach is None:
                return False
        means = np.array([s.mean for s in self.stats.values()]).reshape(-1, 3)
        return not bool(self._near(means, anchor[None, :], reach).any())

    def _drift_envelope(self) -> DriftEnvelope | None:
        """Departure 17's envelope from the config (``None``: ``anchor_envelope_sd`` is)."""
        cfg = self.config
        if cfg.anchor_envelope_sd is None:
            return None
        return DriftEnvelope(
            cfg.anchor_envelope_sd, cfg.anchor_envelope_min_m, cfg.anchor_conflict_m
        )

    def _ranked_shares(self) -> tuple[list[SpeciesStats], NDArray[np.float64]]:
        """The species, leading first, and each one's share of the posterior: its accumulated
        evidence normalised ("scan": its size times its current fitness; equal shares when
        every mass is 0)."""
        stats = sorted(self.stats.values(), key=self._rank_key, reverse=True)
        if self.config.competition_fitness == "scan":
            mass = np.array([s.n * s.fitness for s in stats], dtype=np.float64)
        else:
            mass = np.exp([self.log_weight.get(s.species_id, 0.0) for s in stats])
        share = mass / mass.sum() if mass.sum() > 0 else np.full(mass.size, 1.0 / max(mass.size, 1))
        return stats, share

    def hypotheses(self) -> list[Hypothesis]:
        """The species, heaviest first: each one's mean pose, covariance and size, its share
        of the accumulated evidence (the weights sum to 1) and its fitness for the last scan
        (docs/ceamcl.md)."""
        require_initialised(self, "hypotheses")
        if self._read is not None:  # read this step; fresh arrays, as a new read gives
            return [
                replace(h, pose=h.pose.copy(), covariance=h.covariance.copy())
                for h in self._read[0]
            ]
        stats, share = self._ranked_shares()
        return [
            Hypothesis(
                pose=s.mean.copy(),
                covariance=s.covariance.copy(),
                n_particles=s.n,
                weight=float(w),
                fitness=_reported_fitness(s, self._peak_fitness.get(s.species_id)),
                label=s.species_id,
            )
            for s, w in zip(stats, share, strict=True)
        ]

    def state(self, hypotheses: Sequence[Hypothesis] | None = None) -> LocalisationState:
        """Read from the species: their evidence shares and fitness
        (:func:`ceamcl.filters.state.read_hypotheses`), and the map's agreement with the
        scans (:class:`ceamcl.filters.state.MapAgreement`); INITIALISING until the first
        step. AMBIGUOUS, the anchor's place and the leader's, where the species read LOCALISED
        but departure 18 holds the estimate at the anchor (the estimate is not the leader's
        place: two places fit the scan)."""
        require_initialised(self, "state")
        read = self._species_state(hypotheses)
        at, _, share, unvouched = self._held
        if at != self.t or share is None or read.state is not State.LOCALISED:
            return read
        weights = (max(share, 1.0 - share), min(share, 1.0 - share))
        far = "the leading place lies beyond the odometry's reach of the last confident pose"
        if np.isfinite(unvouched):
            why = (
                f"{far}, and the map explains {unvouched:.0%} of the scan there, less than a "
                f"place the robot is found at ({self.config.far_vouch_share:.0%}): the "
                f"estimate stays at that pose ({share:.0%} of the weight by this scan's fit, "
                f"the leader {1.0 - share:.0%})"
            )
        elif self._unconfirmed_at == self.t:
            why = (
                f"{far}, and the leader has not read LOCALISED long enough since the estimate "
                f"coasted on that pose (at two updates, over a stride of motion): the estimate "
                f"stays there for now ({share:.0%} of the weight by this scan's fit, the "
                f"leader {1.0 - share:.0%})"
            )
        else:
            why = (
                f"{far}, which fits the scan as well: the estimate stays there ({share:.0%} of "
                f"the weight, the leader {1.0 - share:.0%})"
            )
        return LocalisationState(
            State.AMBIGUOUS, read.confidence, 2, weights, why, read.map_explained
        )

    def _species_state(self, hypotheses: Sequence[Hypothesis] | None = None) -> LocalisationState:
        """:meth:`state` as the species read it."""
        if not self.stats or self.t == 0:
            return initialising()
        if hypotheses is None or (
            self._read is not None and _same_hypotheses(hypotheses, self._read[0])
        ):
            read_hyps, read = self._species_read()
            return self.map_agreement.apply(read, self.t, self.last_scan, read_hyps)
        return self.map_agreement.apply(
            self._read_state(hypotheses), self.t, self.last_scan, hypotheses
        )

    def _read_state(self, hyps: Sequence[Hypothesis]) -> LocalisationState:
        """The state from the species alone, as the recovery reads it."""
        if not self.stats or self.t == 0:
            return initialising()
        return read_hypotheses(hyps, crossing=wall_crossing(self.grid, self.last_scan))

    def particle_weights(self) -> NDArray[np.float64]:
        """Each particle's in-species weight times its species' share, normalised (measured
        by the runner at every step, so no :class:`Hypothesis` is built for it)."""
        require_initialised(self, "particle_weights")
        weights = np.zeros(self.particle_set.n)
        stats, share = self._ranked_shares()
        for s, w in zip(stats, share, strict=True):
            weights[s.members] = s.weights * float(w)
        total = weights.sum()
        if total > 0:
            weights /= total
        return weights

    def particles(self) -> ParticleSnapshot:
        """A copy of the samples, their weights (:meth:`particle_weights`) and species ids."""
        require_initialised(self, "particles")
        ps = self.particle_set
        return ParticleSnapshot(ps.poses.copy(), self.particle_weights(), ps.labels.copy())


ALGORITHM = Algorithm(
    "ceamcl",
    CEAMCLConfig,
    CEAMCL,
    summary="coevolution-based adaptive MCL: species, Lotka-Volterra competition, evolution",
)


def _same_hypotheses(a: Sequence[Hypothesis], b: Sequence[Hypothesis]) -> bool:
    """Do two lists hold the same hypotheses (the same objects, or equal values)?"""
    return len(a) == len(b) and all(
        x is y
        or (
            x.label == y.label
            and x.weight == y.weight
            and x.fitness == y.fitness
            and x.n_particles == y.n_particles
            and np.array_equal(x.pose, y.pose)
            and np.array_equal(x.covariance, y.covariance)
        )
        for x, y in zip(a, b, strict=True)
    )


def _reported_fitness(s: SpeciesStats, peak: float | None = None) -> float:
    """How well a hypothesis fits the scan: its fittest individual's fitness, NaN-safe, or
    the ``peak`` its evidence climb found this step where that is higher (docs/state.md). The
    mean over its individuals depends on how far the motion spread them since the last scan:
    on intel's corrected log (a scan every 0.67 m) a species on the truth has a median mean
    fitness of 0.20 and a median best of 0.91."""
    best = s.best_fitness if np.isfinite(s.best_fitness) else s.fitness
    return best if peak is None else max(best, peak)


#: Departure 18's neighbourhood of the anchor: positions 0.1 m apart within 0.8 m, headings
#: 0.05 rad apart within 0.2 rad (1,773 poses; where a look-alike led on fr079 raw, the anchor
#: was 0.3-0.5 m off the truth).
HOLD_RADIUS_M = 0.8
HOLD_STEP_M = 0.1
HOLD_RAD = 0.2
HOLD_STEP_RAD = 0.05


def look_around_reach(cfg: CEAMCLConfig, increment: OdometryIncrement) -> tuple[float, float]:
    """How far the look-around searches around a species' peak: ``look_around_m`` plus the gain
    times the step's travel (at most ``look_around_max_m``), and ``look_around_rad`` plus the
    gain times its turn (at most ``look_around_max_rad``). The turn is the motion
    model's (:attr:`OdometryIncrement.turns`): a step backwards, ``rot1`` = pi, is no turn."""
    assert cfg.look_around_m is not None
    radius = min(cfg.look_around_max_m, cfg.look_around_m + cfg.look_around_gain * increment.trans)
    turn = sum(increment.turns)
    spread = min(cfg.look_around_max_rad, cfg.look_around_rad + cfg.look_around_gain * turn)
    return radius, spread


#: departure 44: the surfaces of a scan (chords of 0.2 m, as the test poses' headings read them)
#: and the angle within which their normals face along the robot's axis
_SURFACES = HeadingPrior()
_FACING_RAD = np.pi / 4


def _along_offsets(heading: float, reach_m: float, cfg: CEAMCLConfig) -> NDArray[np.float64]:
    """Offsets ``(dx, dy, dtheta)`` of :meth:`CEAMCL._look_along`: every ``look_around_step_m``
    along ``heading`` within ``reach_m`` either way, each a step to either side and
    ``look_around_step_rad`` either way (the zero offset included)."""
    step, step_rad = cfg.look_around_step_m, cfg.look_around_step_rad
    n = int(np.floor(reach_m / step + 1e-9))
    along, side, turn = np.meshgrid(
        np.arange(-n, n + 1) * step,
        np.array([-step, 0.0, step]),
        np.array([-step_rad, 0.0, step_rad]),
        indexing="ij",
    )
    a, b = along.ravel(), side.ravel()
    c, s = np.cos(heading), np.sin(heading)
    return np.column_stack([a * c - b * s, a * s + b * c, turn.ravel()])


def _look_around_offsets(
    radius_m: float, step_m: float, spread_rad: float, step_rad: float
) -> NDArray[np.float64]:
    """Offsets ``(dx, dy, dtheta)`` of :meth:`CEAMCL._look_around`: a square grid of
    ``step_m`` within ``radius_m`` times headings of ``step_rad`` within ``spread_rad``."""
    n = int(np.floor(radius_m / step_m))
    g = np.arange(-n, n + 1) * step_m
    dx, dy = np.meshgrid(g, g, indexing="ij")
    inside = dx**2 + dy**2 <= radius_m**2 + 1e-12
    m = int(np.floor(spread_rad / step_rad))
    dth = np.arange(-m, m + 1) * step_rad
    xy = np.column_stack([dx[inside], dy[inside]])
    out = np.empty((xy.shape[0] * dth.size, 3))
    out[:, :2] = np.repeat(xy, dth.size, axis=0)
    out[:, 2] = np.tile(dth, xy.shape[0])
    return out


#: :func:`_look_around_offsets` of departure 18's grid, built once.
_HOLD_OFFSETS = _look_around_offsets(HOLD_RADIUS_M, HOLD_STEP_M, HOLD_RAD, HOLD_STEP_RAD)
