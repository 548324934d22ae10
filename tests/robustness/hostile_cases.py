"""Generated hostile inputs for the command line (issue 16), each with what must happen.

A :class:`Case` writes its input files into an empty folder (``setup``), names the command
line to run there and the fragments its one-line error must contain (a file, line or field).
:func:`all_cases` generates them by category; ``test_hostile_inputs.py`` runs them in
``hostile_driver.py`` (many per interpreter) under a memory cap and a time limit, and a few
per category as real subprocesses.
"""

from __future__ import annotations

import gzip
import os
import struct
import zlib
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from tests.box_room import box_ranges

Setup = Callable[[Path], None]

BEAMS = 37
QUIET_MCL = ("--quiet", "--algorithm", "mcl")


@dataclass(frozen=True)
class Case:
    """One hostile input: files made by ``setup`` in an empty folder, the command run there,
    the exit code expected and fragments its stderr must hold (all of them)."""

    category: str
    name: str
    argv: tuple[str, ...]
    setup: Setup
    fragments: tuple[str, ...]
    exit_code: int = 2
    warnings: int = 0  # exit 0 cases: the number of "ceamcl: warning:" lines expected
    env: dict[str, str] = field(default_factory=dict)

    @property
    def id(self) -> str:
        return f"{self.category}/{self.name}"


# ---------------------------------------------------------------------------- file makers
def flaser(
    x: float,
    t: float | str,
    ranges: list[float] | list[str] | None = None,
    pose: tuple[float, float, float] | None = None,
) -> str:
    r = ranges if ranges is not None else box_ranges(x, 0.0, BEAMS)
    p = "{:g} {:g} {:g}".format(*(pose or (x, 0.0, 0.0)))
    return f"FLASER {len(r)} " + " ".join(str(v) for v in r) + f" {p} {p} {t} nohost {t}"


def box_log_lines(scans: int = 12, *, neff: bool = False) -> list[str]:
    lines = ["PARAM robot_front_laser_max 8.0 nohost 0"]
    for k in range(scans):
        lines.append(flaser(0.1 * k, f"{0.1 * k:g}"))
        if neff:
            lines.append(f"NEFF 30.0 {0.1 * k:g} nohost {0.1 * k:g}")
    return lines


def write_lines(name: str, lines: list[str], *, gz: bool = False) -> Setup:
    def setup(d: Path) -> None:
        text = ("\n".join(lines) + "\n").encode()
        (d / name).write_bytes(gzip.compress(text, mtime=0) if gz else text)

    return setup


def write_bytes(name: str, data: bytes) -> Setup:
    def setup(d: Path) -> None:
        (d / name).write_bytes(data)

    return setup


def map_yaml(image: str = "map.pgm", **changes: str) -> str:
    doc = {
        "image": image,
        "resolution": "0.05",
        "origin": "[-2.0, -2.0, 0.0]",
        "negate": "0",
        "occupied_thresh": "0.65",
        "free_thresh": "0.196",
    }
    doc.update(changes)
    return "".join(f"{k}: {v}\n" for k, v in doc.items() if v != "")


def pgm(width: int, height: int, value: int = 254) -> bytes:
    body = np.full((height, width), value, dtype=np.uint8)
    body[0, :] = body[-1, :] = body[:, 0] = body[:, -1] = 0
    return f"P5\n{width} {height}\n255\n".encode() + body.tobytes()


def write_map(
    yaml_text: str | None = None, image: bytes | None = None, image_name: str = "map.pgm"
) -> Setup:
    def setup(d: Path) -> None:
        (d / "map.yaml").write_text(yaml_text if yaml_text is not None else map_yaml())
        (d / image_name).write_bytes(image if image is not None else pgm(100, 80))

    return setup


def png_header_only(width: int, height: int) -> bytes:
    """A PNG whose header claims ``width x height`` pixels and whose data is one tiny chunk."""

    def chunk(kind: bytes, data: bytes) -> bytes:
        crc = zlib.crc32(kind + data) & 0xFFFFFFFF
        return struct.pack(">I", len(data)) + kind + data + struct.pack(">I", crc)

    ihdr = struct.pack(">IIBBBBB", width, height, 8, 0, 0, 0, 0)
    return (
        b"\x89PNG\r\n\x1a\n"
        + chunk(b"IHDR", ihdr)
        + chunk(b"IDAT", zlib.compress(b"\x00" * 64))
        + chunk(b"IEND", b"")
    )


