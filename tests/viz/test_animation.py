"""Tests of ``ceamcl.viz.animation``: living domains, frame selection, frames, GIF and MP4."""

from __future__ import annotations

import dataclasses
import itertools
import os
import sys
from pathlib import Path

import numpy as np
import pytest
from PIL import Image

from ceamcl.filters.base import ParticleSnapshot
from ceamcl.viz.animation import (
    animate_run,
    ellipse_outline,
    ffmpeg_path,
    frame_steps,
    living_domains,
    render_frames,
    replay_frames,
    save_frame,
    write_gif,
    write_mp4,
)
from tests.viz.runs import SNAPSHOT_EVERY, STEPS, short_run


def _snapshot(poses: np.ndarray, labels: np.ndarray) -> ParticleSnapshot:
    return ParticleSnapshot(poses, np.full(poses.shape[0], 1.0 / poses.shape[0]), labels)


def test_living_domain_is_the_two_sigma_ellipse_of_each_label() -> None:
    rng = np.random.default_rng(0)
    n = 20000
    angle = 0.5
    rot = np.array([[np.cos(angle), -np.sin(angle)], [np.sin(angle), np.cos(angle)]])
    sd = np.array([0.4, 0.1])
    a_xy = (rng.standard_normal((n, 2)) * sd) @ rot.T + [2.0, 3.0]
    b_xy = rng.standard_normal((n, 2)) * 0.05 + [7.0, 1.0]
    lonely = np.array([[5.0, 5.0], [5.1, 5.0]])  # two particles: no ellipse
    xy = np.vstack([a_xy, b_xy, lonely])
    poses = np.column_stack([xy, np.zeros(xy.shape[0])])
    labels = np.r_[np.full(n, 3), np.full(n, 8), [5, 5]].astype(np.int64)
    rows = living_domains(_snapshot(poses, labels))
    assert rows[:, 0].tolist() == [3.0, 8.0]
    la, lb = rows
    np.testing.assert_allclose(la[1:3], [2.0, 3.0], atol=0.02)
    np.testing.assert_allclose(la[3:5], 2.0 * sd, rtol=0.03)
    # the ellipse's major axis is a line: angle defined modulo pi
    assert abs(np.angle(np.exp(2j * (la[5] - angle)))) < 0.05
    np.testing.assert_allclose(lb[3:5], [0.1, 0.1], rtol=0.05)


def test_ellipse_outline_lies_on_the_ellipse() -> None:
    row = np.array([0.0, 1.0, -2.0, 3.0, 1.0, 0.7])
    pts = ellipse_outline(row)
    c, s = np.cos(-0.7), np.sin(-0.7)
    local = (pts - [1.0, -2.0]) @ np.array([[c, s], [-s, c]])
    np.testing.assert_allclose((local[:, 0] / 3.0) ** 2 + local[:, 1] ** 2, 1.0, atol=1e-9)
    np.testing.assert_allclose(pts[0], pts[-1])


def test_frame_steps_follow_stride_and_end_at_the_last_step() -> None:
    result, _, _ = short_run()
    assert frame_steps(result, SNAPSHOT_EVERY) == [*range(0, STEPS, SNAPSHOT_EVERY)]
    assert frame_steps(result, 10) == [0, 10, 20, 30, 40]
    # a stride the snapshots do not support keeps what exists, and always the last step
    assert frame_steps(result, 7) == [0, 35, 40]
    bare = dataclasses.replace(result, snapshots={})
    assert frame_steps(bare, 5) == [0, STEPS - 1]
    with pytest.raises(ValueError, match="stride"):
        frame_steps(result, 0)


def test_replay_frames_carry_the_runs_particles_truth_and_estimate() -> None:
    result, _, _ = short_run()
    frames = replay_frames(result, 10)
    assert [f.step for f in frames] == [0, 10, 20, 30, 40]
    assert result.truth is not None
    for f in frames:
        assert f.particles is result.snapshots[f.step]
        np.testing.assert_array_equal(f.estimate, result.estimates[f.step])
        np.testing.assert_array_equal(f.truth, result.truth[f.step])
        assert f.time == pytest.approx(result.times[f.step])
        assert set(f.ellipses[:, 0].astype(int)) <= set(f.particles.labels.tolist())
    # CEAMCL starts with several species: several living domains
    assert frames[0].ellipses.shape[0] > 1


