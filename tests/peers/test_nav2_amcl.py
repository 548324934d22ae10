"""Tests of the Nav2 AMCL peer (``ceamcl.peers.nav2_amcl``), which wraps the ``amcl`` wheel."""

from __future__ import annotations

import csv
import subprocess
import sys
import textwrap
from pathlib import Path

import numpy as np
import pytest

from ceamcl.errors import ConfigError
from ceamcl.maps.grid import OccupancyGrid
from ceamcl.motion.odometry import OdometryIncrement, OdometryNoise, increment_between
from ceamcl.peers import available
from ceamcl.runner import run_filter
from ceamcl.sensors.scan import LaserScan, select_beam_indices
from ceamcl.simulation import SimulatedLog, SimulationConfig, Simulator, get_scenario

needs_wheel = pytest.mark.skipif(
    not available(), reason="Nav2 AMCL wheel not installed (pip install 'ceamcl[peers]')"
)


def office_log(seed: int) -> tuple[OccupancyGrid, SimulatedLog, np.random.Generator]:
    sc = get_scenario("office")
    grid = sc.grid()
    sim, filt = np.random.SeedSequence(seed).spawn(2)
    return grid, sc.simulate(np.random.default_rng(sim), grid), np.random.default_rng(filt)


def test_core_modules_do_not_import_the_wheel() -> None:
    code = (
        "import sys, ceamcl, ceamcl.filters, ceamcl.runner, ceamcl.peers, ceamcl.peers.nav2_amcl;"
        "print('amcl' in sys.modules)"
    )
    out = subprocess.run(
        [sys.executable, "-c", code], capture_output=True, text=True, check=True
    ).stdout
    assert out.strip() == "False"


def test_missing_wheel_is_a_config_error(monkeypatch: pytest.MonkeyPatch) -> None:
    from ceamcl.peers.nav2_amcl import make_nav2_amcl

    monkeypatch.setitem(sys.modules, "amcl", None)  # makes `import amcl` raise ImportError
    assert not available()
    grid = get_scenario("office").grid()
    with pytest.raises(ConfigError, match=r"pip install 'ceamcl\[peers\]'"):
        make_nav2_amcl(grid, np.random.default_rng(0))


# ---------------------------------------------------------------------------------- conversions
@needs_wheel
def test_grid_conversion_round_trip() -> None:
    from ceamcl.peers.nav2_amcl import amcl_cell_values, to_amcl_grid

    data = np.array([[0, 100, -1, 10], [70, 0, 0, 40], [0, 0, 100, 0]], dtype=np.int8)
    grid = OccupancyGrid(data, 0.1, (2.0, -1.0, 0.0))
    g = to_amcl_grid(grid)
    assert (g.size_x, g.size_y) == (4, 3)
    assert g.scale == pytest.approx(0.1)
    # The wheel's origin is the centre of cell (0, 0), in the grid frame.
    assert (g.origin_x, g.origin_y) == pytest.approx((0.05, 0.05))
    expected = [[0, 100, -1, 0], [100, 0, 0, -1], [0, 0, 100, 0]]
    assert amcl_cell_values(grid).tolist() == expected
    assert g.to_list() == expected


@needs_wheel
def test_scan_conversion() -> None:
    from ceamcl.peers.nav2_amcl import amcl_ranges, to_amcl_scan

    ranges = np.array([1.0, np.nan, 0.01, 8.0, np.inf, 9.5, 2.5])
    scan = LaserScan(ranges, -0.3, 0.1, 0.02, 8.0)
    rows = amcl_ranges(scan)
    assert rows[:, 0].tolist() == [1.0, 8.0, 8.0, 8.0, 8.0, 2.5]  # NaN dropped, rest -> max
    np.testing.assert_allclose(rows[:, 1], scan.angles[[0, 2, 3, 4, 5, 6]])
    s = to_amcl_scan(scan)
    assert s.size() == 6 and s.range_max == 8.0
    np.testing.assert_allclose(np.array(s.ranges), rows)
    long = LaserScan(np.linspace(1.0, 3.0, 181), -np.pi / 2, np.pi / 180, 0.02, 8.0)
    picked = amcl_ranges(long, 60)
    np.testing.assert_allclose(picked[:, 1], long.angles[select_beam_indices(181, 60)])


