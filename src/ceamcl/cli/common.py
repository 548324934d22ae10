"""Shared pieces of the command line: argument types, the visual-output options, the progress
bar, a run's summary table."""

from __future__ import annotations

import argparse
import math
import os
import tempfile
import warnings
from collections.abc import Iterable, Mapping, Sequence
from pathlib import Path
from typing import Any

from rich.console import Console
from rich.markup import escape
from rich.progress import (
    BarColumn,
    MofNCompleteColumn,
    Progress,
    TaskID,
    TextColumn,
    TimeElapsedColumn,
)
from rich.table import Table
from rich.text import Text

from ceamcl import budget
from ceamcl.errors import ConfigError
from ceamcl.filters import registry
from ceamcl.outputs import DEFAULT_FPS, DEFAULT_STRIDE
from ceamcl.warmup import WarmUp, warm_up


def _whole_number(text: str, lowest: int, wanted: str) -> int:
    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a whole number, got {text!r}") from None
    if value < lowest:
        raise argparse.ArgumentTypeError(f"expected {wanted}, got {value}")
    return value


def non_negative_int(text: str) -> int:
    """argparse type: a whole number >= 0, with a clear message otherwise."""
    return _whole_number(text, 0, "a non-negative number")


def positive_int(text: str) -> int:
    """argparse type: a whole number >= 1 (a negative one is answered as 0 is, not with
    "non-negative", which 0 would satisfy)."""
    return _whole_number(text, 1, "a positive whole number")


def positive_float(text: str) -> float:
    """argparse type: a finite number > 0."""
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a number, got {text!r}") from None
    if not (value > 0.0 and value < float("inf")):
        raise argparse.ArgumentTypeError(f"expected a positive finite number, got {text}")
    return value


def non_negative_float(text: str) -> float:
    """argparse type: a finite number >= 0."""
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a number, got {text!r}") from None
    if not (value >= 0.0 and value < float("inf")):
        raise argparse.ArgumentTypeError(f"expected a non-negative finite number, got {text}")
    return value


#: A laser farther than this from the robot's axis is not a mount (a typo, or millimetres).
MAX_MOUNT_M = 2.0


def laser_mount(text: str) -> tuple[float, float, float]:
    """argparse type: ``X,Y,YAW``, the laser's pose on the robot (m, m, rad), its position
    within :data:`MAX_MOUNT_M` of the axis and its yaw within [-pi, pi]."""
    parts = text.split(",")
    shape = f"expected X,Y,YAW (three numbers), got {text!r}"
    if len(parts) != 3:
        raise argparse.ArgumentTypeError(shape)
    try:
        x, y, yaw = (float(t) for t in parts)
    except ValueError:
        raise argparse.ArgumentTypeError(shape) from None
    if not all(math.isfinite(v) for v in (x, y, yaw)):
        raise argparse.ArgumentTypeError(f"expected finite numbers, got {text!r}")
    if math.hypot(x, y) > MAX_MOUNT_M or abs(yaw) > math.pi:
        raise argparse.ArgumentTypeError(
            f"expected a laser within {MAX_MOUNT_M:g} m of the robot's axis and a yaw within "
            f"[-pi, pi] rad, got {text!r}"
        )
    return x, y, yaw


def require_available(algorithm: str) -> None:
    """Refuse, with the reason, an algorithm that is registered but cannot run here (the Nav2
    peer without its optional extra)."""
    reason = registry.unavailable_reason(algorithm)
    if reason is not None:
        raise ConfigError(f"algorithm: {algorithm} cannot run here: {reason}")


def algorithm_names(values: Sequence[str] | None) -> list[str] | None:
    """``--algorithms`` as given (space- or comma-separated) as a list of names; ``None`` when
    the option was left out (every algorithm); an empty list is refused."""
    if values is None:
        return None
    names = [n for v in values for n in (p.strip() for p in v.split(",")) if n]
    if not names:
        raise ConfigError(
            f"algorithms: expected one or more algorithm names, got {list(values)!r} "
            "(leave --algorithms out to run all)"
        )
    return names


def hush_dask_graph_warnings() -> None:
    """For ``--quiet``: no Dask ``Sending large graph of size ...`` warning (six lines a batch
    on evaluate-log, whose trials each carry the map and their log window, about 14 MiB: a hint
    to Dask programmers, not news about the run). :func:`ceamcl.cli.main` scopes the filter to
    the command."""
    warnings.filterwarnings("ignore", message="Sending large graph", category=UserWarning)


