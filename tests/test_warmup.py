"""``ceamcl.warmup``: every kernel a run calls is made ready before the run, for the argument
types the run calls it with, so no run compiles in the middle (a cold Numba cache made the first
updates of a real log stall for seconds)."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

from ceamcl.cli import main
from ceamcl.warmup import KERNELS, kernels, parse_signature, signature_text, warm_up

DATA = Path(__file__).resolve().parents[2] / "shared" / "data"
RAW = DATA / "carmen-raw" / "fr079.clf.gz"
CORRECTED = DATA / "carmen" / "freiburg-079-corrected.log.gz"

#: Runs a process of its own (whose kernels start unloaded) in two phases. First the kernels
#: without the beam model's (``warm_up(beam_model=False)``, what a run with the likelihood field
#: readies) and what such runs call: a simulated drive with a kidnap, every algorithm on it, a map
#: built from that drive, the ROS node's core and, where the shared data is mounted, CEAMCL on
#: the first 1,300 scans of fr079 raw at Nav2's pace (its map built from the corrected log; the
#: run recovers twice there). Then every kernel (``warm_up()``) and the beam model: its table
#: and exact ray casting in CEAMCL, amcl's scoring in KLD-AMCL. Prints, as JSON, the signatures
#: kernels met after each phase's warm-up ("new_lf", "new_beam"), and the listed kernels' calls
#: from Python with their argument types ("called").
SCRIPT = r"""
import gc, importlib, json, sys
import numpy as np
from numba import typeof
from numba.core.registry import CPUDispatcher
from ceamcl.warmup import KERNELS, signature_text, warm_up


def seen():
    return {
        f"{d.py_func.__module__}.{d.py_func.__qualname__}": {
            signature_text(s) for s in d.signatures
        }
        for d in gc.get_objects()
        if isinstance(d, CPUDispatcher) and d.py_func.__module__.startswith("ceamcl.")
    }


def met_since(before):
    new = {k: sorted(v - before.get(k, set())) for k, v in seen().items()}
    return {k: v for k, v in new.items() if v}


called = set()
originals = {}


def counted(key, dispatcher):
    def call(*args):
        called.add((key, signature_text(tuple(typeof(a) for a in args))))
        return dispatcher(*args)

    return call


def count_calls(on):
    # what Python calls the listed kernels with: through their modules
    for module_name, names, _ in KERNELS:
        module = importlib.import_module(module_name)
        for name in names:
            key = f"{module_name}.{name}"
            if on:
                originals[key] = getattr(module, name)
                setattr(module, name, counted(key, originals[key]))
            else:
                setattr(module, name, originals[key])


from ceamcl.filters import registry
from ceamcl.filters.policies import on_motion
from ceamcl.mapping import MappingConfig, build_map
from ceamcl.sensors.scan import laser_poses
from ceamcl.runner import run_filter
from ceamcl.simulation.scenarios import Kidnap, Scenario
from ceamcl.ros.localiser import Localiser
from ceamcl.ros.params import parse

drive = Scenario(
    "short kidnap",
    "small-office",
    np.array([1.5, 4.25, 0.0]),
    [np.array([3.8, 4.25]), np.array([3.8, 3.0])],
    kidnap=Kidnap(2.5, np.array([5.5, 6.5, 0.0]), [np.array([7.0, 6.5])]),
)
algorithms = [
    a for a in registry.names() if registry.unavailable_reason(a) is None and a != "nav2-amcl"
]

warm_up(beam_model=False)
before = seen()
count_calls(True)
grid = drive.grid()
log = drive.simulate(np.random.default_rng(0), grid)
for name in algorithms:
    run_filter(registry.make_filter(name, grid, np.random.default_rng(1)), log)
build_map(log, laser_poses(log.true_poses, log.laser.pose), MappingConfig(resolution_m=0.05))
node = Localiser(parse({"seed": 0}))
node.set_map(grid)
for k in range(40):
    node.scan(tuple(log.odometry[k]), log.scan(k))
if len(sys.argv) > 2:
    from ceamcl.replay import obtain_map, prepare_log

    prepared = prepare_log(sys.argv[1], truth_from=sys.argv[2])
    real_grid, _ = obtain_map(prepared.map_log, None, own=False)
    f = registry.make_filter("ceamcl", real_grid, np.random.default_rng(0))
    run_filter(f, prepared.log.window(0, 1300), update_when=on_motion(0.25, 0.2))