@needs_wheel
def test_pose_conversion_round_trip_with_a_rotated_map() -> None:
    from ceamcl.peers.nav2_amcl import from_amcl_pose, to_amcl_pose

    grid = OccupancyGrid(np.zeros((20, 30), dtype=np.int8), 0.1, (1.0, 2.0, 0.4))
    pose = np.array([1.5, 2.8, 3.0])
    inside = to_amcl_pose(grid, pose)
    assert inside[2] == pytest.approx(3.0 - 0.4)
    np.testing.assert_allclose(from_amcl_pose(grid, inside), pose, atol=1e-12)


@needs_wheel
def test_a_known_pose_comes_back_where_it_was() -> None:
    """A still robot seen by noise-free scans: the wheel's estimate settles on the true pose.

    This pins the map convention: had we handed the wheel the corner of cell (0, 0) as its
    origin (it expects the centre), estimates would sit half a cell (2.5 cm) off on average.
    """
    from ceamcl.peers.nav2_amcl import make_nav2_amcl

    grid = get_scenario("office").grid()
    cfg = SimulationConfig(range_sigma_m=0.0, random_reading_prob=0.0)
    rng = np.random.default_rng(0)
    poses = grid.sample_free_poses(400, rng)
    ix, iy = grid.world_to_cell(poses[:, 0], poses[:, 1])
    poses = poses[grid.distance_to_occupied[iy, ix] > 0.5][:8]
    ranges = Simulator(grid, cfg).scans(poses, rng)
    still = OdometryIncrement(0.0, 0.0, 0.0)
    bias = []
    for pose, r in zip(poses, ranges, strict=True):
        f = make_nav2_amcl(grid, rng, max_beams=90)
        f.initialise_pose(pose, np.diag([0.05**2, 0.05**2, 0.03**2]))
        for _ in range(10):
            f.step(still, cfg.laser.scan(r))
        bias.append(f.estimate().pose - pose)
    b = np.array(bias)
    assert np.all(np.abs(np.mean(b[:, :2], axis=0)) < 0.0125)
    assert np.all(np.hypot(b[:, 0], b[:, 1]) < 0.06)


@needs_wheel
def test_every_update_moves_weights_and_resamples() -> None:
    """The wheel applies no update thresholds: every scan is a sensor update and a resampling,
    so repeated scans with no motion shrink the particle cloud."""
    from ceamcl.peers.nav2_amcl import make_nav2_amcl

    grid, log, rng = office_log(1)
    f = make_nav2_amcl(grid, rng)
    f.initialise_pose(log.true_poses[0], np.diag([0.3**2, 0.3**2, 0.1**2]))
    still = OdometryIncrement(0.0, 0.0, 0.0)
    spread = []
    for _ in range(4):
        d = f.step(still, log.scan(0))
        assert d.resampled and d.updated == 1.0
        spread.append(np.trace(f.estimate().covariance[:2, :2]))
    # Had the wheel skipped updates for no motion, the cloud (and its spread) would not change.
    assert len(set(spread)) == len(spread)
    assert spread[-1] < spread[0] < 2 * 0.3**2
    # No scan: no update, odometry only accumulates.
    assert f.step(OdometryIncrement(0.0, 0.5, 0.0), None).updated == 0.0


@needs_wheel
def test_parameters_are_mapped() -> None:
    from ceamcl.peers.nav2_amcl import make_nav2_amcl

    grid = get_scenario("office").grid()
    noise = OdometryNoise(0.1, 0.2, 0.3, 0.4)
    f = make_nav2_amcl(grid, np.random.default_rng(0), odometry_noise=noise, n_particles=300)
    assert f.config.odometry_noise == noise
    assert (f.config.min_particles, f.config.max_particles) == (300, 300)
    assert (f.config.alpha_slow, f.config.alpha_fast) == (0.0, 0.0)
    on = make_nav2_amcl(grid, np.random.default_rng(0), recovery=True, max_beams=30)
    assert (on.config.alpha_slow, on.config.alpha_fast) == (0.001, 0.1)
    assert on.config.beam.max_beams == 30
    with pytest.raises(ConfigError, match="max_beams"):
        make_nav2_amcl(grid, np.random.default_rng(0), max_beams=1)


