"""CEAMCL settings: the paper's defaults (section 4) and the choices it leaves open."""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace
from functools import cached_property

import numpy as np

from ceamcl.filters.ceamcl.initialisation import InitialisationConfig
from ceamcl.filters.ceamcl.phases import CompetitionConfig, GrowthConfig, SplitMergeConfig
from ceamcl.filters.evolution import EvolutionConfig
from ceamcl.filters.headings import HeadingPrior
from ceamcl.filters.state import DEFAULT_THRESHOLDS
from ceamcl.motion.odometry import STRIDE_M, STRIDE_RAD
from ceamcl.sensors.beam_skip import BeamSkipConfig

#: What the ``w`` of eqs. 9 and 16 is (``CEAMCLConfig.competition_fitness``).
COMPETITION_FITNESS: tuple[str, ...] = ("evidence", "scan")
#: What the kidnap test's running averages follow (``CEAMCLConfig.recovery_reads``).
RECOVERY_READS: tuple[str, ...] = ("fittest", "mean")
#: What the leading species' estimate is weighted by (``CEAMCLConfig.estimate_likelihood``).
ESTIMATE_LIKELIHOOD: tuple[str, ...] = ("tempered", "full")


@dataclass(frozen=True)
class CEAMCLConfig:
    """Parameters of CEAMCL. Paper defaults first; docs/ceamcl.md explains the others.

    Paper (section 4):
        n_test: test poses for initial species generation (N_test), at most; see
            ``test_poses_per_m2``.
        cell_m: side of the x-y cells of section 3.1 (150 x 150 over 15 m).
        mu: threshold on scaled cell weights that defines V.
        eta: eq. 5 factor of the initial sample size.
        growth_rate: r, the maximum growth rate of every species (per filter step).
        epsilon_m2: minimum living domain a species keeps (eq. 15).
        tracking_epsilon_m2: the same while a single species lives (tracking): 1.5 m^2, a floor
            of 120 samples, where the paper's 40 drift off a real robot (docs/ceamcl.md,
            "epsilon"); ``None``: ``epsilon_m2`` throughout.
        fill_tracking_floor: a lone species below that floor grows to it at once, not by
            eq. 9's logistic steps (docs/ceamcl.md, departure 8).
        delta_per_m2: resources per square metre of living domain (eq. 15).
        evolution: p_c = 0.85, p_m = 0.15 and the mutation's Sigma.

    Left open by the paper (NOTES.md):
        cell_top_k, cell_fitness_exponent, cell_smoothing: how a cell's weight is formed.
        min_species_size: a species whose size falls below this dies out.
        split_cell_m, split_cell_rad: cells of the x-y-heading grid whose connected regions
            decide a split (heading included, so a pose and its mirror image part ways).
        merge_valley_ratio: two overlapping species merge unless the fitness along the segment
            between their means falls below this fraction of the smaller end value.
        merge_probe_points: interior points probed on that segment.
        max_samples: safety cap on the total sample size.
        tracking_samples: sample size of the single species of ``initialise_pose``.
        test_batch: test poses weighted per likelihood call (bounds memory).

    Initialisation (docs/ceamcl.md, "test poses"):
        test_poses_per_m2: test poses per square metre of free space, both rounds together
            up to ``n_test`` (``None``: all of ``n_test``); the paper's 10^6 over its hall is
            about 4,700 a square metre.
        init_refine_share, init_refine_per_pose, init_refine_sigma_xy_m,
            init_refine_sigma_rad: a second round of test poses, ``init_refine_per_pose``
            Gaussian draws around each of the best ``init_refine_share`` of the first, so that
            the cells see each place near its peak; ``init_refine_share=0``: one round, as in
            the paper. A 1 % second round over 450 uniform test poses per m^2 cost a third to
            a half of one round of 1,500 per m^2 for the same success (docs/ceamcl.md,
            departure 20); with headings drawn from the scan (``test_pose_headings``) 150 per
            m^2 does as well (the default, departure 27).
        recovery_n_test: a recovery's search scores at most this many test poses (both rounds),
            ``None``: ``n_test``. A recovery runs inside one update, so this bounds the longest
            update: 250,000 is about 0.3 s on the workplace's 2-core VM, and binds only on maps
            of more than about 1,500 m^2 of free space (at the 150 test poses a square metre of
            the first search; the shared logs' maps hold 525-1,015 m^2). On a 16,800 m^2
            hospital campus each recovery scored 10^6 (docs/real-data.md, "The same three
            buildings with a GMapping truth").
        recovery_test_poses_per_m2: the density of a recovery's search (its second opinion,
            ``recovery_prior``); ``None`` (the default): the global initialisation's. Until
            departure 28 (docs/ceamcl.md) recoveries searched at 450 with uniform headings:
            a search that finds a far look-alike at its peak let it out-fit the tracked place
            by more than the kidnap odds of 1e-6, in a room the map holds poorly; searches
            sparser than the first one (100 or 75 per m^2) still did with 1e-9.
        init_polish_rounds: greedy rounds that move each initial sample to a better pose
            nearby (the mutation's Sigma doubled, halved each round) before the first step.
        test_pose_headings: the first round's headings drawn from the scan's geometry, its
            surface normals correlated with the map's (:class:`~ceamcl.filters.headings.
            HeadingPrior`, docs/ceamcl.md, departure 27); ``None``: uniform, as in the paper.
        recovery_test_pose_headings: a recovery's search draws its headings so too (``True``,
            the default since departure 28; ``False``: uniformly).
        search_with_field: a filter weighing with the beam model scores the test poses of
            its global initialisation with ROS amcl's likelihood field of the same parameters
            and weighs the samples it chose with the beam model
            (:func:`~ceamcl.sensors.search.search_model`, docs/ceamcl.md, departure 29); ``False``:
            ray-cast every test pose. Recoveries always search with the filter's own model.
            No effect with the field.

    Read differently from the paper (docs/ceamcl.md, "evidence"):
        competition_fitness: the ``w`` of eqs. 9 and 16. "evidence" (default): each species'
            accumulated evidence, its marginal likelihood multiplied over the steps and
            divided by the leading species', so a mark once seen still decides after the
            robot has left it; "scan": the paper's literal reading, the mean fitness of the
            species' individuals under the current scan only.
        evidence_memory: exponent on a species' past evidence at each step (1: every past scan
            counts fully; below 1, old scans fade with that factor per step); 0.93 since
            docs/ceamcl.md's departure 33 (0.9 before).
        evidence_memory_step_m, evidence_memory_step_rad: the step the memory is for; a step
            that moves the robot farther or turns it more (updates paced by ``update_min_d``)
            applies ``evidence_memory`` once per such length (docs/ceamcl.md, departure 6);
            ``None``: once per step whatever the motion.
        evidence_probes, evidence_rounds, evidence_shrink: a greedy climb from each
            species' best sample (rounds of probes with the mutation's Sigma, multiplied by
            ``evidence_shrink`` each round) that finds how well the species can explain the
            scan, for its evidence only.
        evidence_warm_start, evidence_warm_gate: the climb also tries the species' peak of
            the step before, moved by the odometry, when it lies within ``evidence_warm_gate``
            mutation Sigmas of the best sample in every coordinate (docs/ceamcl.md, departure
            6).
        evidence_climb_at_start: the climb also runs at the scan a global initialisation
            or a recovery starts from, so the species' first evidence is how well each can
            explain that scan, as at every later update, not how near its polished samples
            happen to sit to its peak (docs/ceamcl.md, departure 43; ``False``: the first
            evidence is the best sample's, as before 2026-12-03).
        viable_fit_margin, viable_size, viable_weight_min, viable_memory: while the filter is
            ambiguous (at least two species hold ``viable_weight_min`` of the weight each), a
            species whose fitness (its fittest individual's, or its climb's peak) is within
            ``viable_fit_margin`` of the leading species' (departure 24) and fits
            (``confirm_fit_below``), and has at a running share (``viable_memory`` an update)
            of at least a half of the recent updates, keeps at least ``viable_size`` samples:
            equal species coexist, and the competition cannot starve one that fits as well as
            the leader before the evidence can turn (docs/ceamcl.md, departure 13). Its weight
            stays what its evidence says. ``viable_fit_margin=None``: eq. 9 alone.
        see_through_margin_m, see_through_tolerance: with the likelihood field, each step's
            evidence of a species is taken at its best sample with the readings that pass
            more than ``see_through_margin_m`` through a mapped wall scored as unexplained,
            the ``see_through_tolerance`` share of the beams forgiven
            (:mod:`ceamcl.sensors.see_through`); ``None``: the likelihood field alone.

    Not in the paper (kidnapped robot, docs/ceamcl.md):
        recovery: re-run the initial species generation when the fitness collapses.
        recovery_ratio, recovery_alpha_fast, recovery_alpha_slow: collapse means the fast
            running average of the fittest species' fitness below ``recovery_ratio`` times the
            slow one.
        recovery_reads: which fitness of a species those averages follow: ``"fittest"`` (the
            default) its fittest individual's, or the peak its evidence climb found, as the
            localisation state reads it; ``"mean"`` the mean over its individuals, as before
            docs/ceamcl.md departure 26 (it falls whenever the motion spreads the samples).
        recovery_warmup_steps: steps after any initialisation before collapse is tested.
        recovery_prior: with a number, a recovery keeps the species it had beside the new
            ones (docs/ceamcl.md, departure 9): each new species starts at ``recovery_prior``
            times the leading species' weight (the odds that the robot was carried off rather
            than the scans being poor), then both gather evidence; ``None``: the old species
            are dropped and the new ones start level. 1e-9 (20.7 nats; 1e-6 until departure
            28): more than a far look-alike found at its peak has been measured to out-fit
            the tracked place by on one scan (18.3 nats, fr079's doubtful room).
        recovery_drift_m, recovery_drift_rad: a new species whose mean pose lies within
            these distances (m, and rad of heading) of a species the filter had starts level
            with it instead of at ``recovery_prior``: the kept pose having drifted off the
            robot (an odometry fault, a stretch the map explains poorly) is far likelier than
            a kidnap (docs/ceamcl.md, departure 11). ``recovery_drift_m=None``: every new
            species starts at ``recovery_prior``.
        recovery_anchor_m: the filter's last confident pose (the leading hypothesis the last
            time its state said LOCALISED), carried on by the odometry, counts as a species the
            filter had in ``recovery_drift_m``'s test for this many metres of travel: a new
            species near where the odometry says the robot is since it was last localised
            starts level, even after a look-alike place has taken the lead from the drifted
            species (docs/ceamcl.md, departure 14). ``None``: only the living species count.
        recovery_drift_from_anchor: with an anchor, a drift is measured from it: a species the
            filter had within ``recovery_drift_m`` of the anchor is the anchor's own place,
            and a new species near it starts level only if it lies within
            ``recovery_drift_m`` of the anchor too, so drifts do not chain along a corridor
            (docs/ceamcl.md, departure 37). ``False`` (the default): near any species the
            filter had. An option, not the default: it cures a corridor excursion (aces raw,
            seed 2) but loses windows where the anchor itself has drifted (fr079's doubtful
            room) on the tuning seeds.
        estimate_likelihood: what :meth:`~ceamcl.filters.ceamcl.filter.CEAMCL.estimate`
            weighs the leading species' samples by (docs/ceamcl.md, departure 35, measured and
            not the default). ``"tempered"`` (default): the species' own weights, its mean
            ``x-bar`` of section 3.3. ``"full"``: the scan's likelihood as the sensor model
            has it before tempering (each sample's tempered log-likelihood over the sensor's
            ``temper``), the posterior mean the untempered beams give, read from the tempered
            cloud by importance weights: closer to the truth where the odometry is biased
            (intel's raw log, 13 % lower APE), further where it is as the motion model says
            (the simulator, logs with synthetic odometry). The same with amcl's scoring
            (temper 1). The covariance is the species' in both; the hypotheses keep the
            species' means.
        coast_when_lost: while the state says LOST, the last confident pose
            (``recovery_anchor_m``) is still held and the leading species has left it,
            :meth:`~ceamcl.filters.ceamcl.filter.CEAMCL.estimate` is that pose carried by the
            odometry, not the leading species (docs/ceamcl.md, departures 15 and 17): where
            the map does not hold what the robot sees, the odometry is a better guess than a
            species sliding along what the map lacks or another place a recovery proposed.
            The species keep searching; the hypotheses are theirs. ``False``: the leading
            species, whatever the state.
        anchor_envelope_sd, anchor_envelope_min_m, anchor_conflict_m: the odometry's drift
            envelope of the last confident pose (docs/ceamcl.md, departure 17): this many
            standard deviations of its position drift, at least ``anchor_envelope_min_m``. The
            drift is 0.1 m plus 0.06 m a metre travelled (freiburg-079's raw odometry) and a
            heading random walk whose variance a metre the filter measures as it runs (at
            least freiburg-079's, :data:`~ceamcl.filters.ceamcl.anchor.HEADING_Q`). A leading
            species beyond it has left the pose (``coast_when_lost``); a LOCALISED pose the map
            vouches for beyond it replaces the last confident pose only once the same place
            has disagreed with it over ``anchor_conflict_m`` metres of travel.
            With an envelope the estimate coasts once the leader has stood beyond it with the
            state LOST at ``coast_after_updates`` consecutive updates (a single doubtful
            update, as while the odometry is wrong and the scans are right, does not).
            ``anchor_envelope_sd=None``: departure 15 as first adopted, coasting only after a
            recovery and beyond ``recovery_drift_m`` / ``recovery_drift_rad``, and every
            LOCALISED pose the map vouches for replaces the last.
        coast_while_lost_m: once the estimate coasts on the last confident pose (with an
            envelope), it stays there while the state says LOST, even where the leading
            species comes back within the envelope, for at most this many metres of travel
            after it came back (docs/ceamcl.md, departure 39): the envelope widens with the
            travel, and a species sliding 1-1.3 m off in a room the map holds poorly otherwise
            took the estimate back and forth; beyond a few metres the odometry's drift costs
            more than a species that follows the scans while it reads them poorly. ``None``:
            the leader is the estimate again as soon as it stands within the envelope.
        far_confirm: a leader beyond the envelope that reads LOCALISED for the first time
            after the estimate coasted does not take the estimate at that update; it does at
            the next if it still reads LOCALISED (docs/ceamcl.md, departure 40): the mirror of
            ``coast_after_updates``. A recovery's place 26 m off that the map vouched for read
            LOCALISED for one update in fr079's doubtful room and took the estimate.
        far_confirm_m, far_confirm_rad: with ``far_confirm``, the far leader is held back at
            every update until the robot has travelled ``far_confirm_m`` or turned
            ``far_confirm_rad`` since it first read LOCALISED, while it reads so at each
            (docs/ceamcl.md, departure 41): Nav2's ``update_min_d`` and ``update_min_a``, so
            that at Nav2's pace this is departure 40's next update, and at every scan the
            same stretch of motion rather than the next scan, 3 cm on. ``None`` for both: the
            next update, whatever the motion.
        estimate_continues_m: a leading species within this many metres (and
            ``recovery_drift_rad``) of the last update's estimate carried on by the odometry
            continues that estimate even under another id (docs/ceamcl.md, departure 25): the
            tracked species a recovery keeps, or departure 19's species beside it, unless the
            species read the state LOST at that update. Departure 18 judges only a leader that
            moves the estimate further, a place a recovery proposed (metres away;
            :data:`~ceamcl.filters.ceamcl.anchor.CHAIN_M` bounds what a species following the
            scans moves in an update). ``None``: the same species only.
        anchor_hold_margin: with an envelope, a leading species beyond it that was not the
            last update's estimate (a place a recovery proposed) yields the estimate to the
            anchor while the state is not LOCALISED, and, while it is, as long as a pose near
            the anchor (within 0.8 m and 0.2 rad) fits the update's scan within this margin of
            the leader's best sample (tempered log-likelihood, every beam; docs/ceamcl.md,
            departure 18): a far look-alike needs to out-fit the place the odometry carried the
            robot to, not only to fit; a recovery's far place, by its handicap
            (``recovery_prior``) as well (departure 19). ``None``: the leader unless the
            estimate coasts.
        anchor_species: with ``anchor_hold_margin``, when the leading species stands beyond
            the anchor's envelope and no species stands near the anchor, the best pose of that
            grid, if it fits as well as the leader (the same test), starts a species of
            ``delta x epsilon`` samples at the leader's weight less what it fits worse at the
            update's scan (docs/ceamcl.md, departure 19): the place the odometry carried the
            robot to competes instead of being only reported.
        anchor_returns: while the leading species' mean fitness is below this, the anchor
            yields only to a place that fits better (docs/ceamcl.md, departure 38). A
            LOCALISED pose more than :data:`~ceamcl.filters.ceamcl.anchor.CHAIN_M` from the
            held anchor does not replace it at an update where the best pose around the
            anchor (departure 18's grid) fits the scan better than the leader's best sample.
            And while the leader, even one that continues the estimate, stands more than
            ``CHAIN_M`` from the held anchor and no species stands within ``CHAIN_M`` of it, a
            pose around the anchor that out-fits the leader by ``anchor_hold_margin`` starts a
            species there (departure 19's start, with ``anchor_species``): a recovery's place
            along a corridor that won a few cluttered scans does not keep the estimate once
            the scans say the robot is where the odometry carried it. A leader that fits (a
            robot carried off and found) is not asked, so a kidnap costs nothing more. Default
            the state's fit floor, 0.55. ``None``: the anchor yields to every LOCALISED pose
            the map vouches for (within its envelope at once, beyond it after
            ``anchor_conflict_m``), and its place starts a species only when a far leader that
            is not the estimate is judged.
        anchor_keep_fit: while the estimate is held at the anchor (departures 18-23) and the
            leading species' mean fitness is below this, every species within the anchor's
            reach keeps at least ``delta x epsilon`` samples, whatever eq. 9 says (docs/ceamcl.md,
            departure 36): where no place fits the scan (people, clutter the map lacks) nothing
            is refuted, and the place the odometry carried the robot to must still be there
            when the scans come back. A leader that fits (a robot carried off and found again)
            competes as before. ``None``: off. Default the state's fit floor, 0.55.
        far_vouch_share: with ``anchor_hold_margin``, a leading species beyond the anchor's
            envelope that was not the last update's estimate and that the species read
            LOCALISED takes the estimate from the anchor only where the map explains at least
            this share of the scan at its mean (:class:`~ceamcl.filters.state.MapAgreement`'s
            share; the state then says AMBIGUOUS): a robot carried off and found again is
            explained there as a tracked pose is, a far look-alike of a room the map holds
            poorly is not (docs/ceamcl.md, departure 23). 0.63: the share the map gives at
            least at 95 % of the true poses of intel-corrected and fhw (their 5th percentile,
            0.639, rounded down). ``None``: no such test.
        recovery_prior_fades: ``False`` (the default): the handicap ``recovery_prior`` of a
            new species beyond ``recovery_drift_m`` stays in its weight while other species
            live, so a far place must out-fit the near ones by that much in the evidence the
            memory keeps; ``True``: it fades with the evidence memory like any past evidence
            (departure 9 as first measured).
        recovery_lost_updates: a recovery also fires when the filter's own state
            (:meth:`~ceamcl.filters.ceamcl.filter.CEAMCL.state`) has said LOST at this many
            consecutive updates with a scan (docs/ceamcl.md, departure 10): the kidnap test sees
            a fall, not a filter that stays lost. Each further recovery fired this way before
            the state leaves LOST waits twice as long, so a place the map does not hold costs
            a bounded share of the time. ``None``: the kidnap test alone.
        init_is_a_search: the global initialisation counts as the first search of a LOST
            streak that starts at its first update: the lost-streak recovery then waits twice
            ``recovery_lost_updates`` (until the state leaves LOST), since it would repeat the
            search the initialisation has just made (docs/ceamcl.md, departure 30).
            ``False``: it fires after ``recovery_lost_updates`` as after any update.

    Not in the paper (unmapped obstacles, docs/ceamcl.md):
        beam_skip: while a single species lives (tracking), the short readings it cannot
            explain (unmapped obstacles) are left out of the step's weighting, as ROS amcl's
            beam skipping does (:mod:`ceamcl.sensors.beam_skip`); ``None`` weighs every beam.

    Not in the paper (the localisation state, docs/state.md):
        confirm_fit_below: when a lone species' fittest individual scores below this (the
            state's ``fit_min``), the evidence climb looks for a pose of the species that fits
            before its fitness is reported; a species that climbed (every species while
            several compete) reports the better of its fittest individual and the climb's
            peak. ``None``: a lone species never climbs.

    Not in the paper (odometry faults, docs/ceamcl.md departure 12):
        look_around_m: a lone species in doubt (above) also scores a grid of poses around
            its best pose, within this many metres plus ``look_around_gain`` times the
            odometry's translation since the last update (at most ``look_around_max_m``) and
            ``look_around_rad`` plus the gain times its rotation, ``look_around_step_m`` and
            ``look_around_step_rad`` apart: first the turns within three times
            ``look_around_rad``, then, when nothing there is found, those beyond, out to
            ``look_around_max_rad`` (by default what the rule gives for Nav2's stride of
            turning, 0.2 rad: departure 42);
            when the best beats the species' best pose by ``look_around_margin`` (tempered
            log-likelihood, every beam) and, refined, fits (``confirm_fit_below``), the
            worst ``look_around_share`` of the samples are drawn again around it. ``None``:
            no look-around (the evidence climb alone).

    Not in the paper (a track the scans cannot place, docs/ceamcl.md departure 44):
        track_drift_sd: a lone species counts the odometry's travel while fewer than
            ``track_facing_m`` metres of the surfaces its scans end on face along the robot's
            axis (within 45 degrees of straight ahead or behind: a corridor's side walls face
            across it); when that many do again, it looks along its track (its heading)
            within this many standard deviations of the odometry's drift over the travel so
            counted (departure 15's 0.06 m a metre, ``anchor.DRIFT_SD_M_PER_M``; at most
            ``track_look_max_m``), and
            the count falls to ``track_drift_decay`` of itself at each such update. The look
            runs when its reach is at least ``track_look_min_m``: the evidence climb and
            departure 12's look-around, then poses ``look_around_step_m`` apart along the
            heading (and a step either side, ``look_around_step_rad`` either way), accepted
            by departure 12's test. ``None``: no count, no look.
    """

    n_test: int = 1_000_000
    test_poses_per_m2: float | None = 150.0
    recovery_n_test: int | None = 250_000
    recovery_test_poses_per_m2: float | None = None
    init_refine_share: float = 0.01
    init_refine_per_pose: int = 10
    init_refine_sigma_xy_m: float = 0.1
    init_refine_sigma_rad: float = 0.1
    init_polish_rounds: int = 3
    test_pose_headings: HeadingPrior | None = field(default_factory=HeadingPrior)
    recovery_test_pose_headings: bool = True
    search_with_field: bool = True
    cell_m: float = 0.1
    mu: float = 0.85
    eta: float = 2.0
    growth_rate: float = 0.2
    epsilon_m2: float = 0.5
    tracking_epsilon_m2: float | None = 1.5
    fill_tracking_floor: bool = True
    delta_per_m2: float = 80.0
    evolution: EvolutionConfig = field(
        default_factory=lambda: EvolutionConfig(selection="metropolis")
    )
    cell_top_k: int = 3
    cell_fitness_exponent: float = 0.16
    cell_smoothing: int = 3
    min_species_size: int = 3
    split_cell_m: float = 0.5
    split_cell_rad: float = np.deg2rad(30.0)
    merge_valley_ratio: float = 0.75
    merge_probe_points: int = 3
    max_samples: int = 20_000
    tracking_samples: int = 300
    test_batch: int = 250_000
    competition_fitness: str = "evidence"
    evidence_memory: float = 0.93
    evidence_memory_step_m: float | None = 0.05
    evidence_memory_step_rad: float | None = 0.1
    evidence_probes: int = 6
    evidence_rounds: int = 4
    evidence_shrink: float = 0.6
    evidence_warm_start: bool = True
    evidence_warm_gate: float = 3.0
    evidence_climb_at_start: bool = True
    viable_fit_margin: float | None = 0.02
    viable_size: int = 6
    viable_weight_min: float = DEFAULT_THRESHOLDS.weight_min
    viable_memory: float = 0.05
    see_through_margin_m: float | None = 0.5
    see_through_tolerance: float = 0.1
    recovery: bool = True
    recovery_ratio: float = 0.5
    recovery_alpha_fast: float = 0.3
    recovery_alpha_slow: float = 0.02
    recovery_reads: str = "fittest"
    recovery_warmup_steps: int = 20
    recovery_prior: float | None = 1e-9
    recovery_drift_m: float | None = 4.0
    recovery_drift_rad: float = 1.0
    recovery_prior_fades: bool = False
    recovery_anchor_m: float | None = 20.0
    recovery_drift_from_anchor: bool = False
    estimate_likelihood: str = "tempered"
    coast_when_lost: bool = True
    anchor_envelope_sd: float | None = 3.0
    anchor_envelope_min_m: float = 0.5
    anchor_conflict_m: float = 2.0
    estimate_continues_m: float | None = 1.0
    coast_after_updates: int = 2
    coast_while_lost_m: float | None = 2.0
    far_confirm: bool = True
    far_confirm_m: float | None = STRIDE_M
    far_confirm_rad: float | None = STRIDE_RAD
    anchor_hold_margin: float | None = 3.0
    anchor_species: bool = True
    anchor_keep_fit: float | None = DEFAULT_THRESHOLDS.fit_min
    anchor_returns: float | None = DEFAULT_THRESHOLDS.fit_min
    far_vouch_share: float | None = 0.63
    recovery_lost_updates: int | None = 3
    init_is_a_search: bool = True
    beam_skip: BeamSkipConfig | None = field(default_factory=BeamSkipConfig)
    confirm_fit_below: float | None = DEFAULT_THRESHOLDS.fit_min
    look_around_m: float | None = 0.3
    look_around_gain: float = 2.0
    look_around_max_m: float = 1.0
    look_around_step_m: float = 0.1
    look_around_rad: float = 0.1
    look_around_step_rad: float = 0.05
    look_around_max_rad: float = 0.1 + 2.0 * STRIDE_RAD  # departure 42: one stride's turn
    look_around_margin: float = 3.0
    look_around_share: float = 0.5
    track_drift_sd: float | None = 2.0
    track_facing_m: float = 1.0
    track_look_min_m: float = 0.4
    track_look_max_m: float = 5.0
    track_drift_decay: float = 0.7

    def __post_init__(self) -> None:
        checks = {
            "n_test": self.n_test >= 1,
            "cell_m": self.cell_m > 0,
            "mu": 0 < self.mu < 1,
            "eta": self.eta > 0,
            "growth_rate": self.growth_rate >= 0,
            "epsilon_m2": self.epsilon_m2 > 0,
            "tracking_epsilon_m2": self.tracking_epsilon_m2 is None or self.tracking_epsilon_m2 > 0,
            "delta_per_m2": self.delta_per_m2 > 0,
            "cell_top_k": self.cell_top_k >= 1,
            "cell_fitness_exponent": self.cell_fitness_exponent > 0,
            "cell_smoothing": self.cell_smoothing >= 1,
            "min_species_size": self.min_species_size >= 1,
            "viable_fit_margin": self.viable_fit_margin is None or self.viable_fit_margin >= 0,
            "viable_size": self.viable_size >= self.min_species_size,
            "viable_weight_min": 0 < self.viable_weight_min <= 1,
            "far_vouch_share": self.far_vouch_share is None or 0 <= self.far_vouch_share <= 1,
            "viable_memory": 0 < self.viable_memory <= 1,
            "split_cell_m": self.split_cell_m > 0,
            "split_cell_rad": 0 < self.split_cell_rad <= np.pi,
            "merge_valley_ratio": 0 <= self.merge_valley_ratio <= 1,
            "merge_probe_points": self.merge_probe_points >= 1,
            "max_samples": self.max_samples >= self.min_species_size,
            "tracking_samples": self.tracking_samples >= self.min_species_size,
            "test_batch": self.test_batch >= 1,
            "competition_fitness": self.competition_fitness in COMPETITION_FITNESS,
            "evidence_memory": 0 < self.evidence_memory <= 1,
            "evidence_probes": self.evidence_probes >= 0,
            "evidence_rounds": self.evidence_rounds >= 0,
            "evidence_shrink": 0 < self.evidence_shrink <= 1,
            "evidence_warm_gate": self.evidence_warm_gate > 0,
            "evidence_memory_step_m": self.evidence_memory_step_m is None
            or self.evidence_memory_step_m > 0,
            "evidence_memory_step_rad": self.evidence_memory_step_rad is None
            or self.evidence_memory_step_rad > 0,
            "test_poses_per_m2": self.test_poses_per_m2 is None or self.test_poses_per_m2 > 0,
            "recovery_n_test": self.recovery_n_test is None or self.recovery_n_test >= 1,
            "recovery_test_poses_per_m2": self.recovery_test_poses_per_m2 is None
            or self.recovery_test_poses_per_m2 > 0,
            "init_polish_rounds": self.init_polish_rounds >= 0,
            "init_refine_share": 0 <= self.init_refine_share <= 1,
            "init_refine_per_pose": 0 <= self.init_refine_per_pose <= 100,
            "init_refine_sigma_xy_m": self.init_refine_sigma_xy_m > 0,
            "init_refine_sigma_rad": self.init_refine_sigma_rad > 0,
            "see_through_margin_m": self.see_through_margin_m is None
            or self.see_through_margin_m >= 0,
            "see_through_tolerance": 0 <= self.see_through_tolerance < 1,
            "confirm_fit_below": self.confirm_fit_below is None or 0 < self.confirm_fit_below <= 1,
            "look_around_m": self.look_around_m is None
            or 0 <= self.look_around_m <= self.look_around_max_m,
            "look_around_gain": self.look_around_gain >= 0,
            "look_around_max_m": 0 < self.look_around_max_m <= 5.0,
            "look_around_step_m": 0.01 <= self.look_around_step_m <= self.look_around_max_m,
            "look_around_rad": 0 <= self.look_around_rad <= np.pi / 3,
            "look_around_step_rad": 0.005 <= self.look_around_step_rad <= np.pi / 3,
            "look_around_max_rad": self.look_around_rad <= self.look_around_max_rad <= np.pi,
            "look_around_margin": self.look_around_margin >= 0,
            "look_around_share": 0 < self.look_around_share <= 1,
            "track_drift_sd": self.track_drift_sd is None or 0 < self.track_drift_sd <= 10,
            "track_facing_m": self.track_facing_m > 0,
            "track_look_min_m": 0 < self.track_look_min_m <= self.track_look_max_m,
            # bounds the look's grid: at most 2 x 10 m / look_around_step_m poses x 9
            "track_look_max_m": self.track_look_max_m <= 10.0,
            "track_drift_decay": 0 <= self.track_drift_decay < 1,
            "recovery_ratio": 0 < self.recovery_ratio < 1,
            "recovery_reads": self.recovery_reads in RECOVERY_READS,
            "estimate_likelihood": self.estimate_likelihood in ESTIMATE_LIKELIHOOD,
            "recovery_alpha_fast": 0 < self.recovery_alpha_fast <= 1,
            "recovery_alpha_slow": 0 < self.recovery_alpha_slow < self.recovery_alpha_fast,
            "recovery_warmup_steps": self.recovery_warmup_steps >= 0,
            "recovery_prior": self.recovery_prior is None or 0 < self.recovery_prior <= 1,
            "recovery_drift_m": self.recovery_drift_m is None or self.recovery_drift_m >= 0,
            "recovery_drift_rad": 0 <= self.recovery_drift_rad <= math.pi,
            "recovery_anchor_m": self.recovery_anchor_m is None or self.recovery_anchor_m >= 0,
            "anchor_envelope_sd": self.anchor_envelope_sd is None or self.anchor_envelope_sd > 0,
            "anchor_envelope_min_m": self.anchor_envelope_min_m >= 0,
            "anchor_conflict_m": self.anchor_conflict_m >= 0,
            "estimate_continues_m": self.estimate_continues_m is None
            or (math.isfinite(self.estimate_continues_m) and self.estimate_continues_m >= 0),
            "coast_after_updates": self.coast_after_updates >= 1,
            "coast_while_lost_m": self.coast_while_lost_m is None
            or (math.isfinite(self.coast_while_lost_m) and self.coast_while_lost_m >= 0),
            "far_confirm_m": self.far_confirm_m is None
            or (math.isfinite(self.far_confirm_m) and self.far_confirm_m > 0),
            "far_confirm_rad": self.far_confirm_rad is None
            or (math.isfinite(self.far_confirm_rad) and self.far_confirm_rad > 0),
            "anchor_keep_fit": self.anchor_keep_fit is None or 0 < self.anchor_keep_fit <= 1,
            "anchor_returns": self.anchor_returns is None or 0 < self.anchor_returns <= 1,
            "anchor_hold_margin": self.anchor_hold_margin is None
            or (math.isfinite(self.anchor_hold_margin) and self.anchor_hold_margin >= 0),
            "recovery_lost_updates": self.recovery_lost_updates is None
            or self.recovery_lost_updates >= 1,
        }
        for name, ok in checks.items():
            if not ok:
                raise ValueError(f"{name}: value {getattr(self, name)!r} is out of range")

    @property
    def species_floor(self) -> int:
        """Samples a species holds at eq. 13-16's floor, ``delta x epsilon`` (40 at the
        defaults): what departures 19 and 36 give a species they start or keep."""
        return round(self.delta_per_m2 * self.epsilon_m2)

    # Each phase takes only its own settings (``filters.ceamcl.phases``, ``initialisation``).
    @cached_property
    def initialisation(self) -> InitialisationConfig:
        """Section 3.1's settings."""
        return InitialisationConfig(
            n_test=self.n_test,
            test_poses_per_m2=self.test_poses_per_m2,
            refine_share=self.init_refine_share,
            refine_per_pose=self.init_refine_per_pose,
            refine_sigma=(self.init_refine_sigma_xy_m, self.init_refine_sigma_rad),
            polish_rounds=self.init_polish_rounds,
            polish_sigma=(
                2 * self.evolution.mutation_sigma_xy_m,
                2 * self.evolution.mutation_sigma_theta_rad,
            ),
            test_batch=self.test_batch,
            cell_m=self.cell_m,
            mu=self.mu,
            eta=self.eta,
            cell_top_k=self.cell_top_k,
            cell_fitness_exponent=self.cell_fitness_exponent,
            cell_smoothing=self.cell_smoothing,
            min_species_size=self.min_species_size,
            max_samples=self.max_samples,
            headings=self.test_pose_headings,
        )

    @cached_property
    def recovery_initialisation(self) -> InitialisationConfig:
        """Section 3.1's settings for a recovery's second opinion (``recovery_prior``), at
        ``recovery_test_poses_per_m2`` where that is set, at most ``recovery_n_test`` test
        poses, its headings uniform unless ``recovery_test_pose_headings``."""
        density = self.recovery_test_poses_per_m2
        cap = self.recovery_n_test
        return replace(
            self.initialisation,
            n_test=self.n_test if cap is None else min(self.n_test, cap),
            test_poses_per_m2=self.test_poses_per_m2 if density is None else density,
            headings=self.test_pose_headings if self.recovery_test_pose_headings else None,
        )

    @cached_property
    def growth(self) -> GrowthConfig:
        """The sample-size phase's settings."""
        return GrowthConfig(self.min_species_size, self.max_samples)

    @cached_property
    def split_merge(self) -> SplitMergeConfig:
        """The split and merge phase's settings."""
        return SplitMergeConfig(
            min_species_size=self.min_species_size,
            split_cell_m=self.split_cell_m,
            split_cell_rad=self.split_cell_rad,
            merge_valley_ratio=self.merge_valley_ratio,
            merge_probe_points=self.merge_probe_points,
        )

    @cached_property
    def competition(self) -> CompetitionConfig:
        """The competition phase's settings (eqs. 9-16)."""
        return CompetitionConfig(
            self.growth_rate,
            self.epsilon_m2,
            self.delta_per_m2,
            self.tracking_epsilon_m2,
            self.fill_tracking_floor,
        )
