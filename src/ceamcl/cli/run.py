"""``ceamcl run``: replay a real log (CARMEN or ROS bag) through a filter from global
localisation, and write its trajectory, summary, diagnostics and plot."""

from __future__ import annotations

import argparse
from collections.abc import Mapping, Sequence
from typing import Any

from rich.console import Console
from rich.markup import escape
from rich.table import Table
from rich.text import Text

from ceamcl.checks import physical_warnings
from ceamcl.cli.common import (
    RunProgress,
    add_output_arguments,
    laser_mount,
    make_progress,
    non_negative_float,
    non_negative_int,
    number,
    plain_table,
    positive_float,
    positive_int,
    print_written,
    require_available,
    warm_kernels,
)
from ceamcl.errors import ConfigError
from ceamcl.filters import registry
from ceamcl.io.truth_check import TruthDoubt, doubtful_truth
from ceamcl.maps.grid import OccupancyGrid
from ceamcl.outputs import OutputOptions
from ceamcl.replay import (
    DEFAULT_UPDATE_MIN_A,
    DEFAULT_UPDATE_MIN_D,
    PreparedLog,
    UpdatePace,
    check_pace,
    choose_pace,
    obtain_map,
    prepare_log,
    replay_log,
)

DEFAULT_ALGORITHM = "ceamcl"
#: The states of the console's share row, in its order (the shares add up to 100 %).
STATE_ORDER = ("LOCALISED", "AMBIGUOUS", "LOST", "INITIALISING")


def log_path(args: argparse.Namespace) -> str:
    """The log named positionally or with ``--log`` (exactly one of the two)."""
    given = [v for v in (args.log, args.log_option) if v is not None]
    if len(given) != 1:
        raise ConfigError(
            "log: give the log once, as LOG or --log LOG" + ("" if given else " (none given)")
        )
    return str(given[0])


def add_log_arguments(p: argparse.ArgumentParser, *, frames: bool = True) -> None:
    """Options shared by the commands that read a log (run, map-from-log, evaluate-log, play).
    ``frames=False``: the caller defines ``--odom-frame`` and ``--base-frame`` itself (``play``
    publishes the frames it reads)."""
    p.add_argument(
        "log",
        metavar="LOG",
        nargs="?",
        default=None,
        help="CARMEN log (.log/.clf, plain or .gz), ROS 1 .bag file or ROS 2 bag folder "
        "(or give it as --log LOG)",
    )
    p.add_argument("--log", dest="log_option", metavar="LOG", default=None, help=argparse.SUPPRESS)
    p.add_argument(
        "--laser",
        type=positive_int,
        default=1,
        help="CARMEN: which laser (1 front: FLASER/ROBOTLASER1/RAWLASER1, 2 rear, 3, 4)",
    )
    p.add_argument(
        "--max-range",
        type=positive_float,
        default=None,
        metavar="M",
        help="sensor maximum in metres: readings at or beyond it are no-return "
        "(default: from the log; 80 m for old-style CARMEN lasers)",
    )
    p.add_argument(
        "--odometry-sign",
        choices=("auto", "recorded"),
        default="auto",
        help="CARMEN: auto: when the ODOM lines' velocity shows that the odometry lost its sign "
        "(its poses keep moving forward while the robot backs up), each increment between scans "
        "takes the velocity's sign; recorded: the odometry as recorded",
    )
    p.add_argument("--scan-topic", default=None, help="bag: sensor_msgs/LaserScan topic")
    p.add_argument(
        "--odom-topic",
        default=None,
        help="bag: nav_msgs/Odometry topic (default: the only one; else the odom->base TF)",
    )
    if frames:
        p.add_argument("--odom-frame", default="odom", help="bag: TF parent frame of the odometry")
        p.add_argument("--base-frame", default="base_link", help="bag: TF child frame (robot base)")


#: Cell side of a map built from the log when ``--resolution`` is not given.
DEFAULT_RESOLUTION_M = 0.05


def add_map_arguments(p: argparse.ArgumentParser) -> None:
    """``--map`` and ``--resolution`` (of a map built from the log; refused with ``--map``,
    whose cells are the file's: :func:`map_resolution`)."""
    p.add_argument(
        "--map", default=None, metavar="MAP.yaml", help="ROS map (default: built from the log)"
    )
    p.add_argument(
        "--resolution",
        type=positive_float,
        default=None,
        help=f"cell side of a map built from the log [m] (default {DEFAULT_RESOLUTION_M}; "
        "not with --map, whose cells are the file's)",
    )


