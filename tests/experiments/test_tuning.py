"""The tuning sweep (experiments/tuning.py), its CLI, and the presets it chose."""

from __future__ import annotations

import csv
from dataclasses import asdict
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from ceamcl.cli import main
from ceamcl.errors import ConfigError
from ceamcl.experiments.common import ExperimentSettings
from ceamcl.experiments.routes import paper_course
from ceamcl.experiments.tuning import (
    BASELINES,
    PRESETS,
    TUNING_SEED,
    Candidate,
    TuningGrid,
    TuningRow,
    best_rows,
    candidates,
    read_tuning_csv,
    run_tuning,
    score_key,
    write_tuning,
)
from ceamcl.filters import registry
from ceamcl.filters.headings import HeadingPrior
from ceamcl.maps.worlds import get_world

DOCS_CSV = Path(__file__).resolve().parents[2] / "docs" / "tuning.csv"


def row(**kw: object) -> TuningRow:
    base: dict[str, object] = dict(
        algorithm="mcl",
        max_beams=60,
        temper=1.0,
        n_particles=1000,
        init_test_poses=0,
        runs=12,
        kept_all_rate=0.5,
        success_rate=0.5,
        converged_runs=6,
        converged_s=10.0,
        likelihood_evaluations=1e6,
    )
    base.update(kw)
    return TuningRow(**base)  # type: ignore[arg-type]


# ---------------------------------------------------------------------- the score and grid
def test_score_prefers_kept_all_then_success_then_time_then_fewer_evaluations() -> None:
    rows = [
        row(kept_all_rate=0.9, success_rate=0.9, converged_s=20.0),
        row(kept_all_rate=1.0, success_rate=0.5),
        row(kept_all_rate=1.0, success_rate=1.0, converged_s=None),
        row(kept_all_rate=1.0, success_rate=1.0, converged_s=8.0, likelihood_evaluations=2e6),
        row(kept_all_rate=1.0, success_rate=1.0, converged_s=8.0, likelihood_evaluations=1e6),
    ]
    ranked = sorted(rows, key=score_key)
    assert ranked == [rows[4], rows[3], rows[2], rows[1], rows[0]]
    assert best_rows(rows) == {"mcl": rows[4]}
    # a rate read back from tuning.csv (six digits) ties the same rate computed
    read = row(kept_all_rate=0.833333, success_rate=1.0)
    computed = row(kept_all_rate=10 / 12, success_rate=11 / 12)
    assert best_rows([computed, read]) == {"mcl": read}


def test_grid_candidates_and_amcls_scoring_takes_no_temper() -> None:
    grid = TuningGrid()
    mcl = candidates(["mcl"], grid)
    kld = candidates(["kld-amcl"], grid)
    # headings from the scan only where there are test poses (two budgets of three)
    assert len(mcl) == 2 * 4 * 3 * (3 + 2) and len(kld) == 2 * 3 * (3 + 2)
    assert {c.temper for c in kld} == {1.0}
    assert all("temper" not in c.sensor_settings() for c in kld)
    assert not any(c.init_headings and c.init_test_poses == 0 for c in mcl)
    c = Candidate("kld-amcl", 30, 1.0, 5000, 100_000)
    assert c.config().max_particles == 5000 and c.config().init_test_poses == 100_000
    assert c.config().init_headings is None
    guided = Candidate("mcl", 30, 0.1, 5000, 100_000, init_headings=True).config()
    assert guided.init_headings == HeadingPrior() and guided.init_test_poses == 100_000
    with pytest.raises(ConfigError, match="tunes mcl, gmcl, kld-amcl"):
        candidates(["ceamcl"], grid)
    # a grid without a configuration (headings from the scan, no test poses) is refused
    with pytest.raises(ConfigError, match=r"init-headings: .* no configuration to run"):
        TuningGrid(init_test_poses=(0,), init_headings=(True,))


