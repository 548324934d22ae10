"""Everything a run writes: its files (``trajectory.tum``, ``groundtruth.tum``,
``diagnostics.csv``, ``species.csv``, ``summary.json``, ``run.png``, ``species.png``) and the
visual outputs (``run.gif``/``run.mp4``, ``report.html``, MCAP for Foxglove).

The runner (:mod:`ceamcl.runner`) runs a filter and returns a :class:`~ceamcl.runner.RunResult`;
this module, one layer above it, turns results into files. In Python::

    options = OutputOptions(gif=True, report=True)       # or OutputOptions.from_args(args)
    result = run_filter(f, log, snapshot_every=options.snapshot_every)
    files = write_run_files(result, grid, "run-out", summary, title="...", log=log, outputs=options)

``snapshot_every`` is the stride when an output needs the particles of every frame, else 0
(no snapshots kept, no memory spent). The command-line options that build
:class:`OutputOptions` are added by :func:`ceamcl.cli.common.add_output_arguments`.
"""

from __future__ import annotations

import os
from collections.abc import Callable, Mapping
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

from ceamcl.errors import ConfigError
from ceamcl.filters.ceamcl.records import species_of
from ceamcl.io.mcap_export import ScanLog, write_mcap
from ceamcl.io.results import (
    ensure_output_dir,
    write_diagnostics_csv,
    write_json,
    write_species_csv,
)
from ceamcl.io.tum import write_tum
from ceamcl.maps.grid import OccupancyGrid
from ceamcl.runner import RunResult

DEFAULT_FPS = 10.0
DEFAULT_STRIDE = 5


@dataclass(frozen=True)
class OutputOptions:
    """Which visual outputs to write and how.

    ``gif``/``mp4``: the animation (``run.gif``, ``run.mp4``; mp4 needs ffmpeg);
    ``fps``: frames per second of the animation and the report's replay;
    ``stride``: one frame every ``stride`` steps; ``report``: ``report.html``;
    ``mcap``: path of an MCAP file for Foxglove (relative paths are relative to the current
    folder, not to the output folder), or ``None``.
    """

    gif: bool = True
    mp4: bool = False
    fps: float = DEFAULT_FPS
    stride: int = DEFAULT_STRIDE
    report: bool = False
    mcap: Path | None = None

    def __post_init__(self) -> None:
        if self.mcap is not None and not isinstance(self.mcap, Path):
            object.__setattr__(self, "mcap", Path(self.mcap))  # a str works too
        if not (self.fps > 0 and self.fps < float("inf")):
            raise ConfigError(
                f"fps: expected a positive number of frames per second, got {self.fps}"
            )
        if self.stride < 1:
            raise ConfigError(f"stride: expected a positive number of steps, got {self.stride}")

    @classmethod
    def none(cls) -> OutputOptions:
        """No visual output at all."""
        return cls(gif=False)

    @classmethod
    def from_args(cls, args: Mapping[str, Any] | Any) -> OutputOptions:
        """Options from parsed command-line arguments (an ``argparse.Namespace`` from
        :func:`ceamcl.cli.common.add_output_arguments`, or a mapping; missing ones take their
        defaults). ``--mp4`` without ffmpeg on the PATH is an error, raised here, before the
        run; so is ``--mcap`` into a folder that does not exist and that ``--out`` (``out``)
        does not create."""
        get: Callable[[str, Any], Any]
        if isinstance(args, Mapping):
            get = args.get
        else:

            def get(name: str, default: Any) -> Any:
                return getattr(args, name, default)

        mcap = get("mcap", None)
        fps, stride = get("fps", None), get("stride", None)
        options = cls(
            gif=bool(get("gif", True)),
            mp4=bool(get("mp4", False)),
            fps=DEFAULT_FPS if fps is None else float(fps),
            stride=DEFAULT_STRIDE if stride is None else int(stride),
            report=bool(get("report", False)),
            mcap=None if mcap is None else Path(mcap),
        )
        # given for an output that is not written, they were ignored without a word
        drawn = options.gif or options.mp4 or options.report
        if fps is not None and not drawn:
            raise ConfigError(
                "fps: --fps sets the frame rate of run.gif, run.mp4 and the report's replay; "
                "expected it with --gif, --mp4 or --report"
            )
        if stride is not None and not options.any:
            raise ConfigError(
                "stride: --stride sets how often a run is drawn; expected it with --gif, --mp4, "
                "--report or --mcap"
            )
        if options.mcap is not None:
            out = get("out", None)
            _check_mcap_target(options.mcap, None if out is None else Path(out))
        if options.mp4:
            from ceamcl.viz.animation import ffmpeg_path  # matplotlib: see write_run_files

            if ffmpeg_path() is None:
                raise ConfigError(
                    "mp4: --mp4 needs ffmpeg on the PATH (e.g. apt-get install ffmpeg); "
                    "install it or leave out --mp4 (run.gif needs nothing)"
                )
        return options

    def only_mcap(self) -> OutputOptions:
        """These options without the files that go into an output folder."""
        return replace(self, gif=False, mp4=False, report=False)

    @property
    def any(self) -> bool:
        return self.gif or self.mp4 or self.report or self.mcap is not None

    @property
    def snapshot_every(self) -> int:
        """What to pass to ``run_filter(..., snapshot_every=...)``."""
        return self.stride if self.any else 0


