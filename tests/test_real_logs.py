"""The real CARMEN logs of ``../shared/data/carmen``: parsing, mapping, global localisation,
and the three commands end to end. Skipped, saying why, where the data is absent."""

from __future__ import annotations

import csv
import json
from pathlib import Path

import numpy as np
import pytest

from ceamcl.cli import main
from ceamcl.experiments.log_windows import start_windows
from ceamcl.filters.ceamcl import CEAMCLConfig
from ceamcl.filters.registry import make_filter as _build
from ceamcl.io.logs import open_log
from ceamcl.io.tum import read_tum
from ceamcl.mapping import map_from_log
from ceamcl.maps.ros_io import load_map
from ceamcl.peers import available as peers_available
from ceamcl.replay import filter_rng as _filter_rng
from ceamcl.replay import obtain_map, prepare_log
from ceamcl.runner import run_filter

DATA = Path(__file__).resolve().parents[2] / "shared" / "data" / "carmen"
LOGS = {
    # name: (scans, beams per scan, ODOM lines)
    "intel": (910, 180, 14541),
    "freiburg-079": (4791, 360, 9725),
    "fhw": (488, 180, 13935),
}


def log_path(name: str) -> Path:
    path = DATA / f"{name}-corrected.log.gz"
    if not path.is_file():
        pytest.skip(f"real log {path} is absent (the shared data folder is not mounted)")
    return path


@pytest.mark.parametrize("name", list(LOGS))
def test_log_parses_with_the_right_counts(name: str) -> None:
    scans, beams, odom = LOGS[name]
    log = open_log(log_path(name))
    assert len(log) == scans
    assert set(log.beam_counts.tolist()) == {beams}
    assert log.info["message_counts"]["FLASER"] == scans
    assert log.info["message_counts"]["ODOM"] == odom
    assert log.info["skipped_messages"] == {"NEFF": scans}
    # timestamps run forward (intel has 4 small steps back, up to 0.86 s: kept as recorded)
    assert np.mean(np.diff(log.times) >= 0) > 0.99
    # FLASER geometry: first beam to the right, 1 or 0.5 degree apart (CARMEN's guess)
    assert log.angle_min[0] == pytest.approx(-np.pi / 2)
    assert log.angle_increment[0] == pytest.approx(np.pi / beams)


def test_no_return_readings_are_classified_as_max_range() -> None:
    log = open_log(log_path("freiburg-079"))
    r = log.ranges_flat
    no_return = r >= 81.9  # the SICK's 81.91 m code
    assert no_return.sum() > 1000
    assert np.all(r[no_return] >= log.range_max[0])
    assert np.all(r[~no_return] < log.range_max[0])


@pytest.fixture(scope="module")
def intel() -> tuple[object, object]:
    prepared = prepare_log(log_path("intel"), seed=0)
    grid, _ = obtain_map(prepared.log, None)
    return prepared, grid


def test_intel_map_has_plausible_size_and_free_area(intel: tuple[object, object]) -> None:
    prepared, grid = intel
    log = prepared.log  # type: ignore[attr-defined]
    w, h = grid.size_m  # type: ignore[attr-defined]
    # the Intel lab is a building of roughly 30 x 30 m
    assert 30 < w < 70 and 30 < h < 70
    assert 250 < grid.free_area_m2 < 1200  # type: ignore[attr-defined]
    assert grid.occupied_mask.sum() * 0.05**2 > 10  # type: ignore[attr-defined]
    # the robot drove through free space
    on_free = grid.is_free(log.true_poses[:, 0], log.true_poses[:, 1])  # type: ignore[attr-defined]
    assert on_free.mean() > 0.95


