"""``ceamcl warm-up``: compile every kernel into Numba's cache, ahead of any run."""

from __future__ import annotations

import argparse

from rich.console import Console

from ceamcl.cli.common import make_progress
from ceamcl.warmup import warm_up


def register(sub: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    """Add ``ceamcl warm-up``."""
    p = sub.add_parser(
        "warm-up",
        help="compile every kernel into Numba's cache now (for a container image or a "
        "read-only install), so no run compiles",
        description="Load every compiled kernel the filters call, compiling those Numba's "
        "cache lacks (about 18 s on 2 cores the first time, well under a second after). "
        "Every run does this before it starts; this command does it alone, e.g. while "
        "building a container image with NUMBA_CACHE_DIR set to a folder the image keeps "
        "(docs/performance.md, 'Compiled before the run').",
    )
    p.add_argument("--quiet", action="store_true", help="no progress bar or summary")
    p.set_defaults(run=run)


def run(args: argparse.Namespace, console: Console) -> int:
    progress = make_progress("compiled kernels", console, quiet=args.quiet)
    with progress:
        task = progress.add_task("signatures", total=None)
        ready = warm_up(lambda done, total: progress.update(task, completed=done, total=total))
    if not args.quiet:
        console.print(ready.describe(), markup=False)
        if ready.cache_dir:
            console.print(f"Numba's cache: {ready.cache_dir} and its siblings", markup=False)
    return 0
