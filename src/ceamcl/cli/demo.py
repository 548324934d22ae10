"""``ceamcl demo``: simulate the paper's run and localise globally."""

from __future__ import annotations

import argparse
from collections.abc import Mapping
from typing import Any

from rich.console import Console
from rich.table import Table

from ceamcl.cli.common import (
    RunProgress,
    add_output_arguments,
    check_particles,
    make_progress,
    non_negative_int,
    number,
    plain_table,
    positive_int,
    print_written,
    require_available,
    warm_kernels,
)
from ceamcl.demo import DEFAULT_ALGORITHM, run_demo
from ceamcl.experiments.common import pct
from ceamcl.filters import registry
from ceamcl.outputs import OutputOptions


def register(sub: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    """Add ``ceamcl demo``."""
    demo = sub.add_parser("demo", help="simulate the paper's run and localise globally")
    demo.add_argument(
        "--algorithm",
        choices=registry.names(),
        default=DEFAULT_ALGORITHM,
        help="any registered algorithm (nav2-amcl needs the [peers] extra)",
    )
    demo.add_argument(
        "--world",
        choices=("symmetric-hall", "marked-hall"),
        default="symmetric-hall",
        help="the paper's hall, or the same with a box in room 3",
    )
    demo.add_argument(
        "--start-room",
        type=int,
        choices=range(4),
        default=0,
        help="room the robot starts in (0 SW, 1 SE, 2 NE, 3 NW)",
    )
    demo.add_argument(
        "--seed", type=non_negative_int, default=0, help="one seed reproduces the run bit for bit"
    )
    demo.add_argument(
        "--sensor",
        choices=registry.SENSOR_MODELS,
        default="likelihood-field",
        help="sensor model (nav2-amcl always uses the wheel's own beam model)",
    )
    demo.add_argument(
        "--particles",
        type=positive_int,
        default=None,
        help="sample size of fixed-size filters (MCL, GMCL)",
    )
    demo.add_argument("--out", default="demo-out", help="folder for the results")
    demo.add_argument("--quiet", action="store_true", help="no progress bar or table")
    add_output_arguments(demo, animation_default=True)
    demo.set_defaults(run=run)


def run(args: argparse.Namespace, console: Console) -> int:
    check_particles(args.particles, args.algorithm)
    outputs = OutputOptions.from_args(args)
    require_available(args.algorithm)
    progress = make_progress(
        f"[bold]{args.algorithm}[/] on {args.world}", console, quiet=args.quiet
    )
    with progress:
        warm_kernels(progress, args.sensor, [args.algorithm])
        bar = RunProgress(progress)
        outcome = run_demo(
            args.algorithm,
            world=args.world,
            start_room=args.start_room,
            seed=args.seed,
            sensor=args.sensor,
            n_particles=args.particles,
            out=args.out,
            on_step=bar.step,
            on_start=bar.start,
            outputs=outputs,
            on_frame=bar.frame,
        )
    if not args.quiet:
        title = f"ceamcl demo ({args.algorithm} on {args.world}, seed {args.seed})"
        console.print(hypotheses_table(title, outcome.summary))
        console.print(state_table(title, outcome.summary))
        print_written(console, outcome.out_dir, outcome.files)
    return 0


#: Hypotheses the console lists (the rest are summed up in one line).
SHOWN_HYPOTHESES = 8


def _where(image: int | None, images: int) -> str:
    if image is None:
        return "spurious"
    if image == 0:
        return "the truth"
    return f"image {image} of {images}"


def _hypotheses_count(s: Mapping[str, Any]) -> str:
    n = s["hypotheses_count"]
    if "species_final" in s:
        return f"{n} species"
    return f"{n} hypothesis" if n == 1 else f"{n} hypotheses"


def hypotheses_table(title: str, s: Mapping[str, Any]) -> Table:
    """What a user should read first: the hypotheses at the end, their weights, where each
    is (at the truth, at one of its symmetric images, spurious) and how far from the truth."""
    hyps = s["hypotheses_final"][:SHOWN_HYPOTHESES]
    with_truth = "image" in (hyps[0] if hyps else {})
    header = ["#", "is", "weight", "fitness", "pose [m, m, rad]"]
    if with_truth:
        header.append("off truth [m, rad]")
    rows = []
    for i, h in enumerate(hyps):
        estimate = i == s.get("estimate_hypothesis")
        where = _where(h["image"], s["symmetric_images"]) if with_truth else ""
        if estimate:
            where = f"{where}, estimate" if where else "estimate"
        row = [
            str(i + 1),
            where,
            pct(h["weight"]),
            number(h["fitness"], 2),
            f"{h['x']:.2f}, {h['y']:.2f}, {h['theta']:.2f}",
        ]
        if with_truth:
            row.append(f"{h['position_error_m']:.2f}, {h['heading_error_rad']:.2f}")
        rows.append(row)
    rest = s["hypotheses_count"] - len(hyps)
    if rest > 0:
        held = max(1.0 - sum(h["weight"] for h in hyps), 0.0)
        more = [f"+{rest}", "more", pct(held)]
        rows.append(more + [""] * (len(header) - len(more)))
    return plain_table(f"{title}: {_hypotheses_count(s)} at the end", header, rows, left=2)


def _estimate_text(s: Mapping[str, Any]) -> str:
    off = f"{s['final_position_error_m']:.2f} m, {s['final_heading_error_rad']:.2f} rad"
    image = s.get("estimate_image")
    if image == 0:
        return f"at the truth (off {off})"
    if image is None:
        return f"wrong: at no image of the truth (off {off})"
    return f"image {image} of {s['symmetric_images']} alike (off truth {off})"


def state_table(title: str, s: Mapping[str, Any]) -> Table:
    """The state of the filter at the end and what the run cost."""
    rows: list[tuple[str, str]] = []
    if "truth_weight" in s:
        rows += [
            (
                "nearest hypothesis, off truth [m, rad]",
                f"{s['closest_hypothesis_error_m']:.3f}, "
                f"{s['closest_hypothesis_heading_error_rad']:.3f}",
            ),
            ("estimate", _estimate_text(s)),
            ("images of the truth held", f"{s['images_kept']} of {s['symmetric_images']}"),
            (
                "weight at truth / its images / spurious",
                f"{pct(s['truth_weight'])} / {pct(s['true_image_weight'])} / "
                f"{pct(s['spurious_weight'])}",
            ),
            (
                "confidently wrong (>= 90 % on one pose)",
                "yes" if s["confidently_wrong"] else "no",
            ),
        ]
    state = _hypotheses_count(s)
    evals = s["likelihood_evaluations"]
    if "final_state" in s:
        rows.append(
            (
                "localisation state (docs/state.md)",
                f"{s['final_state']} ({s['final_state_confidence']:.2f}): "
                f"{s['final_state_reason']}",
            )
        )
    rows += [
        ("species or hypotheses", state),
        ("sample size initial -> final", f"{s['samples_initial']} -> {s['samples_final']}"),
        (
            "likelihood evaluations (initialisation)",
            "not counted"
            if evals is None
            else f"{evals:,} ({s['initialisation_likelihood_evaluations']:,})",
        ),
        ("restarts of global localisation", str(s["restarts"])),
        ("steps", str(s["steps"])),
        (
            "step time mean / median [ms]",
            f"{number(s['mean_step_ms'], 1)} / {number(s['median_step_ms'], 1)}",
        ),
    ]
    return plain_table(f"{title}: the filter at the end", ("measure", "value"), rows, left=2)