@pytest.fixture(scope="module")
def frames() -> list[np.ndarray]:
    result, grid, _ = short_run()
    return list(render_frames(result, grid, stride=SNAPSHOT_EVERY, size_px=(480, 270)))


def test_render_frames_gives_one_rgb_image_per_frame_and_they_change(
    frames: list[np.ndarray],
) -> None:
    result, _, _ = short_run()
    assert len(frames) == len(frame_steps(result, SNAPSHOT_EVERY))
    for f in frames:
        assert f.shape == (270, 480, 3) and f.dtype == np.uint8
    for a, b in itertools.pairwise(frames):
        assert np.any(a != b)


def test_render_frames_reports_progress() -> None:
    result, grid, _ = short_run()
    calls: list[tuple[int, int]] = []
    n = len(
        list(
            render_frames(
                result,
                grid,
                stride=20,
                size_px=(320, 180),
                on_frame=lambda i, t: calls.append((i, t)),
            )
        )
    )
    assert calls == [(i + 1, n) for i in range(n)]


def test_write_gif_keeps_every_frame_at_the_frame_rate(
    frames: list[np.ndarray], tmp_path: Path
) -> None:
    path = write_gif(frames, tmp_path / "run.gif", fps=5.0)
    with Image.open(path) as im:
        assert im.format == "GIF"
        assert im.n_frames == len(frames)
        assert im.size == (480, 270)
        assert im.info["duration"] == 200
        assert im.info.get("loop") == 0
        im.seek(len(frames) - 1)
        last = np.asarray(im.convert("RGB"), dtype=np.int16)
    # palette quantisation changes colours a little, never the picture
    assert np.mean(np.abs(last - frames[-1])) < 8.0
    assert [p.name for p in tmp_path.iterdir()] == ["run.gif"]


def test_write_gif_rejects_nonsense(frames: list[np.ndarray], tmp_path: Path) -> None:
    with pytest.raises(ValueError, match="no frames"):
        write_gif([], tmp_path / "a.gif")
    with pytest.raises(ValueError, match="fps"):
        write_gif(frames, tmp_path / "a.gif", fps=0.0)
    assert not list(tmp_path.iterdir())


@pytest.mark.skipif(ffmpeg_path() is None, reason="ffmpeg is not installed (run.mp4 needs it)")
def test_write_mp4_with_ffmpeg(frames: list[np.ndarray], tmp_path: Path) -> None:
    path = write_mp4(frames, tmp_path / "run.mp4", fps=10.0)
    data = path.read_bytes()
    assert b"ftyp" in data[:64] and len(data) > 1000


