"""``ceamcl bench``: time the kernels, the filters and CEAMCL beside Nav2 AMCL; write
``bench.json`` and ``bench.md``."""

from __future__ import annotations

import argparse

from rich.console import Console

from ceamcl import peers
from ceamcl.bench import BenchSettings, run_bench, write_report
from ceamcl.cli.common import make_progress
from ceamcl.io.results import ensure_output_dir


def register(sub: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    """Add ``ceamcl bench``."""
    p = sub.add_parser(
        "bench",
        help="time the sensor kernels, filter updates and CEAMCL beside Nav2 AMCL",
        description="Time a full filter update (beam model and likelihood field, N = 1000, "
        "5000, 20000, 60 beams) beside Nav2 AMCL (skipped when the 'amcl' wheel is absent), "
        "CEAMCL's initial species generation and steps, scaling with N, beams and map size, "
        "peak memory and compile times; write bench.json and bench.md.",
    )
    p.add_argument("--out", default="bench-out", help="output folder (default: bench-out)")
    p.add_argument(
        "--quick", action="store_true", help="a smoke run of a few seconds with small sizes"
    )
    p.add_argument("--quiet", action="store_true", help="no progress bar")
    p.set_defaults(run=run)


def run(args: argparse.Namespace, console: Console) -> int:
    out = ensure_output_dir(args.out)  # fail before minutes of work, not after
    settings = BenchSettings.quick_run() if args.quick else BenchSettings()
    with_peer = peers.available()
    if not with_peer:
        console.print("Nav2 AMCL ('amcl' wheel) not installed: the peer columns are skipped.")
    with make_progress("{task.description}", console, quiet=args.quiet) as progress:
        task = progress.add_task("bench", total=settings.n_items(with_peer))
        first = [True]

        def tick(label: str) -> None:
            if not first[0]:
                progress.advance(task)
            first[0] = False
            progress.update(task, description=label)

        result = run_bench(settings, tick)
        progress.update(task, completed=settings.n_items(with_peer), description="done")
    js, md = write_report(result, out)
    for t in result["targets"]:
        verdict = "not measured" if t["pass"] is None else ("PASS" if t["pass"] else "FAIL")
        value = "-" if t["value"] is None else f"{t['value']:.2f}"
        console.print(f"{verdict:>12}  {t['target']}: {value}")
    console.print(f"wrote {js} and {md}")
    return 0
