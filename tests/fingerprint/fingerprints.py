"""Fingerprints of fixed-seed runs: the bits every algorithm produces, per sensor model.

A fingerprint is a set of SHA-256 digests of what a run returns (estimates, hypotheses, the
final particles and each step's record) for one algorithm, one sensor model and one scenario:
the paper's symmetric hall (simulated) and the start of a real log (``fhw-corrected`` from
``../shared/data``, with its seeded synthetic odometry and its own map). ``test_fingerprints``
compares them with ``fingerprints.json``; a change that means to alter behaviour regenerates
the file on purpose, and says so in its commit::

    .venv/bin/python -m tests.fingerprint.fingerprints --update

Bits depend on the machine as well as on the code: NumPy picks SIMD kernels for the CPU it
finds (AVX-512 or AVX2 on x86-64), Numba compiles for the host CPU and OpenBLAS picks its
kernels at run time, and each rounds differently in the last place, which a particle filter
then amplifies. Fingerprints are therefore computed in a child process pinned to portable
code paths (:data:`PORTABLE_ENV`: NumPy's x86-64 baseline, Numba's generic CPU, OpenBLAS's
Nehalem kernels), so that any x86-64 machine gives the same bits, and ``fingerprints.json``
records the library versions they were made with (:func:`environment`): with other versions
the test skips and says which differ, as a new NumPy may round differently.
"""

from __future__ import annotations

import argparse
import hashlib
import json
import math
import os
import platform
import subprocess
import sys
from collections.abc import Iterable
from importlib import metadata
from pathlib import Path
from typing import Any

import numpy as np

from ceamcl.filters import make_filter, species_of
from ceamcl.runner import RunResult, run_filter
from ceamcl.simulation import paper_scenario
from ceamcl.simulation.simulator import SimulatedLog

ALGORITHMS = ("ceamcl", "gmcl", "mcl", "kld-amcl", "kld-amcl-recovery")
SENSORS = ("likelihood-field", "beam")
SCENARIOS = ("paper", "fhw")
PAPER_STEPS = 30
LOG_SCANS = 12
FILTER_SEED = 11
JSON_PATH = Path(__file__).with_name("fingerprints.json")
SHARED_LOG = Path(__file__).resolve().parents[2] / ".." / "shared" / "data" / "carmen"
FHW = SHARED_LOG / "fhw-corrected.log.gz"
PROJECT = Path(__file__).resolve().parents[2]
#: Portable numeric code paths (module docstring); x86-64 only.
PORTABLE_ENV = {
    "NPY_DISABLE_CPU_FEATURES": "X86_V3 X86_V4 AVX512_ICL AVX512_SPR",
    "NUMBA_CPU_NAME": "generic",
    "OPENBLAS_CORETYPE": "Nehalem",
}
PORTABLE_MACHINES = ("x86_64", "AMD64")
LIBRARIES = ("numpy", "scipy", "numba", "llvmlite")
#: A bound on the child process that computes the fingerprints (about a minute here).
CHILD_TIMEOUT_S = 900


def environment() -> dict[str, str]:
    """What the bits depend on besides the code: the machine's architecture, Python's minor
    version and the numeric libraries' versions."""
    env = {
        "machine": platform.machine(),
        "python": f"{sys.version_info.major}.{sys.version_info.minor}",
    }
    env.update({lib: metadata.version(lib) for lib in LIBRARIES})
    return env


def environment_differences(recorded: dict[str, str]) -> list[str]:
    """How this environment differs from ``recorded`` (``name: recorded -> here``)."""
    here = environment()
    return [
        f"{k}: {recorded.get(k)} -> {here.get(k)}"
        for k in sorted(set(recorded) | set(here))
        if recorded.get(k) != here.get(k)
    ]


def compute_portably(scenarios: Iterable[str] = SCENARIOS) -> dict[str, dict[str, str]]:
    """:func:`compute` in a child process with :data:`PORTABLE_ENV` (bounded in time)."""
    env = {**os.environ, **PORTABLE_ENV}
    done = subprocess.run(
        [sys.executable, "-m", "tests.fingerprint.fingerprints", "--json", *scenarios],
        cwd=PROJECT,
        env=env,
        capture_output=True,
        text=True,
        timeout=CHILD_TIMEOUT_S,
        check=False,
    )
    if done.returncode != 0:
        raise RuntimeError(f"fingerprint child process failed:\n{done.stderr[-4000:]}")
    got: dict[str, dict[str, str]] = json.loads(done.stdout)
    return got