# ---------------------------------------------------------------------- a small sweep
def test_a_small_sweep_runs_table1s_trials_and_writes_every_row(tmp_path: Path) -> None:
    settings = ExperimentSettings(
        course=paper_course().select([0]),
        algorithms=("mcl", "kld-amcl"),
        trials=1,
        seed=TUNING_SEED,
        executor="serial",
        max_time_s=2.0,
    )
    grid = TuningGrid(
        max_beams=(30,),
        temper=(1.0, 0.1),
        n_particles=(200,),
        init_test_poses=(0, 5000),
        init_headings=(False, True),
    )
    result = run_tuning(settings, grid, quiet=True)
    # (0 | 5000 uniform | 5000 guided) for each temper; kld-amcl: temper 1 only
    assert len(result.rows) == 2 * 3 + 3
    assert sum(r.init_headings for r in result.rows) == 3
    for r in result.rows:
        assert r.runs == 1
        # the initialisation's evaluations count: N_test, or N uniform particles, then the run
        assert r.likelihood_evaluations >= max(r.init_test_poses, r.n_particles)
    paths = write_tuning(result, tmp_path, {"command": "test"})
    assert [p.name for p in paths] == ["tuning.csv", "tuning.md"]
    back = read_tuning_csv(tmp_path / "tuning.csv")
    assert [r.candidate for r in back] == [r.candidate for r in result.rows]
    for a, b in zip(back, result.rows, strict=True):
        assert a.kept_all_rate == b.kept_all_rate and a.runs == b.runs
        assert a.likelihood_evaluations == pytest.approx(b.likelihood_evaluations, rel=1e-5)
    assert "Chosen presets" in (tmp_path / "tuning.md").read_text()


def test_a_tuning_csv_row_with_a_bad_field_is_refused_naming_its_line(tmp_path: Path) -> None:
    good = tmp_path / "good.csv"
    with good.open("w", newline="") as fh:
        w = csv.DictWriter(fh, fieldnames=[*asdict(row()).keys()])
        w.writeheader()
        w.writerow(asdict(row(init_headings=True)))
        w.writerow(asdict(row()))
    assert [r.init_headings for r in read_tuning_csv(good)] == [True, False]
    text = good.read_text().splitlines()
    bad = tmp_path / "bad.csv"
    bad.write_text("\n".join([text[0], text[1], text[2].replace("False", "maybe")]) + "\n")
    with pytest.raises(ConfigError, match=r"bad\.csv:3: .*init_headings"):
        read_tuning_csv(bad)
    # a sweep written before the column reads as uniform headings
    old = tmp_path / "old.csv"
    header = text[0].replace(",init_headings", "")
    old.write_text(header + "\n" + text[2].rsplit(",", 1)[0] + "\n")
    assert [r.init_headings for r in read_tuning_csv(old)] == [False]


def test_make_filter_applies_sensor_settings_to_either_model() -> None:
    grid = get_world("small-office")
    for sensor in ("likelihood-field", "beam"):
        f = registry.make_filter(
            "mcl",
            grid,
            np.random.default_rng(0),
            sensor=sensor,
            sensor_settings={"max_beams": 7, "temper": 0.3},
        )
        assert f.sensor.config.max_beams == 7  # type: ignore[attr-defined]
        assert f.sensor.config.temper == 0.3  # type: ignore[attr-defined]
    with pytest.raises(ConfigError, match="sensor: LikelihoodFieldModel has no setting 'beams'"):
        registry.make_filter("mcl", grid, np.random.default_rng(0), sensor_settings={"beams": 7})
    with pytest.raises(ConfigError, match="temper: applies to scoring 'product' only"):
        registry.make_filter(
            "kld-amcl", grid, np.random.default_rng(0), sensor_settings={"temper": 0.3}
        )


