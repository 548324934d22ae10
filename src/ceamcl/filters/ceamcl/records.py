"""What a CEAMCL step reports: its species (section 3.5) and the events of its phases."""

from __future__ import annotations

from dataclasses import dataclass

from ceamcl.filters.base import StepDiagnostics, StepRecord


@dataclass(frozen=True)
class SpeciesRecord:
    """One species at the end of a CEAMCL step (section 3.5): id, size ``n``, increment
    ``dn`` for the next step, mean fitness, living-domain area, resources, carrying capacity
    and mean pose."""

    species_id: int
    n: int
    dn: float
    fitness: float
    area_m2: float
    resources: float
    capacity: float
    x: float
    y: float
    theta: float


@dataclass(frozen=True)
class CEAMCLRecord(StepRecord):
    """A CEAMCL step: every species, and what the phases did (samples added by growth,
    extinctions, splits, merges, restarts, kidnap recoveries; the initial sample size ``n0``
    and ``|V|`` when it ran section 3.1) and the total resources ``R`` (eq. 15)."""

    species: tuple[SpeciesRecord, ...] = ()
    n_species: int = 0
    total_resources: float = 0.0
    new_samples: int = 0
    extinctions: int = 0
    splits: int = 0
    merges: int = 0
    restarts: int = 0
    recoveries: int = 0
    n0: int = 0
    v_cells: int = 0


def species_of(d: StepDiagnostics) -> tuple[SpeciesRecord, ...]:
    """The species of a step's record (none when the filter has no species)."""
    return d.record.species if isinstance(d.record, CEAMCLRecord) else ()


__all__ = ["CEAMCLRecord", "SpeciesRecord", "species_of"]
