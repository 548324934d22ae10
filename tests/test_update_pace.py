"""Updates at a real robot's pace (``run_filter(..., update_when=...)``, ``UpdatePace``): the
filter is stepped once the odometry has moved ``update_min_d`` or turned ``update_min_a`` since
the last update, with the whole increment since then, and every algorithm alike."""

from __future__ import annotations

import numpy as np
import pytest

from ceamcl.filters.base import Hypothesis, ParticleSnapshot, PoseEstimate, StepRecord
from ceamcl.filters.policies import on_motion
from ceamcl.filters.state import LocalisationState, read_hypotheses
from ceamcl.motion.odometry import OdometryIncrement, apply_increment
from ceamcl.replay import UpdatePace, make_paced_filter
from ceamcl.runner import run_filter
from ceamcl.sensors.scan import LaserScan
from ceamcl.simulation import office_scenario


class PoseLog:
    """A log of odometry poses only (scans empty)."""

    def __init__(self, odometry: np.ndarray) -> None:
        self.odometry = np.asarray(odometry, dtype=np.float64)
        self.times = np.arange(len(self.odometry), dtype=np.float64)

    def __len__(self) -> int:
        return len(self.odometry)

    def scan(self, k: int) -> LaserScan:
        return LaserScan(np.full(4, 5.0), -1.0, 0.5, 0.0, 30.0, (0.0, 0.0, 0.0), float(k))


class DeadReckoning:
    """A 'filter' that integrates the increments it is given, and remembers them."""

    name = "dead-reckoning"

    def __init__(self) -> None:
        self.pose = np.zeros(3)
        self.increments: list[OdometryIncrement] = []

    def initialise_global(self, scan: LaserScan) -> StepRecord:
        return StepRecord()

    def step(self, increment: OdometryIncrement, scan: LaserScan | None) -> StepRecord:
        self.increments.append(increment)
        i = increment
        self.pose = apply_increment(self.pose, i.rot1, i.trans, i.rot2)[0]
        return StepRecord()

    def estimate(self) -> PoseEstimate:
        return PoseEstimate(self.pose.copy(), np.eye(3))

    def hypotheses(self) -> list[Hypothesis]:
        return [Hypothesis(self.pose.copy(), np.eye(3), 1, 1.0, 1.0, 0)]

    def particles(self) -> ParticleSnapshot:
        return ParticleSnapshot(self.pose[None, :].copy(), np.ones(1), np.zeros(1, dtype=int))

    def state(self, hypotheses: object = None) -> LocalisationState:
        return read_hypotheses(self.hypotheses())

    def particle_weights(self) -> np.ndarray:
        return np.ones(1)


def test_no_update_before_the_thresholds_and_the_whole_increment_after() -> None:
    # 0.1 m forward per scan, then turning 0.05 rad per scan on the spot.
    xs = np.column_stack([np.arange(8) * 0.1, np.zeros(8), np.zeros(8)])
    turn = np.column_stack([np.full(6, 0.7), np.zeros(6), 0.05 * np.arange(1, 7)])
    odom = np.vstack([xs, turn])
    f = DeadReckoning()
    res = run_filter(f, PoseLog(odom), update_when=on_motion(0.25, 0.2))  # type: ignore[arg-type]
    stepped = [k for k, d in enumerate(res.diagnostics) if k and d.stepped]
    # moved 0.3 m at scan 3, 0.6 m at scan 6; turned 0.25 rad at scan 12 (0.05 x 5)
    assert stepped == [3, 6, 12]
    assert res.updates == 3 and len(f.increments) == 3
    # the increments add up to the odometry from the start to the last update: nothing dropped
    assert f.pose == pytest.approx(odom[12], abs=1e-12)
    assert f.increments[0].trans == pytest.approx(0.3)
    assert f.increments[1].trans == pytest.approx(0.3)
    assert f.increments[2].rot1 + f.increments[2].rot2 == pytest.approx(0.25)
    # held-back scans: the estimate is the last update's carried by the odometry since
    assert np.allclose(res.estimates, odom, atol=1e-12)
    assert all(d.step_ms == 0.0 for d in res.diagnostics if not d.stepped)


