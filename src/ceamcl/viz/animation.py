"""Animations of a run: ``run.gif`` (Pillow) and ``run.mp4`` (ffmpeg, where installed).

Each frame shows the map, the true pose, the estimate, the particles coloured by species (or
cluster, for MCL and GMCL), every species' living domain as its 2-sigma ellipse, and a live panel
of the sample size and the resources over time.

Rendering is fast because one figure is drawn once: the map and the static curves are cached as
a background, and each frame only restores it, updates the moving artists (``set_offsets``,
``set_data``, ``set_segments``) and draws those, then reads the canvas buffer. A 60 s run at the
default stride of 5 steps (120 frames) renders in a few seconds.

The per-frame data (:func:`replay_frames`) is shared with the HTML report.
"""

from __future__ import annotations

import os
import shutil
import subprocess
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.collections import LineCollection
from numpy.typing import NDArray
from PIL import Image

from ceamcl import budget
from ceamcl.filters.base import ParticleSnapshot
from ceamcl.filters.ceamcl.competition import living_domain
from ceamcl.filters.ceamcl.records import CEAMCLRecord, species_of
from ceamcl.io.results import atomic_write
from ceamcl.maps.grid import OccupancyGrid
from ceamcl.runner import RunResult
from ceamcl.viz.draw import draw_map
from ceamcl.viz.state import draw_state_band, state_codes

#: Matplotlib's ``tab10``: species ``i`` is drawn in ``SPECIES_COLOURS[i % 10]`` everywhere
#: (run.png, the animation, the report).
SPECIES_COLOURS: tuple[str, ...] = (
    "#1f77b4",
    "#ff7f0e",
    "#2ca02c",
    "#d62728",
    "#9467bd",
    "#8c564b",
    "#e377c2",
    "#7f7f7f",
    "#bcbd22",
    "#17becf",
)

_ELLIPSE_POINTS = 48


@dataclass(frozen=True, eq=False)
class ReplayFrame:
    """What one frame shows: the step, its time, the particles, the living domains
    (``ellipses``: rows ``label, cx, cy, a, b, angle``; ``a >= b`` are the radii ``2 sqrt(d)``
    of the 2-sigma ellipse of the particles' x-y covariance, ``angle`` in radians), the estimate
    and the truth (``None`` when unknown)."""

    step: int
    time: float
    particles: ParticleSnapshot
    ellipses: NDArray[np.float64]
    estimate: NDArray[np.float64]
    truth: NDArray[np.float64] | None


def living_domains(snapshot: ParticleSnapshot, min_particles: int = 3) -> NDArray[np.float64]:
    """Per label, the 2-sigma ellipse of the particles' unweighted x-y covariance: CEAMCL's
    living domain (eqs. 10-14), computed from the particles so it works for every filter.

    Returns rows ``label, cx, cy, a, b, angle`` (``a >= b`` radii in metres, angle in radians
    of the ``a`` axis); labels with fewer than ``min_particles`` particles are left out.
    """
    rows: list[list[float]] = []
    poses, labels = snapshot.poses, snapshot.labels
    for label in np.unique(labels):
        xy = poses[labels == label, :2]
        if xy.shape[0] < min_particles:
            continue
        cov = np.cov(xy, rowvar=False)
        if not np.all(np.isfinite(cov)):
            continue
        d, u, _ = living_domain(cov)
        a, b = 2.0 * np.sqrt(d[1]), 2.0 * np.sqrt(d[0])
        angle = float(np.arctan2(u[1, 1], u[0, 1]))
        cx, cy = xy.mean(axis=0)
        rows.append([float(label), float(cx), float(cy), float(a), float(b), angle])
    return np.array(rows, dtype=np.float64).reshape(-1, 6)


def frame_steps(result: RunResult, stride: int) -> list[int]:
    """The steps that get a frame: steps with particles kept (``result.snapshots``, plus the
    first and the last step) that are multiples of ``stride``, and always the last step.

    ``run_filter(..., snapshot_every=stride)`` keeps exactly what this needs; a coarser
    ``snapshot_every`` gives fewer frames, and a run without snapshots only its first and last.
    """
    if stride < 1:
        raise ValueError(f"stride: expected a positive number of steps, got {stride}")
    last = result.steps - 1
    available = sorted({0, last, *result.snapshots})
    steps = [k for k in available if k % stride == 0]
    if not steps or steps[-1] != last:
        steps.append(last)
    return steps


