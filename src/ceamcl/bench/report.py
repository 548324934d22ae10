"""``bench.json`` (every figure) and ``bench.md`` (tables a person reads) from a bench result."""

from __future__ import annotations

import math
import os
from pathlib import Path
from typing import Any

from ceamcl.experiments.common import markdown_table, write_text
from ceamcl.io.results import ensure_output_dir, write_json


def target_verdict(t: dict[str, Any]) -> str:
    """PASS or FAIL; without a verdict, "not measured" where there is no value and "no target
    (quick run)" beside a value a quick run measured (it read "not measured" there too)."""
    if t["pass"] is None:
        return "not measured" if t["value"] is None else "no target (quick run)"
    return "PASS" if t["pass"] else "FAIL"


def _f(v: Any, digits: int = 1) -> str:
    """A table cell: ``-`` for None and non-finite numbers, thousands separators."""
    if v is None or (isinstance(v, float) and not math.isfinite(v)):
        return "-"
    if isinstance(v, bool):
        return "yes" if v else "no"
    if isinstance(v, int):
        return f"{v:,}"
    if isinstance(v, float):
        return f"{v:,.{digits}f}"
    return str(v)


def render_markdown(r: dict[str, Any]) -> str:
    m = r["machine"]
    v = m["versions"]
    lines = ["# ceamcl bench", ""]
    if r["settings"]["quick"]:
        lines += [
            "**Quick run (`--quick`)**: small sizes, a smoke test; no figure is a target.",
            "",
        ]
    lines += [
        f"Machine: {m['cpu']}, {m['cores']} cores (numba threads {m['numba_threads']}); "
        f"Python {m['python']}; ceamcl {v.get('ceamcl')}, numpy {v.get('numpy')}, "
        f"numba {v.get('numba')}, scipy {v.get('scipy')}, amcl {v.get('amcl') or 'absent'}. "
        f"Load average at the start: {m.get('load_average')}.",
        "",
        f"Map `{r['settings']['map']}` ({r['settings']['map_cells'][0]} x "
        f"{r['settings']['map_cells'][1]} cells of {r['settings']['resolution_m']} m), "
        f"{r['settings']['beams']} beams per scan, the paper scenario's odometry and scans.",
        f"Peer: {r['peer']['note']}.",
        "",
        "## Targets",
        "",
    ]
    rows = []
    for t in r["targets"]:
        sign = ">=" if t["kind"] == "min" else "<="
        rows.append(
            [t["target"], f"{sign} {t['threshold']:g}", _f(t["value"], 2), target_verdict(t)]
        )
    lines.append(markdown_table(["target", "goal", "measured", ""], rows))

    lines += [
        "## Full filter update (motion, sensor, resampling)",
        "",
        "Median over the timed updates along the route; ns per particle-beam = update time / "
        "(N x 60). Ours: MCL resampling every update; Nav2: the `amcl` wheel with "
        "min = max = N. CPU/wall > 1: both cores worked.",
        "",
    ]
    rows = []
    for row in r["filter_update"]:
        o = row["ours"]
        n2 = row.get("nav2")
        rows.append(
            [
                row["sensor"],
                _f(row["n"]),
                _f(o["ms"], 2),
                _f(o["ns_per_pb"], 1),
                _f(o["cpu_per_wall"], 2),
                _f(n2["ms"], 2) if n2 else "skipped",
                _f(n2["ns_per_pb"], 1) if n2 else "-",
                _f(n2["cpu_per_wall"], 2) if n2 else "-",
                _f(row.get("speedup"), 1),
            ]
        )
    lines.append(
        markdown_table(
            [
                "sensor",
                "N",
                "ours ms",
                "ours ns/pb",
                "ours CPU/wall",
                "Nav2 ms",
                "Nav2 ns/pb",
                "Nav2 CPU/wall",
                "speed-up",
            ],
            rows,
        )
    )

    init = r["ceamcl_init"]
    lines += [
        "## CEAMCL initial species generation",
        "",
        f"{init['n_test']:,} test poses x {init['beams']} beams ({init['sensor']}, "
        f"{init['beams_scored']} beams scored after dropping max-range readings): "
        f"median {init['seconds']:.3f} s over {len(init['all_seconds'])} run(s); "
        f"{init['species']} species, {init['particles']} particles.",
        "",
    ]
    lines.append(
        markdown_table(["phase", "s"], [[k, _f(s, 3)] for k, s in init["phases_s"].items()])
    )
    step = r["ceamcl_step"]
    lines += [
        "## CEAMCL step",
        "",
        f"Paper run from global localisation, {step['steps']} steps: median "
        f"{step['median_ms_all']:.2f} ms at a median {step['median_particles_all']:.0f} "
        f"particles. "
        + (
            f"None holds 700-1300, so the run was made again with delta_per_m2 "
            f"{step['delta_per_m2_for_1000']:g} (the samples grow with delta) for the target's "
            "~1,000: "
            if "delta_per_m2_for_1000" in step
            else ""
        )
        + f"steps with 700-1300 particles: {step['steps_near_1000']}"
        + (
            f", median {step['median_ms']:.2f} ms at {step['median_particles']:.0f} particles "
            f"and {step['median_species']:.0f} species."
            if "median_ms" in step
            else "."
        ),
        "",
    ]

    sc = r["scaling"]
    lines += ["## Scaling: sensor kernels alone", "", "Against N (60 beams, hall):", ""]
    lines.append(
        markdown_table(
            ["sensor", "N", "ns/pb", "ms per call", "first call ms"],
            [
                [
                    x["sensor"],
                    _f(x["n"]),
                    _f(x["ns_per_pb"], 2),
                    _f(x["ms"], 3),
                    _f(x["first_call_ms"], 1),
                ]
                for x in sc["n"]
            ],
        )
    )
    lines += ["Against the beam count (N = 5000):", ""]
    lines.append(
        markdown_table(
            ["sensor", "max_beams", "ns/pb", "ms per call"],
            [
                [x["sensor"], _f(x["max_beams"]), _f(x["ns_per_pb"], 2), _f(x["ms"], 3)]
                for x in sc["beams"]
            ],
        )
    )
    ft = sc["beam_table_full_map"]
    lines += [
        f"Beam-model ray-cast table filled for the whole of `{ft['map']}` at once: "
        f"{ft['seconds']:.2f} s "
        f"(CPU/wall {ft['cpu_per_wall']:.2f}), {ft['mb']:.0f} MB, {ft['rows']:,} cells x "
        f"{ft['angles']} headings. In use it fills lazily, only where particles go.",
        "",
        "Against the map size (synthetic floors, 5 cm cells, N = 5000):",
        "",
    ]
    lines.append(
        markdown_table(
            [
                "cells",
                "metres",
                "distance field s",
                "blocking distance s",
                "LF table s",
                "LF ns/pb",
                "beam ns/pb",
                "beam table MB",
                "peak RSS MiB",
            ],
            [
                [
                    f"{x['cells']} x {x['cells']}",
                    _f(x["size_m"], 0),
                    _f(x["distance_field_s"], 2),
                    _f(x["blocking_distance_field_s"], 2),
                    _f(x["lf_table_s"], 2),
                    _f(x["lf_ns_per_pb"], 2),
                    _f(x["beam_ns_per_pb"], 2),
                    _f(x["beam_table_mb"], 1),
                    _f(x["peak_rss_mb"], 0),
                ]
                for x in sc["maps"]
            ],
        )
    )
    jit = r["jit"]
    lines += [
        "## Compilation (apart from every figure above)",
        "",
        "First call of each kernel in this process: numba compiles it, or loads it from its "
        "on-disk cache (`cache=True`). Cache files present before this run: "
        f"{_f(jit['cache_files_present_before'])}; total {jit['total_ms']:.0f} ms.",
        "",
    ]
    lines.append(
        markdown_table(
            ["kernel", "first call ms"], [[k, _f(t, 1)] for k, t in jit["first_call_ms"].items()]
        )
    )
    lines += ["## Peak memory (resident, whole process)", ""]
    lines.append(
        markdown_table(
            ["after", "MiB"], [[k, _f(t, 0)] for k, t in r["memory_peak_rss_mb"].items()]
        )
    )
    return "\n".join(lines)


def write_report(result: dict[str, Any], out_dir: str | os.PathLike[str]) -> tuple[Path, Path]:
    """Write ``bench.json`` and ``bench.md`` (each whole or not at all)."""
    out = ensure_output_dir(out_dir)
    js = write_json(out / "bench.json", result)
    md = write_text(out / "bench.md", render_markdown(result) + "\n")
    return js, md