def billion_laughs(depth: int, width: int = 9, key: str = "origin") -> str:
    lines = ["a0: &a0 [lol]"]
    for i in range(1, depth + 1):
        refs = ", ".join([f"*a{i - 1}"] * width)
        lines.append(f"a{i}: &a{i} [{refs}]")
    return "\n".join(lines) + f"\n{key}: *a{depth}\n"


def combine(*setups: Setup) -> Setup:
    def setup(d: Path) -> None:
        for s in setups:
            s(d)

    return setup


def routes_yaml(sim: str = "", routes: str | None = None, symmetry: str = "") -> str:
    body = routes or (
        "routes:\n  - name: a\n    start: [0.5, 0.5, 0.0]\n"
        "    waypoints: [[2.5, 0.5], [2.5, 2.5]]\n"
    )
    return f"map: map.yaml\n{body}{symmetry}{sim}"


def room_map() -> Setup:
    """A 4 m x 4 m walled room at 0.05 m (origin 0, 0) for route files."""
    return write_map(map_yaml(origin="[0.0, 0.0, 0.0]"), pgm(80, 80))


def rng_bytes(seed: int, n: int) -> bytes:
    return np.random.default_rng(seed).integers(0, 256, n, dtype=np.uint8).tobytes()


def rng_text_bytes(seed: int, n: int) -> bytes:
    """Random bytes with no NUL and at least one byte that is not UTF-8."""
    data = bytearray(np.random.default_rng(seed).integers(1, 256, n, dtype=np.uint8).tobytes())
    data[n // 2] = 0xFF
    return bytes(data)


RUN_WITH_MAP = ("run", "box.log", "--map", "map.yaml", "--out", "out")
TABLE1_WITH_ROUTES = ("experiment", "table1", "--routes", "routes.yaml", "--out", "out")


def map_case(
    category: str,
    name: str,
    fragments: tuple[str, ...],
    yaml_text: str | None = None,
    image: bytes | None = None,
    image_name: str = "map.pgm",
) -> Case:
    """``ceamcl run`` on the box log with a map of this YAML text and image."""
    log = write_lines("box.log", box_log_lines())
    return Case(
        category,
        name,
        RUN_WITH_MAP,
        combine(log, write_map(yaml_text, image, image_name)),
        fragments,
    )


def routes_case(category: str, name: str, fragments: tuple[str, ...], routes: bytes) -> Case:
    """``ceamcl experiment table1`` with this route file over a 4 m room."""
    setup = combine(room_map(), write_bytes("routes.yaml", routes))
    return Case(category, name, TABLE1_WITH_ROUTES, setup, fragments)


# ---------------------------------------------------------------------------- categories
def memory_cases() -> list[Case]:
    """Inputs whose sizes ask for unbounded memory: refused against the budget."""
    out: list[Case] = []
    log = write_lines("box.log", box_log_lines())
    for depth in (4, 6, 8, 10):
        for key in ("origin", "resolution", "image"):
            text = billion_laughs(depth, key=key)
            text = (
                "\n".join(
                    line for line in map_yaml().splitlines() if not line.startswith(f"{key}:")
                )
                + "\n"
                + text
            )
            out.append(
                map_case("memory", f"map-alias-bomb-{key}-{depth}", ("map.yaml:", "aliases"), text)
            )
    for depth in (6, 10):
        for key in ("routes", "symmetry", "simulation"):
            text = "map: map.yaml\n" + billion_laughs(depth, key=key)
            out.append(
                routes_case(
                    "memory",
                    f"routes-alias-bomb-{key}-{depth}",
                    ("routes.yaml:", "aliases"),
                    text.encode(),
                )
            )
    for res in ("0.0005", "0.0001", "1e-6", "1e-9"):
        for argv in (
            ("map-from-log", "box.log", "--resolution", res, "-o", "out/map.yaml"),
            ("run", "box.log", "--resolution", res, "--out", "out"),
        ):
            refusal = ("box.log: map built at resolution", "memory budget")
            out.append(Case("memory", f"{argv[0]}-resolution-{res}", argv, log, refusal))
    for far in (3000.0, 1e5, 1e9, -1e7):
        lines = [*box_log_lines(6), flaser(0.0, "1.0", pose=(far, far, 0.0))]
        out.append(
            Case(
                "memory",
                f"far-pose-{far:g}",
                ("map-from-log", "far.log", "-o", "out/map.yaml"),
                write_lines("far.log", lines),
                # beyond 10^7 m a pose is refused as no building's; within, the map's size
                ("far.log:8: FLASER: laser pose", "|x|, |y| <= 1e+07 m")
                if abs(far) > 1e7
                else ("far.log: map built at resolution", "memory budget"),
            )
        )
    for n in ("1000000000", "10000000000", str(2**62)):
        for cmd in ("demo", "soak"):
            out.append(
                Case(
                    "memory",
                    f"{cmd}-particles-{n}",
                    # a fixed-size filter: CEAMCL, the default, takes no particle count
                    (cmd, "--algorithm", "mcl", "--particles", n, "--out", "out", "--quiet"),
                    lambda d: None,
                    ("--particles:", "memory budget"),
                )
            )
    for n in ("1000000000", str(2**40)):
        out.append(
            Case(
                "memory",
                f"experiment-trials-{n}",
                ("experiment", "table1", "--trials", n, "--out", "out"),
                lambda d: None,
                ("--trials x routes x algorithms", "memory budget"),
            )
        )
        out.append(
            Case(
                "memory",
                f"evaluate-log-starts-{n}",
                ("evaluate-log", "box.log", "--starts", n, "--out", "out"),
                log,
                ("--starts x algorithms", "memory budget"),
            )
        )
    sims = {
        "speed": "simulation:\n  speed_mps: 1.0e-9\n",
        "rate": "simulation:\n  rate_hz: 1.0e+12\n",
        "turn": "simulation:\n  turn_rate_rps: 1.0e-12\n",
        "rate-speed": "simulation:\n  rate_hz: 1.0e+6\n  speed_mps: 1.0e-3\n",
    }
    for what, sim in sims.items():
        out.append(
            routes_case(
                "memory",
                f"routes-absurd-{what}",
                ("routes.yaml: routes[0]", "steps", "memory budget"),
                routes_yaml(sim).encode(),
            )
        )
    for rotations in (10**9, 10**12, 2**62):
        sym = f"symmetry:\n  rotations: {rotations}\n  centre: [2.0, 2.0]\n"
        out.append(
            routes_case(
                "memory",
                f"routes-rotations-{rotations}",
                ("routes.yaml: symmetry", "memory budget"),
                routes_yaml(symmetry=sym).encode(),
            )
        )
    for w, h in ((10000, 10000), (20000, 20000), (60000, 60000), (2**31 - 1, 2)):
        out.append(
            map_case(
                "memory",
                f"map-image-header-{w}x{h}",
                ("map.yaml", "map.png"),
                map_yaml("map.png"),
                png_header_only(w, h),
                "map.png",
            )
        )
    # 3000 x 3000 cells peak at about 1.05 GiB in a run (87-100 B a cell measured): at 64 B a
    # cell the budget let them through under 1 GiB (budget.MAP_CELL_BYTES)
    big_map = write_map(map_yaml("map.png"), png_header_only(3000, 3000), "map.png")
    for name, limit, shown in (
        ("map-image-over-small-budget", "64MiB", "64.0 MiB"),
        ("map-image-over-a-budget-it-would-exceed", "1GiB", "1.0 GiB"),
    ):
        out.append(
            Case(
                "memory",
                name,
                ("run", "box.log", "--map", "map.yaml", "--out", "out", "--memory-budget", limit),
                combine(log, big_map),
                ("map.yaml: image", "3000 x 3000 pixels", f"memory budget of {shown}"),
            )
        )
    out.append(
        Case(
            "memory",
            "gzip-expands-beyond-budget",
            ("map-from-log", "bomb.log.gz", "-o", "out/map.yaml", "--memory-budget", "1MiB"),
            write_lines("bomb.log.gz", box_log_lines(3000), gz=True),
            ("bomb.log.gz:", "scans kept", "memory budget of 1.0 MiB"),
        )
    )
    odom = [f"ODOM 0 0 0 0 0 0 {0.01 * k:g} nohost {0.01 * k:g}" for k in range(8000)]
    out.append(
        Case(
            "memory",
            "odometry-beyond-budget",
            ("map-from-log", "odom.log.gz", "-o", "out/map.yaml", "--memory-budget", "1MiB"),
            write_lines("odom.log.gz", box_log_lines(3) + odom, gz=True),
            ("odom.log.gz:", "odometry kept", "memory budget of 1.0 MiB"),
        )
    )
    big_line = ["FLASER 400000 " + " ".join(["1.0"] * 400000) + " 0 0 0 0 0 0 1 nohost 1"]
    out.append(
        Case(
            "memory",
            "line-over-bound",
            ("map-from-log", "long.log", "-o", "out/map.yaml", "--memory-budget", "64MiB"),
            write_lines("long.log", box_log_lines(2) + big_line),
            ("long.log:4: line longer than 1.0 MiB",),
        )
    )
    out.append(
        map_case(
            "memory",
            "map-yaml-over-1mib",
            ("map.yaml: larger than 1.0 MiB",),
            map_yaml() + "#" * (2 << 20) + "\n",
        )
    )
    return out


def stream_cases() -> list[Case]:
    """Non-regular files: FIFOs with no writer, endless devices, folders."""
    log = write_lines("box.log", box_log_lines())

    def fifo(d: Path) -> None:
        os.mkfifo(d / "fifo")

    def folder(d: Path) -> None:
        (d / "folder").mkdir()

    def nothing(d: Path) -> None:
        return None

    wait = {"CEAMCL_STREAM_WAIT_S": "0.5"}
    no_data = ("fifo", "no data")
    specs: list[tuple[str, tuple[str, ...], Setup, tuple[str, ...], dict[str, str]]] = [
        ("fifo-no-writer-run", ("run", "fifo", "--out", "out"), fifo, no_data, wait),
        (
            "fifo-no-writer-map-from-log",
            ("map-from-log", "fifo", "-o", "out/m.yaml"),
            fifo,
            no_data,
            wait,
        ),
        (
            "fifo-no-writer-evaluate-log",
            ("evaluate-log", "fifo", "--out", "out"),
            fifo,
            no_data,
            wait,
        ),
        (
            "fifo-no-writer-map",
            ("run", "box.log", "--map", "fifo", "--out", "out"),
            combine(log, fifo),
            no_data,
            wait,
        ),
        (
            "fifo-no-writer-routes",
            ("experiment", "table1", "--routes", "fifo", "--out", "out"),
            fifo,
            no_data,
            wait,
        ),
        (
            "dev-null-log",
            ("run", "/dev/null", "--out", "out"),
            nothing,
            ("/dev/null", "no scan"),
            {},
        ),
        (
            "folder-as-log",
            ("run", "folder", "--out", "out"),
            folder,
            ("folder", "not a ROS 2 bag"),
            {},
        ),
        (
            "folder-as-map",
            ("run", "box.log", "--map", "folder", "--out", "out"),
            combine(log, folder),
            ("folder",),
            {},
        ),
    ]
    for dev in ("/dev/zero", "/dev/urandom"):
        tag = dev.rsplit("/", 1)[1]
        specs += [
            (f"{tag}-log-run", ("run", dev, "--out", "out"), nothing, (dev,), {}),
            (f"{tag}-log-map", ("map-from-log", dev, "-o", "out/m.yaml"), nothing, (dev,), {}),
            (f"{tag}-map-yaml", ("run", "box.log", "--map", dev, "--out", "out"), log, (dev,), {}),
            (
                f"{tag}-routes",
                ("experiment", "table1", "--routes", dev, "--out", "out"),
                nothing,
                (dev,),
                {},
            ),
        ]
    return [Case("stream", n, argv, setup, frags, env=env) for n, argv, setup, frags, env in specs]


def encoding_cases() -> list[Case]:
    """Text that is not UTF-8, binary garbage, damaged containers and images."""
    out: list[Case] = []
    log = write_lines("box.log", box_log_lines())
    good_routes = routes_yaml()
    for enc in ("utf-16", "utf-32", "cp1252-bad"):
        data = (
            good_routes.encode(enc)
            if enc != "cp1252-bad"
            else good_routes.replace("name: a", "name: caf\xe9").encode("cp1252")
        )
        out.append(routes_case("encoding", f"routes-{enc}", ("routes.yaml",), data))
        yaml_data = (
            map_yaml().encode(enc)
            if enc != "cp1252-bad"
            else map_yaml("caf\xe9.pgm").encode("cp1252")
        )
        out.append(
            Case(
                "encoding",
                f"map-yaml-{enc}",
                ("run", "box.log", "--map", "map.yaml", "--out", "out"),
                combine(log, write_map(), write_bytes("map.yaml", yaml_data)),
                ("map.yaml",),
            )
        )
    for seed in range(6):
        out.append(
            Case(
                "encoding",
                f"routes-random-{seed}",
                ("experiment", "table1", "--routes", "routes.yaml", "--out", "out"),
                write_bytes("routes.yaml", rng_text_bytes(seed, 300 + 100 * seed)),
                ("routes.yaml",),
            )
        )
        out.append(
            Case(
                "encoding",
                f"carmen-random-{seed}",
                ("run", "junk.log", "--out", "out"),
                write_bytes("junk.log", rng_text_bytes(100 + seed, 2000)),
                ("junk.log:",),
            )
        )
    for seed in range(8):
        size = [0, 1, 12, 13, 100, 4096, 65536, 13][seed]
        head = b"#ROSBAG V2.0\n" if seed in (3, 4, 5) else b""
        out.append(
            Case(
                "encoding",
                f"bag-random-{seed}",
                ("run", "junk.bag", "--out", "out"),
                write_bytes("junk.bag", head + rng_bytes(seed, size)),
                ("junk.bag",),
            )
        )
    out.append(
        Case(
            "encoding",
            "bag-named-log",
            ("run", "junk.log", "--out", "out"),
            write_bytes("junk.log", b"#ROSBAG V2.0\n" + rng_bytes(9, 500)),
            ("junk.log",),
        )
    )

    def ros2(meta: bytes, db: bytes | None = None) -> Setup:
        def setup(d: Path) -> None:
            (d / "bag2").mkdir()
            (d / "bag2" / "metadata.yaml").write_bytes(meta)
            if db is not None:
                (d / "bag2" / "bag2_0.db3").write_bytes(db)

        return setup

    for i, (meta, db) in enumerate(
        [
            (b"", None),
            (rng_text_bytes(5, 400), None),
            (b"rosbag2_bagfile_information:\n  version: 5\n", rng_bytes(6, 1000)),
            (b"rosbag2_bagfile_information: [1, 2\n", None),
        ]
    ):
        out.append(
            Case(
                "encoding",
                f"ros2-bag-junk-{i}",
                ("run", "bag2", "--out", "out"),
                ros2(meta, db),
                ("bag2",),
            )
        )
    text = ("\n".join(box_log_lines()) + "\n").encode()
    packed = gzip.compress(text, mtime=0)
    for name, data in (
        ("gz-truncated", packed[: len(packed) // 2]),
        ("gz-garbage", b"\x1f\x8b" + rng_bytes(11, 2000)),
        ("gz-header-only", packed[:10]),
        ("nul-bytes", text[:300] + b"\x00" * 50 + text[300:]),
        ("latin1", text.replace(b"nohost", b"h\xf4te", 1)),
        ("utf16", "\n".join(box_log_lines()).encode("utf-16")),
    ):
        out.append(
            Case(
                "encoding",
                f"carmen-{name}",
                ("run", "bad.log", "--out", "out"),
                write_bytes("bad.log", data),
                ("bad.log",),
            )
        )
    images = {
        "png-magic-junk": (b"\x89PNG\r\n\x1a\n" + rng_bytes(12, 300), "map.png"),
        "pgm-header-lies": (b"P5\n100 100\n255\n" + b"\xfe" * 10, "map.pgm"),
        "random-png": (rng_bytes(13, 500), "map.png"),
        "empty-png": (b"", "map.png"),
        "truncated-png": (png_header_only(50, 50)[:40], "map.png"),
        "text-as-pgm": (b"hello world\n", "map.pgm"),
    }
    for name, (data, image_name) in images.items():
        out.append(
            map_case(
                "encoding",
                f"image-{name}",
                ("map.yaml", image_name),
                map_yaml(image_name),
                data,
                image_name,
            )
        )
    return out


def physical_cases() -> list[Case]:
    """Times that go backwards or are not numbers, nonsense ranges, empty algorithm lists."""
    out: list[Case] = []
    base = box_log_lines(12)
    for k, bad in (
        (5, "-130.6"),
        (3, "-2.0"),
        (8, "nan"),
        (8, "inf"),
        (4, "-inf"),
        (11, "NaN"),
    ):
        lines = list(base)
        lines[k + 1] = flaser(0.1 * k, bad)  # line k + 2 of the file (PARAM is line 1)
        where = "timestamp" if bad.lower().lstrip("-") in ("nan", "inf") else "scan time"
        for cmd in ("run", "evaluate-log"):
            out.append(
                Case(
                    "physical",
                    f"{cmd}-time-{bad}-at-{k}",
                    (cmd, "times.log", "--out", "out", "--truth", "yes"),
                    write_lines("times.log", lines),
                    (f"times.log:{k + 2}:", where),
                )
            )
    nan_lines = ["PARAM robot_front_laser_max 8.0 nohost 0"] + [
        flaser(0.1 * k, f"{0.1 * k:g}", ["nan"] * BEAMS) for k in range(6)
    ]
    for nan_cmd in (
        ("run", "nan.log", "--out", "out"),
        ("map-from-log", "nan.log", "-o", "out/m.yaml"),
    ):
        out.append(
            Case(
                "physical",
                f"all-nan-ranges-{nan_cmd[0]}",
                nan_cmd,
                write_lines("nan.log", nan_lines),
                ("nan.log", "no usable reading"),
            )
        )
    for text in ("", ",", " , ", ",,,"):
        out.append(
            Case(
                "physical",
                f"empty-algorithms-{text.strip() or 'blank'}-{len(text)}",
                ("experiment", "table1", "--algorithms", text, "--out", "out"),
                lambda d: None,
                ("algorithms:", "expected one or more algorithm names"),
            )
        )
    for v in ("-1", "0", "nan", "inf", "x"):
        out.append(
            Case(
                "physical",
                f"max-range-{v}",
                ("run", "box.log", "--max-range", v, "--out", "out"),
                write_lines("box.log", base),
                ("--max-range",),
            )
        )
    return out


def cli_cases() -> list[Case]:
    """The kinds test_cli_errors.py and test_map_errors.py check, generated more widely."""
    out: list[Case] = []
    none: Setup = lambda d: None  # noqa: E731
    for cmd in ("demo", "soak"):
        for flag, v in (
            ("--particles", "-5"),
            ("--particles", "0"),
            ("--particles", "x"),
            ("--seed", "-1"),
            ("--seed", "1.5"),
            ("--algorithm", "nope"),
            ("--world", "atlantis"),
            ("--memory-budget", "lots"),
            ("--memory-budget", "0"),
        ):
            out.append(
                Case("cli", f"{cmd}{flag}={v}", (cmd, flag, v, "--out", "out"), none, (flag,))
            )
    for v in ("lots", "-1GiB", "0"):
        argv = ("experiment", "table1", "--memory-budget", v, "--out", "out")
        out.append(
            Case("cli", f"experiment-table1--memory-budget={v}", argv, none, ("--memory-budget",))
        )
    log = write_lines("box.log", box_log_lines())
    for flag, v in (
        ("--resolution", "0"),
        ("--resolution", "-1"),
        ("--resolution", "nan"),
        ("--laser", "0"),
        ("--algorithm", "pf"),
        ("--truth", "maybe"),
        ("--seed", "s"),
    ):
        out.append(
            Case("cli", f"run{flag}={v}", ("run", "box.log", flag, v, "--out", "out"), log, (flag,))
        )
    out.append(
        Case(
            "cli", "run-missing-log", ("run", "nowhere.log", "--out", "out"), none, ("nowhere.log",)
        )
    )
    out.append(Case("cli", "run-no-log", ("run", "--out", "out"), none, ("log:",)))
    out.append(
        Case(
            "cli",
            "run-laser-absent",
            ("run", "box.log", "--laser", "3", "--out", "out"),
            log,
            ("box.log", "laser 3"),
        )
    )
    out.append(
        Case(
            "cli",
            "out-is-a-file",
            ("run", "box.log", "--out", "file/out"),
            combine(log, write_bytes("file", b"x")),
            ("out:", "file"),
        )
    )
    bad_yaml = {
        "missing-resolution": map_yaml(resolution=""),
        "resolution-text": map_yaml(resolution="fast"),
        "resolution-zero": map_yaml(resolution="0"),
        "resolution-negative": map_yaml(resolution="-0.05"),
        "resolution-nan": map_yaml(resolution=".nan"),
        "resolution-inf": map_yaml(resolution=".inf"),
        "origin-short": map_yaml(origin="[0, 0]"),
        "origin-text": map_yaml(origin="[a, b, c]"),
        "origin-nan": map_yaml(origin="[.nan, 0, 0]"),
        "negate-half": map_yaml(negate="0.5"),  # nav2 reads 2 as yes, 0.5 not at all
        "occupied-1.5": map_yaml(occupied_thresh="1.5"),
        "free-above-occupied": map_yaml(free_thresh="0.7"),
        "mode-fancy": map_yaml() + "mode: fancy\n",
        "image-missing": map_yaml("missing.png"),
        "image-empty": map_yaml(image="''"),
        "not-a-mapping": "- 1\n- 2\n",
        "empty": "",
        "not-yaml": "image: [unclosed\n",
        "tabs": "image:\tmap.pgm\n\tresolution: 0.05\n",
    }
    for name, text in bad_yaml.items():
        out.append(map_case("cli", f"map-{name}", ("map.yaml",), text))
    bad_routes = {
        "no-map": "routes: []\n",
        "no-routes": "map: map.yaml\n",
        "start-in-wall": routes_yaml(
            routes="routes:\n  - start: [0.0, 0.0, 0.0]\n    waypoints: [[1, 1]]\n"
        ),
        "start-short": routes_yaml(routes="routes:\n  - start: [1.0]\n    waypoints: [[1, 1]]\n"),
        "unknown-field": routes_yaml() + "colour: red\n",
        "sim-negative": routes_yaml("simulation:\n  speed_mps: -1\n"),
        "rotations-zero": routes_yaml(symmetry="symmetry:\n  rotations: 0\n  centre: [2, 2]\n"),
        "waypoints-nan": routes_yaml(
            routes="routes:\n  - start: [1, 1, 0]\n    waypoints: [[.nan, 1]]\n"
        ),
    }
    for name, text in bad_routes.items():
        out.append(routes_case("cli", f"routes-{name}", ("routes.yaml",), text.encode()))
    return out


def accepted_cases() -> list[Case]:
    """Inputs that are odd but legitimate: they run (exit 0), with the warnings they deserve."""
    log = write_lines("box.log", box_log_lines(12))
    back = box_log_lines(12)
    back[6] = flaser(0.5, "0.1")  # 0.4 s back: jitter, kept
    run_map = ("run", "box.log", "--map", "map.yaml")
    specs: list[tuple[str, tuple[str, ...], Setup, tuple[str, ...], int]] = [
        (
            "yaml-12-float-and-unknown-key",
            run_map,
            combine(log, write_map(map_yaml(resolution="5e-2") + "comment: made by hand\n")),
            ("ignoring unknown key(s) 'comment'",),
            1,
        ),
        (
            "map-smaller-than-the-robot",
            run_map,
            combine(log, write_map(map_yaml(), b"P5\n1 1\n255\n\xfe")),
            ("smaller than the robot",),
            1,
        ),
        (
            "tiny-max-range",
            ("run", "box.log", "--max-range", "1e-300"),
            log,
            ("max range 1e-300 m", "smaller than the robot"),
            2,
        ),
        ("clock-jitter-kept", ("run", "jitter.log"), write_lines("jitter.log", back), (), 0),
        (
            "times-repaired-on-request",
            ("run", "times.log", "--repair-times"),
            write_lines("times.log", [*box_log_lines(6), flaser(0.6, "-130.6")]),
            (),
            0,
        ),
    ]
    return [
        Case("accepted", name, (*argv, "--out", "out", *QUIET_MCL), setup, frags, 0, warns)
        for name, argv, setup, frags, warns in specs
    ]


def all_cases() -> list[Case]:
    cases = (
        memory_cases()
        + stream_cases()
        + encoding_cases()
        + physical_cases()
        + cli_cases()
        + accepted_cases()
    )
    ids = [c.id for c in cases]
    assert len(ids) == len(set(ids)), "case ids must be unique"
    return cases