def map_resolution(args: argparse.Namespace) -> float:
    """The cell side of the map built from the log; ``--resolution`` with ``--map`` refused
    (it was ignored without a word)."""
    if args.resolution is not None and args.map is not None:
        raise ConfigError(
            f"resolution: --resolution {args.resolution:g} sets the cells of a map built from the "
            f"log; {args.map}'s cells are its own; expected one of them"
        )
    return DEFAULT_RESOLUTION_M if args.resolution is None else float(args.resolution)


def add_sensor_argument(p: argparse.ArgumentParser) -> None:
    """The laser's sensor model, as Nav2's ``laser_model_type`` chooses it."""
    p.add_argument(
        "--sensor",
        choices=registry.SENSOR_MODELS,
        default=registry.DEFAULT_SENSOR,
        help="sensor model of every algorithm but nav2-amcl, which always uses the wheel's own "
        "beam model (Nav2's laser_model_type; default %(default)s; docs/sensor-models.md)",
    )


#: What a user of the beam model with CEAMCL should know (docs/sensor-models.md).
BEAM_STATE_NOTE = (
    "CEAMCL's localisation state was calibrated with the likelihood field; with the beam "
    "model its fitness lies lower, so on real logs the state reads LOST at most scans and a "
    "recovery (a ray-cast global search) starts about every 20 scans (docs/sensor-models.md)"
)


def print_sensor_note(console: Console, sensor: str, algorithms: Sequence[str]) -> None:
    """Say so when CEAMCL runs with the beam model (:data:`BEAM_STATE_NOTE`)."""
    if sensor == "beam" and "ceamcl" in algorithms:
        console.print(Text(f"note: {BEAM_STATE_NOTE}", style="yellow"))


def add_truth_arguments(
    p: argparse.ArgumentParser, seed_help: str = "seed of the filter and of synthetic odometry"
) -> None:
    p.add_argument(
        "--truth",
        choices=("auto", "yes", "no"),
        default="auto",
        help="are the log's poses SLAM-corrected ground truth? auto: when the log's content "
        "says so (NEFF messages of a SLAM run, laser pose = robot pose; the file name plays no "
        "part). With truth the filter gets synthetic odometry drawn from it (default: auto)",
    )
    p.add_argument(
        "--truth-from",
        default=None,
        metavar="CORRECTED",
        help="ground truth from the SLAM-corrected log of the same run: LOG's scans are paired "
        "with CORRECTED's by identical ranges, the filter reads LOG's own odometry and every "
        "scan and is scored at the matched scans; without --map the map is built from CORRECTED",
    )
    p.add_argument(
        "--laser-mount",
        type=laser_mount,
        default=None,
        metavar="X,Y,YAW",
        help="the laser's pose on the robot (m, m, rad) at every scan, in place of the log's (a "
        "CARMEN log without one says 0,0,0); with --truth-from the truth is the robot's under "
        "it, and the pairing prints the mount the corrected poses and the odometry suggest",
    )
    p.add_argument(
        "--repair-times",
        action="store_true",
        help="raise scan times that go back by more than 1 s (or are not numbers) to the "
        "latest time before them, instead of refusing the log",
    )
    p.add_argument(
        "--seed",
        type=non_negative_int,
        default=0,
        help=seed_help,
    )


def add_pace_arguments(p: argparse.ArgumentParser) -> None:
    """Update at a real robot's pace (Nav2's update_min_d / update_min_a)."""
    p.add_argument(
        "--update-min-d",
        type=non_negative_float,
        default=None,
        metavar="M",
        help=f"update the filter once the robot has moved M metres since the last update "
        f"(default {DEFAULT_UPDATE_MIN_D:g} on logs with the robot's own odometry; corrected "
        "logs with synthetic odometry update at every scan unless given). The odometry of the "
        "scans in between is accumulated, never dropped; every algorithm gets the same pace",
    )
    p.add_argument(
        "--update-min-a",
        type=non_negative_float,
        default=None,
        metavar="RAD",
        help=f"... or turned RAD radians (default {DEFAULT_UPDATE_MIN_A:g}, as --update-min-d)",
    )
    p.add_argument(
        "--every-scan", action="store_true", help="update the filter at every scan (no pace)"
    )


def open_inputs(
    args: argparse.Namespace,
) -> tuple[PreparedLog, OccupancyGrid, str, UpdatePace | None]:
    """What ``ceamcl run`` and ``ceamcl evaluate-log`` start from: the log with its truth and
    odometry decided, the map (and a sentence saying which), physical-sense warnings given,
    and the update pace."""
    check_log_arguments(args)
    resolution = map_resolution(args)
    prepared = prepare_log(
        log_path(args),
        seed=args.seed,
        truth=args.truth,
        repair_times=args.repair_times,
        truth_from=args.truth_from,
        laser_mount=args.laser_mount,
        **open_kwargs(args),
    )
    grid, map_source = obtain_map(
        prepared.map_log, args.map, resolution, own=prepared.truth_log is None
    )
    physical_warnings(prepared.log, grid, args.map or f"the map built from {prepared.map_log.path}")
    return prepared, grid, map_source, pace_of(args, prepared)