new_lf = met_since(before)

count_calls(False)
warm_up()
before = seen()
count_calls(True)
for name, settings in (("ceamcl", {}), ("ceamcl", {"ray_casting": "exact"}), ("kld-amcl", {})):
    f = registry.make_filter(
        name, grid, np.random.default_rng(1), sensor="beam", sensor_settings=settings
    )
    run_filter(f, log)
new_beam = met_since(before)
print(json.dumps({"new_lf": new_lf, "new_beam": new_beam, "called": sorted(called)}))
"""


def test_the_table_reads_back_as_written() -> None:
    """Each signature of :data:`KERNELS` parses to Numba types and prints back to itself (the
    notation the coverage test below reports missing signatures in)."""
    for _, _, signatures in KERNELS:
        for text in signatures:
            assert signature_text(parse_signature(text)) == text


def test_a_signature_that_is_not_a_tuple_of_types_is_refused() -> None:
    with pytest.raises(ValueError, match="tuple of Numba types"):
        parse_signature("float64[::1]")


def test_warm_up_readies_every_listed_kernel_and_a_second_call_finds_them_loaded() -> None:
    first = warm_up()
    assert first.signatures == len(kernels()) > 0
    for _, dispatcher, signature in kernels():
        assert signature in dispatcher.overloads
    again = warm_up()
    assert (again.compiled, again.from_cache) == (0, 0)
    assert again.describe().endswith(f"({again.signatures} loaded already)")


def test_a_run_after_warm_up_meets_no_kernel_signature_the_list_lacks() -> None:
    """The list is what the package really calls: nothing compiles (or loads) after the
    warm-up, in any algorithm, sensor model, the mapper, the node's core or a real log's
    recoveries; and runs with the likelihood field need none of the beam model's kernels."""
    args = [str(RAW), str(CORRECTED)] if RAW.is_file() and CORRECTED.is_file() else []
    done = subprocess.run(
        [sys.executable, "-c", SCRIPT, *args],
        capture_output=True,
        text=True,
        timeout=600,
        check=False,
    )
    assert done.returncode == 0, done.stderr[-3000:]
    seen = json.loads(done.stdout.strip().splitlines()[-1])
    assert seen["new_lf"] == {}, (
        "kernels a likelihood-field run called with signatures that warm_up(beam_model=False) "
        "did not ready (add them to ceamcl.warmup.KERNELS, or take them out of "
        "BEAM_MODEL_KERNELS): " + json.dumps(seen["new_lf"], indent=1)
    )
    assert seen["new_beam"] == {}, (
        "kernels called with signatures ceamcl.warmup.KERNELS lacks (add them there): "
        + json.dumps(seen["new_beam"], indent=1)
    )
    # and the list holds nothing the runs do not call (a serial and parallel pair counts
    # as called when either is: the problem's size chooses)
    called = {(key, text) for key, text in seen["called"]}
    unused = [
        f"{module}.{'/'.join(names)} {text}"
        for module, names, signatures in KERNELS
        for text in signatures
        if not any((f"{module}.{name}", text) in called for name in names)
    ]
    assert unused == [], f"listed in ceamcl.warmup.KERNELS, never called: {unused}"


def test_with_the_jit_disabled_there_is_nothing_to_ready_and_no_error() -> None:
    """``NUMBA_DISABLE_JIT=1`` (Numba's debugging switch) makes every kernel a Python function:
    the warm-up, which every run does first, says so instead of failing."""
    done = subprocess.run(
        [sys.executable, "-m", "ceamcl", "warm-up"],
        capture_output=True,
        text=True,
        timeout=120,
        check=False,
        env={**os.environ, "NUMBA_DISABLE_JIT": "1"},
    )
    assert done.returncode == 0, done.stderr[-2000:]
    assert "no kernel compiled: NUMBA_DISABLE_JIT is set" in " ".join(done.stdout.split())


def test_ceamcl_warm_up_says_what_it_readied(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["warm-up"]) == 0
    out = " ".join(capsys.readouterr().out.split())
    assert f"{len(kernels())} compiled-kernel signatures ready" in out
    assert "Numba's cache:" in out
