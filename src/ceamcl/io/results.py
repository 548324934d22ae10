"""Writing a run's results: ``summary.json``, ``diagnostics.csv``, TUM trajectories."""

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


def write_diagnostics_csv(
    path: str | os.PathLike[str], records: list[StepDiagnostics], times: list[float] | None = None
) -> Path:
    """One row per step: the runner's fields, the filter's record's scalars, and per-species
    columns ``species_<id>_<field>`` for CEAMCL (blank while a species does not exist)."""
    rows = [r.row() for r in records]
    species_ids = sorted({s.species_id for r in records for s in species_of(r)})
    fields: list[str] = ["time_s"] if times is not None else []
    for row in rows:
        for key in row:
            if key not in fields:
                fields.append(key)
    species_fields = ("n", "dn", "fitness", "area_m2", "resources", "capacity", "x", "y", "theta")
    for sid in species_ids:
        fields.extend(f"species_{sid}_{f}" for f in species_fields)
    with atomic_write(path) as tmp, tmp.open("w", newline="") as fh:
        writer = csv.DictWriter(fh, fieldnames=fields, restval="")
        writer.writeheader()
        for k, (rec, row) in enumerate(zip(records, rows, strict=True)):
            full: dict[str, Any] = dict(row)
            if times is not None:
                full["time_s"] = times[k]
            for s in species_of(rec):
                for f in species_fields:
                    full[f"species_{s.species_id}_{f}"] = getattr(s, f)
            writer.writerow(full)
    return Path(path)
