"""Soak test: run a filter for a very long simulated drive and watch memory and sample size.

The simulated robot drives a closed loop of a built-in world for as many steps as asked
(``small-office``: the office tour and back; the halls: the paper's route and back). The log
is a generator: each step's odometry and scan are made when the filter asks for them, so a
100,000-step run never holds more than one scan.

Memory is the process's resident set size (``VmRSS`` in ``/proc/self/status``; where that file
is missing, the peak RSS from :func:`resource.getrusage`). It is read after the global
initialisation (``rss_start``), at the end of the warm-up (``rss_warm``, the reference), every
``sample_every`` steps after that, and at the end (``rss_end``); ``growth_pct`` is
``100 * (rss_end - rss_warm) / rss_warm``. A garbage collection runs before the reference and
the final reading, so only memory that Python could not give back counts.

:func:`run_soak` returns a :class:`SoakReport`; :func:`write_soak_outputs` writes
``soak.json`` (every figure plus the sampled series) and ``soak.png``.
"""

from __future__ import annotations

import gc
import os
import platform
import resource
import time
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from dataclasses import asdict, dataclass, field
from functools import partial
from pathlib import Path
from typing import Any

import numba
import numpy as np
from numpy.typing import NDArray

from ceamcl.errors import ConfigError
from ceamcl.filters import LocalisationFilter, registry
from ceamcl.io.results import atomic_write, ensure_output_dir, write_json
from ceamcl.maps.grid import OccupancyGrid
from ceamcl.maps.worlds import get_world
from ceamcl.motion.odometry import OdometryMotionModel, increment_between
from ceamcl.runner import measure, timed_step
from ceamcl.sensors.scan import LaserScan
from ceamcl.simulation.scenarios import office_scenario, paper_scenario
from ceamcl.simulation.simulator import SimulationConfig, Simulator, drive_waypoints

SOAK_WORLDS: tuple[str, ...] = ("small-office", "symmetric-hall", "marked-hall")
DEFAULT_MAX_GROWTH_PCT = 5.0