def test_ceamcl_localises_globally_on_intel(intel: tuple[object, object]) -> None:
    """From 3 evenly spread starts, 30 m windows: CEAMCL's hypotheses hold the true pose at
    the end of the window (closest hypothesis within 0.5 m) in most runs."""
    prepared, grid = intel
    log = prepared.log  # type: ignore[attr-defined]
    windows, _ = start_windows(log, 3, window_m=30.0)
    found = []
    for s, e in windows:
        window = log.window(s, e)
        f = _build("ceamcl", grid, _filter_rng(0, s, "ceamcl"))  # type: ignore[arg-type]
        result = run_filter(f, window)
        hyps = result.hypotheses[-1]
        truth = window.true_poses[-1]
        found.append(float(np.min(np.hypot(hyps[:, 0] - truth[0], hyps[:, 1] - truth[1]))) < 0.5)
    assert sum(found) >= 2, found


def test_a_windows_mean_particles_leave_the_initialisation_out(
    intel: tuple[object, object],
) -> None:
    """The mean sample size of an evaluate-log run is over the scans after the global
    initialisation, as its step time is (the test poses' population at the first scan lifted
    it by a fifth on short windows)."""
    from ceamcl.experiments.evaluate_log import LogTrial, run_log_trial

    prepared, grid = intel
    window = prepared.log.window(0, 40)  # type: ignore[attr-defined]
    out = run_log_trial(LogTrial("w", "ceamcl", 0, grid, window, 0))  # type: ignore[arg-type]
    f = _build("ceamcl", grid, _filter_rng(0, 0, "ceamcl"))  # type: ignore[arg-type]
    sizes = [d.n_particles for d in run_filter(f, window).diagnostics]
    assert sizes[0] > np.mean(sizes[1:])  # the initial population would lift the mean
    assert out.mean_particles == pytest.approx(np.mean(sizes[1:]))


def test_map_from_log_cli_writes_a_map_that_loads_back(tmp_path: Path) -> None:
    path = log_path("fhw")
    out = tmp_path / "fhw.yaml"
    assert main(["map-from-log", str(path), "--resolution", "0.1", "-o", str(out), "--quiet"]) == 0
    from ceamcl.mapping import MappingConfig

    expected, _ = map_from_log(open_log(path), MappingConfig(resolution_m=0.1))
    assert load_map(out) == expected
    # with a laser mount, the map `ceamcl run --laser-mount` builds and localises in
    mounted = tmp_path / "fhw-mounted.yaml"
    argv = ["map-from-log", str(path), "--laser-mount", "0.1,0,0", "-o", str(mounted), "--quiet"]
    assert main(argv) == 0
    runs_map, _ = obtain_map(prepare_log(path, laser_mount=(0.1, 0.0, 0.0)).map_log, None)
    assert load_map(mounted) == runs_map


def test_run_cli_writes_every_output(tmp_path: Path) -> None:
    path = log_path("fhw")
    out = tmp_path / "run"
    code = main(
        ["run", str(path), "--algorithm", "mcl", "--seed", "3", "--out", str(out), "--quiet"]
    )
    assert code == 0
    for name in ("trajectory.tum", "groundtruth.tum", "summary.json", "run.png", "diagnostics.csv"):
        assert (out / name).is_file(), name
    summary = json.loads((out / "summary.json").read_text())
    assert summary["odometry"] == "synthetic"
    assert summary["odometry_noise"]["seed"] == 3
    assert "built from the log itself" in summary["map"]
    t, poses = read_tum(out / "groundtruth.tum")
    assert t.size == 488
    np.testing.assert_allclose(poses[:, :2], open_log(path).poses[:, :2], atol=1e-6)