def _check_mcap_target(path: Path, out_dir: Path | None = None) -> None:
    """Refuse an MCAP path whose folder does not exist, unless the command's output folder
    ``out_dir`` (created before anything is written) is that folder or lies inside it."""
    folder = path.parent
    if out_dir is not None and not out_dir.exists():
        target = out_dir.resolve()
        if folder.resolve() in (target, *target.parents):
            return
    if not folder.is_dir():
        raise ConfigError(f"mcap: the folder {str(folder)!r} of {str(path)!r} does not exist")
    if path.is_dir():
        raise ConfigError(f"mcap: {str(path)!r} is a folder; expected a file name")


def write_outputs(
    result: RunResult,
    grid: OccupancyGrid,
    out_dir: str | os.PathLike[str],
    args_or_options: OutputOptions | Mapping[str, Any] | Any,
    *,
    log: ScanLog | None = None,
    summary: Mapping[str, Any] | None = None,
    title: str = "",
    on_frame: Callable[[int, int], None] | None = None,
) -> list[Path]:
    """Write the requested outputs; returns the files written. ``out_dir`` (and its parents)
    is created when an output goes into it (animation, report); the MCAP file's folder must
    exist.

    ``log``: the robot log the run replayed (for the scans in the MCAP file; anything with
    ``len()`` and ``scan(k)``); ``summary``: the run's summary (shown in the report);
    ``on_frame(i, total)``: animation progress.
    """
    options = (
        args_or_options
        if isinstance(args_or_options, OutputOptions)
        else OutputOptions.from_args(args_or_options)
    )
    out = Path(out_dir)
    written: list[Path] = []
    if options.gif or options.mp4 or options.report:
        ensure_output_dir(out)
    if options.gif or options.mp4:
        from ceamcl.viz.animation import animate_run  # matplotlib: see write_run_files

        written += animate_run(
            result,
            grid,
            out,
            gif=options.gif,
            mp4=options.mp4,
            fps=options.fps,
            stride=options.stride,
            title=title,
            on_frame=on_frame,
        )
    if options.report:
        from ceamcl.viz.report import write_report  # matplotlib: see write_run_files

        written.append(
            write_report(
                out / "report.html",
                result,
                grid,
                summary=summary,
                title=title,
                stride=options.stride,
                fps=options.fps,
            )
        )
    if options.mcap is not None:
        _check_mcap_target(options.mcap)
        written.append(write_mcap(options.mcap, result, grid, log))
    return written


#: Every file :func:`write_run_files` may write into a run's folder. Those a run does not
#: write are removed from it first, so a folder holds one run's files only (a CEAMCL run's
#: ``species.csv`` beside a later MCL run's ``summary.json`` would read as MCL's).
RUN_FILES = (
    "trajectory.tum",
    "groundtruth.tum",
    "diagnostics.csv",
    "run.png",
    "species.csv",
    "species.png",
    "summary.json",
    "run.gif",
    "run.mp4",
    "report.html",
)


def clear_run_files(out: Path) -> list[Path]:
    """Remove the files of an earlier run (:data:`RUN_FILES`, nothing else) from ``out``."""
    gone = []
    for name in RUN_FILES:
        path = out / name
        if path.is_file() or path.is_symlink():
            path.unlink()
            gone.append(path)
    return gone


def write_run_files(
    result: RunResult,
    grid: OccupancyGrid,
    out_dir: str | os.PathLike[str] | None,
    summary: Mapping[str, Any],
    *,
    title: str,
    log: ScanLog | None = None,
    outputs: OutputOptions | None = None,
    on_frame: Callable[[int, int], None] | None = None,
) -> list[Path]:
    """The files of one run, as ``ceamcl demo`` and ``ceamcl run`` write them.

    With ``out_dir`` (created with its parents when missing): ``trajectory.tum``,
    ``groundtruth.tum`` (where the run has a truth), ``diagnostics.csv``, ``run.png``,
    ``species.csv`` and ``species.png`` (filters with species) and ``summary.json``, after
    removing an earlier run's files from ``out_dir`` (:data:`RUN_FILES`). ``outputs``
    (:class:`OutputOptions`) adds the visual outputs (without ``out_dir`` only the MCAP file, a
    path of its own); ``log`` gives the MCAP file its scans, ``on_frame(i, total)`` reports the
    animation's progress. Returns the visual outputs written.
    """
    out = None if out_dir is None else Path(out_dir)
    if out is not None:
        ensure_output_dir(out)
        clear_run_files(out)
        # matplotlib (~0.7 s to import) only when a figure is drawn: the CLI imports this
        # module to parse its options.
        from ceamcl.viz.plots import plot_run, plot_species

        write_tum(out / "trajectory.tum", result.times, result.estimates)
        if result.truth is not None:  # at the steps with a true pose (all, or matched scans)
            known = result.truth_known
            write_tum(out / "groundtruth.tum", result.times[known], result.truth[known])
        write_diagnostics_csv(out / "diagnostics.csv", result.diagnostics, list(result.times))
        plot_run(result, grid, out / "run.png", title=title)
        if any(species_of(d) for d in result.diagnostics):
            write_species_csv(out / "species.csv", result.diagnostics, list(result.times))
            plot_species(
                result, out / "species.png", title=f"{title}: sample size and resources (Fig. 6)"
            )
        write_json(out / "summary.json", summary)
    if outputs is None or not outputs.any:
        return []
    return write_outputs(
        result,
        grid,
        out if out is not None else Path(),
        outputs if out is not None else outputs.only_mcap(),
        log=log,
        summary=summary,
        title=title,
        on_frame=on_frame,
    )
