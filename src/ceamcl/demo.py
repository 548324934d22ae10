"""The demo: simulate a scenario, localise globally with a filter, write and plot the results.

Everything ``ceamcl demo`` does is here as a library call::

    from ceamcl.demo import run_demo
    outcome = run_demo("ceamcl", world="symmetric-hall", seed=3, out="demo-out")
"""

from __future__ import annotations

import os
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import NDArray

from ceamcl.experiments.metrics import (
    confidently_wrong,
    covers,
    image_index,
    likelihood_evaluations,
    nearest_error,
    restarts,
    weight_shares,
)
from ceamcl.filters import make_filter, registry
from ceamcl.filters.ceamcl.records import species_of
from ceamcl.filters.state import summarise_states
from ceamcl.io.results import ensure_output_dir
from ceamcl.maps.worlds import symmetric_images
from ceamcl.outputs import write_run_files
from ceamcl.pose import heading_error, position_error
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


#: Final hypotheses listed in ``summary.json`` (the filter's order: CEAMCL's fittest first).
SUMMARY_HYPOTHESES = 16


def truth_images(world: str, truth: NDArray[np.float64]) -> NDArray[np.float64]:
    """The poses that look the same as ``truth`` in ``world`` (the truth first): the hall's
    four 90 degree images in the hall worlds, the truth alone elsewhere."""
    if world in HALL_WORLDS:
        return symmetric_images(truth)
    return np.asarray(truth, dtype=np.float64).reshape(1, 3)


def summarise(result: RunResult, log: SimulatedLog, **context: Any) -> dict[str, Any]:
    """The fields of ``summary.json``.

    With a truth, each final hypothesis says where it is (``image``: 0 at the truth, ``k`` at
    the truth's symmetric image ``k``, ``None`` spurious; docs/experiments.md) and how far from
    the truth; the precision side at the end follows (``truth_weight``, ``true_image_weight``,
    ``spurious_weight``, ``confidently_wrong``, the nearest hypothesis' errors), and
    ``estimate_image`` says which image the estimate is at."""
    step_ms = result.step_ms
    pos_err = result.position_errors
    head_err = result.heading_errors
    final_h = result.hypotheses[-1]
    hyps: list[dict[str, Any]] = [
        {"x": h[0], "y": h[1], "theta": h[2], "weight": h[3], "fitness": h[4]}
        for h in final_h[:SUMMARY_HYPOTHESES]
    ]
    evaluations = likelihood_evaluations(result.diagnostics)
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
        "hypotheses_count": int(final_h.shape[0]),
        "likelihood_evaluations": None if evaluations is None else int(evaluations.sum()),
        "initialisation_likelihood_evaluations": (
            None if evaluations is None else int(evaluations[0])
        ),
        **restarts(result.diagnostics),
        "hypotheses_final": hyps,
    }
    if result.truth is not None and final_h.shape[0]:
        truth = result.truth[-1]
        images = truth_images(log.world, truth)
        where = image_index(final_h, images)
        for h, row, k in zip(hyps, final_h, where, strict=False):
            h["image"] = None if k < 0 else int(k)
            h["position_error_m"] = float(position_error(row[:3], truth))
            h["heading_error_rad"] = float(heading_error(row[:3], truth))
        # In a symmetric world the estimate is one of several equally fit hypotheses; the
        # closest hypothesis tells whether the truth is still tracked.
        near_m, near_rad = nearest_error(final_h, truth)
        shares = weight_shares(final_h, images)
        estimate_at = image_index(result.estimates[-1:], images)[0]
        # the hypothesis the estimate is (CEAMCL: the fittest species), if any
        on = covers(final_h[:SUMMARY_HYPOTHESES, :3], result.estimates[-1:], 1e-6, 1e-6)[:, 0]
        estimate_ok = bool(estimate_at == 0)
        summary.update(
            {
                "closest_hypothesis_error_m": near_m,
                "closest_hypothesis_heading_error_rad": near_rad,
                "symmetric_images": int(images.shape[0]),
                "images_kept": int(np.unique(where[where >= 0]).size),
                "estimate_image": None if estimate_at < 0 else int(estimate_at),
                "estimate_hypothesis": int(np.argmax(on)) if on.any() else None,
                "truth_weight": shares.truth,
                "true_image_weight": shares.true_images,
                "spurious_weight": shares.spurious,
                "heaviest_weight": shares.heaviest,
                "confidently_wrong": bool(confidently_wrong(estimate_ok, shares.heaviest)),
            }
        )
    summary.update(summarise_states([d.state for d in result.diagnostics], result.times))
    first, last = species_of(result.diagnostics[0]), species_of(result.diagnostics[-1])
    if first or last:
        summary["species_initial"] = len(first)
        summary["species_final"] = len(last)
    if result.truth is not None and log.world in HALL_WORLDS and final_h.shape[0]:
        # Position only: an image counts when some hypothesis is within the experiments' 0.5 m.
        near = covers(final_h[:, :3], symmetric_images(result.truth[-1]), heading_tol=np.inf)
        summary["symmetric_images_covered"] = int(np.sum(near.any(axis=0)))
    return summary


#: The algorithm of ``ceamcl demo`` and of :func:`run_demo` when none is named.
DEFAULT_ALGORITHM = "ceamcl"


def run_demo(
    algorithm: str = DEFAULT_ALGORITHM,
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
    """Simulate ``scenario`` on ``world`` and localise globally with ``algorithm`` (by default
    :data:`DEFAULT_ALGORITHM`, CEAMCL, as ``ceamcl demo``).

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
        result,
        log,
        seed=seed,
        scenario=scenario,
        start_room=start_room,
        sensor=registry.sensor_of(algorithm, sensor),  # the Nav2 peer weighs with its own
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