def test_without_a_policy_every_entry_is_a_step() -> None:
    odom = np.column_stack([np.arange(5) * 0.01, np.zeros(5), np.zeros(5)])
    f = DeadReckoning()
    res = run_filter(f, PoseLog(odom))  # type: ignore[arg-type]
    assert res.updates == 4 and all(d.stepped for d in res.diagnostics)


@pytest.mark.parametrize("pace", [UpdatePace(0.5, 0.4), UpdatePace(0.1, 0.1)])
def test_every_algorithm_is_stepped_at_the_same_scans(pace: UpdatePace) -> None:
    # a pace coarser and one finer than KLD-AMCL's own 0.25 m / 0.2 rad: under either, every
    # KLD-AMCL (its presets too, whose thresholds are the config's) updates at every scan the
    # runner gives it, so no filter of a comparison skips an update the others make
    sc = office_scenario()
    grid = sc.grid()
    log = sc.simulate(np.random.default_rng(3), grid)
    flags = {}
    for algo in ("mcl", "gmcl", "kld-amcl", "kld-amcl-recovery", "kld-amcl-tuned"):
        f = make_paced_filter(algo, grid, np.random.default_rng(4))
        res = run_filter(f, log, update_when=pace.policy())
        flags[algo] = [d.stepped for d in res.diagnostics]
        if algo.startswith("kld-amcl"):
            # its own thresholds are off under the pace: every scan it is given updates it
            assert all(d.record.updated for d in res.diagnostics if d.stepped)  # type: ignore[attr-defined]
    assert len({tuple(v) for v in flags.values()}) == 1
    held = flags["mcl"].count(False)
    assert 0 < held < len(log) - 1  # the pace really held some scans back, and not all


def test_at_every_scan_kld_amcl_updates_at_every_scan_too() -> None:
    """Without a pace (--every-scan, a corrected log's key scans) the runner steps every
    algorithm at every scan; the KLD-AMCL variants kept their own 0.25 m / 0.2 rad and skipped
    most of them (1,512 of 4,932 on fr079 raw), while the report said "every scan"."""
    sc = office_scenario()
    grid = sc.grid()
    log = sc.simulate(np.random.default_rng(3), grid)
    for algo in ("kld-amcl", "kld-amcl-recovery", "kld-amcl-tuned"):
        f = make_paced_filter(algo, grid, np.random.default_rng(4))
        res = run_filter(f, log)
        updated = [d.record.updated for d in res.diagnostics[1:]]  # type: ignore[attr-defined]
        assert all(updated), f"{algo}: {updated.count(False)} of {len(updated)} scans skipped"


def test_a_negative_threshold_is_refused() -> None:
    from ceamcl.errors import ConfigError

    with pytest.raises(ConfigError, match="update-min-d"):
        UpdatePace(-0.1, 0.2)


def test_a_paced_ceamcl_runs_species_and_resources_continue_across_held_scans() -> None:
    """Under a pace every species' life was cut at each held-back scan (species.png drew dots,
    run.png found no species alive at the end) and the resources curve was NaN there."""
    from ceamcl.viz.animation import series
    from ceamcl.viz.plots import species_lives

    sc = office_scenario()
    grid = sc.grid()
    log = sc.simulate(np.random.default_rng(3), grid)
    pace = UpdatePace(0.5, 0.4)
    f = make_paced_filter("ceamcl", grid, np.random.default_rng(4))
    res = run_filter(f, log, update_when=pace.policy())
    held = [k for k, d in enumerate(res.diagnostics) if not d.stepped]
    assert held
    lives = species_lives(res)
    longest = max(lives, key=lambda life: int(life.steps[-1] - life.steps[0]))
    assert any(longest.steps[0] < k < longest.steps[-1] for k in held)  # lived across them
    _, resources = series(res)
    assert np.isfinite(resources).all()


def test_a_config_given_for_a_replay_loses_its_own_thresholds_too() -> None:
    """A KLD-AMCL config passed in (a particle count, say) kept its 0.25 m / 0.2 rad: the
    runner's pace decided for every algorithm but that one."""
    from ceamcl.filters.registry import with_config

    grid = office_scenario().grid()
    cfg = with_config("kld-amcl", max_particles=500)
    f = make_paced_filter("kld-amcl", grid, np.random.default_rng(0), config=cfg)
    assert (f.config.update_min_d, f.config.update_min_a, f.config.max_particles) == (0.0, 0.0, 500)  # type: ignore[attr-defined]
