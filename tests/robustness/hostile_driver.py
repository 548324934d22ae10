"""Run many hostile cases in one interpreter: ``python hostile_driver.py OUT.json ID ...``.

Starting a Python process with NumPy, Numba and SciPy takes about a second, so the bulk of
the generated cases run here, one after another, each in its own empty folder, with the
command's stdout and stderr captured and a per-case time limit (``SIGALRM``). The process runs
under the memory cap ``HOSTILE_MEMORY_CAP`` (bytes of address space, set by the test). The
results (exit code, stderr, seconds, files left behind) are written as JSON for the test to
check. A traceback inside a case is caught here and reported as ``exit_code`` -1 with the
traceback as stderr, so it fails its test instead of ending the run.
"""

from __future__ import annotations

import contextlib
import io
import json
import os
import resource
import signal
import sys
import tempfile
import time
import traceback
from pathlib import Path
from typing import Any

sys.path.insert(0, str(Path(__file__).resolve().parents[2]))

from tests.robustness.hostile_cases import Case, all_cases

CASE_TIMEOUT_S = 30
WARM_UP = (
    "ceamcl.cli",
    "ceamcl.demo",
    "ceamcl.soak",
    "ceamcl.experiments.evaluate_log",
    "ceamcl.experiments.common",
    "ceamcl.experiments.routes",
    "ceamcl.experiments.table1",
    "ceamcl.mapping",
    "ceamcl.maps.ros_io",
    "ceamcl.io.rosbag",
    "rosbags.highlevel",
)


class CaseTimeout(BaseException):
    """Raised by the alarm: the case hung."""


def _alarm(signum: int, frame: Any) -> None:
    raise CaseTimeout


def files_under(folder: Path) -> list[str]:
    return sorted(str(p.relative_to(folder)) for p in folder.rglob("*"))


def run_case(case: Case, root: Path) -> dict[str, Any]:
    from ceamcl.cli import main

    folder = root / case.id.replace("/", "__")
    folder.mkdir()
    case.setup(folder)
    before = files_under(folder)
    out, err = io.StringIO(), io.StringIO()
    saved_env = {k: os.environ.get(k) for k in case.env}
    os.environ.update(case.env)
    cwd = os.getcwd()
    os.chdir(folder)
    start, cpu_start = time.perf_counter(), time.process_time()
    signal.alarm(CASE_TIMEOUT_S)
    try:
        with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
            try:
                code = main(list(case.argv))
            except SystemExit as exc:  # argparse
                code = exc.code if isinstance(exc.code, int) else 2
    except CaseTimeout:
        code, err = -2, io.StringIO(f"timed out after {CASE_TIMEOUT_S} s")
    except BaseException:
        code = -1
        err.write(traceback.format_exc())
    finally:
        signal.alarm(0)
        elapsed = time.perf_counter() - start
        cpu = time.process_time() - cpu_start
        os.chdir(cwd)
        for k, v in saved_env.items():
            if v is None:
                os.environ.pop(k, None)
            else:
                os.environ[k] = v
    after = files_under(folder)
    return {
        "id": case.id,
        "exit_code": code,
        "stderr": err.getvalue(),
        "stdout": out.getvalue(),
        "seconds": elapsed,
        "cpu_seconds": cpu,
        "left_behind": sorted(set(after) - set(before)),
    }


def main(argv: list[str]) -> int:
    out_path, wanted = Path(argv[0]), set(argv[1:])
    cap = int(os.environ.get("HOSTILE_MEMORY_CAP", "0"))
    if cap:
        resource.setrlimit(resource.RLIMIT_AS, (cap, cap))
    signal.signal(signal.SIGALRM, _alarm)
    os.environ.setdefault("NUMBA_NUM_THREADS", "1")
    # Start-up first (imports the commands make lazily, and the compiled kernels: on a clean
    # clone Numba's cache is empty and the first case that localises compiled them inside its
    # time limit, 20-30 s on 2 busy cores), so each case's time is its own.
    import importlib

    for module in WARM_UP:
        importlib.import_module(module)
    from ceamcl.warmup import warm_up

    warm_up()
    results = []
    with tempfile.TemporaryDirectory(prefix="hostile-") as tmp:
        for case in all_cases():
            if case.id in wanted:
                results.append(run_case(case, Path(tmp)))
    out_path.write_text(json.dumps(results, indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