# ---------------------------------------------------------------------------------- runs
@needs_wheel
def test_tracks_a_simulated_run_from_a_known_start() -> None:
    from ceamcl.peers.nav2_amcl import make_nav2_amcl

    grid, log, rng = office_log(7)
    f = make_nav2_amcl(grid, rng)
    f.initialise_pose(log.true_poses[0], np.diag([0.1**2, 0.1**2, 0.05**2]))
    errors = np.zeros(len(log))
    for k in range(1, len(log)):
        f.step(increment_between(log.odometry[k - 1], log.odometry[k]), log.scan(k))
        errors[k] = np.hypot(*(f.estimate().pose[:2] - log.true_poses[k, :2]))
    settled = log.times >= 5.0
    assert errors[settled].max() < 0.15
    assert np.mean(errors[settled]) < 0.06
    hyps = f.hypotheses()
    assert len(hyps) == 1 and hyps[0].weight == 1.0 and 0.0 < hyps[0].fitness <= 1.0


@needs_wheel
def test_scans_with_fewer_beams_than_max_beams_do_not_hang() -> None:
    from ceamcl.peers.nav2_amcl import make_nav2_amcl

    grid, log, rng = office_log(2)
    f = make_nav2_amcl(grid, rng)
    f.initialise_pose(log.true_poses[0], np.diag([0.05**2, 0.05**2, 0.02**2]))
    s = log.scan(0)
    r = s.ranges.copy()
    r[10:] = np.nan  # 10 usable beams, max_beams 60: the raw wheel would loop forever
    d = f.step(
        OdometryIncrement(0.0, 0.0, 0.0),
        LaserScan(r, s.angle_min, s.angle_increment, s.range_min, s.range_max, s.pose),
    )
    assert d.updated == 1.0
    assert np.all(np.isfinite(f.estimate().pose))


@needs_wheel
def test_global_initialisation_runs_and_reports() -> None:
    from ceamcl.peers.nav2_amcl import make_nav2_amcl

    grid, log, rng = office_log(0)
    f = make_nav2_amcl(grid, rng)
    res = run_filter(f, log)
    assert res.algorithm == "nav2-amcl"
    assert np.all(np.isfinite(res.estimates))
    assert all(
        d.n_particles == 2000 and d.record.columns()["n_particles_is_upper_bound"] == 1.0
        for d in res.diagnostics
    )
    # Before the first scan the estimate is the centre of free space, spread over the map.
    cov0 = res.initial_particles.poses.std(axis=0)
    assert cov0[0] > 1.0 and cov0[1] > 1.0
    snap = f.particles()
    assert snap.poses.shape == (500, 3) and np.all(snap.labels == 0)
    assert all(h.shape == (1, 5) for h in res.hypotheses)
    pe = res.position_errors
    assert pe is not None
    # No assertion on convergence: the wheel has no global localisation. Print what it did.
    print(f"nav2-amcl global init on small-office: final error {pe[-1]:.2f} m")


@needs_wheel
def test_same_seed_reproduces_a_run_in_a_fresh_process() -> None:
    script = textwrap.dedent(
        """
        import hashlib, sys
        import numpy as np
        from ceamcl.motion.odometry import increment_between
        from ceamcl.peers.nav2_amcl import make_nav2_amcl
        from ceamcl.simulation import get_scenario
        sc = get_scenario("office"); grid = sc.grid()
        log = sc.simulate(np.random.default_rng(1), grid)
        f = make_nav2_amcl(grid, np.random.default_rng(int(sys.argv[1])))
        f.initialise_pose(log.true_poses[0], np.diag([0.1**2, 0.1**2, 0.05**2]))
        est = []
        for k in range(1, 40):
            f.step(increment_between(log.odometry[k - 1], log.odometry[k]), log.scan(k))
            est.append(f.estimate().pose)
        print(f.seeded, hashlib.sha256(np.array(est).tobytes()).hexdigest())
        """
    )

    def run(seed: int) -> str:
        return subprocess.run(
            [sys.executable, "-c", script, str(seed)], capture_output=True, text=True, check=True
        ).stdout.strip()

    a, b, c = run(3), run(3), run(4)
    if not a.startswith("True"):
        pytest.skip("no glibc drand48 state to seed: the wheel cannot be made reproducible")
    assert a == b
    assert a != c