def _digest(chunks: Iterable[bytes]) -> str:
    h = hashlib.sha256()
    for c in chunks:
        h.update(c)
    return h.hexdigest()[:16]


def _num(x: Any) -> str:
    v = float(x)
    return "nan" if math.isnan(v) else repr(v)


def step_record(d: Any) -> list[str]:
    """What a step's record says, as text: common fields, then every species' figures."""
    out = [
        str(int(d.step)),
        str(int(d.n_particles)),
        _num(d.ess),
        str(bool(d.resampled)),
        str(int(d.likelihood_evaluations)),
        str(bool(d.reinitialised)),
    ]
    for s in species_of(d):
        out.append(
            ",".join(
                [str(s.species_id), str(s.n)]
                + [
                    _num(getattr(s, k))
                    for k in (
                        "dn",
                        "fitness",
                        "area_m2",
                        "resources",
                        "capacity",
                        "x",
                        "y",
                        "theta",
                    )
                ]
            )
        )
    return out


def run_fingerprint(result: RunResult) -> dict[str, str]:
    fp = result.final_particles
    return {
        "estimates": _digest([result.estimates.tobytes()]),
        "hypotheses": _digest(h.tobytes() for h in result.hypotheses),
        "particles": _digest(
            [fp.poses.tobytes(), fp.weights.tobytes(), fp.labels.astype(np.int64).tobytes()]
        ),
        "steps": _digest("|".join(step_record(d)).encode() for d in result.diagnostics),
    }


def paper_log() -> tuple[Any, SimulatedLog]:
    scenario = paper_scenario(0)
    full = scenario.simulate(np.random.default_rng(2026))
    n = PAPER_STEPS
    log = SimulatedLog(
        full.times[:n],
        full.true_poses[:n],
        full.odometry[:n],
        full.ranges[:n],
        full.laser,
        full.world,
    )
    return scenario.grid(), log


def fhw_log() -> tuple[Any, Any]:
    from ceamcl.io.carmen import read_carmen
    from ceamcl.io.logs import DEFAULT_SYNTHETIC_NOISE
    from ceamcl.mapping import MappingConfig, map_from_log

    log = read_carmen(FHW)
    log = log.with_synthetic_odometry(DEFAULT_SYNTHETIC_NOISE, np.random.default_rng(5))
    grid, _ = map_from_log(log, MappingConfig(resolution_m=0.05))
    return grid, log.window(0, LOG_SCANS)


def fingerprint(algorithm: str, sensor: str, grid: Any, log: Any) -> dict[str, str]:
    f = make_filter(algorithm, grid, np.random.default_rng(FILTER_SEED), sensor=sensor)
    return run_fingerprint(run_filter(f, log))


def compute(scenarios: Iterable[str] = SCENARIOS) -> dict[str, dict[str, str]]:
    out: dict[str, dict[str, str]] = {}
    for scenario in scenarios:
        grid, log = paper_log() if scenario == "paper" else fhw_log()
        for sensor in SENSORS:
            for algorithm in ALGORITHMS:
                out[f"{scenario}/{sensor}/{algorithm}"] = fingerprint(algorithm, sensor, grid, log)
    return out


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--update", action="store_true", help="rewrite fingerprints.json")
    parser.add_argument(
        "--json",
        nargs="*",
        metavar="SCENARIO",
        help="print the fingerprints of these scenarios (default all) as JSON, as computed in "
        "this process (the test runs it with PORTABLE_ENV)",
    )
    args = parser.parse_args()
    if args.json is not None:
        print(json.dumps(compute(args.json or SCENARIOS), sort_keys=True))
        return
    if platform.machine() not in PORTABLE_MACHINES:
        raise SystemExit(f"fingerprints are recorded on x86-64, not {platform.machine()}")
    got = compute_portably()
    if args.update:
        record = {"environment": environment(), "fingerprints": got}
        JSON_PATH.write_text(json.dumps(record, indent=1, sort_keys=True) + "\n")
        print(f"wrote {len(got)} fingerprints to {JSON_PATH}")
        return
    recorded = json.loads(JSON_PATH.read_text())
    want = recorded["fingerprints"]
    bad = [k for k in got if got[k] != want.get(k)]
    print(f"{len(got) - len(bad)} of {len(got)} fingerprints match; differ: {bad}")
    if diff := environment_differences(recorded["environment"]):
        print(f"recorded with other libraries: {'; '.join(diff)}")


if __name__ == "__main__":
    main()