def test_evaluate_log_cli_small(tmp_path: Path) -> None:
    path = log_path("intel")
    out = tmp_path / "ev"
    argv = [
        "evaluate-log",
        str(path),
        "--starts",
        "2",
        "--algorithms",
        "mcl",
        "--scans",
        "6",
        "--hold",
        "3",
        "--executor",
        "serial",
        "--out",
        str(out),
        "--quiet",
    ]
    assert main(argv) == 0
    rows = (out / "evaluate.csv").read_text().splitlines()
    assert len(rows) == 3 and rows[0].startswith("algorithm,start_index")
    assert [r.split(",")[1] for r in rows[1:]] == ["0", "904"]
    # every pose scored, the initialisation's included: 5000 at the start, 5000 an update
    for row in csv.DictReader(rows):
        assert float(row["likelihood_evaluations"]) == 5000 * (1 + int(row["updates"]))
    assert "| mcl | 2 |" in (out / "evaluate.md").read_text()
    assert (out / "errors.png").is_file() and (out / "success.png").is_file()


def test_evaluate_log_compares_evaluations_where_both_localised(tmp_path: Path) -> None:
    """Issue 17's "at equal success": evaluate.md compares the first algorithm's likelihood
    evaluations with each other's over the windows both localised, as evaluate.csv has them."""
    out = tmp_path / "ev"
    argv = ["evaluate-log", str(log_path("intel")), "--starts", "3", "--scans", "8"]
    argv += ["--hold", "3", "--algorithms", "mcl-tuned", "mcl", "--executor", "serial"]
    assert main([*argv, "--out", str(out), "--quiet"]) == 0
    with (out / "evaluate.csv").open() as fh:
        runs = {(r["algorithm"], r["start_index"]): r for r in csv.DictReader(fh)}
    both = [
        s
        for (a, s), r in runs.items()
        if a == "mcl" and r["success"] == "True" and runs[("mcl-tuned", s)]["success"] == "True"
    ]
    text = (out / "evaluate.md").read_text()
    assert "## Likelihood evaluations at equal success" in text
    (line,) = [ln for ln in text.splitlines() if ln.startswith("| mcl-tuned / mcl |")]
    cells = [c.strip() for c in line.split("|")[2:-1]]
    assert int(cells[0]) == len(both)
    if both:  # the pair's means, from the runs' own counts
        mine = np.mean([float(runs[("mcl-tuned", s)]["likelihood_evaluations"]) for s in both])
        theirs = np.mean([float(runs[("mcl", s)]["likelihood_evaluations"]) for s in both])
        assert float(cells[1]) == pytest.approx(mine, abs=0.5)
        assert float(cells[2]) == pytest.approx(theirs, abs=0.5)
        assert float(cells[3]) == pytest.approx(mine / theirs, abs=5e-4)
    else:
        assert cells[3] == "-"


@pytest.mark.skipif(not peers_available(), reason="Nav2 AMCL wheel not installed")
def test_evaluate_log_says_nav2_amcl_is_not_comparable_in_global_localisation(
    tmp_path: Path,
) -> None:
    """Issue 17: the wheel has no uniform global initialisation, so evaluate-log's row of
    nav2-amcl says "not comparable" where the others give a success rate, and evaluate.csv
    keeps its measured runs, marked."""
    out = tmp_path / "ev"
    argv = ["evaluate-log", str(log_path("intel")), "--starts", "1", "--scans", "6"]
    argv += ["--hold", "3", "--algorithms", "mcl", "nav2-amcl", "--executor", "serial"]
    assert main([*argv, "--out", str(out), "--quiet"]) == 0
    text = (out / "evaluate.md").read_text()
    rows = {line.split("|")[1].strip(): line for line in text.splitlines() if line.startswith("| ")}
    assert rows["nav2-amcl"].split("|")[3].strip() == "not comparable"
    assert rows["mcl"].split("|")[3].strip().endswith("%")
    # the wheel hides its particle count: its max_particles is printed as a bound
    assert rows["nav2-amcl"].split("|")[11].strip() == "<= 2000"
    assert rows["mcl"].split("|")[11].strip() == "5000"
    assert "nav2-amcl: global localisation not comparable" in text
    with (out / "evaluate.csv").open() as fh:
        marked = {r["algorithm"]: r["localises_globally"] for r in csv.DictReader(fh)}
    assert marked == {"mcl": "True", "nav2-amcl": "False"}


