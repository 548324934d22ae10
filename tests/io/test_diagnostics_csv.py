"""``diagnostics.csv`` keeps one width however many species a run creates; the species go to
``species.csv``, one row per step and living species."""

from __future__ import annotations

import csv
from pathlib import Path

import pytest

from ceamcl.filters.base import StepDiagnostics
from ceamcl.filters.ceamcl.records import CEAMCLRecord, Events, SpeciesRecord
from ceamcl.io.results import SPECIES_FIELDS, write_diagnostics_csv, write_species_csv


def _step(k: int, ids: list[int]) -> StepDiagnostics:
    species = tuple(
        SpeciesRecord(i, 10 + i, 0.5, 0.8, 1.0, 2.0, 3.0, float(k), float(i), 0.1) for i in ids
    )
    record = CEAMCLRecord(
        resampled=True,
        likelihood_evaluations=5,
        species=species,
        n_species=len(species),
        total_resources=1.0,
        events=Events(splits=1),
    )
    return StepDiagnostics(k, sum(s.n for s in species), 3.0, 1.5, record)


def _read(path: Path) -> list[dict[str, str]]:
    with path.open(newline="") as fh:
        return list(csv.DictReader(fh))


def test_width_is_bounded_however_many_species_come_and_go(tmp_path: Path) -> None:
    # 500 steps, three new species at every step: 1,500 species in all, as on a real log.
    records = [_step(k, [3 * k, 3 * k + 1, 3 * k + 2]) for k in range(500)]
    times = [0.1 * k for k in range(500)]
    diag = tmp_path / "diagnostics.csv"
    write_diagnostics_csv(diag, records, times)
    with diag.open(newline="") as fh:
        header = next(csv.reader(fh))
    assert len(header) < 30, header
    assert not any(h.startswith("species_") for h in header)
    rows = _read(diag)
    assert len(rows) == 500 and rows[7]["n_species"] == "3" and rows[7]["splits"] == "1"
    species = tmp_path / "species.csv"
    write_species_csv(species, records, times)
    long = _read(species)
    assert list(long[0]) == ["time_s", "step", "species_id", *SPECIES_FIELDS]
    assert len(long) == 1500
    row = next(r for r in long if r["species_id"] == "301")  # step 100, its second species
    assert row["step"] == "100" and float(row["time_s"]) == pytest.approx(10.0)
    assert (row["n"], row["x"], row["y"]) == ("311", "100.0", "301.0")


def test_species_csv_of_a_run_without_species_has_only_its_header(tmp_path: Path) -> None:
    records = [StepDiagnostics(k, 100, 50.0, 1.0, CEAMCLRecord()) for k in range(3)]
    path = write_species_csv(tmp_path / "species.csv", records)
    assert path.read_text().strip() == ",".join(["step", "species_id", *SPECIES_FIELDS])
