"""Raw Radish logs (``../shared/data/carmen-raw``) with truth from their corrected logs
(``--truth-from``), replayed at a real robot's pace. The logs are cut to their first few
hundred scans (written to a temporary folder) to keep ``make test`` fast. Skipped, saying why,
where the shared data is absent."""

from __future__ import annotations

import csv
import gzip
import json
import re
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from ceamcl.cli import main
from ceamcl.io.tum import read_tum
from ceamcl.pose import relative_poses

DATA = Path(__file__).resolve().parents[2] / "shared" / "data"
RAW = DATA / "carmen-raw" / "fr079.clf.gz"
CORRECTED = DATA / "carmen" / "freiburg-079-corrected.log.gz"
OTHER = DATA / "carmen" / "intel-corrected.log.gz"
#: the initialisation the doubtful-room scenarios below were traced with (the default until
#: docs/ceamcl.md's departure 24): 1,500 uniform test poses per m^2 in one round, recoveries at
#: the same density, a recovery's far places at the kidnap odds of then (1e-6, until departure
#: 28). A recovery's proposals depend on it; with the default's the same seeds meet other
#: places, and with 1e-9 the far place of the last test below never takes the estimate.
ONE_ROUND: dict[str, Any] = {
    "test_poses_per_m2": 1500.0,
    "init_refine_share": 0.0,
    "test_pose_headings": None,
    "recovery_test_poses_per_m2": None,
    "recovery_n_test": None,  # recoveries searched as the first search did (10^6 on fr079)
    "recovery_prior": 1e-6,
}
#: the far-place scenario of departure 23 as traced: ``ONE_ROUND``, the evidence memory of
#: its time (0.9 a step; 0.93 since departure 33) and a start's evidence without departure
#: 43's climb (before 2026-12-03)
FAR_PLACE_SCENARIO: dict[str, Any] = {
    **ONE_ROUND,
    "evidence_memory": 0.9,
    "evidence_climb_at_start": False,
}
#: the likelihood field's end-point offset the doubtful-room scenarios were traced with: ROS
#: amcl's lookup, each range scored where it ends (half a cell farther since 2026-12-02,
#: docs/sensor-models.md). The same seeds take other courses with the default; where a
#: scenario no longer arises with it, its test runs the traced one and says so.
AMCL_LOOKUP = 0.0


def known_miss(seed: int, reason: str) -> Any:
    """A seed of a parametrised run that is expected to miss, for the reason given (strict:
    the test says when it stops missing)."""
    return pytest.param(seed, marks=pytest.mark.xfail(strict=True, reason=reason))


def need(*paths: Path) -> None:
    for p in paths:
        if not p.is_file():
            pytest.skip(f"real log {p} is absent (the shared data folder is not mounted)")


def head_of_log(src: Path, dst: Path, scans: int) -> Path:
    """The log's lines up to (and with) its ``scans``-th FLASER line, as a plain file."""
    kept = 0
    with gzip.open(src, "rt") as fin, dst.open("w") as fout:
        for line in fin:
            fout.write(line)
            if line.startswith("FLASER"):
                kept += 1
                if kept == scans:
                    break
    return dst


@pytest.fixture(scope="module")
def cut_logs(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, Path]:
    need(RAW, CORRECTED)
    folder = tmp_path_factory.mktemp("raw")
    raw = head_of_log(RAW, folder / "fr079-head.clf", 300)
    corrected = head_of_log(CORRECTED, folder / "fr079-corrected-head.log", 250)
    return raw, corrected


def test_run_raw_with_truth_from_the_corrected_log(
    cut_logs: tuple[Path, Path], tmp_path: Path
) -> None:
    raw, corrected = cut_logs
    out = tmp_path / "run"
    args = ["run", str(raw), "--truth-from", str(corrected), "--algorithm", "mcl"]
    code = main([*args, "--quiet", "--out", str(out)])
    assert code == 0
    summary = json.loads((out / "summary.json").read_text())
    pairing = summary["truth_pairing"]
    assert summary["scans"] == 300 and summary["odometry"] == "recorded"
    assert 200 <= pairing["matched_scans"] <= 250
    # fr079's laser sits 4 cm behind its robot's centre: the truth is the robot's pose
    assert pairing["mount_moved_pairs"] == pairing["matched_scans"]
    assert abs(pairing["mount_shift_m"] - 0.04) < 1e-3
    assert np.allclose(pairing["laser_mount_used"], [-0.04, 0.0, 0.0], atol=1e-4)
    assert "corrected log" in summary["map"]  # the raw odometry drifts: map from the truth
    # the filter was stepped at the robot's pace, not at every scan
    assert summary["update_policy"].startswith("update when moved 0.25 m or turned 0.2 rad")
    assert 0 < summary["updates"] < 299
    # groundtruth.tum at the matched scans, trajectory.tum at every scan, both evo-readable
    t_truth, truth = read_tum(out / "groundtruth.tum")
    t_est, _ = read_tum(out / "trajectory.tum")
    assert t_truth.size == pairing["matched_scans"] and t_est.size == 300
    assert np.all(np.isfinite(truth)) and set(t_truth) <= set(t_est)
    assert np.isfinite(summary["final_position_error_m"])
    fit = summary["truth_fit"]  # how well the truth explains its scans on the map
    assert 0.5 < fit["median_share"] <= 1 and isinstance(fit["doubtful_scans"], list)