def test_write_mp4_pipes_raw_rgb_frames_to_ffmpeg(
    frames: list[np.ndarray], tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    # a stand-in ffmpeg: checks the frame size it is told, counts the bytes it is sent
    fake = tmp_path / "bin" / "ffmpeg"
    fake.parent.mkdir()
    fake.write_text(
        f"#!{sys.executable}\n"
        "import sys\n"
        "a = sys.argv\n"
        "w, h = map(int, a[a.index('-s') + 1].split('x'))\n"
        "data = sys.stdin.buffer.read()\n"
        "open(a[-1], 'w').write(f'{w} {h} {a[a.index(\"-r\") + 1]} {len(data) // (w * h * 3)}')\n"
        "sys.exit(0 if len(data) % (w * h * 3) == 0 else 1)\n"
    )
    fake.chmod(0o755)
    monkeypatch.setenv("PATH", f"{fake.parent}{os.pathsep}{os.environ['PATH']}")
    path = write_mp4(frames, tmp_path / "run.mp4", fps=12.5)
    assert path.read_text() == f"480 270 12.5 {len(frames)}"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["bin", "run.mp4"]


def test_write_mp4_without_ffmpeg_says_so(
    frames: list[np.ndarray], tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setattr("ceamcl.viz.animation.shutil.which", lambda name: None)
    with pytest.raises(RuntimeError, match="ffmpeg"):
        write_mp4(frames, tmp_path / "run.mp4")


def test_animate_run_and_save_frame_write_files(tmp_path: Path) -> None:
    result, grid, _ = short_run("mcl")
    written = animate_run(result, grid, tmp_path, stride=10, fps=4.0)
    assert written == [tmp_path / "run.gif"]
    with Image.open(written[0]) as im:
        assert im.n_frames == len(frame_steps(result, 10))
    assert animate_run(result, grid, tmp_path / "none", gif=False, mp4=False) == []
    png = save_frame(result, grid, tmp_path / "frame.png", step=12)
    with Image.open(png) as im:
        assert im.format == "PNG" and im.size == (800, 450)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["frame.png", "run.gif"]


def test_an_animation_the_memory_budget_cannot_hold_is_refused_naming_a_stride_that_fits(
    tmp_path: Path,
) -> None:
    # every frame is held until the GIF is written: 2,727 frames of intel raw at every scan
    # peaked at 5.2 GB whatever the budget
    from ceamcl import budget
    from ceamcl.viz.animation import FRAME_BYTES

    result, grid, _ = short_run("mcl")
    n = len(frame_steps(result, 10))
    assert n >= 3
    with budget.use(budget.Budget((n - 1) * FRAME_BYTES)):
        with pytest.raises(
            budget.BudgetError,
            match=rf"run\.gif/run\.mp4 at --stride 10 \(--stride 20 or more would fit\): {n} "
            "animation frames would need",
        ):
            animate_run(result, grid, tmp_path, stride=10)
    assert not any(tmp_path.iterdir())


def test_the_gifs_palette_keeps_every_species_colour(tmp_path: Path) -> None:
    # a median cut of a few frames merged small species into the map's greys: blue and cyan
    # species came out grey in run.gif
    import matplotlib.colors

    from ceamcl.viz.animation import SPECIES_COLOURS

    rng = np.random.default_rng(0)
    frames = []
    for _ in range(5):
        f = rng.integers(90, 170, (120, 200, 3), dtype=np.uint8)  # many greys and tints
        for i, c in enumerate(SPECIES_COLOURS):
            f[2:4, 2 + 4 * i : 4 + 4 * i] = [round(255 * v) for v in matplotlib.colors.to_rgb(c)]
        frames.append(f)
    path = write_gif(frames, tmp_path / "run.gif", fps=5.0)
    with Image.open(path) as im:
        back = np.asarray(im.convert("RGB"))
    for i, c in enumerate(SPECIES_COLOURS):
        want = [round(255 * v) for v in matplotlib.colors.to_rgb(c)]
        assert back[2, 2 + 4 * i].tolist() == want, c


def test_a_real_logs_epoch_clock_is_shown_as_time_since_the_first_step() -> None:
    # intel's scans are stamped about 9.76e8 s: run.gif's header read "t = 976054476.3 s",
    # species.png's axis "+9.7605e8", and report.html's chart and label disagreed
    from dataclasses import replace

    from ceamcl.viz.report import replay_data

    result, grid, _ = short_run("mcl")
    late = replace(result, times=result.times + 976_054_476.0)
    frames = replay_frames(late, SNAPSHOT_EVERY)
    assert frames[0].time == 0.0
    assert frames[-1].time == pytest.approx(result.times[frames[-1].step] - result.times[0])
    data = replay_data(late, grid, stride=SNAPSHOT_EVERY)
    assert data["times"][0] == 0.0 and data["frames"][0]["t"] == 0.0


def test_the_gif_draws_the_true_path_through_steps_whose_truth_is_known() -> None:
    # a raw log's truth is known at its paired scans only (910 of 13,631 on intel, never two
    # in a row): the path, drawn with its NaN gaps, never showed
    from dataclasses import replace

    from ceamcl.viz.animation import _Renderer

    result, grid, _ = short_run("mcl")
    assert result.truth is not None
    sparse = result.truth.copy()
    sparse[1::2] = np.nan
    gappy = replace(result, truth=sparse)
    renderer = _Renderer(gappy, grid, "", (480, 270))
    frames = replay_frames(gappy, SNAPSHOT_EVERY)
    last = frames[-1]
    renderer.render(last)
    x, _ = renderer.truth_path.get_data()
    assert len(x) == np.isfinite(sparse[: last.step + 1, 0]).sum() > 1
    assert np.all(np.isfinite(np.asarray(x, dtype=float)))
    odd = next(f for f in frames if f.step % 2 == 1)
    renderer.render(odd)  # no truth at this step: no ring, and no error
    assert len(renderer.truth.get_data()[0]) == 0
