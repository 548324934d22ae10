"""Sensor kernels give the same numbers bit for bit in any process: compiled fresh or loaded
from numba's cache, with one numba thread or several, serial or parallel variant. Experiments
rely on it (a seed gives the same run whichever executor runs it); ``fastmath`` broke it once
(FMA contraction differed between compilations)."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np

from ceamcl.maps.worlds import get_world
from ceamcl.sensors.beam_model import BeamModel
from ceamcl.sensors.likelihood_field import PARALLEL_MIN_POSES, LikelihoodFieldModel
from ceamcl.sensors.scan import LaserGeometry

SCRIPT = """
import json, sys
import numpy as np
from ceamcl.maps.worlds import get_world
from ceamcl.sensors.beam_model import BeamModel
from ceamcl.sensors.likelihood_field import LikelihoodFieldModel
from ceamcl.sensors.scan import LaserGeometry
n = int(sys.argv[1])
grid = get_world("symmetric-hall")
rng = np.random.default_rng(11)
poses = grid.sample_free_poses(n, rng)
scan = LaserGeometry.covering(np.pi, 181, 8.0).scan(rng.uniform(0.2, 9.0, 181))
out = {}
for name, model in (("lf", LikelihoodFieldModel(grid)), ("beam", BeamModel(grid))):
    out[name] = model.log_likelihood(poses, model.prepare(scan)).tolist()
print(json.dumps(out))
"""


def here(n: int) -> dict[str, list[float]]:
    grid = get_world("symmetric-hall")
    rng = np.random.default_rng(11)
    poses = grid.sample_free_poses(n, rng)
    scan = LaserGeometry.covering(np.pi, 181, 8.0).scan(rng.uniform(0.2, 9.0, 181))
    out = {}
    for name, model in (("lf", LikelihoodFieldModel(grid)), ("beam", BeamModel(grid))):
        out[name] = model.log_likelihood(poses, model.prepare(scan)).tolist()
    return out


def test_fresh_single_threaded_compilation_gives_the_same_numbers(tmp_path: Path) -> None:
    for n in (50, PARALLEL_MIN_POSES + 10):  # the serial and the parallel variant
        env = {**os.environ, "NUMBA_CACHE_DIR": str(tmp_path / f"cache{n}")}
        env["NUMBA_NUM_THREADS"] = "1"
        proc = subprocess.run(
            [sys.executable, "-c", SCRIPT, str(n)],
            capture_output=True,
            text=True,
            env=env,
            timeout=600,
            check=True,
        )
        other = json.loads(proc.stdout)
        mine = here(n)
        for name in ("lf", "beam"):
            assert np.array_equal(np.array(other[name]), np.array(mine[name])), (name, n)


def test_serial_and_parallel_variants_have_their_own_cache_files(tmp_path: Path) -> None:
    # Numba keys its cache by function name and bytecode, not by compile options: two njit
    # wrappers of one function used to share entries, so the "parallel" kernel could load
    # serial code (or the reverse) depending on which compiled first.
    env = {**os.environ, "NUMBA_CACHE_DIR": str(tmp_path)}
    subprocess.run(
        [sys.executable, "-c", SCRIPT, str(PARALLEL_MIN_POSES + 10)],
        capture_output=True,
        env=env,
        timeout=600,
        check=True,
    )
    subprocess.run(
        [sys.executable, "-c", SCRIPT, "10"], capture_output=True, env=env, timeout=600, check=True
    )
    names = {p.name for p in tmp_path.rglob("*.nbi")}
    for kernel in ("_lf_kernel_py", "_beam_table_kernel_py"):
        assert any(f"{kernel}_serial-" in n for n in names), (kernel, names)
        assert any(f"{kernel}_parallel-" in n for n in names), (kernel, names)
