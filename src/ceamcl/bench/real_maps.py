"""``ceamcl bench --real-maps``: speed on real buildings (issue 17, item 6).

Two measurements, both on the real logs of ``../shared/data`` (``--data`` elsewhere):

**Initialisation against map area.** The maps built from the SLAM-corrected logs (intel
525 m^2 of free space, freiburg-079 938 m^2, fhw 1,015 m^2) and two composites of them laid side
by side in one grid (freiburg-079 + fhw, about 1,950 m^2; the same pair beside its mirror image,
about 3,900 m^2: a mirrored building is another building to a laser, so the composite has no
exact look-alikes the real maps lack). On each map, with a fresh grid (no distance field yet):
the time of the first global initialisation (building the map's distance field and likelihood
table included: what a robot pays when it is given a new map and asked to localise), then the
median of warm repeats, for CEAMCL with its defaults (150 test poses per m^2 of free space
with headings from the scan, and the second round around the best of them: section 3.1,
docs/ceamcl.md departures 24 and 27) and ``mcl-tuned`` (10^6 test poses, headings from the
scan, resampled to 5,000). Nav2 AMCL's Python wheel has no uniform global
initialisation: not comparable there. Area is the free area (what the filters sample); the
bounding box is given beside it.

**Steps at a real scan rate.** The raw logs (``carmen-raw``: the robot's own odometry, every
scan, 4.6-5.1 scans a second) over a window of ``scans`` scans from the first scan with truth,
at Nav2's pace (update once moved 0.25 m or turned 0.2 rad; the other scans only carry the
odometry) and at every scan (what a robot pays when it updates at each of its scans):

- global localisation from the window's first scan: CEAMCL, ``mcl-tuned``, ``kld-amcl-tuned``
  (the tuned presets) and ``kld-amcl-recovery`` (Nav2's defaults with recovery);
- tracking from the true pose perturbed by 0.5 m / 0.3 rad (as ``evaluate-log --tracking``):
  CEAMCL with its own sample size, then ``nav2-amcl`` and ``mcl-tuned`` with CEAMCL's mean
  sample size of that run (min = max for Nav2), so the time compares like with like.

Per run: the median and p95 time of an update, the mean time per scan (0 for a scan that only
carries the odometry), the load (time spent / time the log lasted: the share of one core the
filter needs at the log's scan rate) and the scan rate that load would allow, the mean sample
size, and whether it localised (global: converged and held 5 m travelled; tracking: APE RMSE),
so no speed is read from a filter that lost the robot.

Every figure is wall-clock time on this machine, in one process, after the kernels' first
calls (compiled or loaded from numba's cache on the small-office world first).
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import matplotlib.pyplot as plt
import numpy as np
from numpy.typing import NDArray

from ceamcl import peers
from ceamcl.bench.report import _f as report_cell
from ceamcl.bench.report import target_verdict
from ceamcl.bench.suite import machine_info
from ceamcl.errors import ConfigError
from ceamcl.experiments.common import markdown_table, write_text
from ceamcl.experiments.figures import _save
from ceamcl.experiments.metrics import score_errors
from ceamcl.experiments.tracking_log import perturbed_start, start_covariance
from ceamcl.filters import registry
from ceamcl.filters.base import LocalisationFilter
from ceamcl.io.recorded import RecordedLog
from ceamcl.io.results import write_json
from ceamcl.io.truth_check import doubtful_truth
from ceamcl.maps.grid import UNKNOWN, OccupancyGrid
from ceamcl.motion.odometry import increment_between
from ceamcl.replay import UpdatePace, filter_rng, make_paced_filter, obtain_map, prepare_log
from ceamcl.runner import RunResult, run_filter
from ceamcl.simulation import paper_scenario

#: Where the real logs are by default: ``../shared/data`` beside the project's folder.
DEFAULT_DATA = Path(__file__).resolve().parents[3].parent / "shared" / "data"
CORRECTED = {
    "intel": "carmen/intel-corrected.log.gz",
    "freiburg-079": "carmen/freiburg-079-corrected.log.gz",
    "fhw": "carmen/fhw-corrected.log.gz",
}
RAW = {"intel": "carmen-raw/intel.clf.gz", "fr079": "carmen-raw/fr079.clf.gz"}
RAW_TRUTH = {"intel": "intel", "fr079": "freiburg-079"}
#: Cells of unknown space between the parts of a composite map (1 m).
GAP_CELLS = 20
GLOBAL_ALGORITHMS = ("ceamcl", "mcl-tuned", "kld-amcl-tuned", "kld-amcl-recovery")
INIT_ALGORITHMS = ("ceamcl", "mcl-tuned")
#: Issue 17's targets: (key, text, threshold).
TARGETS: tuple[tuple[str, str, float], ...] = (
    ("init_1000", "CEAMCL initialisation, map of ~1,000 m^2 (s, first call)", 1.0),
    ("init_4000", "CEAMCL initialisation, map of ~4,000 m^2 (s, first call)", 3.0),
    ("step_ms", "CEAMCL median update, raw logs at Nav2's pace, global (ms)", 5.0),
    ("step_vs_mcl", "CEAMCL median update / mcl-tuned's, same runs (ratio)", 1.0),
    (
        "step_state_vs_mcl",
        "the same, each update with its state read after it (ratio)",
        1.0,
    ),
)

Progress = Callable[[str], None]


@dataclass(frozen=True)
class RealMapsSettings:
    """What to measure; :meth:`quick_run` is a smoke run (one map, a short window)."""

    data: Path = DEFAULT_DATA
    scans: int = 2500
    init_repeats: int = 3
    rounds: int = 3
    seed: int = 0
    composites: bool = True
    raw_logs: tuple[str, ...] = ("intel", "fr079")
    map_logs: tuple[str, ...] = ("intel", "freiburg-079", "fhw")
    quick: bool = False

    @classmethod
    def quick_run(cls, data: Path = DEFAULT_DATA) -> RealMapsSettings:
        return cls(
            data=data,
            scans=120,
            init_repeats=1,
            rounds=1,
            composites=False,
            raw_logs=("intel",),
            map_logs=("fhw",),
            quick=True,
        )

    def missing(self) -> list[Path]:
        """The files of ``data`` these settings read that are absent."""
        wanted = [self.data / CORRECTED[m] for m in self.map_logs]
        for r in self.raw_logs:
            wanted += [self.data / RAW[r], self.data / CORRECTED[RAW_TRUTH[r]]]
        return [p for p in dict.fromkeys(wanted) if not p.is_file()]

    def check(self) -> None:
        """Raise :class:`~ceamcl.errors.ConfigError` naming every absent file."""
        missing = self.missing()
        if missing:
            raise ConfigError(
                "bench --real-maps: the real logs are absent: "
                + ", ".join(str(p) for p in missing)
                + "; pass --data DIR, the folder holding carmen/ and carmen-raw/"
            )

    def n_items(self) -> int:
        maps = len(self.map_logs) + (2 if self.composites else 0)
        return 1 + maps + len(self.raw_logs) * 3


def side_by_side(parts: Sequence[OccupancyGrid], columns: int, name: str) -> OccupancyGrid:
    """One grid holding ``parts`` in rows of ``columns``, each in a block of the largest part's
    size, :data:`GAP_CELLS` of unknown space between blocks (every part at one resolution)."""
    res = parts[0].resolution
    if any(abs(p.resolution - res) > 1e-12 for p in parts):
        raise ValueError("side_by_side: every part needs the same resolution")
    bh = max(p.height for p in parts) + GAP_CELLS
    bw = max(p.width for p in parts) + GAP_CELLS
    rows = math.ceil(len(parts) / columns)
    data = np.full((rows * bh, columns * bw), UNKNOWN, dtype=np.int8)
    for i, p in enumerate(parts):
        r, c = divmod(i, columns)
        data[r * bh : r * bh + p.height, c * bw : c * bw + p.width] = p.data
    return OccupancyGrid(data, res, (0.0, 0.0, 0.0), name=name)


def mirrored(grid: OccupancyGrid) -> OccupancyGrid:
    """The map mirrored left to right (another building to a laser)."""
    return grid.with_data(np.ascontiguousarray(grid.data[:, ::-1]), name=f"{grid.name}-mirrored")


def _warm_up() -> None:
    """First calls of every kernel the runs use (compile or load numba's cache), on the paper
    scenario's hall: a global initialisation and a few steps of each algorithm."""
    scenario = paper_scenario(0)
    grid = scenario.grid()
    log = scenario.simulate(np.random.default_rng(0))
    for algo in GLOBAL_ALGORITHMS:
        f = registry.make_filter(algo, grid, np.random.default_rng(0))
        f.initialise_global(log.scan(0))
        for k in range(1, 4):
            f.step(increment_between(log.odometry[k - 1], log.odometry[k]), log.scan(k))


def _init_row(name: str, grid: OccupancyGrid, scan: Any, s: RealMapsSettings) -> dict[str, Any]:
    row: dict[str, Any] = {
        "map": name,
        "free_area_m2": grid.free_area_m2,
        "bounding_area_m2": grid.width * grid.height * grid.resolution**2,
        "cells": [grid.width, grid.height],
    }
    for algo in INIT_ALGORITHMS:
        g = grid.with_data(grid.data)  # a new grid: no cached distance field yet
        times = []
        for r in range(1 + s.init_repeats):
            f = registry.make_filter(algo, g, np.random.default_rng(s.seed + r))
            t0 = time.perf_counter()
            f.initialise_global(scan)
            times.append(time.perf_counter() - t0)
        row[algo] = {
            "first_s": times[0],
            "warm_s": float(np.median(times[1:])) if len(times) > 1 else None,
            "particles": int(f.particle_weights().size),
        }
    return row


def _map_set(s: RealMapsSettings) -> list[tuple[str, OccupancyGrid, Any]]:
    maps: dict[str, tuple[OccupancyGrid, Any]] = {}
    for m in s.map_logs:
        prepared = prepare_log(s.data / CORRECTED[m], seed=s.seed)
        grid, _ = obtain_map(prepared.map_log, None)
        maps[m] = (grid, prepared.log.scan(0))
    out = [(m, g, scan) for m, (g, scan) in maps.items()]
    if s.composites and {"freiburg-079", "fhw"} <= maps.keys():
        fr, fhw = maps["freiburg-079"][0], maps["fhw"][0]
        scan = maps["fhw"][1]
        out.append(("freiburg-079 + fhw", side_by_side([fr, fhw], 2, "composite-2"), scan))
        four = side_by_side([fr, fhw, mirrored(fr), mirrored(fhw)], 2, "composite-4")
        out.append(("freiburg-079 + fhw + both mirrored", four, scan))
    return out


def _run_row(
    log_name: str,
    mode: str,
    pace: UpdatePace | None,
    results: Sequence[RunResult],
    log: RecordedLog,
    algorithm: str,
    budget: int | None,
    doubtful: NDArray[np.bool_] | None = None,
) -> dict[str, Any]:
    """One row from the repeats of one run (identical but for their times, which are pooled:
    the repeats of every algorithm were interleaved, so a slow spell of a shared machine
    falls on all of them alike)."""
    result = results[0]
    upd = np.concatenate([r.update_ms for r in results])
    upd_state = np.concatenate([r.update_state_ms for r in results])
    step = np.concatenate([r.step_ms for r in results])
    duration = float(log.times[-1] - log.times[0])
    spent_s = float(step.sum()) / 1e3 / len(results)
    load = spent_s / duration if duration > 0 else math.nan
    per_scan_ms = float(step.mean())
    row: dict[str, Any] = {
        "log": log_name,
        "mode": mode,
        "pace": "every scan" if pace is None else pace.describe(),
        "algorithm": algorithm,
        "particle_budget": budget,
        "scans": result.steps,
        "updates": result.updates,
        "repeats": len(results),
        "log_s": duration,
        "scan_rate_hz": (result.steps - 1) / duration if duration > 0 else math.nan,
        "mean_particles": float(np.mean([d.n_particles for d in result.diagnostics[1:]])),
        "median_update_ms": float(np.median(upd)),
        "p95_update_ms": float(np.percentile(upd, 95)),
        "median_update_state_ms": float(np.median(upd_state)),
        "mean_ms_per_scan": per_scan_ms,
        "load": load,
        "max_scan_rate_hz": 1e3 / per_scan_ms if per_scan_ms > 0 else math.inf,
        "initialisation_ms": float(np.median([r.diagnostics[0].step_ms for r in results])),
    }
    known = result.truth_known
    pos, head = result.position_errors, result.heading_errors
    if pos is not None and head is not None and known.any():
        if mode == "global":
            score = score_errors(result.times, pos, head, hold_m=5.0, travelled=log.travelled_m)
            row["localised"] = bool(score.success)
        row["ape_rmse_m"] = float(np.sqrt(np.mean(pos[known] ** 2)))
        # beside it, never instead: the scans where the truth explains its own scans
        sound = known if doubtful is None else known & ~doubtful
        row["ape_rmse_outside_doubtful_m"] = (
            float(np.sqrt(np.mean(pos[sound] ** 2))) if sound.any() else math.nan
        )
    return row


def _make(
    algorithm: str,
    grid: OccupancyGrid,
    seed: int,
    particles: int | None,
) -> LocalisationFilter:
    rng = filter_rng(seed, 0, algorithm)
    if particles is None:
        return make_paced_filter(algorithm, grid, rng)
    if algorithm == "nav2-amcl":  # a fixed count: min = max, as in ``ceamcl bench``
        cfg = registry.with_config(algorithm, min_particles=particles, max_particles=particles)
        return make_paced_filter(algorithm, grid, rng, config=cfg)
    return make_paced_filter(algorithm, grid, rng, n_particles=particles)


def _rounds(
    algorithms: Sequence[str],
    grid: OccupancyGrid,
    log: RecordedLog,
    s: RealMapsSettings,
    pace: UpdatePace | None,
    particles: int | None,
    start: tuple[np.ndarray, np.ndarray] | None,
    done: dict[str, RunResult] | None = None,
) -> dict[str, list[RunResult]]:
    """``s.rounds`` rounds of every algorithm over ``log`` (global localisation, or tracking
    from ``start``), each round in another order; CEAMCL sizes itself, the others get
    ``particles`` (None: their own). ``done``: first-round runs made already (the first
    algorithm of round 0 runs first anyway)."""
    policy = None if pace is None else pace.policy()
    out: dict[str, list[RunResult]] = {a: [] for a in algorithms}
    for r in range(s.rounds):
        k = r % len(algorithms)
        for algo in [*algorithms[k:], *algorithms[:k]]:
            if r == 0 and done is not None and algo in done:
                out[algo].append(done[algo])
                continue
            f = _make(algo, grid, s.seed, None if algo == "ceamcl" else particles)
            out[algo].append(run_filter(f, log, update_when=policy, initial_pose=start))
    return out


def measure_raw_log(name: str, s: RealMapsSettings, tick: Progress) -> list[dict[str, Any]]:
    """Global localisation and tracking over a window of raw log ``name`` (module docstring)."""
    prepared = prepare_log(
        s.data / RAW[name], seed=s.seed, truth_from=s.data / CORRECTED[RAW_TRUTH[name]]
    )
    grid, _ = obtain_map(prepared.map_log, None, own=False)
    full = prepared.log
    first = int(np.flatnonzero(full.has_truth_at)[0])
    log = full.window(first, min(len(full), first + s.scans))
    assert log.true_poses is not None
    doubtful = doubtful_truth(log, grid).mask(len(log))
    rows: list[dict[str, Any]] = []
    nav2 = peers.available()
    start = (perturbed_start(log.true_poses[0], s.seed), start_covariance())
    for pace in (UpdatePace(), None):
        what = "Nav2's pace" if pace is not None else "every scan"
        policy = None if pace is None else pace.policy()
        if pace is not None:
            tick(f"{name}: global localisation ({what}, {s.rounds} rounds)")
            global_runs = _rounds(list(GLOBAL_ALGORITHMS), grid, log, s, pace, None, None)
            for algo, res in global_runs.items():
                rows.append(_run_row(name, "global", pace, res, log, algo, None, doubtful))
        tick(f"{name}: tracking ({what}, {s.rounds} rounds)")
        # the peers get CEAMCL's mean sample size of this run (it is the same in every round)
        first_run = run_filter(
            _make("ceamcl", grid, s.seed, None), log, update_when=policy, initial_pose=start
        )
        n = max(1, round(float(np.mean([d.n_particles for d in first_run.diagnostics[1:]]))))
        algos = ["ceamcl", "mcl-tuned"] + (["nav2-amcl"] if nav2 else [])
        sized = {"ceamcl": first_run}  # it is round 0's CEAMCL run
        for algo, res in _rounds(algos, grid, log, s, pace, n, start, sized).items():
            budget = None if algo == "ceamcl" else n
            rows.append(_run_row(name, "tracking", pace, res, log, algo, budget, doubtful))
    return rows


def evaluate_targets(result: dict[str, Any]) -> list[dict[str, Any]]:
    """Issue 17's speed targets with the measured value (None: not measured in this run)."""
    vals: dict[str, float | None] = {k: None for k, *_ in TARGETS}
    maps = result.get("maps", [])

    def near(area: float) -> dict[str, Any] | None:
        close = [m for m in maps if abs(m["free_area_m2"] - area) <= 0.25 * area]
        return min(close, key=lambda m: abs(m["free_area_m2"] - area)) if close else None

    for key, area in (("init_1000", 1000.0), ("init_4000", 4000.0)):
        m = near(area)
        if m is not None:
            vals[key] = float(m["ceamcl"]["first_s"])
    glob = [
        r for r in result.get("steps", []) if r["mode"] == "global" and r["pace"] != "every scan"
    ]
    ours = {r["log"]: r["median_update_ms"] for r in glob if r["algorithm"] == "ceamcl"}
    if ours:
        vals["step_ms"] = float(max(ours.values()))
    for target, column in (
        ("step_vs_mcl", "median_update_ms"),
        ("step_state_vs_mcl", "median_update_state_ms"),
    ):
        by = {(r["algorithm"], r["log"]): r[column] for r in glob}
        ratios = [
            by["ceamcl", log] / by["mcl-tuned", log]
            for algo, log in by
            if algo == "ceamcl" and ("mcl-tuned", log) in by
        ]
        if ratios:
            vals[target] = float(max(ratios))
    quick = bool(result.get("settings", {}).get("quick", False))
    return [
        {
            "key": key,
            "target": text,
            "threshold": thr,
            "value": v,
            # a quick run's figures are a smoke test, not a target
            "pass": None if v is None or quick else bool(v <= thr),
        }
        for key, text, thr in TARGETS
        for v in (vals[key],)
    ]


def run_real_maps(settings: RealMapsSettings, progress: Progress | None = None) -> dict[str, Any]:
    """Both measurements (module docstring); ``progress(label)`` before each item."""
    tick: Progress = progress or (lambda _label: None)
    settings.check()
    tick("first calls of the kernels (the paper's hall)")
    _warm_up()
    maps = []
    for name, grid, scan in _map_set(settings):
        tick(f"initialisation: {name} ({grid.free_area_m2:,.0f} m^2 free)")
        maps.append(_init_row(name, grid, scan, settings))
    steps: list[dict[str, Any]] = []
    for name in settings.raw_logs:
        steps += measure_raw_log(name, settings, tick)
    result: dict[str, Any] = {
        "settings": {
            "quick": settings.quick,
            "data": str(settings.data),
            "scans": settings.scans,
            "init_repeats": settings.init_repeats,
            "rounds": settings.rounds,
            "seed": settings.seed,
        },
        "machine": machine_info(),
        "peer": "nav2-amcl" if peers.available() else "absent (pip install 'ceamcl[peers]')",
        "maps": maps,
        "steps": steps,
    }
    result["targets"] = evaluate_targets(result)
    return result


# ------------------------------------------------------------------------------------ report
def _f(v: Any, digits: int = 2) -> str:
    return report_cell(v, digits)


def render_markdown(r: dict[str, Any]) -> str:
    """``real_maps.md``: the targets, initialisation against area, steps at a real scan rate."""
    m = r["machine"]
    s = r["settings"]
    lines = ["# ceamcl bench --real-maps", ""]
    if s["quick"]:
        lines += ["**Quick run (`--quick`)**: one map, a short window; no figure is a target.", ""]
    lines += [
        f"Machine: {m['cpu']}, {m['cores']} cores (numba threads {m['numba_threads']}); Python "
        f"{m['python']}; load average at the start {m.get('load_average')}. Data: `{s['data']}`; "
        f"seed {s['seed']}; Nav2 AMCL peer: {r['peer']}. What is measured and how: "
        '`ceamcl.bench.real_maps` (docs/performance.md, "Real maps").',
        "",
        "## Targets (issue 17)",
        "",
    ]
    rows = []
    for t in r["targets"]:
        rows.append([t["target"], f"<= {t['threshold']:g}", _f(t["value"]), target_verdict(t)])
    lines.append(markdown_table(["target", "goal", "measured", ""], rows))
    lines += [
        "## Global initialisation against map area",
        "",
        "First call on a fresh grid (its distance field and likelihood table built inside), then "
        f"the median of {s['init_repeats']} warm repeats. CEAMCL with its defaults: 150 test "
        "poses per m^2 of free space (headings from the scan) and a second round around the "
        "best 1 %, into species (section 3.1); `mcl-tuned`: 10^6 test poses (headings from "
        "the scan) weighed by the first scan, resampled to 5,000. `nav2-amcl`: not comparable "
        "(its Python wheel has no uniform global initialisation).",
        "",
    ]
    rows = [
        [
            mp["map"],
            _f(mp["free_area_m2"], 0),
            _f(mp["bounding_area_m2"], 0),
            f"{mp['cells'][0]} x {mp['cells'][1]}",
            _f(mp["ceamcl"]["first_s"]),
            _f(mp["ceamcl"]["warm_s"]),
            _f(mp["ceamcl"]["particles"]),
            _f(mp["mcl-tuned"]["first_s"]),
            _f(mp["mcl-tuned"]["warm_s"]),
        ]
        for mp in r["maps"]
    ]
    lines.append(
        markdown_table(
            [
                "map",
                "free m^2",
                "bounding m^2",
                "cells",
                "CEAMCL first s",
                "CEAMCL warm s",
                "CEAMCL initial particles",
                "mcl-tuned first s",
                "mcl-tuned warm s",
            ],
            rows,
        )
    )
    lines += [
        "## Steps at a real scan rate (raw logs, the robot's own odometry)",
        "",
        f"A window of {s['scans']:,} scans from the first scan with truth. *update*: a scan at "
        "which the filter was stepped; *+ state*: the update and the reading of the filter's "
        "localisation state after it (CEAMCL reads its species' state and the map's "
        "agreement inside its step, a particle filter clusters its particles for it "
        "afterwards: the runner and the ROS node read it after every update); *per scan*: "
        "all scans, 0 for those that only carry the "
        "odometry; *load*: time spent / time the log lasted (share of one core at the log's "
        "scan rate); *max rate*: the scan rate that per-scan cost would allow. Tracking peers "
        "run with CEAMCL's mean sample size of the same run (Nav2: min = max). *localised*: "
        "converged and held 5 m travelled (global); APE RMSE over the matched scans, and beside it "
        "over those outside the stretches where the truth is doubtful (`ceamcl.io.truth_check`).",
        "",
    ]
    rows = [
        [
            st["log"],
            st["mode"],
            "every scan" if st["pace"] == "every scan" else "Nav2 (0.25 m / 0.2 rad)",
            st["algorithm"],
            _f(st["mean_particles"], 0),
            f"{st['updates']:,} / {st['scans']:,}",
            _f(st["scan_rate_hz"], 1),
            _f(st["median_update_ms"]),
            _f(st["p95_update_ms"]),
            _f(st["median_update_state_ms"]),
            _f(st["mean_ms_per_scan"]),
            f"{100 * st['load']:.2f} %",
            _f(st["max_scan_rate_hz"], 0),
            _f(st.get("localised")),
            _f(st.get("ape_rmse_m")),
            _f(st.get("ape_rmse_outside_doubtful_m")),
        ]
        for st in r["steps"]
    ]
    lines.append(
        markdown_table(
            [
                "log",
                "mode",
                "pace",
                "algorithm",
                "particles",
                "updates / scans",
                "scans/s",
                "update median ms",
                "update p95 ms",
                "update + state median ms",
                "per scan ms",
                "load",
                "max rate Hz",
                "localised",
                "APE RMSE m",
                "APE RMSE outside doubtful truth m",
            ],
            rows,
        )
    )
    return "\n".join(lines)


def plot_real_maps(r: dict[str, Any], path: Path) -> Path:
    """``real_maps.png``: initialisation time against free area; update time per run."""
    steps = r["steps"]
    fig, axes = plt.subplots(1, 2, figsize=(13, max(4.2, 0.24 * len(steps) + 1.2)))
    ax = axes[0]
    maps = sorted(r["maps"], key=lambda mp: mp["free_area_m2"])
    area = [mp["free_area_m2"] for mp in maps]
    for algo in INIT_ALGORITHMS:
        ax.plot(area, [mp[algo]["first_s"] for mp in maps], "o-", label=f"{algo}, first call")
        warm = [mp[algo]["warm_s"] for mp in maps]
        if all(w is not None for w in warm):
            ax.plot(area, warm, "o--", alpha=0.6, label=f"{algo}, warm")
    ax.plot([1000, 4000], [1.0, 3.0], "k+", ms=12, mew=2, label="targets (issue 17)")
    ax.set_xlabel("free area of the map (m^2)")
    ax.set_ylabel("global initialisation (s)")
    ax.grid(alpha=0.3)
    ax.legend(fontsize=8)
    ax = axes[1]
    labels = [
        f"{st['log']} {st['mode']}, {'every scan' if st['pace'] == 'every scan' else 'paced'}: "
        f"{st['algorithm']} ({st['mean_particles']:.0f})"
        for st in steps
    ]
    y = np.arange(len(steps))
    med = np.array([st["median_update_ms"] for st in steps])
    p95 = np.array([st["p95_update_ms"] for st in steps])
    colours = {
        "ceamcl": "C0",
        "mcl-tuned": "C1",
        "kld-amcl-recovery": "C2",
        "nav2-amcl": "C3",
        "kld-amcl-tuned": "C4",
    }
    ax.barh(y, med, color=[colours.get(st["algorithm"], "C7") for st in steps])
    ax.errorbar(p95, y, fmt="k|", ms=8, label="p95")
    ax.set_yticks(y, labels, fontsize=7)
    ax.invert_yaxis()
    ax.set_xlabel("update time, median (bar) and p95 (ms)")
    ax.axvline(5.0, color="k", ls=":", lw=1, label="5 ms target")
    ax.grid(alpha=0.3, axis="x")
    ax.legend(fontsize=8)
    fig.suptitle("ceamcl bench --real-maps")
    return _save(fig, path)


def write_real_maps(r: dict[str, Any], out: Path) -> tuple[Path, Path, Path]:
    """``real_maps.json``, ``real_maps.md`` and ``real_maps.png`` in ``out``."""
    js = write_json(out / "real_maps.json", r)
    md = write_text(out / "real_maps.md", render_markdown(r) + "\n")
    png = plot_real_maps(r, out / "real_maps.png")
    return js, md, png