def check_output_files(out: str | os.PathLike[str], names: Iterable[str], command: str) -> None:
    """Before the runs, refuse an output folder (it exists) that the results could not be
    written into: one that cannot be written in fact (``os.access`` says yes to root on a
    read-only file system or under ``/sys``) or one where a folder stands in place of a file
    ``command`` writes (``names``). Either failed after every run, with a traceback."""
    folder = Path(out)
    try:
        fd, probe = tempfile.mkstemp(prefix=".ceamcl-probe-", dir=folder)
        os.close(fd)
        os.unlink(probe)
    except OSError as exc:
        raise ConfigError(
            f"out: cannot write into output folder {str(folder)!r}: {exc.strerror}"
        ) from None
    for name in names:
        target = folder / name
        if target.is_dir():
            raise ConfigError(
                f"out: {str(target)!r} is a folder; {command} writes a file of that name there"
            )


def write_error(exc: OSError, out: str | os.PathLike[str]) -> ConfigError:
    """An OSError while results were written as a one-line error naming the file (its final
    name, not the temporary one) and what failed."""
    name = Path(exc.filename).name if exc.filename else ""
    name = name.split(".tmp")[0]
    target = Path(out) / name if name else Path(out)
    return ConfigError(f"out: cannot write {str(target)!r}: {exc.strerror or exc}")


def check_particles(count: int | None, algorithm: str | None = None) -> None:
    """Refuse a ``--particles`` count beyond the memory budget, before any filter is built;
    with ``algorithm``, refuse one for an algorithm that sizes itself (CEAMCL: eq. 16), which
    would ignore it."""
    if count is None:
        return
    if algorithm is not None and registry.get(algorithm).with_particles is None:
        raise ConfigError(
            f"particles: {algorithm} sizes its own sample (it takes no particle count); "
            "expected no --particles"
        )
    budget.require("--particles", count, budget.PARTICLE_BYTES, "particles")


#: The label of :func:`make_progress` that shows each task's description alone.
TASK_DESCRIPTION = "{task.description}"


def make_progress(label: str, console: Console, *, quiet: bool = False) -> Progress:
    """The one progress-bar style of the CLI: label and the task's description, bar,
    done/total, elapsed time.

    ``label`` (Rich markup) is followed by each task's description, so the bars of one run
    read apart (``...: steps``, ``...: animation frames``; with the label alone both read the
    same); :data:`TASK_DESCRIPTION` shows the description alone. Braces in ``label`` (a log's
    name) are text, not fields.
    """
    if label != TASK_DESCRIPTION:
        label = label.replace("{", "{{").replace("}", "}}") + ": " + TASK_DESCRIPTION
    return Progress(
        TextColumn(label),
        BarColumn(),
        MofNCompleteColumn(),
        TimeElapsedColumn(),
        console=console,
        disable=quiet,
        transient=False,
    )


def warm_kernels(
    progress: Progress, sensor: str | None = None, algorithms: Iterable[str] = ()
) -> WarmUp:
    """Every compiled kernel ready before a run (:mod:`ceamcl.warmup`), shown as a task of
    ``progress`` while it lasts; a line says so where kernels had to be compiled (a cold
    Numba cache), so the run's own times hold no compilation. The beam model's kernels are
    left out where ``sensor`` is the likelihood field and no algorithm brings its own sensor
    model (the Nav2 peer scores its hypotheses with our beam model)."""
    beam_model = sensor != "likelihood-field" or any(a in registry.OWN_SENSOR for a in algorithms)
    task = progress.add_task("compiled kernels", total=None)
    ready = warm_up(
        lambda done, total: progress.update(task, completed=done, total=total),
        beam_model=beam_model,
    )
    progress.remove_task(task)
    if ready.compiled and not progress.disable:
        progress.console.print(ready.describe(), markup=False)
    return ready


class RunProgress:
    """Callbacks that show one run in ``progress``: its steps (``start(total)``, ``step(k)``)
    and, once the animation starts, its frames (``frame(i, total)``)."""

    def __init__(self, progress: Progress, unit: str = "steps") -> None:
        self.progress = progress
        self.task = progress.add_task(unit, total=None)
        self.frames: TaskID | None = None

    def start(self, total: int) -> None:
        self.progress.update(self.task, total=total)

    def step(self, k: int) -> None:
        self.progress.update(self.task, completed=k + 1)

    def frame(self, i: int, total: int) -> None:
        if self.frames is None:
            self.frames = self.progress.add_task("animation frames", total=total)
        self.progress.update(self.frames, completed=i)