def test_a_laser_mount_given_replaces_the_logs(cut_logs: tuple[Path, Path], tmp_path: Path) -> None:
    """``--laser-mount``: the filter's laser sits there at every scan and the truth is the
    robot's under it (the corrected log's laser pose less that mount), as summary.json says."""
    raw, corrected = cut_logs
    out = tmp_path / "run"
    args = ["run", str(raw), "--truth-from", str(corrected), "--algorithm", "mcl"]
    assert main([*args, "--laser-mount=0.092,0.005,0", "--quiet", "--out", str(out)]) == 0
    pairing = json.loads((out / "summary.json").read_text())["truth_pairing"]
    assert pairing["laser_mount_used"] == [0.092, 0.005, 0.0]
    assert pairing["mount_moved_pairs"] == pairing["matched_scans"]
    assert abs(pairing["mount_shift_m"] - np.hypot(0.092, 0.005)) < 1e-6


def test_logs_of_different_runs_are_a_one_line_error(
    cut_logs: tuple[Path, Path], tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    need(OTHER)
    raw, _ = cut_logs
    out = tmp_path / "run"
    code = main(["run", str(raw), "--truth-from", str(OTHER), "--quiet", "--out", str(out)])
    err = capsys.readouterr().err.strip()
    assert code != 0
    assert "none of its 910 scans has the ranges of a scan of" in err
    assert len(err.splitlines()) == 1
    assert not out.exists()  # nothing half-done left behind


def test_evaluate_log_raw_with_truth_from(
    cut_logs: tuple[Path, Path], tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    raw, corrected = cut_logs
    out = tmp_path / "ev"
    args = ["evaluate-log", str(raw), "--truth-from", str(corrected), "--starts", "2"]
    args += ["--scans", "120", "--algorithms", "mcl", "kld-amcl", "--executor", "serial"]
    assert main([*args, "--out", str(out)]) == 0
    # at the pace most scans only add their odometry: the console gives the updates' cost
    said = " ".join(capsys.readouterr().out.split())
    runs = list(csv.DictReader((out / "evaluate.csv").open()))
    update = {
        a: np.mean([float(r["mean_update_ms"]) for r in runs if r["algorithm"] == a])
        for a in ("mcl", "kld-amcl")
    }
    printed = re.search(
        r"update mean / median \(the scans that updated the filter\): "
        r"mcl ([\d.]+) / ([\d.]+) ms, kld-amcl ([\d.]+) / ([\d.]+) ms",
        said,
    )
    assert printed, said
    for algo, (mean, median) in zip(
        ("mcl", "kld-amcl"), ((printed[1], printed[2]), (printed[3], printed[4])), strict=True
    ):
        assert mean == f"{update[algo]:.1f}"
        # the median of both runs' updates pooled lies between the runs' own medians
        own = [float(r["median_update_ms"]) for r in runs if r["algorithm"] == algo]
        assert min(own) - 0.05 <= float(median) <= max(own) + 0.05
    md = (out / "evaluate.md").read_text()
    assert "at the 250 of 300 scans that match" in md
    assert "filter updates (every algorithm): update when moved 0.25 m" in md
    rows = (out / "evaluate.csv").read_text().splitlines()
    assert len(rows) == 1 + 2 * 2
    header = rows[0].split(",")
    upd = [int(r.split(",")[header.index("updates")]) for r in rows[1:]]
    # the same windows and the same pace: both algorithms are stepped equally often
    assert upd[0] == upd[1] and upd[2] == upd[3] and 0 < upd[0] < 119
    assert (out / "errors.png").is_file()
    assert "ground truth vs the map: a median" in (out / "evaluate.md").read_text()
    # the seed is on record for a raw log too (it was only in a synthetic odometry's line)
    assert "- seed: 0 (the filters' generators" in md
    assert all(r.split(",")[header.index("seed")] == "0" for r in rows[1:])


def test_evaluate_log_and_run_weigh_with_the_sensor_model_asked_for(
    cut_logs: tuple[Path, Path], tmp_path: Path
) -> None:
    """``--sensor beam`` (Nav2's ``laser_model_type``): the report names it, and the runs are
    the beam model's, not the default field's (the same windows, seed and pace)."""
    raw, corrected = cut_logs
    base = ["evaluate-log", str(raw), "--truth-from", str(corrected), "--starts", "1"]
    base += ["--scans", "120", "--algorithms", "mcl", "--executor", "serial", "--quiet"]
    rows = {}
    for sensor in ("likelihood-field", "beam"):
        out = tmp_path / sensor
        assert main([*base, "--sensor", sensor, "--out", str(out)]) == 0
        assert f"- sensor model: {sensor} for every algorithm" in (out / "evaluate.md").read_text()
        rows[sensor] = next(csv.DictReader((out / "evaluate.csv").open()))
    assert rows["beam"]["updates"] == rows["likelihood-field"]["updates"]  # the same pace
    assert (
        rows["beam"]["position_rmse_from_first_m"]
        != rows["likelihood-field"]["position_rmse_from_first_m"]
    )
    out = tmp_path / "run"
    args = ["run", str(raw), "--truth-from", str(corrected), "--algorithm", "mcl"]
    assert main([*args, "--sensor", "beam", "--quiet", "--out", str(out)]) == 0
    assert json.loads((out / "summary.json").read_text())["sensor"] == "beam"


def test_evaluate_log_tracking_with_the_beam_model(
    cut_logs: tuple[Path, Path], tmp_path: Path
) -> None:
    raw, corrected = cut_logs
    out = tmp_path / "tr"
    args = ["evaluate-log", str(raw), "--truth-from", str(corrected), "--tracking"]
    args += ["--sensor", "beam", "--algorithms", "ceamcl", "--particles", "200"]
    assert main([*args, "--executor", "serial", "--quiet", "--out", str(out)]) == 0
    md = (out / "tracking.md").read_text()
    assert "- sensor model: beam for every algorithm but nav2-amcl" in md
    row = next(csv.DictReader((out / "tracking.csv").open()))
    # from 0.5 m off, the beam model's scans bring the estimate onto the truth and keep it
    assert float(row["ape_median_m"]) < 0.2 and float(row["ape_rmse_m"]) < 0.3


INTEL_RAW = DATA / "carmen-raw" / "intel.clf.gz"


def _track_intel_raw(scans: int, seed: int, **config: Any) -> Any:
    """CEAMCL (``config`` on top of its defaults) tracking intel raw's first ``scans`` scans
    from the first with truth, at Nav2's pace, from the true pose perturbed by 0.5 m / 0.3
    rad with ``seed``: the run (:class:`~ceamcl.runner.RunResult`)."""
    need(INTEL_RAW, OTHER)
    from ceamcl.experiments.tracking_log import perturbed_start, start_covariance
    from ceamcl.filters.registry import with_config
    from ceamcl.replay import UpdatePace, filter_rng, make_paced_filter, obtain_map, prepare_log
    from ceamcl.runner import run_filter

    prepared = prepare_log(INTEL_RAW, truth_from=OTHER)
    grid, _ = obtain_map(prepared.map_log, None, own=False)
    log = prepared.log
    first = int(np.flatnonzero(log.has_truth_at)[0])
    window = log.window(first, first + scans)
    assert window.true_poses is not None
    cfg = with_config("ceamcl", **config)
    f = make_paced_filter("ceamcl", grid, filter_rng(seed, 0, "ceamcl"), config=cfg)
    start = (perturbed_start(window.true_poses[0], seed), start_covariance())
    return run_filter(f, window, update_when=UpdatePace().policy(), initial_pose=start)


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_ceamcl_tracks_intel_through_unmapped_clutter(seed: int) -> None:
    """Intel's first 700 raw scans, tracked from the true pose perturbed by 0.5 m / 0.3 rad:
    from raw scan ~190 on the laser sees obstacles the map lacks and the log-likelihood at the
    true pose falls by about 25 (docs/real-data.md). Leaving out the short readings no
    hypothesis explains (beam skipping), CEAMCL stays on the truth and no recovery fires;
    weighing every beam, its recovery fired twice and it ended 12-18 m away (seeds 0-2)."""
    need(INTEL_RAW, OTHER)
    result = _track_intel_raw(700, seed, tracking_samples=2000)
    errors = result.position_errors
    assert errors is not None
    known = result.truth_known
    assert known.sum() >= 40
    assert not any(d.record.columns().get("recoveries", 0) for d in result.diagnostics)
    assert errors[known][5:].max() < 0.5  # after the first 5 matched scans (the start's 0.5 m)


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_ceamcl_reads_intels_track_closer_at_the_full_likelihood(seed: int) -> None:
    """Intel's first 3,000 raw scans tracked at Nav2's pace with 200 samples, from the true
    pose perturbed by 0.5 m / 0.3 rad: the estimate read at the scan's untempered likelihood
    (``estimate_likelihood="full"``, docs/ceamcl.md departure 35) is closer to the truth than
    the species' mean (the default), in RMSE and median. The filter runs the same either way
    (the estimate feeds nothing back). Measured: 0.090-0.097 m against 0.098-0.115 m RMSE
    (seeds 0-2); over the whole log 0.091-0.094 against 0.105-0.109 m (seeds 0-3). Not the
    default: on other buildings and with odometry as the motion model has it, the mean is as
    close or closer (docs/ceamcl.md)."""
    need(INTEL_RAW, OTHER)
    errors = {}
    for reading in ("full", "tempered"):
        result = _track_intel_raw(3000, seed, tracking_samples=200, estimate_likelihood=reading)
        assert result.position_errors is not None
        errors[reading] = result.position_errors[result.truth_known]
    full, tempered = errors["full"], errors["tempered"]
    assert full.size == tempered.size >= 150
    assert np.sqrt(np.mean(full**2)) < np.sqrt(np.mean(tempered**2))
    assert np.median(full) < np.median(tempered)


@pytest.fixture(scope="module")
def fr079_raw() -> tuple[Any, Any]:
    """The whole raw fr079 log with its truth, and the map built from the corrected log; its
    odometry *as recorded* (unsigned: the tests below exercise what the filter does about a
    wheel odometry that reports backing up as moving forward; the reader now repairs it by
    default, ``test_fr079s_odometry_takes_the_sign_of_its_velocity``)."""
    need(RAW, CORRECTED)
    from ceamcl.replay import obtain_map, prepare_log

    prepared = prepare_log(RAW, truth_from=CORRECTED, odometry_sign="recorded")
    grid, _ = obtain_map(prepared.map_log, None, own=False)
    return prepared, grid


@pytest.mark.parametrize(
    "seed",
    # seed 1 missed from 2026-12-02 (the third recovery's place 10.5 m off took the run to its
    # end) until departure 43 (2026-12-03: the climb at a recovery's scan): seeds 0-13 now end
    # within 0.09 m, at most 2.2 m off on the way, after 2-4 recoveries
    [0, 1, 2],
)
def test_ceamcl_recovers_near_the_track_after_fr079s_odometry_fault(
    seed: int, fr079_raw: tuple[Any, Any]
) -> None:
    """fr079 raw, scans 780-960, tracked from the true pose perturbed by 0.5 m / 0.3 rad: at
    scans 854-859 the robot backs up while its wheel odometry reports the motion forward (the
    log's odometry never moves backwards; docs/ceamcl.md, departure 12), and through
    scans 842-878 the scans fit the true pose worse than places 12-28 m away (tempered
    log-likelihood -1 to -9 at the truth, about 0 there; docs/ceamcl.md, departure 11). The
    recoveries this fires find species at the truth; starting level with the kept species
    (within ``recovery_drift_m``) and ahead of the far places by ``recovery_prior`` that does
    not fade, they keep the estimate within a few metres and end on the truth. With the
    recovery of departure 9 (every new species at a fading ``recovery_prior``) the estimate
    went 25-28 m away (seeds 0-4). The recovery alone, without departure 12's look-around
    (which often keeps the species on the truth here without any recovery)."""
    from ceamcl.experiments.tracking_log import perturbed_start, start_covariance
    from ceamcl.filters.registry import with_config
    from ceamcl.replay import UpdatePace, filter_rng, make_paced_filter
    from ceamcl.runner import run_filter

    prepared, grid = fr079_raw
    window = prepared.log.window(780, 960)
    assert window.true_poses is not None
    known = np.all(np.isfinite(window.true_poses), axis=1)
    first = int(np.flatnonzero(known)[0])
    pace = UpdatePace()
    cfg = with_config("ceamcl", tracking_samples=2000, look_around_m=None)
    f = make_paced_filter("ceamcl", grid, filter_rng(seed, 0, "ceamcl"), config=cfg)
    start = (perturbed_start(window.true_poses[first], seed), start_covariance())
    result = run_filter(f, window, update_when=pace.policy(), initial_pose=start)
    errors = result.position_errors
    assert errors is not None
    assert any(d.record.columns().get("recoveries", 0) for d in result.diagnostics)
    scored = errors[result.truth_known]
    assert scored.size >= 150
    assert scored[5:].max() < 6.0  # measured 0.20-0.23 m (seeds 0-5; 3.1-3.9 m in an earlier code)
    assert scored[-1] < 0.5


def _track_fr079(
    fr079_raw: tuple[Any, Any], first: int, last: int, seed: int, **settings: Any
) -> tuple[Any, Any]:
    """fr079 raw scans ``first``-``last`` tracked by CEAMCL (2,000-sample budget, Nav2's
    pace) from the true pose at ``first`` perturbed by 0.5 m / 0.3 rad."""
    from ceamcl.experiments.tracking_log import perturbed_start, start_covariance
    from ceamcl.filters.registry import with_config
    from ceamcl.replay import UpdatePace, filter_rng, make_paced_filter
    from ceamcl.runner import run_filter

    prepared, grid = fr079_raw
    window = prepared.log.window(first, last)
    assert window.true_poses is not None and np.all(np.isfinite(window.true_poses[0]))
    pace = UpdatePace()
    cfg = with_config("ceamcl", tracking_samples=2000, **settings)
    f = make_paced_filter("ceamcl", grid, filter_rng(seed, 0, "ceamcl"), config=cfg)
    start = (perturbed_start(window.true_poses[0], seed), start_covariance())
    result = run_filter(f, window, update_when=pace.policy(), initial_pose=start)
    assert result.position_errors is not None
    return result, result.position_errors[result.truth_known]


@pytest.mark.parametrize(
    "seed",
    [
        0,
        1,
        known_miss(
            2,
            "with the field's end points read half a cell farther (2026-12-02) seed 2 strays "
            "5.95 m and spends one recovery, as seeds 3 and 5 strayed 6.0 m before (without "
            "one); seeds 0, 1 and 3-7 stay within 0.91 m and end within 0.12 m",
        ),
    ],
)
def test_ceamcl_follows_fr079_backing_up_with_unsigned_odometry(
    seed: int, fr079_raw: tuple[Any, Any]
) -> None:
    """fr079 raw, scans 1300-1460: at scans 1405-1433 the robot backs up about 3 m while its
    wheel odometry reports the same motion forward (0.5 m wrong an update at Nav2's pace).
    Looking around when the lone species fits poorly (departure 12), CEAMCL follows the scans
    with no recovery (largest error 0.87-0.97 m in seeds 0-2, mostly between updates, where
    the odometry alone carries the estimate); without it two recoveries fired in every seed and
    the error reached 1.67-2.33 m. Measured again 2026-11-30 over seeds 0-7: seeds 3 and 5
    stray 6.0 m without a recovery, and every seed ends within 0.16 m. The default's noise per
    stride of travel leaves these updates as amcl's rule has them (none spans 0.5 m); strides
    of 0.25 m (measured, not adopted) had seeds 1 and 4 spend a recovery each."""
    result, errors = _track_fr079(fr079_raw, 1300, 1460, seed)
    assert errors.size >= 140
    assert not any(d.record.columns().get("recoveries", 0) for d in result.diagnostics)
    assert any(d.record.columns().get("look_arounds", 0) for d in result.diagnostics)
    assert errors[5:].max() < 1.3
    assert errors[-1] < 0.5


def test_fr079s_truth_is_doubtful_in_one_room(fr079_raw: tuple[Any, Any]) -> None:
    """At the true poses (the corrected log's laser poses, less fr079's laser mount), fr079
    raw's scans fit the map built from that log (a median 90 % of the end points within 0.15 m
    of an obstacle), except in one room, scans 1148-1239 (down to 4 %), where every filter's
    error measures the truth as much as the filter (docs/real-data.md, departure 12). Elsewhere
    the share dips below a half only for a few scans (measured: 1626-1633, lowest 0.46)."""
    from ceamcl.io.truth_check import doubtful_truth

    prepared, grid = fr079_raw
    doubt = doubtful_truth(prepared.log, grid)
    assert 0.85 < doubt.median < 0.95
    room = [(a, b, low) for a, b, low in doubt.stretches if b - a >= 20]
    ((first, last, lowest),) = room
    assert 1140 <= first <= 1150 and 1235 <= last <= 1245
    assert lowest < 0.1
    assert all(low > 0.3 for a, b, low in doubt.stretches if b - a < 20)


def _local_steps(poses: np.ndarray) -> np.ndarray:
    """Each increment's translation in the robot's frame."""
    return relative_poses(poses[:-1], poses[1:])[:, :2]


def test_fr079s_odometry_takes_the_sign_of_its_velocity() -> None:
    """fr079's raw odometry never moves backwards, though its ODOM lines record a negative
    velocity while the robot backs up. Read with the default ``odometry_sign="auto"``, each
    increment takes the velocity's sign: where the truth backs up by more than 3 cm between
    two consecutive scans, the odometry's increment is within a few centimetres of the
    truth's (measured: mean 0.044 m, against 0.130 m as recorded; 121 of 168 now backwards)."""
    need(RAW, CORRECTED)
    from ceamcl.io.carmen import read_carmen
    from ceamcl.io.truth import pair_truth

    corrected = read_carmen(CORRECTED)
    assert "odometry_sign" not in corrected.info  # no velocity recorded: left alone
    errors = {}
    for sign in ("auto", "recorded"):
        raw = read_carmen(RAW, odometry_sign=sign)
        pairing = pair_truth(raw, corrected)
        consecutive = np.diff(pairing.raw_index) == 1
        odo = _local_steps(np.asarray(raw.poses)[pairing.raw_index])
        truth = _local_steps(pairing.truth_poses)
        back = consecutive & (truth[:, 0] < -0.03)
        assert back.sum() > 100
        errors[sign] = (np.hypot(*(odo - truth)[back].T).mean(), (odo[back, 0] < -0.01).mean())
    assert "no sign" in read_carmen(RAW).info["odometry_sign"]
    assert errors["recorded"][1] == 0.0  # as recorded, never backwards
    assert errors["auto"][1] > 0.5
    assert errors["auto"][0] < 0.5 * errors["recorded"][0]


def _fr079_tracking_errors(
    seed: int,
    end: int,
    samples: int = 2000,
    lookup: float | None = None,
    every_scan: bool = False,
    **config: Any,
) -> tuple[np.ndarray, np.ndarray]:
    """CEAMCL (a budget of ``samples``, ``config`` on top) tracking fr079 raw at Nav2's pace
    (or ``every_scan``) from the first scan with truth, perturbed by 0.5 m / 0.3 rad with
    ``seed``, to scan ``end``: each scan's raw-log index and position error (NaN without
    truth). ``lookup``: the likelihood field's ``end_point_offset_m`` (``None``: the
    default's)."""
    from ceamcl.experiments.tracking_log import perturbed_start, start_covariance
    from ceamcl.filters.registry import with_config
    from ceamcl.replay import UpdatePace, filter_rng, make_paced_filter, obtain_map, prepare_log
    from ceamcl.runner import run_filter
    from ceamcl.sensors.likelihood_field import LikelihoodFieldConfig, LikelihoodFieldModel

    prepared = prepare_log(RAW, truth_from=CORRECTED)
    grid, _ = obtain_map(prepared.map_log, None, own=False)
    first = int(np.flatnonzero(prepared.log.has_truth_at)[0])
    window = prepared.log.window(first, end)
    assert window.true_poses is not None
    pace = UpdatePace()
    cfg = with_config("ceamcl", tracking_samples=samples, **config)
    sensor = LikelihoodFieldModel(grid, LikelihoodFieldConfig(end_point_offset_m=lookup))
    f = make_paced_filter("ceamcl", grid, filter_rng(seed, 0, "ceamcl"), config=cfg, sensor=sensor)
    start = (perturbed_start(window.true_poses[0], seed), start_covariance())
    when = None if every_scan else pace.policy()
    result = run_filter(f, window, update_when=when, initial_pose=start)
    errors = result.position_errors
    assert errors is not None
    return np.arange(len(window)) + first, np.where(result.truth_known, errors, np.nan)


@pytest.mark.parametrize(
    ("anchor", "init", "room_max"),
    [(20.0, {}, 2.0), (20.0, ONE_ROUND, 2.0), (None, ONE_ROUND, None)],
)
def test_ceamcl_holds_fr079s_track_through_the_doubtful_room(
    anchor: float | None, init: dict[str, Any], room_max: float | None
) -> None:
    """fr079 raw (odometry read with its sign), tracked from the first scan with truth,
    perturbed by 0.5 m / 0.3 rad, seed 1, to scan 1450. In the room of scans 1148-1239 the map
    lacks what the scans show: the tracked species drifts and recoveries fire. Without the
    last confident pose (``recovery_anchor_m=None``: departure 14, and with it the coasting
    and holding of departures 15-19 that read it) every new species beyond
    ``recovery_drift_m`` of the drifted ones starts at ``recovery_prior`` and nothing holds
    the estimate: a place far away leads in the room (measured 29.3 m off). With it, the
    filter's last confident pose, carried on by the odometry, counts as a place it had, and
    the estimate stays within 0.96 m of the truth through the room. Both are back on the
    track after it (measured at most 0.21 / 0.22 m off from scan 1290; docs/ceamcl.md,
    departure 14, and docs/real-data.md, "whose pose" for the truth these figures use). The
    figures are with the initialisation they were traced with (``ONE_ROUND``); the default's
    holds the track through the room as well. With the field's end points read half a cell
    farther (2026-12-02) the anchor keeps it within 1.51 m in the room (25 of 113 scans more
    than 1 m off) with either initialisation, 26.1 m without it; 0.24-0.26 m after it."""
    need(RAW, CORRECTED)
    scan, errors = _fr079_tracking_errors(1, 1450, recovery_anchor_m=anchor, **init)
    after = np.isfinite(errors) & (scan >= 1290)
    room = np.isfinite(errors) & (scan >= 1148) & (scan <= 1260)
    assert after.sum() > 100 and room.sum() > 80
    assert errors[after].max() < 0.6
    if room_max is not None:
        assert errors[room].max() < room_max
    else:
        assert errors[room].max() > 5.0


@pytest.mark.parametrize("envelope", [3.0, None])
def test_in_fr079s_doubtful_room_a_sliding_species_yields_to_the_odometry(
    envelope: float | None,
) -> None:
    """Tracking fr079 raw (seed 0, Nav2's pace) through the room of scans 1148-1239: before
    any recovery the lone species slides along what the map lacks (1.5 m in 3.5 m of travel)
    while the state says LOST, and at scan 1200 the map explains the scan better where it slid
    to than at the truth. With departure 17's drift envelope the estimate is the last
    confident pose carried by the odometry once the species has stood beyond the envelope at
    two updates running, and the slid pose does not replace that pose at once: measured 11 of
    113 scans more than 1 m off, room RMSE 0.62 m. With departure 15 alone
    (``anchor_envelope_sd=None``): 68 scans, 1.20 m (docs/ceamcl.md, departure 17). With the
    field's end points read half a cell farther (2026-12-02): 26 scans, 0.77 m, against 88
    scans, 1.43 m; the two runs are told apart at one line, 40 scans and 0.9 m."""
    need(RAW, CORRECTED)
    scan, errors = _fr079_tracking_errors(0, 1300, anchor_envelope_sd=envelope)
    room = np.isfinite(errors) & (scan >= 1148) & (scan <= 1260)
    assert room.sum() > 80
    off = int(np.count_nonzero(errors[room] > 1.0))
    rmse = float(np.sqrt(np.mean(errors[room] ** 2)))
    if envelope is not None:
        assert off <= 40 and rmse < 0.9
    else:
        assert off > 40 and rmse > 0.9


@pytest.mark.parametrize(("coast", "from_anchor"), [(True, False), (False, False), (False, True)])
def test_while_lost_in_fr079s_doubtful_room_ceamcl_reports_the_odometrys_pose(
    coast: bool, from_anchor: bool
) -> None:
    """Tracking fr079 raw (seed 0, Nav2's pace) through the room of scans 1148-1239, which the
    map holds poorly: recoveries fire and propose places up to several metres off. With
    departure 15 the estimate, while the state says LOST after a recovery, is the last pose the
    map vouched for, carried on by the odometry, when the leading species stands beyond
    ``recovery_drift_m`` of it: measured at most 1.03 m off in the room (1.71 m when this test
    was written), 3 of 113 scans more than 1 m off. With ``coast_when_lost=False`` it follows
    the leading species: 91 scans more than 1 m off, at most 5.10 m (4.86 m when this test was
    written), or 2.66 m with departure 37's option (``recovery_drift_from_anchor=True``: no
    place starts level through a drift of a drift; docs/ceamcl.md, departures 15 and 37).
    With the field's end points read half a cell farther (2026-12-02): at most 1.63 m, 26
    scans more than 1 m off, against 65 scans and 4.71 m (2.34 m with departure 37's option);
    the runs are told apart at 40 scans."""
    need(RAW, CORRECTED)
    scan, errors = _fr079_tracking_errors(
        0, 1300, coast_when_lost=coast, recovery_drift_from_anchor=from_anchor
    )
    room = np.isfinite(errors) & (scan >= 1148) & (scan <= 1260)
    assert room.sum() > 80
    worst = float(errors[room].max())
    off = int(np.count_nonzero(errors[room] > 1.0))
    if coast:
        assert worst < 2.5 and off <= 40
    else:
        assert off > 40
        if not from_anchor:
            assert worst > 3.5


@pytest.mark.parametrize(
    ("seed", "far", "keep", "back", "while_lost", "init", "stays"),
    [
        (10, 0.63, 0.55, 0.55, True, {}, True),
        (23, 0.63, 0.55, 0.55, True, FAR_PLACE_SCENARIO, True),
        (23, 0.63, None, None, False, FAR_PLACE_SCENARIO, True),
        (23, None, 0.55, None, False, FAR_PLACE_SCENARIO, True),
        (23, None, None, 0.55, False, FAR_PLACE_SCENARIO, True),
        (23, None, None, None, True, FAR_PLACE_SCENARIO, True),
        (23, None, None, None, False, FAR_PLACE_SCENARIO, False),
    ],
)
def test_a_far_place_that_outlives_the_rest_does_not_take_fr079s_estimate(
    seed: int,
    far: float | None,
    keep: float | None,
    back: float | None,
    while_lost: bool,
    init: dict[str, Any],
    stays: bool,
) -> None:
    """Tracking fr079 raw at Nav2's pace with 200 samples (seed 10) through the doubtful room:
    a recovery proposes a place 21 m away that fits the room's scans better than the truth,
    and the species at the anchor's place, started by departure 19, dies out (scan 1231). The
    far place, alone, holds no handicap and the state reads LOCALISED; without departure 23
    (``far_vouch_share=None``) it takes the estimate for 7 scans (measured 20.7 m off). With
    it the map explains too little of the scan there (35 % at scan 1231) to vouch for it as
    for a robot found again, the anchor holds and its place competes again (docs/ceamcl.md,
    departures 22 and 23: departure 22 kept the far place's handicap for this run, and was
    removed once departure 23 did its work). The scenario is the one traced with
    ``ONE_ROUND``; the default's initialisation, with every departure on, stays within 2 m
    as well. Since short reversing steps of the odometry are read backwards
    (``increment_between``, 2026-11-30) seed 10 takes another course; of seeds 0-23 with
    ``ONE_ROUND``, seed 23 is the one where the far place outlives the rest (26.1 m off
    without departure 23, 1.48 m with it; the others at most 1.70 m either way). That was with
    the evidence memory of 0.9 (``FAR_PLACE_SCENARIO`` keeps it); with 0.93 (departure 33) the
    far place fades before it can lead in every one of seeds 0-34 even without departure 23
    (at most 3.23 m off), so the scenario is the traced one, not the default's; since the
    field's end points are read half a cell farther (2026-12-02) seed 23 with the four
    departures off stays within 1.66 m even with ``FAR_PLACE_SCENARIO``, so its rows run with
    the lookup they were traced with (``AMCL_LOOKUP``); seed 10, all default, 0.93 m. The motion
    noise per stride of travel (2026-11-30) leaves every update at Nav2's pace here as it was;
    with a stride of 0.25 m instead of 0.5 (measured, not adopted: docs/real-data.md, "Noise
    per stride of travel") seed 4 was the contrast and seed 20 strayed 25.9 m for one update
    with departure 23 (a far place the map explained at 63.4 %, just above its floor).
    Departure 36 (``anchor_keep_fit``: while the estimate is held at the anchor and the
    leader fits no better than 0.55 on average, the anchor's species are kept) covers the
    same run on its own: the species at the anchor's place no longer dies out, and the
    estimate stays within 1.48 m with either departure alone. Departure 38 (``anchor_returns``,
    2026-12-01: the anchor's place starts a species again when it out-fits a leader that does
    not fit) covers it on its own as well (1.37 m), and so does departure 39
    (``coast_while_lost_m``, 2026-12-02: once the estimate coasts on the anchor it stays there
    while the state says LOST, for up to 2 m of travel; 1.33 m); only with the four off does
    the far place take it (26.1 m). ``FAR_PLACE_SCENARIO`` also pins the start's evidence of
    the trace (``evidence_climb_at_start=False``): with departure 43's climb (2026-12-03) seed 23
    stays within 1.48 m even with the four departures off."""
    need(RAW, CORRECTED)
    scan, errors = _fr079_tracking_errors(
        seed,
        1300,
        samples=200,
        far_vouch_share=far,
        anchor_keep_fit=keep,
        anchor_returns=back,
        coast_while_lost_m=2.0 if while_lost else None,
        lookup=AMCL_LOOKUP if init is FAR_PLACE_SCENARIO else None,
        **init,
    )
    room = np.isfinite(errors) & (scan >= 1148) & (scan <= 1260)
    assert room.sum() > 80
    worst = float(errors[room].max())
    if stays:
        assert worst < 2.0
    else:
        assert worst > 10.0


@pytest.mark.parametrize("confirm", [True, False])
def test_a_far_place_localised_for_one_update_does_not_take_fr079s_estimate(
    confirm: bool,
) -> None:
    """Tracking fr079 raw at Nav2's pace, 200 samples (seed 19, a tuning seed of the tracking
    protocol) through the doubtful room: the estimate coasts on the last confident pose while
    the species are LOST, and at scan 1218 a recovery's place 26 m off, which the map explains
    well enough to vouch for (departure 23), reads LOCALISED for one update, then LOST again.
    With departure 40 (``far_confirm``) a far leader takes the estimate from a coasting anchor
    only when it still reads LOCALISED at the next update: measured at most 0.98 m off in the
    room. Without it the place takes the estimate for 7 scans, 26.1 m off (docs/ceamcl.md,
    departure 40). Traced with ROS amcl's lookup of the field (``AMCL_LOOKUP``); with the
    end points read half a cell farther (the default since 2026-12-02) no far place reads
    LOCALISED in this run, and the estimate stays within 0.89 m either way. The run also pins
    the start's evidence it was traced with (``evidence_climb_at_start=False``): with departure
    43's climb (the default since 2026-12-03) the far place never takes the estimate here,
    departure 40 or not (0.98 m at worst)."""
    need(RAW, CORRECTED)
    scan, errors = _fr079_tracking_errors(
        19,
        1300,
        samples=200,
        max_samples=200,
        lookup=AMCL_LOOKUP,
        far_confirm=confirm,
        evidence_climb_at_start=False,
    )
    room = np.isfinite(errors) & (scan >= 1148) & (scan <= 1260)
    assert room.sum() > 80
    far = int(np.count_nonzero(errors[room] > 5.0))
    if confirm:
        assert far == 0 and float(errors[room].max()) < 2.0
    else:
        assert far > 0


@pytest.mark.parametrize("stride", [True, False])
def test_at_every_scan_a_far_place_takes_the_estimate_only_over_a_stride(stride: bool) -> None:
    """Tracking fr079 raw at every scan, 160 samples (seed 0, the CLI's every-scan protocol)
    through the doubtful room: after the estimate coasted, a recovery's place 12.7 m off reads
    LOCALISED at scan 1212, LOST at 1213 and LOCALISED again at 1214-1217. Departure 40 holds it
    for one update, which at every scan is 3 cm of travel: without departure 41
    (``far_confirm_m=far_confirm_rad=None``) it takes the estimate at 1214 for five scans,
    12.7-13.0 m off. With it the place must read LOCALISED at every update over Nav2's stride
    (0.25 m or 0.2 rad) while the estimate stays on the anchor, and never does: one scan more
    than 1 m off in the room, at most 1.2 m (docs/ceamcl.md, departure 41). Traced before
    departure 43 (the climb at a start's scan, the default since 2026-12-03), whose absence the
    run pins: with it no far place takes the estimate here, departure 41 or not (1.14 m)."""
    need(RAW, CORRECTED)
    off = {} if stride else {"far_confirm_m": None, "far_confirm_rad": None}
    scan, errors = _fr079_tracking_errors(
        0,
        1300,
        samples=160,
        max_samples=160,
        every_scan=True,
        evidence_climb_at_start=False,
        **off,
    )
    room = np.isfinite(errors) & (scan >= 1148) & (scan <= 1260)
    assert room.sum() > 80
    far = int(np.count_nonzero(errors[room] > 5.0))
    if stride:
        assert far == 0 and float(errors[room].max()) < 2.0
    else:
        assert far > 0


def test_a_raw_runs_report_and_mcap_carry_the_truth_where_it_is_known(
    cut_logs: tuple[Path, Path], tmp_path: Path
) -> None:
    """With --truth-from the truth is NaN at the unpaired scans: --report and --mcap ended in a
    traceback after the whole run (NaN is no JSON) and the output folder was removed."""
    from mcap.reader import make_reader

    raw, corrected = cut_logs
    out, mcap = tmp_path / "run", tmp_path / "run.mcap"
    args = ["run", str(raw), "--truth-from", str(corrected), "--algorithm", "mcl"]
    assert main([*args, "--report", "--mcap", str(mcap), "--quiet", "--out", str(out)]) == 0
    matched = json.loads((out / "summary.json").read_text())["truth_pairing"]["matched_scans"]
    assert "null" in (out / "report.html").read_text()  # the unpaired scans' truth
    with mcap.open("rb") as fh:
        summary = make_reader(fh).get_summary()
    assert summary is not None
    counts = {
        c.topic: summary.statistics.channel_message_counts[i] for i, c in summary.channels.items()
    }
    assert counts["/ground_truth"] == matched < counts["/estimate"]


def test_a_look_around_does_not_move_the_track_through_walls() -> None:
    """The issue's check on fr079 raw (``evaluate-log RAW --truth-from CORRECTED --starts 5
    --algorithms ceamcl``, seed 0), its window from scan 1048: at the update of scan 1581, in
    a turn on the spot where the map explains about 60 % of the scan at the truth, the lone
    species looked around (departure 12) and moved half its samples to a pose 0.4 m off that
    the likelihood field preferred by more than the look-around's margin while it sent more
    of the scan through the map's walls than the species' own best pose; the estimate went
    0.55 m off and the window failed to hold. The look-around now compares the two as the
    evidence does, each paying for its readings through walls (docs/ceamcl.md, departure 32)."""
    need(RAW, CORRECTED)
    from ceamcl.experiments.evaluate_log import log_trials, run_log_trial
    from ceamcl.experiments.log_windows import start_windows
    from ceamcl.experiments.metrics import DEFAULT_HOLD_M
    from ceamcl.replay import UpdatePace, obtain_map, prepare_log

    prepared = prepare_log(RAW, truth_from=CORRECTED)
    grid, _ = obtain_map(prepared.map_log, None, own=False)
    windows, _ = start_windows(prepared.log, 5)
    assert windows[1][0] == 1048
    (trial,) = log_trials(
        prepared, grid, ["ceamcl"], windows[1:2], pace=UpdatePace(), hold_m=DEFAULT_HOLD_M
    )
    result = run_log_trial(trial)
    assert result.success
    assert result.final_position_error_m < 0.5