@needs_wheel
def test_global_localisation_rows_say_not_comparable(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch
) -> None:
    """Issue 17: the wheel has no uniform global initialisation, so Table 1's row of
    nav2-amcl says "not comparable" where the others give a success rate (the console table
    and table1.md), why beneath, and table1.csv keeps what was measured, marked."""
    from ceamcl.cli import main

    monkeypatch.setenv("COLUMNS", "200")  # the console's cells unwrapped
    out = tmp_path / "t1"
    args = ["experiment", "table1", "--trials", "1", "--start-routes", "0", "--executor", "serial"]
    args += ["--algorithms", "ceamcl,nav2-amcl", "--max-time", "3", "--out", str(out)]
    assert main(args) == 0
    printed = " ".join(capsys.readouterr().out.split())
    assert "not comparable" in printed and "no uniform global initialisation" in printed
    text = (out / "table1.md").read_text()
    rows = {line.split("|")[1].strip(): line for line in text.splitlines() if line.startswith("| ")}
    assert "not comparable" in rows["nav2-amcl"] and "not comparable" not in rows["ceamcl"]
    assert "nav2-amcl: global localisation not comparable" in text
    with (out / "table1.csv").open() as fh:
        csv_rows = {r["algorithm"]: r for r in csv.DictReader(fh)}
    assert csv_rows["nav2-amcl"]["localises_globally"] == "False"
    assert csv_rows["ceamcl"]["localises_globally"] == "True"
    assert 0.0 <= float(csv_rows["nav2-amcl"]["success_rate"]) <= 1.0  # measured, kept


@needs_wheel
def test_marked_hall_rows_say_not_comparable(tmp_path: Path) -> None:
    """The same for the marked-hall experiment: its route cells say "not comparable" and
    marked.csv marks the measured rows."""
    from ceamcl.cli import main

    out = tmp_path / "m"
    args = ["experiment", "marked", "--trials", "1", "--start-routes", "0", "--executor", "serial"]
    args += ["--algorithms", "mcl,nav2-amcl", "--max-time", "2", "--quiet", "--out", str(out)]
    assert main(args) == 0
    text = (out / "marked.md").read_text()
    assert "| nav2-amcl | not comparable | not comparable |" in text
    assert "| mcl | not comparable" not in text
    with (out / "marked.csv").open() as fh:
        marked = {(r["algorithm"], r["localises_globally"]) for r in csv.DictReader(fh)}
    assert marked == {("mcl", "True"), ("nav2-amcl", "False")}


@needs_wheel
def test_a_runs_summary_names_the_model_the_peer_weighs_with(tmp_path: Path) -> None:
    """The Nav2 peer weighs with the wheel's beam model whatever sensor model it is given; the
    summaries of `demo` and `soak` named the one it was given."""
    import json

    from ceamcl.cli import main

    out = tmp_path / "s"
    args = ["soak", "--algorithm", "nav2-amcl", "--steps", "30", "--warmup", "5", "--quiet"]
    assert main([*args, "--out", str(out)]) in (0, 1)  # 1: growth over the limit, not our point
    config = json.loads((out / "soak.json").read_text())["config"]
    assert config["sensor"] == "the wheel's own beam model"


@needs_wheel
def test_kidnapped_start_is_not_comparable_but_its_recovery_is(tmp_path: Path) -> None:
    """The kidnapped robot starts with a global localisation, which the wheel does not have:
    'localised before kidnap' says "not comparable" for it; the recovery after the kidnap (the
    wheel's own) keeps its measured figure."""
    from ceamcl.cli import main

    out = tmp_path / "k"
    args = ["experiment", "kidnapped", "--trials", "1", "--executor", "serial", "--quiet"]
    args += ["--algorithms", "mcl,nav2-amcl", "--max-time", "30", "--recovery-window", "4"]
    assert main([*args, "--out", str(out)]) == 0
    rows = {
        line.split("|")[1].strip(): [c.strip() for c in line.split("|")[2:]]
        for line in (out / "kidnapped.md").read_text().splitlines()
        if line.startswith("| ") and not line.startswith("| algorithm")
    }
    assert rows["nav2-amcl"][1] == "not comparable" and rows["mcl"][1].endswith("%")
    assert rows["nav2-amcl"][2].endswith("%")  # recovered: measured