@dataclass(frozen=True)
class SoakConfig:
    """What to run. ``warmup_steps`` None: a tenth of the run, at most 5,000 steps."""

    steps: int = 100_000
    algorithm: str = "ceamcl"
    world: str = "small-office"
    sensor: str = "likelihood-field"
    seed: int = 0
    particles: int | None = None
    warmup_steps: int | None = None
    sample_every: int = 100
    max_growth_pct: float = DEFAULT_MAX_GROWTH_PCT

    def __post_init__(self) -> None:
        if self.steps < 2:
            raise ConfigError(f"steps: expected at least 2, got {self.steps}")
        registry.get(self.algorithm)  # an unknown name is a ConfigError naming the choices
        if self.world not in SOAK_WORLDS:
            raise ConfigError(
                f"world: the soak drives a loop in one of {', '.join(SOAK_WORLDS)}, "
                f"got {self.world!r}"
            )
        if self.sensor not in registry.SENSOR_MODELS:
            raise ConfigError(
                f"sensor: unknown sensor model {self.sensor!r}; expected one of "
                f"{', '.join(registry.SENSOR_MODELS)}"
            )
        if self.seed < 0:
            raise ConfigError(f"seed: expected a non-negative number, got {self.seed}")
        if self.particles is not None and self.particles < 1:
            raise ConfigError(f"particles: expected a positive count, got {self.particles}")
        if self.warmup_steps is not None and not 0 <= self.warmup_steps < self.steps:
            raise ConfigError(
                f"warmup_steps: expected 0 <= warmup_steps < steps ({self.steps}), "
                f"got {self.warmup_steps}"
            )
        if self.sample_every < 1:
            raise ConfigError(f"sample_every: expected a positive count, got {self.sample_every}")
        if not self.max_growth_pct > 0:
            raise ConfigError(f"max_growth_pct: expected > 0, got {self.max_growth_pct}")

    @property
    def warmup(self) -> int:
        if self.warmup_steps is not None:
            return self.warmup_steps
        return max(1, min(5_000, self.steps // 10))


# ------------------------------------------------------------------------------ the drive
def loop_route(world: str, config: SimulationConfig | None = None) -> NDArray[np.float64]:
    """True poses ``(L, 3)`` of one closed loop in ``world``: the scenario's route, then back
    to the start and its heading. The last pose is one step before the first, so the loop
    can be repeated without a pause."""
    cfg = config or SimulationConfig()
    scenario = office_scenario(cfg) if world == "small-office" else paper_scenario(0, world, cfg)
    start = np.asarray(scenario.start, dtype=np.float64)
    points = [np.asarray(w, dtype=np.float64)[:2] for w in scenario.waypoints]
    back = [*points[-2::-1], start]  # retrace the route to the start position
    path = drive_waypoints(start, [*points, *back[:-1], start], cfg)
    # Turn back to the starting heading on the spot; drop the final pose (= the first one).
    tail = drive_waypoints(path[-1], [np.array([*start[:2], start[2]])], cfg)
    loop = np.vstack([path, tail[1:]])
    if np.allclose(loop[-1], loop[0]):
        loop = loop[:-1]
    return loop


@dataclass
class SimulatedStream:
    """A simulated log made step by step along a repeated loop (nothing is stored per step).

    Iterating yields ``(true_pose, odometry_pose, scan)``; odometry drifts like wheel odometry
    (the simulator's noise model) and scans are ray-cast from the true pose."""

    grid: OccupancyGrid
    loop: NDArray[np.float64]
    steps: int
    rng: np.random.Generator
    config: SimulationConfig = field(default_factory=SimulationConfig)

    def __len__(self) -> int:
        return self.steps

    def __iter__(self) -> Iterator[tuple[NDArray[np.float64], NDArray[np.float64], LaserScan]]:
        sim = Simulator(self.grid, self.config)
        # the data's noise: Table 5.6 over each step, as synthetic_odometry draws it
        model = OdometryMotionModel(self.config.odometry_noise, stride_m=None)
        dt = 1.0 / self.config.rate_hz
        size = self.loop.shape[0]
        truth = self.loop[0].copy()
        odom = truth.copy()
        for k in range(self.steps):
            if k > 0:
                nxt = self.loop[k % size]
                inc = increment_between(truth, nxt)
                odom = model.sample(odom[None, :], inc, self.rng)[0]
                truth = nxt.copy()
            with _one_thread():  # 181 rays: a thread hand-off costs more than it saves
                ranges = sim.scans(truth[None, :], self.rng)[0]
            yield truth, odom, self.config.laser.scan(ranges, stamp=k * dt)


@contextmanager
def _one_thread() -> Iterator[None]:
    previous = numba.get_num_threads()
    numba.set_num_threads(1)
    try:
        yield
    finally:
        numba.set_num_threads(previous)


# ------------------------------------------------------------------------------ measuring
def rss_kb() -> int:
    """Resident set size of this process in KiB (``VmRSS``; else the peak from getrusage)."""
    try:
        with open("/proc/self/status", encoding="ascii") as fh:
            for line in fh:
                if line.startswith("VmRSS:"):
                    return int(line.split()[1])
    except OSError:
        pass
    return int(resource.getrusage(resource.RUSAGE_SELF).ru_maxrss)


def sample_size_bounds(f: LocalisationFilter) -> tuple[int, int]:
    """The smallest and largest sample size ``f`` may have by its configuration."""
    cfg = getattr(f, "config", None)
    if f.name == "ceamcl":
        return 1, int(cfg.max_samples)  # type: ignore[union-attr]
    for lo_name, hi_name in (
        ("min_particles", "max_particles"),
        ("min_samples", "max_samples"),
        ("n_particles", "n_particles"),
    ):
        lo, hi = getattr(cfg, lo_name, None), getattr(cfg, hi_name, None)
        if isinstance(lo, int) and isinstance(hi, int):
            return lo, hi
    return 1, 2**62


@dataclass
class SoakReport:
    """What a soak run measured. RSS in KiB; ``series_*`` sampled every ``sample_every``."""

    config: dict[str, Any]
    steps: int
    warmup_steps: int
    wall_s: float
    init_s: float
    steps_per_s: float
    rss_start_kb: int
    rss_warm_kb: int
    rss_end_kb: int
    rss_peak_after_warmup_kb: int
    growth_pct: float
    samples_min: int
    samples_max: int
    samples_bound_low: int
    samples_bound_high: int
    samples_within_bounds: bool
    reinitialisations: int
    position_error_mean_m: float
    position_error_max_m: float
    share_within_0_5_m: float
    nonfinite_estimates: int
    series_step: list[int]
    series_rss_kb: list[int]
    series_samples: list[int]
    environment: dict[str, str]

    @property
    def memory_flat(self) -> bool:
        return self.growth_pct < float(self.config["max_growth_pct"])

    @property
    def passed(self) -> bool:
        return self.memory_flat and self.samples_within_bounds and self.nonfinite_estimates == 0

    def as_dict(self) -> dict[str, Any]:
        out = asdict(self)
        out["memory_flat"] = self.memory_flat
        out["passed"] = self.passed
        return out


def run_soak(
    config: SoakConfig,
    *,
    on_step: Callable[[int], None] | None = None,
) -> SoakReport:
    """Global localisation on the first scan, then ``config.steps - 1`` filter steps."""
    seeds = np.random.SeedSequence(config.seed).spawn(2)
    sim_rng, filter_rng = (np.random.default_rng(s) for s in seeds)
    grid = get_world(config.world)
    sim_cfg = SimulationConfig()
    stream = SimulatedStream(
        grid, loop_route(config.world, sim_cfg), config.steps, sim_rng, sim_cfg
    )
    f = registry.make_filter(
        config.algorithm, grid, filter_rng, sensor=config.sensor, n_particles=config.particles
    )
    lo, hi = sample_size_bounds(f)
    warmup = config.warmup

    n_min, n_max = 2**62, 0
    reinit = 0
    err_sum, err_max, within, counted, nonfinite = 0.0, 0.0, 0, 0, 0
    series_step: list[int] = []
    series_rss: list[int] = []
    series_n: list[int] = []
    rss_start = rss_warm = rss_peak = 0
    t_init = time.perf_counter()
    t_loop = t_init
    prev_odom: NDArray[np.float64] | None = None
    for k, (truth, odom, scan) in enumerate(stream):
        if prev_odom is None:
            diag = measure(f, k, partial(f.initialise_global, scan))
            rss_start = rss_kb()
            t_loop = time.perf_counter()
        else:
            diag = timed_step(f, k, increment_between(prev_odom, odom), scan)
        prev_odom = odom
        n = diag.n_particles
        n_min, n_max = min(n_min, n), max(n_max, n)
        reinit += int(diag.reinitialised)
        pose = f.estimate().pose
        if not np.all(np.isfinite(pose)):
            nonfinite += 1
        elif k >= warmup:
            err = float(np.hypot(pose[0] - truth[0], pose[1] - truth[1]))
            err_sum += err
            err_max = max(err_max, err)
            within += int(err < 0.5)
            counted += 1
        if k == warmup:
            gc.collect()
            rss_warm = rss_kb()
            rss_peak = rss_warm
        if k % config.sample_every == 0 or k == config.steps - 1:
            now = rss_kb()
            if k >= warmup:
                rss_peak = max(rss_peak, now)
            series_step.append(k)
            series_rss.append(now)
            series_n.append(n)
        if on_step is not None:
            on_step(k)
    gc.collect()
    rss_end = rss_kb()
    rss_peak = max(rss_peak, rss_end)
    end = time.perf_counter()
    loop_s = end - t_loop
    return SoakReport(
        config={
            **asdict(config),
            # the model the filter weighs with (the Nav2 peer: its own, whatever it was given)
            "sensor": registry.sensor_of(config.algorithm, config.sensor),
            "warmup_steps": warmup,
        },
        steps=config.steps,
        warmup_steps=warmup,
        wall_s=end - t_init,
        init_s=t_loop - t_init,
        steps_per_s=(config.steps - 1) / loop_s if loop_s > 0 else float("nan"),
        rss_start_kb=rss_start,
        rss_warm_kb=rss_warm,
        rss_end_kb=rss_end,
        rss_peak_after_warmup_kb=rss_peak,
        growth_pct=100.0 * (rss_end - rss_warm) / rss_warm if rss_warm else float("nan"),
        samples_min=n_min,
        samples_max=n_max,
        samples_bound_low=lo,
        samples_bound_high=hi,
        samples_within_bounds=lo <= n_min and n_max <= hi,
        reinitialisations=reinit,
        position_error_mean_m=err_sum / counted if counted else float("nan"),
        position_error_max_m=err_max if counted else float("nan"),
        share_within_0_5_m=within / counted if counted else float("nan"),
        nonfinite_estimates=nonfinite,
        series_step=series_step,
        series_rss_kb=series_rss,
        series_samples=series_n,
        environment={
            "python": platform.python_version(),
            "numpy": np.__version__,
            "machine": platform.machine(),
            "cpus": str(os.cpu_count()),
        },
    )


def write_soak_outputs(report: SoakReport, out_dir: str | os.PathLike[str]) -> list[Path]:
    """Write ``soak.json`` and ``soak.png`` (RSS and sample size over the run) to ``out_dir``
    (created if needed; files are replaced atomically)."""
    out = ensure_output_dir(out_dir)
    paths = [write_json(out / "soak.json", report.as_dict())]
    paths.append(plot_soak(report, out / "soak.png"))
    return paths


def plot_soak(report: SoakReport, path: str | os.PathLike[str]) -> Path:
    # matplotlib (~0.7 s) only when the figure is drawn: `ceamcl soak --help` imports this module
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    out = Path(path)
    fig, (ax1, ax2) = plt.subplots(2, 1, figsize=(8, 6), sharex=True)
    steps = np.asarray(report.series_step)
    ax1.plot(steps, np.asarray(report.series_rss_kb) / 1024.0, lw=1)
    ax1.axvline(report.warmup_steps, color="grey", ls="--", lw=0.8, label="end of warm-up")
    ax1.axhline(report.rss_warm_kb / 1024.0, color="tab:green", lw=0.8, label="reference")
    ax1.set_ylabel("RSS [MiB]")
    ax1.set_title(
        f"soak: {report.config['algorithm']} on {report.config['world']}, "
        f"{report.steps} steps, RSS growth {report.growth_pct:+.2f}%"
    )
    ax1.legend(loc="lower right", fontsize=8)
    ax2.plot(steps, report.series_samples, lw=1, color="tab:orange")
    ax2.axhline(report.samples_bound_high, color="tab:red", lw=0.8, ls=":", label="bound")
    if report.samples_bound_low > 1:
        ax2.axhline(report.samples_bound_low, color="tab:red", lw=0.8, ls=":")
    ax2.set_ylabel("sample size")
    ax2.set_xlabel("step")
    ax2.set_yscale("log")
    ax2.legend(loc="upper right", fontsize=8)
    try:
        fig.tight_layout()
        with atomic_write(out, keep_suffix=True) as tmp:  # removed if interrupted
            fig.savefig(tmp, dpi=110)
    finally:
        plt.close(fig)
    return out
