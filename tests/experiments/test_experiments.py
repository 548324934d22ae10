"""Trials and experiments: seeds, executors (incl. a real Dask cluster) and a smoke run of every
``ceamcl experiment`` (short runs: one start, two algorithms, runs cut after a few seconds)."""

from __future__ import annotations

import csv
import math
from pathlib import Path

import numpy as np
import pytest

from ceamcl.cli import main
from ceamcl.errors import ConfigError
from ceamcl.experiments.common import ExperimentSettings, trial_rows
from ceamcl.experiments.routes import paper_course
from ceamcl.experiments.table1 import run_table1
from ceamcl.experiments.trials import Trial, run_trial, simulate_trial_log
from ceamcl.filters import registry
from ceamcl.filters.registry import names as all_algorithms
from ceamcl.filters.registry import resolve as resolve_algorithms


def test_every_algorithm_sees_the_same_log_and_repetitions_differ() -> None:
    course = paper_course()
    a = simulate_trial_log(Trial("t", "ceamcl", course, 1, 0, 7, max_time_s=2.0))
    b = simulate_trial_log(Trial("t", "mcl", course, 1, 0, 7, max_time_s=2.0))
    c = simulate_trial_log(Trial("t", "mcl", course, 1, 1, 7, max_time_s=2.0))
    assert np.array_equal(a.ranges, b.ranges) and np.array_equal(a.odometry, b.odometry)
    assert not np.array_equal(a.ranges, c.ranges)
    assert a.times[-1] == pytest.approx(2.0)


def test_a_trial_is_reproducible_bit_for_bit() -> None:
    trial = Trial("t", "mcl", paper_course(), 2, 0, 3, max_time_s=1.5)
    r1, r2 = run_trial(trial), run_trial(trial)
    assert np.array_equal(r1.estimates, r2.estimates)
    assert np.array_equal(r1.covered, r2.covered)


@pytest.mark.parametrize("algorithm", all_algorithms())
def test_every_algorithm_counts_its_initialisation_evaluations(algorithm: str) -> None:
    """trials.csv's likelihood_evaluations include the global initialisation: step 0's record
    scores at least every particle the filter starts with (CEAMCL: its N_test test poses),
    and the run's total is the sum of the steps'. A filter that cannot count says so (None),
    never 0."""
    reason = registry.unavailable_reason(algorithm)
    if reason is not None:
        pytest.skip(reason)
    record = run_trial(Trial("t", algorithm, paper_course(), 0, 0, 5, max_time_s=0.5))
    m, evals = record.metrics, record.precision.likelihood_evaluations
    if registry.get(algorithm).reports == "estimate":  # the Nav2 peer's wheel hides them
        assert evals is None and m.likelihood_evaluations is None
        return
    assert evals is not None and evals.shape == record.times.shape
    assert m.initialisation_likelihood_evaluations == evals[0] >= record.n_particles[0] > 0
    assert m.likelihood_evaluations == int(evals.sum()) >= evals[0]
    if algorithm == "ceamcl":
        init = registry.get("ceamcl").default().initialisation
        assert evals[0] >= init.test_pose_count(paper_course().grid().free_area_m2)


def test_unknown_algorithm_is_a_config_error() -> None:
    with pytest.raises(ConfigError, match="algorithms"):
        resolve_algorithms(["ceamcl", "ekf"])
    run, skipped = resolve_algorithms(None)
    assert set(run) | set(skipped) == set(all_algorithms())


_TIMING = {"mean_step_ms", "median_step_ms"}


def _numbers(settings: ExperimentSettings) -> tuple[list[dict[str, object]], list[np.ndarray]]:
    result = run_table1(settings, quiet=True)
    rows = [
        {k: v for k, v in row.items() if k not in _TIMING} for row in trial_rows(result.records)
    ]
    return rows, [r.estimates for r in result.records]