@needs_wheel
def test_the_peer_used_before_its_initialisation_says_so() -> None:
    """Before an initialisation the peer reported the wheel's pose (0, 0, 0) with a zero
    covariance and tracked from there, as the other filters did: now the same
    FilterStateError as theirs."""
    from ceamcl.errors import FilterStateError
    from ceamcl.peers.nav2_amcl import make_nav2_amcl

    grid, log, rng = office_log(3)
    f = make_nav2_amcl(grid, rng)
    inc = increment_between(log.odometry[0], log.odometry[1])
    for call in (
        lambda: f.step(inc, log.scan(1)),
        f.estimate,
        f.hypotheses,
        f.state,
        f.particles,
        f.particle_weights,
    ):
        with pytest.raises(FilterStateError, match="call initialise_global"):
            call()
    f.initialise_pose(log.true_poses[0], np.diag([0.01, 0.01, 0.01]))
    f.step(inc, log.scan(1))
    assert np.all(np.isfinite(f.estimate().pose))


@needs_wheel
def test_the_peer_refuses_a_seed_for_a_generator() -> None:
    from ceamcl.errors import InputTypeError
    from ceamcl.peers.nav2_amcl import make_nav2_amcl

    with pytest.raises(InputTypeError, match=r"rng: expected numpy\.random\.Generator, got int"):
        make_nav2_amcl(get_scenario("office").grid(), 3)  # type: ignore[arg-type]


@needs_wheel
def test_the_peer_names_a_wrong_argument_type() -> None:
    from ceamcl.errors import InputTypeError
    from ceamcl.peers.nav2_amcl import make_nav2_amcl

    grid, log, rng = office_log(3)
    f = make_nav2_amcl(grid, rng)
    with pytest.raises(InputTypeError, match=r"^scan: expected LaserScan, got ndarray"):
        f.initialise_global(log.ranges[0])  # type: ignore[arg-type]
    f.initialise_global(log.scan(0))
    with pytest.raises(InputTypeError, match=r"^increment: expected OdometryIncrement, got tuple"):
        f.step((0.1, 0.0, 0.0), log.scan(1))  # type: ignore[arg-type]


def test_the_peer_checks_its_initial_pose_and_increments_as_every_filter() -> None:
    # The wrapper took a NaN pose, a 2 x 2 covariance (reshape error) and NaN odometry without
    # a word, where the filters refuse them naming the field.
    from ceamcl.errors import CeamclError, ConfigError
    from ceamcl.motion.odometry import OdometryIncrement
    from ceamcl.peers.nav2_amcl import make_nav2_amcl

    grid, log, rng = office_log(3)
    f = make_nav2_amcl(grid, rng)
    with pytest.raises(ConfigError, match=r"^pose: expected three finite numbers"):
        f.initialise_pose([np.nan, 0.0, 0.0], np.eye(3))
    with pytest.raises(ConfigError, match=r"^pose: .*got array") as info:
        f.initialise_pose(np.full((3, 3), np.nan), np.eye(3))
    assert "\n" not in str(info.value)  # one line, even for an array's repr
    with pytest.raises(ConfigError, match=r"^covariance: expected a finite 3 x 3 matrix"):
        f.initialise_pose(log.true_poses[0], np.eye(2))
    with pytest.raises(ConfigError, match=r"^covariance: expected a positive semi-definite"):
        f.initialise_pose(log.true_poses[0], -np.eye(3))
    f.initialise_pose(log.true_poses[0], np.zeros((3, 3)))  # every particle on the pose: fine
    with pytest.raises(CeamclError, match=r"^odometry increment: expected finite"):
        f.step(OdometryIncrement(float("nan"), 0.1, 0.0), log.scan(1))
