"""What a CEAMCL step reports: its species (section 3.5) and the events of its phases."""

from __future__ import annotations

from dataclasses import asdict, dataclass, field, fields

from ceamcl.filters.base import StepDiagnostics, StepRecord


@dataclass(frozen=True)
class SpeciesRecord:
    """One species at the end of a CEAMCL step (section 3.5): id, size ``n``, increment
    ``dn`` for the next step, mean fitness, living-domain area, resources, carrying capacity,
    mean pose and ``weight``, the species' share of the posterior (the evidence it has
    accumulated, docs/ceamcl.md)."""

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
    weight: float = float("nan")


@dataclass
class Events:
    """What the phases of one step did: samples added by growth, species that died out,
    split or merged, restarts and kidnap recoveries; the initial sample size ``n0`` and
    ``|V|`` (``v_cells``) when the step ran section 3.1."""

    new_samples: int = 0
    extinctions: int = 0
    splits: int = 0
    merges: int = 0
    restarts: int = 0
    recoveries: int = 0
    skipped_beams: int = 0
    look_arounds: int = 0
    sprouts: int = 0
    n0: int = 0
    v_cells: int = 0

    def add(self, other: Events) -> None:
        """Add ``other``'s counts to these."""
        for f in fields(self):
            setattr(self, f.name, getattr(self, f.name) + getattr(other, f.name))


@dataclass(frozen=True)
class CEAMCLRecord(StepRecord):
    """A CEAMCL step: every species, the total resources ``R`` (eq. 15) and what the phases
    did (:class:`Events`, a copy)."""

    species: tuple[SpeciesRecord, ...] = ()
    n_species: int = 0
    total_resources: float = 0.0
    events: Events = field(default_factory=Events)

    def columns(self) -> dict[str, float | int | bool]:
        """The scalar fields, then the event counts, by name (CSV columns)."""
        return {**super().columns(), **asdict(self.events)}


def species_of(d: StepDiagnostics) -> tuple[SpeciesRecord, ...]:
    """The species of a step's record (none when the filter has no species)."""
    return d.record.species if isinstance(d.record, CEAMCLRecord) else ()


__all__ = ["CEAMCLRecord", "Events", "SpeciesRecord", "species_of"]