def small_table1(executor: str, workers: int | None = None) -> ExperimentSettings:
    """Two short trials of CEAMCL on one route, run by ``executor``."""
    return ExperimentSettings(
        course=paper_course().select([3]),
        algorithms=("ceamcl",),
        trials=2,
        seed=11,
        max_time_s=2.0,
        executor=executor,
        workers=workers,
    )


def test_dask_cluster_gives_the_same_numbers_as_local_processes() -> None:
    pytest.importorskip("distributed")
    local_rows, local_est = _numbers(small_table1("local", 2))
    dask_rows, dask_est = _numbers(small_table1("dask", 1))
    assert len(local_rows) == 2
    assert dask_rows == local_rows
    assert all(np.array_equal(a, b) for a, b in zip(local_est, dask_est, strict=True))


def _read_csv(path: Path) -> list[dict[str, str]]:
    with path.open() as fh:
        return list(csv.DictReader(fh))


_SMOKE = ["--trials", "1", "--start-routes", "0", "--executor", "serial", "--quiet"]


def test_table1_smoke(tmp_path: Path) -> None:
    out = tmp_path / "t1"
    args = ["experiment", "table1", *_SMOKE, "--algorithms", "ceamcl,mcl", "--max-time", "4"]
    assert main([*args, "--out", str(out)]) == 0
    rows = _read_csv(out / "table1.csv")
    assert [r["algorithm"] for r in rows] == ["ceamcl", "mcl"]
    assert rows[0]["paper_converged_s"] == "6.87"
    assert len(_read_csv(out / "trials.csv")) == 2
    for name in ("table1.md", "fig4_error.png", "fig5_step_time.png", "fig6_resources.png"):
        assert (out / name).stat().st_size > 0
    assert "| ceamcl |" in (out / "table1.md").read_text()
    assert not list(out.glob("*.tmp*"))
    # The precision side, in both files; the initialisation's evaluations count: CEAMCL's
    # N_test test poses are in its step 0, and so in the run's total.
    init = registry.get("ceamcl").default().initialisation
    n_test = init.test_pose_count(paper_course().grid().free_area_m2)
    trials = {t["algorithm"]: t for t in _read_csv(out / "trials.csv")}
    summary_columns = ("spurious_weight", "confidently_wrong_rate", "likelihood_evaluations")
    for row in rows:
        for column in (*summary_columns, "nearest_position_error_mean_m"):
            assert row[column] != "", (row["algorithm"], column)
    for row in trials.values():
        for column in ("spurious_weight", "confidently_wrong", "nearest_position_error_m"):
            assert row[column] != "", (row["algorithm"], column)
    ce = trials["ceamcl"]
    assert int(ce["initialisation_likelihood_evaluations"]) >= n_test
    assert int(ce["likelihood_evaluations"]) > int(ce["initialisation_likelihood_evaluations"])
    assert float(rows[0]["likelihood_evaluations"]) == int(ce["likelihood_evaluations"])
    assert 0.0 <= float(ce["true_image_weight"]) + float(ce["spurious_weight"]) <= 1.0 + 1e-9
    assert ce["confidently_wrong"] in ("0", "1")
    assert "likelihood evaluations per run" in (out / "table1.md").read_text()


def test_delta_smoke(tmp_path: Path) -> None:
    out = tmp_path / "d"
    args = ["experiment", "delta", *_SMOKE, "--deltas", "20,160", "--max-time", "3"]
    assert main([*args, "--out", str(out)]) == 0
    rows = _read_csv(out / "delta.csv")
    assert [float(r["delta_per_m2"]) for r in rows] == [20.0, 160.0]
    # More resources per m^2 leave room for more samples (section 4 of the paper).
    assert float(rows[1]["mean_particles"]) > float(rows[0]["mean_particles"])
    assert (out / "fig7_delta.png").stat().st_size > 0