def _snapshot_at(result: RunResult, k: int) -> ParticleSnapshot:
    if k in result.snapshots:
        return result.snapshots[k]
    if k == 0:
        return result.initial_particles
    return result.final_particles


def replay_frames(result: RunResult, stride: int = 5) -> list[ReplayFrame]:
    """One :class:`ReplayFrame` per step of :func:`frame_steps`."""
    frames = []
    for k in frame_steps(result, stride):
        snap = _snapshot_at(result, k)
        frames.append(
            ReplayFrame(
                step=k,
                time=float(result.times[k] - result.times[0]),  # since the first step
                particles=snap,
                ellipses=living_domains(snap),
                estimate=result.estimates[k],
                truth=None if result.truth is None else result.truth[k],
            )
        )
    return frames


def series(result: RunResult) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Per step: the total sample size and the total resources (NaN where a filter has none;
    at a scan the update pace held back, the last update's, which it left unchanged)."""
    n = np.array([d.n_particles for d in result.diagnostics], dtype=np.float64)
    r = np.full(n.size, np.nan)
    last = np.nan
    for k, d in enumerate(result.diagnostics):
        if isinstance(d.record, CEAMCLRecord):
            last = d.record.total_resources
            r[k] = last
        elif not d.stepped:
            r[k] = last
    return n, r


def ellipse_outline(row: NDArray[np.float64], points: int = _ELLIPSE_POINTS) -> NDArray[np.float64]:
    """The closed outline ``(points + 1, 2)`` of one ``living_domains`` row."""
    _, cx, cy, a, b, angle = row
    t = np.linspace(0.0, 2.0 * np.pi, points + 1)
    c, s = np.cos(angle), np.sin(angle)
    ex, ey = a * np.cos(t), b * np.sin(t)
    return np.column_stack([cx + c * ex - s * ey, cy + s * ex + c * ey])


def _colours(labels: NDArray[np.int64]) -> NDArray[np.float64]:
    table = np.array([matplotlib.colors.to_rgba(c) for c in SPECIES_COLOURS])
    return table[np.asarray(labels) % len(SPECIES_COLOURS)]


class _Renderer:
    """One figure, drawn once; :meth:`render` updates the moving artists and returns RGB."""

    def __init__(
        self, result: RunResult, grid: OccupancyGrid, title: str, size_px: tuple[int, int]
    ) -> None:
        dpi = 80
        self.fig = plt.figure(figsize=(size_px[0] / dpi, size_px[1] / dpi), dpi=dpi)
        self.canvas = FigureCanvasAgg(self.fig)
        gs = self.fig.add_gridspec(
            2,
            2,
            width_ratios=(1.25, 1),
            left=0.06,
            right=0.97,
            bottom=0.1,
            top=0.9,
            wspace=0.25,
            hspace=0.45,
        )
        ax = self.fig.add_subplot(gs[:, 0])
        self._draw_map(ax, grid)
        self.ax_map = ax
        self.fig.suptitle(title, fontsize=11)

        self.particles = ax.scatter([], [], s=8, linewidths=0, zorder=2, animated=True)
        self.domains = LineCollection([], linewidths=1.4, zorder=3, animated=True)
        ax.add_collection(self.domains)
        (self.truth_path,) = ax.plot(
            [], [], "-", color="#2ca02c", lw=1.2, alpha=0.7, zorder=3, animated=True
        )
        # a ring, so the particles at the true pose stay visible inside it
        (self.truth,) = ax.plot(
            [],
            [],
            "o",
            mfc="none",
            mec="#00a000",
            mew=2.2,
            ms=13,
            zorder=5,
            animated=True,
            label="truth",
        )
        (self.truth_heading,) = ax.plot(
            [], [], "-", color="#00a000", lw=2.2, zorder=5, animated=True
        )
        (self.estimate,) = ax.plot(
            [], [], "x", color="red", ms=10, mew=2.5, zorder=6, animated=True, label="estimate"
        )
        group = "species" if any(species_of(d) for d in result.diagnostics) else "cluster"
        ax.plot([], [], "o", color="0.5", ms=4, label=f"particles (colour: {group})")
        ax.plot([], [], "-", color="0.5", lw=1.4, label="living domain (2σ)")
        ax.legend(
            loc="lower left",
            fontsize=7,
            framealpha=0.85,
            handles=[self.truth, self.estimate, *ax.lines[-2:]],
        )

        n, r = series(result)
        t = result.times - result.times[0]  # as the frames' header: since the first step
        self.ax_n = self.fig.add_subplot(gs[0, 1])
        self.ax_n.plot(t, n, "-", color="0.6", lw=1)
        self.ax_n.set_ylabel("sample size", fontsize=8)
        self.ax_n.set_xlim(float(t[0]), float(t[-1]) if t[-1] > t[0] else float(t[0]) + 1.0)
        self.ax_n.set_ylim(0, max(float(np.nanmax(n)) * 1.08, 1.0))
        self.ax_n.grid(alpha=0.3)
        self.ax_n.tick_params(labelsize=7)
        (self.n_live,) = self.ax_n.plot([], [], "k-", lw=2, animated=True)
        # the localisation state as a coloured band along the bottom of the sample-size chart
        self.states = result.states
        if any(st is not None for st in self.states):
            top = self.ax_n.get_ylim()[1]
            draw_state_band(self.ax_n, t, state_codes(self.states), 0.0, 0.06 * top)
        self.ax_r = self.fig.add_subplot(gs[1, 1], sharex=self.ax_n)
        self.has_resources = bool(np.any(np.isfinite(r)))
        if self.has_resources:
            self.ax_r.plot(t, r, "-", color="0.6", lw=1)
            self.ax_r.set_ylim(0, max(float(np.nanmax(r)) * 1.08, 1.0))
            self.ax_r.set_ylabel("total resources R", fontsize=8)
        else:
            self.ax_r.set_ylabel("hypotheses", fontsize=8)
            counts = np.array([h.shape[0] for h in result.hypotheses], dtype=np.float64)
            self.ax_r.plot(t, counts, "-", color="0.6", lw=1)
            self.ax_r.set_ylim(0, max(float(counts.max()) * 1.08, 1.0))
            r = counts
        self.ax_r.set_xlabel("time since the first step [s]", fontsize=8)
        self.ax_r.grid(alpha=0.3)
        self.ax_r.tick_params(labelsize=7)
        (self.r_live,) = self.ax_r.plot([], [], "g-", lw=2, animated=True)
        self.n_series, self.r_series, self.t = n, r, t
        self.text = self.fig.text(0.06, 0.935, "", fontsize=9, animated=True)
        self.truth_xy = None if result.truth is None else result.truth[:, :2]
        self.group = group

        self.canvas.draw()
        self.background = self.canvas.copy_from_bbox(self.fig.bbox)
        self.moving = (
            self.particles,
            self.domains,
            self.truth_path,
            self.truth,
            self.truth_heading,
            self.estimate,
            self.n_live,
            self.r_live,
            self.text,
        )

    @staticmethod
    def _draw_map(ax: matplotlib.axes.Axes, grid: OccupancyGrid) -> None:
        draw_map(ax, grid)
        x0, x1, y0, y1 = grid.bounds
        ax.set_xlim(x0, x1)
        ax.set_ylim(y0, y1)
        ax.tick_params(labelsize=7)
        ax.xaxis.label.set_fontsize(8)
        ax.yaxis.label.set_fontsize(8)

    def render(self, frame: ReplayFrame) -> NDArray[np.uint8]:
        k = frame.step
        snap = frame.particles
        self.particles.set_offsets(snap.poses[:, :2])
        # an (N, 4) RGBA array is a valid colour list; Matplotlib's stubs only name sequences
        self.particles.set_facecolor(_colours(snap.labels))  # type: ignore[arg-type]
        self.domains.set_segments([ellipse_outline(row) for row in frame.ellipses])
        domain_colours = _colours(frame.ellipses[:, 0].astype(np.int64))
        self.domains.set_color(domain_colours)  # type: ignore[arg-type]
        self.estimate.set_data([frame.estimate[0]], [frame.estimate[1]])
        if self.truth_xy is not None:
            # the path through the steps with truth so far (a raw log's truth is known at its
            # paired scans only: drawn with its gaps, the path vanished), the ring where the
            # truth is known at this step
            seen = self.truth_xy[: k + 1]
            seen = seen[np.isfinite(seen).all(axis=1)]
            self.truth_path.set_data(seen[:, 0], seen[:, 1])
        if frame.truth is not None and np.all(np.isfinite(frame.truth)):
            x, y, th = frame.truth
            self.truth.set_data([x], [y])
            r0, r1 = 0.25, 0.75  # from the ring outwards
            c, s = np.cos(th), np.sin(th)
            self.truth_heading.set_data([x + r0 * c, x + r1 * c], [y + r0 * s, y + r1 * s])
        else:
            self.truth.set_data([], [])
            self.truth_heading.set_data([], [])
        self.n_live.set_data(self.t[: k + 1], self.n_series[: k + 1])
        self.r_live.set_data(self.t[: k + 1], self.r_series[: k + 1])
        n_species = int(np.unique(snap.labels).size)
        res = self.r_series[k]
        res_text = f"   R = {res:.0f}" if self.has_resources and np.isfinite(res) else ""
        st = self.states[k] if k < len(self.states) else None
        state_text = "" if st is None else f"   {st.state.name} ({st.confidence:.2f})"
        self.text.set_text(
            f"t = {frame.time:5.1f} s   step {k}   N = {snap.poses.shape[0]}   "
            f"{self.group} = {n_species}{res_text}{state_text}"
        )
        self.canvas.restore_region(self.background)
        for artist in self.moving:
            self.fig.draw_artist(artist)
        buf = np.asarray(self.canvas.buffer_rgba())
        return np.ascontiguousarray(buf[:, :, :3])

    def close(self) -> None:
        plt.close(self.fig)


def render_frames(
    result: RunResult,
    grid: OccupancyGrid,
    *,
    stride: int = 5,
    title: str = "",
    size_px: tuple[int, int] = (800, 450),
    on_frame: Callable[[int, int], None] | None = None,
) -> Iterator[NDArray[np.uint8]]:
    """RGB frames ``(H, W, 3)`` of the run, one per :func:`frame_steps` step.

    ``on_frame(i, total)`` is called after each frame (progress bars hook in here).
    """
    frames = replay_frames(result, stride)
    renderer = _Renderer(result, grid, title or f"{result.algorithm} on {grid.name}", size_px)
    try:
        for i, frame in enumerate(frames):
            yield renderer.render(frame)
            if on_frame is not None:
                on_frame(i + 1, len(frames))
    finally:
        renderer.close()


def _palette_image(samples: list[NDArray[np.uint8]]) -> Image.Image:
    """One 256-colour palette for the whole GIF: the species' colours exactly (a median cut
    of a few frames merged small species into the map's greys: blue and cyan species came out
    grey), then a median cut of the sampled frames side by side for the rest."""
    fixed = [tuple(round(255 * v) for v in matplotlib.colors.to_rgb(c)) for c in SPECIES_COLOURS]
    strip = np.concatenate(samples, axis=1)
    cut = Image.fromarray(strip).quantize(256 - len(fixed), method=Image.Quantize.MEDIANCUT)
    rest = (cut.getpalette() or [])[: 3 * (256 - len(fixed))]
    palette = [v for rgb in fixed for v in rgb] + rest
    image = Image.new("P", (1, 1))
    image.putpalette(palette + [0] * (768 - len(palette)))
    return image


def write_gif(
    frames: list[NDArray[np.uint8]], path: str | os.PathLike[str], fps: float = 10.0
) -> Path:
    """Save RGB frames as a looping GIF with one shared palette (no dithering, optimised)."""
    if not frames:
        raise ValueError("write_gif: no frames")
    if not fps > 0:
        raise ValueError(f"fps: expected > 0, got {fps}")
    picks = sorted({round(i * (len(frames) - 1) / 11) for i in range(12)})  # up to 12 frames
    palette = _palette_image([frames[i] for i in picks])
    images = [
        Image.fromarray(f).quantize(palette=palette, dither=Image.Dither.NONE) for f in frames
    ]
    with atomic_write(path, keep_suffix=True) as tmp:
        images[0].save(
            tmp,
            format="GIF",
            save_all=True,
            append_images=images[1:],
            duration=max(round(1000.0 / fps), 20),
            loop=0,
            optimize=True,
        )
    return Path(path)


def ffmpeg_path() -> str | None:
    """The ffmpeg executable on the PATH, or ``None``."""
    return shutil.which("ffmpeg")


def write_mp4(
    frames: list[NDArray[np.uint8]], path: str | os.PathLike[str], fps: float = 10.0
) -> Path:
    """Pipe RGB frames to ffmpeg (H.264, yuv420p so every player opens it)."""
    exe = ffmpeg_path()
    if exe is None:
        raise RuntimeError("write_mp4: ffmpeg is not on the PATH")
    if not frames:
        raise ValueError("write_mp4: no frames")
    with atomic_write(path, keep_suffix=True) as tmp:
        _pipe_to_ffmpeg(exe, frames, fps, tmp)
    return Path(path)


def _pipe_to_ffmpeg(exe: str, frames: list[NDArray[np.uint8]], fps: float, out: Path) -> None:
    h, w = frames[0].shape[:2]
    cmd = [
        exe,
        "-y",
        "-loglevel",
        "error",
        "-f",
        "rawvideo",
        "-pix_fmt",
        "rgb24",
        "-s",
        f"{w}x{h}",
        "-r",
        f"{fps:g}",
        "-i",
        "-",
        # yuv420p needs even sides
        "-vf",
        "pad=ceil(iw/2)*2:ceil(ih/2)*2",
        "-c:v",
        "libx264",
        "-pix_fmt",
        "yuv420p",
        "-movflags",
        "+faststart",
        str(out),
    ]
    proc = subprocess.Popen(cmd, stdin=subprocess.PIPE, stderr=subprocess.PIPE)
    assert proc.stdin is not None
    try:
        for f in frames:
            proc.stdin.write(np.ascontiguousarray(f).tobytes())
    finally:
        proc.stdin.close()
    err = proc.stderr.read().decode(errors="replace") if proc.stderr else ""
    if proc.wait() != 0:
        raise RuntimeError(f"write_mp4: ffmpeg failed: {err.strip()}")


#: Memory a rendered frame holds until the animation is written: the 800 x 450 RGB image and
#: its palette copy, with Pillow's and matplotlib's overhead (measured 2026-11-30: 1.75 MB a
#: frame; `--every-scan --gif` on intel raw, 2,727 frames, peaked at 5.2 GB before this check).
FRAME_BYTES = 2 << 20


def animate_run(
    result: RunResult,
    grid: OccupancyGrid,
    out_dir: str | os.PathLike[str],
    *,
    gif: bool = True,
    mp4: bool = False,
    fps: float = 10.0,
    stride: int = 5,
    title: str = "",
    on_frame: Callable[[int, int], None] | None = None,
) -> list[Path]:
    """Render the run once and write ``run.gif`` and/or ``run.mp4`` into ``out_dir``.

    Every frame is held until the files are written (the GIF's palette is shared): their
    number is checked against the memory budget first (:data:`FRAME_BYTES` each), and a run
    too long for it is refused, naming the ``--stride`` that would fit."""
    if not (gif or mp4):
        return []
    n = len(frame_steps(result, stride))
    fits = max(1, budget.current().memory_bytes // FRAME_BYTES)
    if n > fits:
        need = stride * -(-n // fits)  # a stride about that many times coarser fits
        budget.require(
            f"run.gif/run.mp4 at --stride {stride} (--stride {need} or more would fit)",
            n,
            FRAME_BYTES,
            "animation frames",
        )
    frames = list(render_frames(result, grid, stride=stride, title=title, on_frame=on_frame))
    out = Path(out_dir)
    written = []
    if gif:
        written.append(write_gif(frames, out / "run.gif", fps))
    if mp4:
        written.append(write_mp4(frames, out / "run.mp4", fps))
    return written


def save_frame(
    result: RunResult,
    grid: OccupancyGrid,
    path: str | os.PathLike[str],
    *,
    step: int | None = None,
    stride: int = 5,
    title: str = "",
) -> Path:
    """One frame as a PNG (the README's picture): the frame at ``step`` or the closest after."""
    frames = replay_frames(result, stride)
    pick = frames[-1]
    if step is not None:
        pick = next((f for f in frames if f.step >= step), frames[-1])
    renderer = _Renderer(result, grid, title or f"{result.algorithm} on {grid.name}", (800, 450))
    try:
        rgb = renderer.render(pick)
    finally:
        renderer.close()
    with atomic_write(path, keep_suffix=True) as tmp:
        Image.fromarray(rgb).save(tmp, format="PNG", optimize=True)
    return Path(path)