def test_cli_tune(tmp_path: Path) -> None:
    out = tmp_path / "tune"
    args = ["experiment", "tune", "--trials", "1", "--start-routes", "0", "--executor", "serial"]
    args += ["--quiet", "--algorithms", "mcl", "--max-beams", "30", "--tempers", "0.1"]
    args += ["--particle-counts", "100", "--init-test-poses", "0", "--max-time", "2"]
    assert main([*args, "--out", str(out)]) == 0
    with (out / "tuning.csv").open() as fh:
        rows = list(csv.DictReader(fh))
    assert [(r["algorithm"], r["max_beams"], r["temper"]) for r in rows] == [("mcl", "30", "0.1")]
    # Each finished configuration is kept; the same sweep again resumes instead of re-running.
    (partial,) = out.glob("tuning-partial-seed10000-trials1-*.csv")
    assert len(read_tuning_csv(partial)) == 1
    assert main([*args, "--tempers", "0.1,0.03", "--out", str(out)]) == 0
    assert [r.temper for r in read_tuning_csv(partial)] == [0.1, 0.03]
    assert len(read_tuning_csv(out / "tuning.csv")) == 2
    # another protocol (another route, no cut-off) does not take those rows for its own
    other = [a for a in args if a not in ("--max-time", "2")]
    other[other.index("--start-routes") + 1] = "1"
    assert main([*other, "--max-time", "3", "--out", str(out)]) == 0
    assert len(list(out.glob("tuning-partial-*.csv"))) == 2
    (row,) = read_tuning_csv(out / "tuning.csv")
    assert (
        row.runs == 1
        and row.likelihood_evaluations != read_tuning_csv(partial)[0].likelihood_evaluations
    )
    assert main(["experiment", "tune", "--algorithms", "ceamcl", "--out", str(out)]) == 2
    # headings from the scan: a second configuration where there are test poses
    guided = ["--init-test-poses", "1000", "--init-headings", "uniform,scan"]
    assert main([*args, *guided, "--out", str(tmp_path / "g")]) == 0
    back = read_tuning_csv(tmp_path / "g" / "tuning.csv")
    assert sorted(r.init_headings for r in back) == [False, True]
    with pytest.raises(SystemExit) as exc:
        main([*args, "--init-headings", "sideways", "--out", str(tmp_path / "h")])
    assert exc.value.code == 2