def check_log_arguments(args: argparse.Namespace) -> None:
    """Refuse, before the log is read, the combinations of ``run`` and ``evaluate-log`` options
    one of which would be ignored or refused only after the work of reading it."""
    check_pace(args.update_min_d, args.update_min_a, every_scan=args.every_scan)
    check_truth_from(args.truth_from, None if args.truth == "auto" else f"--truth {args.truth}")


def check_truth_from(truth_from: str | None, truth_option: str | None) -> None:
    """Refuse a truth option (``truth_option``: as given, e.g. ``--truth no``) beside
    ``--truth-from``, whose corrected log is the truth (``run``, ``evaluate-log``, ``play``)."""
    if truth_from is not None and truth_option is not None:
        raise ConfigError(
            f"truth: {truth_option} has no effect with --truth-from, whose corrected log is the "
            "truth; expected one of them"
        )


def pace_of(args: argparse.Namespace, prepared: PreparedLog) -> UpdatePace | None:
    return choose_pace(prepared, args.update_min_d, args.update_min_a, every_scan=args.every_scan)


def open_kwargs(args: argparse.Namespace) -> dict[str, Any]:
    return {
        "laser": args.laser,
        "max_range_m": args.max_range,
        "odometry_sign": args.odometry_sign,
        "scan_topic": args.scan_topic,
        "odom_topic": args.odom_topic,
        "odom_frame": args.odom_frame,
        "base_frame": args.base_frame,
    }


def truth_doubt(prepared: Any, grid: OccupancyGrid) -> TruthDoubt | None:
    """How well the log's truth explains its scans on ``grid`` (:mod:`ceamcl.io.truth_check`),
    made once per command for its console and its files; ``None`` without truth."""
    return doubtful_truth(prepared.log, grid) if prepared.has_truth else None


def print_truth(console: Console, prepared: Any, doubt: TruthDoubt | None = None) -> None:
    """What was decided about ground truth and odometry, and repaired scan times; with
    ``doubt`` (:func:`truth_doubt`), how well the truth explains its scans on the map."""
    console.print(f"ground truth: {prepared.truth_reason}", markup=False)
    if doubt is not None:
        console.print(doubt.summary())
    if not prepared.has_truth:
        console.print("odometry: the log's recorded odometry (no ground truth: no errors scored)")
    if prepared.pairing is not None:
        console.print(
            f"odometry: the log's recorded odometry; scored at the {prepared.pairing.n_matched} "
            f"of {len(prepared.log)} scans with truth"
        )
    no_return = prepared.log.info.get("max_range_from")
    if no_return:
        console.print(f"laser: {no_return}", markup=False)
    sign = prepared.log.info.get("odometry_sign")
    if sign:
        console.print(f"odometry: {sign} (--odometry-sign recorded reads it as recorded)")
    repaired = int(prepared.log.info.get("repaired_times", 0))
    if repaired:
        console.print(f"scan times: {repaired} raised to the latest before them (--repair-times)")


def _at(scan: int | None, time_s: float | None) -> str:
    return "never" if scan is None else f"scan {scan} ({time_s or 0.0:.1f} s)"


