"""Writing a run's results: ``summary.json``, ``diagnostics.csv``, ``species.csv``, TUM
trajectories."""

from __future__ import annotations

import csv
import json
import math
import os
from collections.abc import Iterator, Mapping
from contextlib import contextmanager
from pathlib import Path
from typing import Any

from ceamcl.errors import ConfigError
from ceamcl.filters.base import StepDiagnostics
from ceamcl.filters.ceamcl.records import species_of
from ceamcl.io.created import missing_ancestor, note_created


def ensure_output_dir(path: str | os.PathLike[str]) -> Path:
    """Create the output folder (and parents); a clear error when it cannot be written."""
    out = Path(path)
    new = missing_ancestor(out)
    try:
        out.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise ConfigError(
            f"out: cannot create output folder {str(out)!r}: {exc.strerror}"
        ) from None
    if new is not None:
        note_created(new)  # removed again if the command fails (ceamcl.io.created)
    if not os.access(out, os.W_OK):
        raise ConfigError(f"out: output folder {str(out)!r} is not writable")
    return out


@contextmanager
def atomic_write(path: str | os.PathLike[str], *, keep_suffix: bool = False) -> Iterator[Path]:
    """A temporary path beside ``path`` to write to: renamed over ``path`` when the block ends
    normally, removed when it raises, so no half-written file is left.

    The temporary name is ``<name>.tmp``, or ``<name>.tmp<suffix>`` with ``keep_suffix`` (for
    writers that choose the format by the suffix, such as ffmpeg).
    """
    out = Path(path)
    tmp = out.with_name(out.name + ".tmp" + (out.suffix if keep_suffix else ""))
    try:
        yield tmp
        os.replace(tmp, out)
    finally:
        tmp.unlink(missing_ok=True)


def _jsonable(value: Any) -> Any:
    if isinstance(value, float) and not math.isfinite(value):
        return None
    if isinstance(value, Mapping):
        return {str(k): _jsonable(v) for k, v in value.items()}
    if isinstance(value, list | tuple):
        return [_jsonable(v) for v in value]
    if hasattr(value, "tolist"):
        return _jsonable(value.tolist())
    return value


def write_json(path: str | os.PathLike[str], data: Mapping[str, Any]) -> Path:
    with atomic_write(path) as tmp:
        tmp.write_text(json.dumps(_jsonable(data), indent=2) + "\n")
    return Path(path)


SPECIES_FIELDS = (
    "n",
    "dn",
    "fitness",
    "weight",
    "area_m2",
    "resources",
    "capacity",
    "x",
    "y",
    "theta",
)


def write_diagnostics_csv(
    path: str | os.PathLike[str], records: list[StepDiagnostics], times: list[float] | None = None
) -> Path:
    """One row per step: ``time_s``, the runner's fields and the filter's record's scalars.
    The columns are the same at every step, so the width does not grow with the run; the
    species of CEAMCL go to :func:`write_species_csv` (long format)."""
    rows = [r.row() for r in records]
    fields: list[str] = ["time_s"] if times is not None else []
    for row in rows:
        for key in row:
            if key not in fields:
                fields.append(key)
    with atomic_write(path) as tmp, tmp.open("w", newline="") as fh:
        writer = csv.DictWriter(fh, fieldnames=fields, restval="")
        writer.writeheader()
        for k, row in enumerate(rows):
            full: dict[str, Any] = dict(row)
            if times is not None:
                full["time_s"] = times[k]
            writer.writerow(full)
    return Path(path)


def write_species_csv(
    path: str | os.PathLike[str], records: list[StepDiagnostics], times: list[float] | None = None
) -> Path:
    """CEAMCL's species in long format: one row per step and living species, columns
    ``time_s``, ``step``, ``species_id`` and :data:`SPECIES_FIELDS`."""
    fields = [*(["time_s"] if times is not None else []), "step", "species_id", *SPECIES_FIELDS]
    with atomic_write(path) as tmp, tmp.open("w", newline="") as fh:
        writer = csv.writer(fh)
        writer.writerow(fields)
        for k, rec in enumerate(records):
            head = [times[k]] if times is not None else []
            for sp in species_of(rec):
                writer.writerow(
                    [*head, rec.step, sp.species_id, *(getattr(sp, f) for f in SPECIES_FIELDS)]
                )
    return Path(path)
