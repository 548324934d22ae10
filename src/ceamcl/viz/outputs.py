"""The visual outputs every command can write: ``run.gif``/``run.mp4``, ``report.html``, MCAP.

Commands share them in three lines::

    add_output_arguments(parser)                       # --gif/--no-animation --mp4 --fps ...
    options = OutputOptions.from_args(args)            # checks ffmpeg before any work
    result = run_filter(f, log, snapshot_every=options.snapshot_every)
    files = write_outputs(result, grid, out_dir, options, log=log, summary=summary)

``snapshot_every`` is the stride when an output needs the particles of every frame, else 0
(no snapshots kept, no memory spent).
"""

from __future__ import annotations

import argparse
import os
from collections.abc import Callable, Mapping
from dataclasses import dataclass, replace
from pathlib import Path
from typing import TYPE_CHECKING, Any

from ceamcl.errors import ConfigError
from ceamcl.maps.grid import OccupancyGrid
from ceamcl.runner import RunResult

if TYPE_CHECKING:
    from ceamcl.io.mcap_export import ScanLog

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
    def from_args(cls, args: argparse.Namespace | Mapping[str, Any]) -> OutputOptions:
        """Options from the arguments :func:`add_output_arguments` added (missing ones take
        their defaults). ``--mp4`` without ffmpeg on the PATH is an error, raised here, before
        the run."""
        get: Callable[[str, Any], Any]
        if isinstance(args, Mapping):
            get = args.get
        else:

            def get(name: str, default: Any) -> Any:
                return getattr(args, name, default)

        mcap = get("mcap", None)
        options = cls(
            gif=bool(get("gif", True)),
            mp4=bool(get("mp4", False)),
            fps=float(get("fps", DEFAULT_FPS)),
            stride=int(get("stride", DEFAULT_STRIDE)),
            report=bool(get("report", False)),
            mcap=None if mcap is None else Path(mcap),
        )
        if options.mcap is not None:
            _check_mcap_target(options.mcap)
        if options.mp4:
            from ceamcl.viz.animation import ffmpeg_path

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


def _check_mcap_target(path: Path) -> None:
    folder = path.parent
    if not folder.is_dir():
        raise ConfigError(f"mcap: the folder {str(folder)!r} of {str(path)!r} does not exist")
    if path.is_dir():
        raise ConfigError(f"mcap: {str(path)!r} is a folder; expected a file name")


def _positive_int(text: str) -> int:
    from ceamcl.cli.common import positive_int

    return positive_int(text)


def _positive_float(text: str) -> float:
    from ceamcl.cli.common import positive_float

    return positive_float(text)


def add_output_arguments(
    parser: argparse.ArgumentParser, *, animation_default: bool = True
) -> None:
    """Add ``--gif/--no-animation``, ``--mp4``, ``--fps``, ``--stride``, ``--report`` and
    ``--mcap FILE`` to ``parser`` (in their own argument group).

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
        type=_positive_float,
        default=DEFAULT_FPS,
        help=f"frames per second of the animation and the replay (default {DEFAULT_FPS:g})",
    )
    group.add_argument(
        "--stride",
        type=_positive_int,
        default=DEFAULT_STRIDE,
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


def write_outputs(
    result: RunResult,
    grid: OccupancyGrid,
    out_dir: str | os.PathLike[str],
    args_or_options: OutputOptions | argparse.Namespace | Mapping[str, Any],
    *,
    log: ScanLog | None = None,
    summary: Mapping[str, Any] | None = None,
    title: str = "",
    on_frame: Callable[[int, int], None] | None = None,
) -> list[Path]:
    """Write the requested outputs; returns the files written.

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
    if options.gif or options.mp4:
        from ceamcl.viz.animation import animate_run

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
        from ceamcl.viz.report import write_report

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
        from ceamcl.io.mcap_export import write_mcap

        _check_mcap_target(options.mcap)
        written.append(write_mcap(options.mcap, result, grid, log))
    return written