def test_marked_smoke(tmp_path: Path) -> None:
    out = tmp_path / "m"
    args = ["experiment", "marked", *_SMOKE, "--algorithms", "mcl", "--max-time", "3"]
    assert main([*args, "--out", str(out)]) == 0
    rows = _read_csv(out / "marked.csv")
    assert {(r["algorithm"], r["route"]) for r in rows} == {("mcl", "room0"), ("mcl", "all")}
    assert all(r["confidently_wrong_rate"] != "" and r["likelihood_evaluations"] for r in rows)
    text = (out / "marked.md").read_text()
    assert "marked-hall" in text and "| mcl | room0 | 1 |" in text


def test_kidnapped_smoke(tmp_path: Path) -> None:
    out = tmp_path / "k"
    args = ["experiment", "kidnapped", "--trials", "1", "--executor", "serial", "--quiet"]
    args += ["--algorithms", "mcl", "--max-time", "30", "--recovery-window", "4"]
    assert main([*args, "--out", str(out)]) == 0
    trials = _read_csv(out / "trials.csv")
    assert len(trials) == 1 and float(trials[0]["kidnap_s"]) == pytest.approx(25.0)
    summary = _read_csv(out / "kidnapped.csv")[0]
    assert summary["confidently_wrong_rate"] in ("0", "1")
    assert float(summary["likelihood_evaluations"]) == int(trials[0]["likelihood_evaluations"])
    assert (out / "kidnapped.png").stat().st_size > 0


def test_the_runs_folder_holds_the_runs_of_the_latest_experiment_only(tmp_path: Path) -> None:
    """``OUT/runs/ALGORITHM/`` kept an earlier experiment's ``run.gif`` (a longer run) beside
    this one's ``summary.json``, and the folder of an algorithm this run did not have whole."""
    import json

    out = tmp_path / "m"
    args = ["experiment", "marked", *_SMOKE, "--max-time", "2", "--out", str(out)]
    assert main([*args, "--algorithms", "mcl,kld-amcl", "--gif", "--mcap", "x.mcap"]) == 0
    assert {p.name for p in (out / "runs" / "mcl").iterdir()} == {
        "run.gif",
        "x.mcap",
        "summary.json",
        ".ceamcl-run",  # what the run wrote: what a later experiment may remove
    }
    assert (out / "runs" / "kld-amcl" / "x.mcap").is_file()
    (out / "runs" / "mcl" / "notes.txt").write_text("mine")
    assert main([*args, "--algorithms", "mcl", "--report", "--max-time", "1"]) == 0
    assert {p.name for p in (out / "runs" / "mcl").iterdir()} == {
        "report.html",
        "summary.json",
        ".ceamcl-run",
        "notes.txt",  # not a file of the command's: left alone
    }
    summary = json.loads((out / "runs" / "mcl" / "summary.json").read_text())
    assert summary["max_time_s"] == 1.0
    assert sorted(p.name for p in (out / "runs").iterdir()) == ["mcl"]  # kld-amcl's is gone
    assert main([*args, "--algorithms", "mcl"]) == 0  # draws nothing: no earlier run stays
    assert [p.name for p in (out / "runs" / "mcl").iterdir()] == ["notes.txt"]