def test_an_interrupted_sweep_keeps_its_partial_rows_in_a_folder_it_created(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """Ctrl-C (or SIGTERM, the same exception) after the first configuration: the folder the
    command created is kept with the finished row, and the sweep resumes from it. Interrupted
    before any row, the folder goes, as for every command."""
    import ceamcl.experiments.tuning as tuning

    out = tmp_path / "new" / "tune"
    args = ["experiment", "tune", "--trials", "1", "--start-routes", "0", "--executor", "serial"]
    args += ["--quiet", "--algorithms", "mcl", "--max-beams", "30", "--tempers", "0.1,0.03"]
    args += ["--particle-counts", "100", "--init-test-poses", "0", "--max-time", "2"]
    args += ["--out", str(out)]
    real = tuning.summarise
    calls: list[float] = []

    def interrupted_at(n: int) -> Any:
        def summarise(c: Candidate, outcomes: Any) -> TuningRow:
            calls.append(c.temper)
            if len(calls) == n:
                raise KeyboardInterrupt
            return real(c, outcomes)

        return summarise

    monkeypatch.setattr(tuning, "summarise", interrupted_at(1))
    assert main(args) == 130
    assert not (tmp_path / "new").exists()  # nothing finished: removed
    calls.clear()
    monkeypatch.setattr(tuning, "summarise", interrupted_at(2))
    assert main(args) == 130
    (partial,) = out.glob("tuning-partial-*.csv")
    assert [r.temper for r in read_tuning_csv(partial)] == [0.1]
    calls.clear()
    monkeypatch.setattr(tuning, "summarise", interrupted_at(99))
    assert main(args) == 0
    assert calls == [0.03]  # resumed: the finished configuration did not run again
    assert sorted(r.temper for r in read_tuning_csv(out / "tuning.csv")) == [0.03, 0.1]


@pytest.mark.parametrize("given", ["mcl,ceamcl", "ceamcl", "nav2-amcl mcl-tuned"])
def test_tune_refuses_an_algorithm_it_does_not_tune_naming_it_before_any_work(
    given: str, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """``--algorithms mcl,ceamcl`` tuned mcl alone without a word, and ``--algorithms ceamcl``
    was refused only after the header, without naming what was given."""
    out = tmp_path / "tune"
    argv = ["experiment", "tune", "--algorithms", *given.split(), "--trials", "1"]
    argv += ["--max-time", "2", "--executor", "serial", "--out", str(out)]
    assert main(argv) == 2
    captured = capsys.readouterr()
    assert captured.out == ""  # no header, no run
    others = [a for a in given.replace(" ", ",").split(",") if a not in BASELINES]
    assert f"got {', '.join(others)}, which it does not tune" in captured.err
    assert "tunes mcl, gmcl, kld-amcl" in captured.err
    assert not out.exists()
    settings = ExperimentSettings(paper_course().select([0]), ("mcl", "ceamcl"), trials=1)
    with pytest.raises(ConfigError, match="got ceamcl, which it does not tune"):
        run_tuning(settings, TuningGrid(), quiet=True)


# ---------------------------------------------------------------------- the presets
DOCS_CSV = Path(__file__).resolve().parents[2] / "docs" / "tuning.csv"


@pytest.mark.parametrize("algorithm", BASELINES)
def test_each_preset_is_the_best_row_of_the_committed_sweep(algorithm: str) -> None:
    """The presets cannot drift from the evidence: each equals its algorithm's best row of
    docs/tuning.csv (config and sensor settings)."""
    best = best_rows(read_tuning_csv(DOCS_CSV))[algorithm]
    preset = registry.get(PRESETS[algorithm])
    want = best.candidate
    assert preset.default() == want.config()
    assert dict(preset.sensor_settings) == want.sensor_settings()
    assert preset.config_type is registry.get(algorithm).config_type


def test_the_committed_sweep_ran_on_seeds_disjoint_from_the_reported_ones() -> None:
    rows = read_tuning_csv(DOCS_CSV)
    assert {r.algorithm for r in rows} == set(BASELINES)
    assert all(r.runs == 12 for r in rows)  # 3 per room, four rooms
    assert f"--seed {TUNING_SEED}" in (DOCS_CSV.parent / "tuning.md").read_text()


@pytest.mark.parametrize("sensor", ["likelihood-field", "beam"])
def test_make_filter_applies_a_presets_sensor_settings_to_either_model(sensor: str) -> None:
    grid = get_world("small-office")
    for name in PRESETS.values():
        spec = registry.get(name)
        f = registry.make_filter(name, grid, np.random.default_rng(0), sensor=sensor)
        assert f.name == name
        cfg = f.sensor.config  # type: ignore[attr-defined]
        for key, value in spec.sensor_settings.items():
            assert getattr(cfg, key) == value
        assert f.config == spec.default()  # type: ignore[attr-defined]


def test_table1_runs_a_preset(tmp_path: Path) -> None:
    out = tmp_path / "t1"
    args = ["experiment", "table1", "--trials", "1", "--start-routes", "0", "--executor", "serial"]
    args += ["--quiet", "--algorithms", "mcl-tuned", "--max-time", "2"]
    assert main([*args, "--out", str(out)]) == 0
    with (out / "table1.csv").open() as fh:
        assert [r["algorithm"] for r in csv.DictReader(fh)] == ["mcl-tuned"]


def test_every_algorithm_includes_the_presets() -> None:
    chosen, _ = registry.resolve(None)
    assert set(PRESETS.values()) <= set(chosen)


def test_a_candidates_temper_reaches_the_sensor_even_when_it_is_one() -> None:
    """Untempered means temper 1 in the sensor model, not the sensor's default (0.2): the
    sweep's "temper 1" rows ran at 0.2 until 2026-11-29 because 1 was left out."""
    grid = paper_course().grid()
    for temper in (1.0, 0.1):
        c = Candidate("mcl", 30, temper, 500, 0)
        assert c.sensor_settings() == {"max_beams": 30, "temper": temper}
        f = registry.make_filter(
            "mcl", grid, np.random.default_rng(0), sensor_settings=c.sensor_settings()
        )
        assert f.sensor.temper == temper  # type: ignore[attr-defined]
