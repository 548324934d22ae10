"""The demo: simulate a scenario, localise globally with a filter, write and plot the results.

Everything ``ceamcl demo`` does is here as a library call::

    from ceamcl.demo import run_demo
    outcome = run_demo("mcl", world="symmetric-hall", seed=3, out="demo-out")
"""

from __future__ import annotations

import os
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from ceamcl.experiments.metrics import covers, restarts
from ceamcl.filters import make_filter
from ceamcl.filters.ceamcl.records import species_of
from ceamcl.io.results import ensure_output_dir
from ceamcl.maps.worlds import symmetric_images
from ceamcl.outputs import write_run_files
from ceamcl.pose import position_error
from ceamcl.runner import RunResult, run_filter
from ceamcl.simulation.scenarios import HALL_WORLDS, get_scenario
from ceamcl.simulation.simulator import SimulatedLog

if TYPE_CHECKING:
    from ceamcl.outputs import OutputOptions


@dataclass
class DemoOutcome:
    result: RunResult
    log: SimulatedLog
    summary: dict[str, Any]
    out_dir: Path | None
    files: list[Path] = field(default_factory=list)  # visual outputs written (gif, report, mcap)


def seeded_generators(seed: int, count: int) -> list[np.random.Generator]:
    """Independent generators for the parts of a run (simulation, filter, ...) from one seed."""
    return [np.random.default_rng(s) for s in np.random.SeedSequence(seed).spawn(count)]


def summarise(result: RunResult, log: SimulatedLog, **context: Any) -> dict[str, Any]:
    """The fields of ``summary.json``."""
    step_ms = result.step_ms
    pos_err = result.position_errors
    head_err = result.heading_errors
    final_h = result.hypotheses[-1]
    summary: dict[str, Any] = {
        **context,
        "algorithm": result.algorithm,
        "world": log.world,
        "steps": result.steps,
        "duration_s": float(result.times[-1] - result.times[0]),
        "final_position_error_m": None if pos_err is None else float(pos_err[-1]),
        "final_heading_error_rad": None if head_err is None else float(head_err[-1]),
        "mean_step_ms": float(step_ms.mean()),
        # The first run of a fresh install compiles the kernels inside the first steps; the
        # median is the steady-state figure.
        "median_step_ms": float(np.median(step_ms)),
        "particles_initial": int(result.diagnostics[0].n_particles),
        "particles_final": int(result.diagnostics[-1].n_particles),
        "samples_initial": int(result.diagnostics[0].n_particles),
        "samples_final": int(result.diagnostics[-1].n_particles),
        **restarts(result.diagnostics),
        "hypotheses_final": [
            {"x": h[0], "y": h[1], "theta": h[2], "weight": h[3], "fitness": h[4]}
            for h in final_h[:16]
        ],
    }
    if result.truth is not None and final_h.shape[0]:
        # In a symmetric world the estimate is one of several equally fit hypotheses; the
        # distance of the closest hypothesis tells whether the truth is still tracked.
        d_truth = position_error(final_h[:, :3], result.truth[-1])
        summary["closest_hypothesis_error_m"] = float(d_truth.min())
    first, last = species_of(result.diagnostics[0]), species_of(result.diagnostics[-1])
    if first or last:
        summary["species_initial"] = len(first)
        summary["species_final"] = len(last)
    if result.truth is not None and log.world in HALL_WORLDS and final_h.shape[0]:
        # Position only: an image counts when some hypothesis is within the experiments' 0.5 m.
        near = covers(final_h[:, :3], symmetric_images(result.truth[-1]), heading_tol=np.inf)
        summary["symmetric_images_covered"] = int(np.sum(near.any(axis=0)))
    return summary


def run_demo(
    algorithm: str = "mcl",
    *,
    world: str = "symmetric-hall",
    scenario: str = "paper",
    start_room: int = 0,
    seed: int = 0,
    sensor: str = "likelihood-field",
    n_particles: int | None = None,
    out: str | os.PathLike[str] | None = None,
    on_step: Callable[[int], None] | None = None,
    on_start: Callable[[int], None] | None = None,
    outputs: OutputOptions | None = None,
    on_frame: Callable[[int, int], None] | None = None,
) -> DemoOutcome:
    """Simulate ``scenario`` on ``world`` and localise globally with ``algorithm``.

    With ``out`` set, writes ``summary.json``, ``trajectory.tum``, ``groundtruth.tum``,
    ``diagnostics.csv`` and ``run.png`` there. ``on_start(total_steps)`` and ``on_step(k)``
    report progress. ``outputs`` (``ceamcl.outputs.OutputOptions``) adds ``run.gif``,
    ``report.html`` and an MCAP file; ``on_frame(i, total)`` reports the animation's progress.
    """
    out_dir = ensure_output_dir(out) if out is not None else None
    sc = get_scenario(scenario, world if scenario == "paper" else None, start_room)
    grid = sc.grid()
    sim_rng, filter_rng = seeded_generators(seed, 2)
    log = sc.simulate(sim_rng, grid)
    if on_start is not None:
        on_start(len(log))
    f = make_filter(algorithm, grid, filter_rng, sensor=sensor, n_particles=n_particles)
    snapshot_every = outputs.snapshot_every if outputs is not None else 0
    result = run_filter(f, log, on_step=on_step, snapshot_every=snapshot_every)
    summary = summarise(
        result, log, seed=seed, scenario=scenario, start_room=start_room, sensor=sensor
    )
    files = write_run_files(
        result,
        grid,
        out_dir,
        summary,
        title=f"{algorithm} on {grid.name}, seed {seed}",
        log=log,
        outputs=outputs,
        on_frame=on_frame,
    )
    return DemoOutcome(result, log, summary, out_dir, files)