def test_an_interrupt_while_drawing_the_runs_keeps_the_finished_tables(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """The tables are written, then the runs re-run for --gif: Ctrl-C there removed the --out
    folder the command had created, tables included. Once the tables are in, it stays."""
    import ceamcl.cli.experiment as experiment_cli

    def interrupted(*args: object, **kwargs: object) -> None:
        raise KeyboardInterrupt

    monkeypatch.setattr(experiment_cli, "_write_run_outputs", interrupted)
    out = tmp_path / "new" / "m"
    args = ["experiment", "marked", *_SMOKE, "--max-time", "1", "--algorithms", "mcl", "--gif"]
    assert main([*args, "--out", str(out)]) == 130
    assert (out / "marked.csv").is_file() and (out / "trials.csv").is_file()


def test_a_trials_visual_outputs_replace_an_earlier_runs_files(tmp_path: Path) -> None:
    """``write_trial_outputs`` into a folder with an earlier run's files (``run.gif``) left them
    beside its own ``summary.json``; it removes them first, as ``write_run_files`` does."""
    from ceamcl.experiments.common import write_trial_outputs
    from ceamcl.outputs import OutputOptions

    settings = ExperimentSettings(paper_course(), ("mcl",), trials=1, max_time_s=1.0)
    record = run_trial(Trial("marked", "mcl", settings.course, 0, 0, 0, max_time_s=1.0))
    (tmp_path / "run.gif").write_bytes(b"GIF89a earlier")
    (tmp_path / "notes.txt").write_text("mine")
    done = write_trial_outputs(record, settings, tmp_path, OutputOptions.none())
    assert done.same_as_record
    assert sorted(p.name for p in tmp_path.iterdir()) == [
        ".ceamcl-run",
        "notes.txt",
        "summary.json",
    ]


def test_clearing_earlier_runs_removes_only_what_a_run_listed(tmp_path: Path) -> None:
    """Every ``*.mcap`` and every file named like a run output in any ``OUT/runs/*/`` was
    removed (a ROS 2 bag kept there with it), and a symbolic link ``runs`` was followed: only
    the files a re-run listed in its marker go now."""
    from ceamcl.experiments.common import RUN_MARKER, clear_earlier_runs

    runs = tmp_path / "runs"
    (runs / "mcl").mkdir(parents=True)
    (runs / "mcl" / "run.gif").write_bytes(b"GIF89a")
    (runs / "mcl" / "x.mcap").write_bytes(b"mcap")
    (runs / "mcl" / RUN_MARKER).write_text("run.gif\nx.mcap\n../elsewhere\n")
    (tmp_path / "elsewhere").write_text("outside the folder: not touched")
    (runs / "bags").mkdir()
    (runs / "bags" / "drive.mcap").write_bytes(b"a bag")
    (runs / "bags" / "summary.json").write_text("{}")
    gone = clear_earlier_runs(tmp_path)
    assert sorted(p.name for p in gone) == [RUN_MARKER, "mcl", "run.gif", "x.mcap"]
    assert sorted(p.name for p in (runs / "bags").iterdir()) == ["drive.mcap", "summary.json"]
    assert (tmp_path / "elsewhere").is_file()
    linked = tmp_path / "linked"
    linked.mkdir()
    (linked / "runs").symlink_to(runs, target_is_directory=True)
    assert clear_earlier_runs(linked) == []


def test_an_output_folder_that_cannot_take_the_results_is_refused_before_the_runs(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    """A folder where a result file goes, or a folder that cannot be written in fact (root
    passes ``os.access`` under /sys): a traceback after every run, with ``marked.csv`` already
    new beside the failed ``trials.csv``. Now one line, before any run."""
    import ceamcl.cli.common as cli_common
    from ceamcl.experiments import marked

    def no_runs(*args: object, **kwargs: object) -> None:
        raise AssertionError("the trials ran")

    monkeypatch.setattr(marked, "run_marked", no_runs)
    out = tmp_path / "m"
    (out / "trials.csv").mkdir(parents=True)
    args = ["experiment", "marked", *_SMOKE, "--algorithms", "mcl", "--max-time", "2"]
    assert main([*args, "--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert err.splitlines() == [
        f"ceamcl: error: out: {str(out / 'trials.csv')!r} is a folder; experiment marked "
        "writes a file of that name there"
    ]
    assert [p.name for p in out.iterdir()] == ["trials.csv"]

    def read_only(*args: object, **kwargs: object) -> None:
        raise PermissionError(13, "Permission denied", str(tmp_path / "ro" / "probe"))

    monkeypatch.setattr(cli_common.tempfile, "mkstemp", read_only)
    assert main([*args, "--out", str(tmp_path / "ro")]) == 2
    err = capsys.readouterr().err
    assert err.startswith("ceamcl: error: out: cannot write into output folder ")
    assert err.rstrip().endswith(": Permission denied") and len(err.splitlines()) == 1
    assert not (tmp_path / "ro").exists()  # created by the command: removed again


def test_a_failed_final_write_is_one_line_and_leaves_the_earlier_files(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    """An OSError while the tables were written (a full disk) was a traceback, and the files
    written before it were new beside old ones. The tables are written aside and moved in:
    the folder keeps the earlier files whole."""
    from ceamcl.experiments import figures

    out = tmp_path / "m"
    out.mkdir()
    for name in ("marked.csv", "trials.csv", "marked.md", "marked.png"):
        (out / name).write_text("earlier")

    def full_disk(shares: object, path: Path, *args: object) -> Path:
        raise OSError(28, "No space left on device", str(path) + ".tmp.png")

    monkeypatch.setattr(figures, "plot_shares", full_disk)
    args = ["experiment", "marked", *_SMOKE, "--algorithms", "mcl", "--max-time", "1"]
    assert main([*args, "--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert err.splitlines() == [
        f"ceamcl: error: out: cannot write {str(out / 'marked.png')!r}: No space left on device"
    ]
    assert sorted(p.name for p in out.iterdir()) == [
        "marked.csv",
        "marked.md",
        "marked.png",
        "trials.csv",
    ]
    assert all(p.read_text() == "earlier" for p in out.iterdir())


def test_cli_errors_are_one_line(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    out = str(tmp_path / "x")
    assert main(["experiment", "table1", "--algorithms", "ekf", "--out", out]) == 2
    assert main(["experiment", "table1", *_SMOKE, "--executor", "spark", "--out", out]) == 2
    assert main(["experiment", "kidnapped", "--world", "symmetric-hall", "--out", out]) == 2
    err = capsys.readouterr().err
    assert err.count("ceamcl: error:") == 3 and "Traceback" not in err


def test_table1_on_a_users_ros_map_with_a_route_file(tmp_path: Path) -> None:
    from ceamcl.maps.ros_io import save_map
    from ceamcl.maps.worlds import get_world

    save_map(get_world("small-office"), tmp_path / "office.yaml")
    routes = tmp_path / "office-routes.yaml"
    routes.write_text(
        "map: office.yaml\n"
        "routes:\n"
        "  - name: corridor\n"
        "    start: [1.5, 4.25, 0.0]\n"
        "    waypoints: [[3.8, 4.25]]\n"
    )
    out = tmp_path / "own"
    args = ["experiment", "table1", "--routes", str(routes), "--trials", "2"]
    args += ["--algorithms", "mcl", "--executor", "serial", "--quiet", "--max-time", "3"]
    assert main([*args, "--out", str(out)]) == 0
    trials = _read_csv(out / "trials.csv")
    assert [(t["route"], t["repetition"]) for t in trials] == [("corridor", "0"), ("corridor", "1")]
    assert "office-routes" in (out / "table1.md").read_text()
    assert "kept all 1" in (out / "table1.md").read_text()


@pytest.mark.parametrize("experiment", ["tune", "state"])
def test_an_experiment_without_runs_to_draw_refuses_the_visual_flags(
    experiment: str, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    # tune keeps one row per configuration and state its runs' states: --gif used to be
    # accepted and, for tune, to fail after the whole sweep; now it is refused before any trial
    out = tmp_path / "x"
    assert main(["experiment", experiment, "--gif", "--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert f"the {experiment} experiment writes tables" in err and len(err.splitlines()) == 1
    assert not out.exists()


def test_csv_cells_keep_epoch_times_and_counts_exact(tmp_path: Path) -> None:
    """A log's epoch start time kept 6 digits (9.76053e+08, to 1,000 s) and a count held in a
    float column (NaN for the Nav2 peer) was written 1.52346e+06."""
    from ceamcl.experiments.common import write_csv

    rows = [
        {"start_time_s": 976052857.337, "evaluations": 1523456.0, "x": 0.1, "gone": math.nan},
        {"start_time_s": 1.5, "evaluations": math.nan, "x": 1e-9, "gone": None},
    ]
    back = _read_csv(write_csv(tmp_path / "t.csv", rows))
    assert back[0] == {
        "start_time_s": "976052857.337",
        "evaluations": "1523456",
        "x": "0.1",
        "gone": "",
    }
    assert back[1] == {"start_time_s": "1.5", "evaluations": "", "x": "1e-09", "gone": ""}


def test_the_console_and_the_markdown_show_the_same_weights() -> None:
    """The console printed the weight at the truth where table1.md printed the true images'
    (27 % against 100 % for the same runs); both show images / truth / spurious now."""
    from ceamcl.cli.experiment import PRECISION_COLUMNS, precision_row
    from ceamcl.experiments.common import PRECISION_HEADER, precision_cells
    from ceamcl.experiments.metrics import PrecisionSummary

    p = PrecisionSummary(1.0, 0.0, 0.266, 0.0, 0.1, 0.1, 0.02, 2.6e5, 1e5)
    assert precision_row(p)[0] == precision_cells(p)[0] == "100% / 27% / 0%"
    assert "truth" in PRECISION_COLUMNS[0] and "at truth" in PRECISION_HEADER[0]


def test_an_interrupted_write_leaves_the_old_file_and_no_temporary_one(tmp_path: Path) -> None:
    """SIGTERM while a table was written left a truncated *.tmp file beside the old one."""
    from ceamcl.experiments.common import write_csv

    class Interrupting:
        def __str__(self) -> str:
            raise KeyboardInterrupt

    path = write_csv(tmp_path / "t.csv", [{"a": 1.0}])
    with pytest.raises(KeyboardInterrupt):
        write_csv(path, [{"a": 2.0}, {"a": Interrupting()}])
    assert _read_csv(path) == [{"a": "1"}]
    assert sorted(p.name for p in tmp_path.iterdir()) == ["t.csv"]


def test_fig5_leaves_the_global_initialisation_out_of_the_time_per_iteration() -> None:
    """Fig. 5 plotted step 0, the global initialisation (about 42 ms), as the first
    iteration, where the tables leave it out of the step times."""
    from ceamcl.experiments.table1 import step_time_curves

    settings = ExperimentSettings(paper_course().select([0]), ("mcl",), trials=1, max_time_s=1.0)
    result = run_table1(settings, quiet=True)
    (c,) = step_time_curves(result)
    assert np.isnan(c.centre[0]) and np.all(np.isfinite(c.centre[1:]))


def test_an_algorithm_has_one_colour_in_every_figure_whatever_the_order_listed() -> None:
    """With --algorithms mcl ceamcl, CEAMCL was orange in one panel of fig6 and blue in the
    other: colours followed the list's order."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from ceamcl.experiments.common import Curve
    from ceamcl.experiments.figures import _draw, algorithm_colour

    t = np.arange(3.0)

    def drawn(labels: list[str]) -> dict[str, str]:
        fig, ax = plt.subplots()
        _draw(ax, [Curve(a, t, t, t, t) for a in labels])
        colours = {str(line.get_label()): str(line.get_color()) for line in ax.get_lines()}
        plt.close(fig)
        return colours

    two = drawn(["mcl", "ceamcl"])
    assert two == drawn(["ceamcl", "mcl"])
    three = drawn(["gmcl", "ceamcl", "mcl"])
    assert {a: three[a] for a in two} == two and len(set(three.values())) == 3
    assert algorithm_colour("ceamcl") != algorithm_colour("mcl")
    assert drawn(["delta 20", "delta 80"]) == {"delta 20": "C0", "delta 80": "C1"}