def test_the_kidnap_test_reads_the_fittest_individual() -> None:
    """docs/ceamcl.md, departure 26. freiburg-079-corrected, seed 1, the protocol's first
    window: read from the fittest species' *mean* fitness, the kidnap test fires at update 114
    while the estimate is within 0.1 m of the truth (the motion spread the samples: mean 0.10,
    best individual 0.84), and each such recovery scores a map-wide search (150 test poses a
    square metre since departure 28, some 140,000 here; 450, some 500,000, before). Read as the
    state reads a species (its fittest individual), no recovery fires in the window and the
    filter ends on the truth."""
    from ceamcl.experiments.metrics import likelihood_evaluations
    from ceamcl.filters.registry import with_config
    from ceamcl.replay import choose_pace, make_paced_filter

    prepared = prepare_log(log_path("freiburg-079"), seed=1)
    grid, _ = obtain_map(prepared.map_log, None, own=True)
    pace = choose_pace(prepared, None, None, every_scan=False)  # None: a corrected log's every scan
    (start, stop), *_ = start_windows(prepared.log, 10, window_m=50.0)[0]
    window = prepared.log.window(start, stop)
    runs = {}
    for reads in ("fittest", "mean"):
        cfg = with_config("ceamcl", recovery_reads=reads)
        f = make_paced_filter("ceamcl", grid, _filter_rng(1, start, "ceamcl"), config=cfg)
        runs[reads] = run_filter(f, window, update_when=None if pace is None else pace.policy())
    fired = {
        reads: [k for k, d in enumerate(r.diagnostics) if k > 0 and d.reinitialised]
        for reads, r in runs.items()
    }
    err = {reads: r.position_errors for reads, r in runs.items()}
    assert err["fittest"] is not None and err["mean"] is not None
    assert fired["fittest"] == []
    assert err["fittest"][-1] < 0.3
    # the mean's false alarms: recoveries on a filter that stood on the truth
    assert fired["mean"] and all(err["mean"][k - 1] < 0.3 for k in fired["mean"])
    spent = {reads: likelihood_evaluations(r.diagnostics).sum() for reads, r in runs.items()}
    search = CEAMCLConfig().recovery_initialisation.test_pose_count(grid.free_area_m2)
    assert spent["mean"] > spent["fittest"] + search * len(fired["mean"])


def test_the_synthetic_odometry_does_not_turn_the_robot_off_the_track_while_it_stands() -> None:
    """freiburg-079-corrected, the windowed protocol's window from scan 684, seed 3: before
    it reaches its poorly mapped last room the SLAM track jitters sideways while the robot
    stands, and the synthetic odometry read each jitter as a turn out of pi/2 and back, turning
    the robot about a radian at random; the species followed it off the track and found the
    truth again too late to hold (docs/real-data.md, "Synthetic odometry that does not turn
    with the SLAM's jitter"). With the old noise the window fails in seeds 3, 4, 7 and 8 of
    1-8 (measured 2026-12-02, with the field's end points read half a cell farther). Seed 2,
    chosen before that, now falls 0.4-2.6 m behind in the last room and holds too late, as
    seed 6 did then; with the old noise it holds there by chance."""
    from ceamcl.experiments.evaluate_log import log_trials, run_log_trial
    from ceamcl.experiments.metrics import DEFAULT_HOLD_M

    prepared = prepare_log(log_path("freiburg-079"), seed=3)
    grid, _ = obtain_map(prepared.map_log, None, own=True)
    windows, _ = start_windows(prepared.log, 10, window_m=50.0)
    at_684 = [w for w in windows if w[0] == 684]
    (trial,) = log_trials(prepared, grid, ["ceamcl"], at_684, hold_m=DEFAULT_HOLD_M)
    result = run_log_trial(trial)
    assert result.success
    assert not result.confidently_wrong