class TrialsProgress:
    """A progress bar over batches of trials: the ``progress(label, done, total)`` callback
    that :func:`ceamcl.experiments.executors.map_trials` calls, one bar per label.

    Use as a context manager: ``with TrialsProgress(console, quiet=q) as progress: ...``.
    """

    def __init__(self, console: Console, *, quiet: bool = False) -> None:
        self.progress = make_progress(TASK_DESCRIPTION, console, quiet=quiet)
        self.tasks: dict[str, TaskID] = {}

    def __enter__(self) -> TrialsProgress:
        self.progress.__enter__()
        return self

    def __exit__(self, *exc: object) -> None:
        self.progress.__exit__(None, None, None)

    def __call__(self, label: str, done: int, total: int) -> None:
        if label not in self.tasks:
            self.tasks[label] = self.progress.add_task(label, total=total)
        self.progress.update(self.tasks[label], completed=done, total=total)


def number(value: float | None, digits: int = 3, missing: str = "-") -> str:
    """A number for a table, or ``missing`` for ``None``/NaN/inf (never ``nan``)."""
    if value is None or not math.isfinite(value):
        return missing
    return f"{value:.{digits}f}"


def plural(count: int, noun: str) -> str:
    """``1 run``, ``2 runs``."""
    return f"{count} {noun}" + ("" if count == 1 else "s")


def plain_table(
    title: str, header: Sequence[str], rows: Iterable[Sequence[str]], *, left: int = 1
) -> Table:
    """A table of plain text (no Rich markup, so units such as ``[s]`` show as written); the
    first ``left`` columns are left-aligned, the others right-aligned."""
    table = Table(title=Text(title))
    for i, name in enumerate(header):
        # a name column folds on a narrow console (mcl-tuned over two lines, not "mcl-tu…")
        table.add_column(
            Text(name),
            justify="left" if i < left else "right",
            overflow="fold" if i < left else "ellipsis",
        )
    for row in rows:
        table.add_row(*(Text(cell) for cell in row))
    return table


def summary_table(title: str, summary: Mapping[str, Any], keys: Iterable[str]) -> Table:
    """A two-column table of the ``keys`` of ``summary`` that are present and not None (a
    number that is not finite shows as ``-``)."""
    rows = [
        (key, number(v) if isinstance(v, float) else str(v))
        for key in keys
        if (v := summary.get(key)) is not None
    ]
    return plain_table(title, ("measure", "value"), rows)


def print_written(console: Console, out_dir: Path | None, files: Iterable[Path]) -> None:
    """Where a run's results went, and its visual outputs."""
    console.print(f"results written to [bold]{escape(str(out_dir))}[/]")
    for path in files:
        console.print(f"  {path}", markup=False)


def add_output_arguments(
    parser: argparse.ArgumentParser, *, animation_default: bool = True
) -> None:
    """Add ``--gif/--no-animation``, ``--mp4``, ``--fps``, ``--stride``, ``--report`` and
    ``--mcap FILE`` to ``parser`` (in their own argument group); read them back with
    :meth:`ceamcl.outputs.OutputOptions.from_args`.

    ``animation_default``: whether ``run.gif`` is written unless ``--no-animation`` is given
    (the demo: yes; batch commands may prefer no).
    """
    group = parser.add_argument_group("visual outputs")
    group.add_argument(
        "--gif",
        dest="gif",
        action="store_true",
        default=animation_default,
        help="write run.gif, the animated run" + (" (default)" if animation_default else ""),
    )
    group.add_argument(
        "--no-animation",
        dest="gif",
        action="store_false",
        help="do not write run.gif",
    )
    group.add_argument(
        "--mp4", action="store_true", help="also write run.mp4 (needs ffmpeg on the PATH)"
    )
    group.add_argument(
        "--fps",
        type=positive_float,
        default=None,
        help=f"frames per second of the animation and the replay (default {DEFAULT_FPS:g})",
    )
    group.add_argument(
        "--stride",
        type=positive_int,
        default=None,
        help=f"one animation frame every N filter steps (default {DEFAULT_STRIDE})",
    )
    group.add_argument(
        "--report",
        action="store_true",
        help="write report.html: summary, figures and an interactive replay in one file",
    )
    group.add_argument(
        "--mcap",
        metavar="FILE",
        default=None,
        help="write the run as MCAP for Foxglove (map, particles, estimate, truth, scans)",
    )