def run_table(title: str, summary: Mapping[str, Any]) -> Table:
    """The console table of ``ceamcl run``: what was run and what happened, units in the
    measures' names, ``never``/``-`` where there is no number."""
    s = summary
    rows: list[tuple[str, str]] = [
        ("scans", str(s["scans"])),
        ("duration [s]", number(s["duration_s"], 1)),
        ("path length [m]", number(s["path_length_m"], 1)),
        ("odometry", s["odometry_source"]),
        ("ground truth", s["ground_truth"] or "none: no errors scored"),
    ]
    if s.get("convergence", "not scored") != "not scored":
        rmse = s["position_rmse_after_convergence_m"], s["heading_rmse_after_convergence_rad"]
        rows += [
            ("convergence", s["convergence"]),
            ("first localised", _at(s["first_localised_scan"], s["first_localised_s"])),
            ("converged, held to the end", _at(s["scans_to_converge"], s["time_to_converge_s"])),
            (
                "scans inside 0.5 m, 0.3 rad",
                f"{s['scans_inside_tolerance']} of {scored} with truth"
                if (scored := (s.get("truth_pairing") or {}).get("matched_scans"))
                else f"{s['scans_inside_tolerance']} of {s['scans']}",
            ),
            ("RMSE after convergence [m, rad]", f"{number(rmse[0], 3)}, {number(rmse[1], 3)}"),
            (
                "final error [m, rad]",
                f"{s['final_position_error_m']:.3f}, {s['final_heading_error_rad']:.3f}",
            ),
        ]
    if "final_state" in s:
        shares = s["state_shares"]
        rows += [
            (
                "state at the end",
                f"{s['final_state']} ({s['final_state_confidence']:.2f}): "
                f"{s['final_state_reason']}",
            ),
            (
                "steps LOCALISED / AMBIGUOUS / LOST / INITIALISING",
                " / ".join(f"{100 * shares.get(k, 0.0):.0f} %" for k in STATE_ORDER),
            ),
        ]
    restarts = str(s["restarts"])
    if s["kidnap_recoveries"]:
        restarts += f" ({s['kidnap_recoveries']} kidnap recoveries)"
    after = f" after scan {s['jumps_from_scan']}" if s["jumps_from_scan"] else ""
    rows += [
        ("restarts of global localisation", restarts),
        (
            "largest estimate jump [m]",
            "-"
            if s["largest_jump_scan"] is None
            else f"{s['largest_jump_m']:.2f} at scan {s['largest_jump_scan']}",
        ),
        (
            f"jumps over {s['jump_threshold_m']:g} m{after}",
            str(s["jumps_over_threshold"]),
        ),
        ("initialisation [ms]", number(s["initialisation_ms"], 0)),
        ("filter updates", f"{s['updates']} ({s['update_policy']})"),
        ("sensor model", str(s.get("sensor", registry.DEFAULT_SENSOR))),
        ("mean step [ms]", number(s["mean_step_ms"], 1)),
        ("median update [ms]", number(s["median_update_ms"], 1)),
        ("mean particles", number(s["mean_particles"], 0)),
    ]
    return plain_table(title, ("measure", "value"), rows)


def register(sub: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    """Add ``ceamcl run``."""
    p = sub.add_parser(
        "run",
        help="replay a real log through a filter from global localisation",
        description="Replay a CARMEN log or ROS bag through a filter, starting with no idea of "
        "the pose. Without --map the map is built from the log itself.",
    )
    add_log_arguments(p)
    add_map_arguments(p)
    p.add_argument(
        "--algorithm", choices=registry.names(), default=DEFAULT_ALGORITHM, help="filter to run"
    )
    add_truth_arguments(p)
    add_pace_arguments(p)
    add_sensor_argument(p)
    p.add_argument("--out", default="run-out", help="folder for the results")
    p.add_argument("--quiet", action="store_true", help="no progress bar or table")
    # Real logs are long: no animation unless --gif asks for it (docs/outputs.md).
    add_output_arguments(p, animation_default=False)
    p.set_defaults(run=run)


def run(args: argparse.Namespace, console: Console) -> int:
    outputs = OutputOptions.from_args(args)  # refuses --mp4 without ffmpeg before the run
    require_available(args.algorithm)
    prepared, grid, map_source, pace = open_inputs(args)
    doubt = truth_doubt(prepared, grid)
    if not args.quiet:
        console.print(f"map: {map_source}", markup=False)
        print_truth(console, prepared, doubt)
        console.print(f"filter updates: {'every scan' if pace is None else pace.describe()}")
        console.print(
            f"sensor model: {registry.sensor_of(args.algorithm, args.sensor)}", markup=False
        )
        print_sensor_note(console, args.sensor, [args.algorithm])
        if prepared.noise is not None:
            n = prepared.noise
            console.print(
                f"odometry: synthetic, drawn from the log's corrected poses with alpha1..4 = "
                f"{n.alpha1:g}, {n.alpha2:g}, {n.alpha3:g}, {n.alpha4:g} (seed {args.seed})"
            )
    progress = make_progress(
        f"[bold]{args.algorithm}[/] on {escape(prepared.log.name)}", console, quiet=args.quiet
    )
    with progress:
        warm_kernels(progress, args.sensor, [args.algorithm])
        bar = RunProgress(progress, "scans")
        outcome = replay_log(
            prepared,
            grid,
            args.algorithm,
            map_source=map_source,
            out=args.out,
            on_start=bar.start,
            on_step=bar.step,
            outputs=outputs,
            on_frame=bar.frame,
            pace=pace,
            truth_doubt=doubt,
            sensor=args.sensor,
        )
    if not args.quiet:
        console.print(
            run_table(f"ceamcl run ({args.algorithm}, seed {args.seed})", outcome.summary)
        )
        console.print(Text(f"verdict: {outcome.summary['verdict']}"))
        print_written(console, outcome.out_dir, outcome.files)
    return 0
