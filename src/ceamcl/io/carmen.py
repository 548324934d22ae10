"""CARMEN log files (``.log``, ``.clf``; plain, gzip, bzip2 or xz), read line by line.

The format is that of CARMEN's logger and ``carmen/src/global/readlog.c``: one message per
line, the message name first, fields separated by white space. This module reads:

``FLASER n r_1 .. r_n x y theta odom_x odom_y odom_theta [timestamp [host [logger_timestamp]]]``
``RLASER ...`` (the same for the rear laser)
    Old-style laser messages. ``x y theta`` is the laser's pose in the world, ``odom_*`` the
    robot's. The geometry is not in the line; CARMEN guesses it from the beam count
    (``carmen_laser_guess_fov`` / ``carmen_laser_guess_angle_increment``): the first beam
    points to the right, at ``-pi/2``, and

    ====  ===============  ============
    n     field of view    increment
    ====  ===============  ============
    180   179 deg          1 deg
    181   180 deg          1 deg
    360   179.5 deg        0.5 deg
    361   180 deg          0.5 deg
    400   99.75 deg        0.25 deg
    401   100 deg          0.25 deg
    other 180 deg          fov / (n - 1)
    ====  ===============  ============

    CARMEN gives these messages a maximum range of 80 m; a ``PARAM robot_front_laser_max``
    (or ``robot_rear_laser_max``) line overrides it. The sensor reports "no return" with a
    reading at or beyond that maximum (81.91 m, 81.83 m in the Radish logs); such readings
    are kept as they are and a :class:`~ceamcl.sensors.scan.LaserScan` classifies them as
    max-range readings. Some lasers report no return *below* 80 m (ACES: 50.00 m) and their
    logs say nothing of it: without a PARAM, when the log's largest reading recurs as no
    real distance does (:func:`no_return_reading`), it is the maximum, and ``info``
    (``max_range_from``) says so.

``ROBOTLASER<id> type start_angle fov resolution max_range accuracy remission_mode n r_1..r_n
m e_1..e_m lx ly ltheta x y theta tv rv forward_safety side_safety turn_axis timestamp host
logger_timestamp``
    New-style laser message with explicit geometry: beam ``i`` at ``start_angle + i *
    resolution``, readings ``>= max_range`` are no-return. ``lx ly ltheta`` is the laser's
    pose in the world, ``x y theta`` the robot's.

``RAWLASER<id> type start_angle fov resolution max_range accuracy remission_mode n r_1..r_n
m e_1..e_m timestamp host logger_timestamp``
    The same without poses (the pose then comes from ``ODOM``, see :mod:`ceamcl.io.logs`).

``ODOM x y theta tv rv accel [timestamp [host [logger_timestamp]]]``, ``PARAM name value ...``
and ``#`` comment lines.

Every other message (``NEFF``, ``SYNC``, ``TRUEPOS``, ``SONAR``, ...) is skipped and counted.
Trailing fields after the timestamp (host, logger timestamp) are optional, so logs written
without host names read as well; nothing more may follow a laser message's fields (more
fields, or a logger timestamp that is not a number, mean the beam count does not agree with
the ranges given: the line would be read shifted). A malformed line raises
:class:`~ceamcl.errors.LogFormatError` naming the file, the line and what was expected.

Files are read as a stream (:func:`iter_carmen`): only the scans of the chosen laser and the
odometry are kept in memory, as arrays (:func:`read_carmen`). A line ends at LF, CR LF or a
lone CR (classic Mac OS); a UTF-8 byte order mark at the start of the file is skipped.
"""

from __future__ import annotations

import bz2
import gzip
import io
import lzma
import math
import os
import re
import zlib
from collections import Counter
from collections.abc import Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import IO, cast

import numpy as np
from numpy.typing import NDArray

from ceamcl import budget
from ceamcl.errors import ConfigError, LogFormatError
from ceamcl.io import streams
from ceamcl.io.odometry_sign import MOVE_M, check_sign, forward_steps, signed_poses
from ceamcl.io.recorded import RecordedLog, check_pose_values, poses_at_scans
from ceamcl.pose import relative_poses

__all__ = [
    "CARMEN_DEFAULT_MAX_RANGE_M",
    "CarmenComment",
    "CarmenLaser",
    "CarmenOdometry",
    "CarmenParam",
    "CarmenSkipped",
    "guess_angle_increment",
    "guess_fov",
    "iter_carmen",
    "no_return_reading",
    "read_carmen",
]

#: Memory a kept scan holds beyond its ranges (array header, time, geometry, poses, line).
SCAN_OVERHEAD_BYTES = 400

#: Memory a kept ODOM line holds (a tuple of five floats).
ODOM_BYTES = 200

#: The maximum range CARMEN assumes for old-style laser messages (readlog.c).
CARMEN_DEFAULT_MAX_RANGE_M = 80.0

_LASER_ID = {"FLASER": 1, "RLASER": 2}
_NUMBERED = re.compile(r"^(ROBOTLASER|RAWLASER)(\d+)$")


# ------------------------------------------------------------------------------ messages
@dataclass(frozen=True, eq=False)
class CarmenLaser:
    """One laser message. ``laser_pose``/``robot_pose`` are world poses (``None`` for RAWLASER).

    ``max_range`` is ``nan`` for old-style messages (CARMEN's default or a PARAM applies,
    decided by :func:`read_carmen`).
    """

    kind: str
    laser_id: int
    ranges: NDArray[np.float64]
    start_angle: float
    fov: float
    angle_increment: float
    max_range: float
    laser_pose: tuple[float, float, float] | None
    robot_pose: tuple[float, float, float] | None
    timestamp: float
    line: int


@dataclass(frozen=True)
class CarmenOdometry:
    x: float
    y: float
    theta: float
    tv: float
    rv: float
    accel: float
    timestamp: float
    line: int


@dataclass(frozen=True)
class CarmenParam:
    name: str
    value: str
    line: int


@dataclass(frozen=True)
class CarmenComment:
    text: str
    line: int


@dataclass(frozen=True)
class CarmenSkipped:
    """A message this reader does not use (its name only)."""

    kind: str
    line: int


CarmenMessage = CarmenLaser | CarmenOdometry | CarmenParam | CarmenComment | CarmenSkipped


# ------------------------------------------------------------------------------ geometry
def guess_fov(n_beams: int) -> float:
    """Field of view (rad) CARMEN assumes for an old-style scan of ``n_beams`` readings."""
    deg = {181: 180.0, 180: 179.0, 361: 180.0, 360: 179.5, 401: 100.0, 400: 99.75}
    return math.radians(deg.get(n_beams, 180.0))


def guess_angle_increment(n_beams: int) -> float:
    """Angle (rad) between beams CARMEN assumes for an old-style scan of ``n_beams`` readings."""
    if n_beams in (180, 181):
        return math.pi / 180.0
    if n_beams in (360, 361):
        return math.pi / 360.0
    if n_beams in (400, 401):
        return math.pi / 720.0
    return guess_fov(n_beams) / (n_beams - 1) if n_beams > 1 else 0.0


# ------------------------------------------------------------------------------ parsing
class _Line:
    """Tokens of one line with a cursor; every read names the field on failure."""

    def __init__(self, path: str, lineno: int, kind: str, tokens: list[str]) -> None:
        self.path, self.lineno, self.kind, self.tokens, self.pos = path, lineno, kind, tokens, 1

    def error(self, what: str) -> LogFormatError:
        return LogFormatError(f"{self.path}:{self.lineno}: {self.kind}: {what}")

    def _take(self, count: int, what: str) -> list[str]:
        end = self.pos + count
        if end > len(self.tokens):
            got = len(self.tokens) - self.pos
            raise self.error(f"expected {what} ({count} value(s)), the line ends after {got}")
        out = self.tokens[self.pos : end]
        self.pos = end
        return out

    def number(self, what: str) -> float:
        tok = self._take(1, what)[0]
        try:
            return float(tok)
        except ValueError:
            raise self.error(f"{what}: expected a number, got {tok!r}") from None

    def count(self, what: str) -> int:
        tok = self._take(1, what)[0]
        try:
            value = int(tok)
        except ValueError:
            try:
                f = float(tok)
            except ValueError:
                f = math.nan
            if not f.is_integer():
                raise self.error(f"{what}: expected a whole number, got {tok!r}") from None
            value = int(f)
        if value < 0:
            raise self.error(f"{what}: expected a non-negative count, got {value}")
        return value

    def numbers(self, count: int, what: str) -> NDArray[np.float64]:
        toks = self._take(count, what)
        try:
            return np.array([float(t) for t in toks], dtype=np.float64)
        except ValueError:
            bad = next(t for t in toks if not _is_number(t))
            raise self.error(f"{what}: expected numbers, got {bad!r}") from None

    def pose(self, what: str) -> tuple[float, float, float]:
        v = self.numbers(3, what)
        check_pose_values(v, what, self.error)
        return float(v[0]), float(v[1]), float(v[2])

    def finite(self, what: str) -> float:
        value = self.number(what)
        if not math.isfinite(value):
            raise self.error(f"{what}: expected a finite number, got {value}")
        return value

    def timestamp(self) -> float:
        """The IPC timestamp if the line has one (host and logger time may follow)."""
        if self.pos >= len(self.tokens):
            return math.nan
        value = self.number("timestamp")
        if not math.isfinite(value):
            raise self.error(f"timestamp: expected a finite number of seconds, got {value}")
        return value

    def laser_end(self, n: int, fields: str) -> float:
        """The timestamp of a laser line whose ``fields`` (the ``n`` ranges and what follows
        them) end at the cursor. Only ``[timestamp [host [logger_timestamp]]]`` may follow: a
        beam count that does not agree with the ranges given shifts every later field, and a
        line read so would be wrong silently (the 180th range taken for the laser's x)."""
        rest = self.tokens[self.pos :]
        layout = f"expected {fields}, then [timestamp [host [logger_timestamp]]]"
        if len(rest) > 3:
            raise self.error(
                f"the beam count {n} and the fields do not agree: {len(rest)} fields follow "
                f"where at most 3 may ({layout})"
            )
        if len(rest) == 3 and not _is_number(rest[2]):
            raise self.error(
                f"the beam count {n} and the fields do not agree: the logger timestamp is "
                f"{rest[2]!r}, not a number ({layout})"
            )
        if rest and not _is_number(rest[0]):
            raise self.error(
                f"timestamp: expected a number, got {rest[0]!r} (does the beam count {n} agree "
                f"with the fields? {layout})"
            )
        return self.timestamp()


def _is_number(tok: str) -> bool:
    try:
        float(tok)
    except ValueError:
        return False
    return True


def _parse_old_laser(ln: _Line) -> CarmenLaser:
    n = ln.count("beam count")
    ranges = ln.numbers(n, f"{n} ranges")
    laser_pose = ln.pose("laser pose x y theta")
    robot_pose = ln.pose("robot pose odom_x odom_y odom_theta")
    ts = ln.laser_end(n, f"{n} ranges, 6 pose values")
    return CarmenLaser(
        kind=ln.kind,
        laser_id=_LASER_ID[ln.kind],
        ranges=ranges,
        start_angle=-math.pi / 2.0,
        fov=guess_fov(n),
        angle_increment=guess_angle_increment(n),
        max_range=math.nan,
        laser_pose=laser_pose,
        robot_pose=robot_pose,
        timestamp=ts,
        line=ln.lineno,
    )


def _parse_new_laser(ln: _Line, kind: str, laser_id: int) -> CarmenLaser:
    ln.count("laser type")
    start = ln.finite("start_angle")
    fov = ln.finite("fov")
    res = ln.finite("angular_resolution")
    max_range = ln.number("maximum_range")
    ln.number("accuracy")
    ln.count("remission_mode")
    n = ln.count("beam count")
    ranges = ln.numbers(n, f"{n} ranges")
    m = ln.count("remission count")
    ln.numbers(m, f"{m} remissions")
    laser_pose = robot_pose = None
    fields = f"{n} ranges, remission count {m}, {m} remissions"
    if kind == "ROBOTLASER":
        laser_pose = ln.pose("laser pose x y theta")
        robot_pose = ln.pose("robot pose x y theta")
        ln.numbers(5, "tv rv forward_safety_dist side_safety_dist turn_axis")
        fields += ", 6 pose values, tv rv forward_safety_dist side_safety_dist turn_axis"
    ts = ln.laser_end(n, fields)
    if not (math.isfinite(max_range) and max_range > 0):
        raise ln.error(f"maximum_range: expected a positive number, got {max_range}")
    return CarmenLaser(
        kind=f"{kind}{laser_id}",
        laser_id=laser_id,
        ranges=ranges,
        start_angle=start,
        fov=fov,
        angle_increment=res,
        max_range=max_range,
        laser_pose=laser_pose,
        robot_pose=robot_pose,
        timestamp=ts,
        line=ln.lineno,
    )


def _parse_odom(ln: _Line) -> CarmenOdometry:
    v = ln.numbers(6, "x y theta tv rv accel")
    check_pose_values(v, "x y theta", ln.error)
    if not np.isfinite(v[3]):
        raise ln.error(f"tv: expected a finite number, got {v[3]}")
    x, y, theta, tv, rv, accel = (float(a) for a in v)
    return CarmenOdometry(x, y, theta, tv, rv, accel, timestamp=ln.timestamp(), line=ln.lineno)


def parse_line(text: str, path: str = "<string>", lineno: int = 1) -> CarmenMessage | None:
    """One line of a CARMEN log; ``None`` for a blank line."""
    stripped = text.strip()
    if not stripped:
        return None
    if stripped.startswith("#"):
        return CarmenComment(stripped[1:].strip(), lineno)
    tokens = stripped.split()
    kind = tokens[0]
    ln = _Line(path, lineno, kind, tokens)
    if kind in _LASER_ID:
        return _parse_old_laser(ln)
    if kind == "ODOM":
        return _parse_odom(ln)
    if kind == "PARAM":
        if len(tokens) < 3:
            raise ln.error("expected a parameter name and a value")
        return CarmenParam(tokens[1], tokens[2], lineno)
    numbered = _NUMBERED.match(kind)
    if numbered:
        return _parse_new_laser(ln, numbered.group(1), int(numbered.group(2)))
    return CarmenSkipped(kind, lineno)


_BZIP2 = re.compile(rb"BZh[1-9](1AY&SY|\x17rE8P\x90)")

#: Errors of a damaged or truncated compressed stream: gzip's, xz's, and bzip2's, which says
#: "Invalid data stream" with a bare ``OSError`` (as a failing disk under a plain log would).
_DAMAGED = (EOFError, OSError, zlib.error, lzma.LZMAError)


def _open_binary(path: Path) -> io.BufferedIOBase:
    """A binary stream over the file (or pipe), decompressed on the fly when it starts with
    the magic of gzip, bzip2 or xz (logs are published as ``.gz`` and ``.bz2``; a ``.bz2``
    was refused as binary data, and the README had users pipe it through ``bzcat``). The
    magic is sniffed from a kept buffer, so a pipe loses nothing. A text log cannot start
    with any of them: bzip2's is ``BZh``, a block size digit and the block magic ``1AY&SY``
    (or the empty stream's ``\x17rE8P\x90``)."""
    try:
        magic = streams.sniff(path, 10, "CARMEN log")
        raw = streams.open_input(path, "CARMEN log")
    except FileNotFoundError:
        raise LogFormatError(f"{path}: log file not found") from None
    except OSError as exc:
        raise LogFormatError(f"{path}: cannot read the log: {exc.strerror or exc}") from None
    if magic.startswith(b"\x1f\x8b"):
        return gzip.GzipFile(fileobj=raw, mode="rb")
    if _BZIP2.match(magic):
        return bz2.BZ2File(raw, mode="rb")
    if magic.startswith(b"\xfd7zXZ\x00"):
        return lzma.LZMAFile(cast(IO[bytes], raw), mode="rb")
    return raw


#: Bytes read from the file at a time while splitting it into lines.
_CHUNK_BYTES = 1 << 16
_BOM = b"\xef\xbb\xbf"


def _raw_lines(path: Path, fh: io.BufferedIOBase, limit: int) -> Iterator[bytes]:
    """The file's lines without their line ends, split at CR LF (Windows), LF (Unix) and a
    lone CR (classic Mac OS) alike, each at most ``limit`` bytes. Read in chunks of what the
    stream has (``read1``), so a pipe's line is handed on as soon as it is complete."""
    parts: list[bytes] = []  # the pieces of a line not ended yet
    size = 0  # their length
    lineno = 0
    cr_last = False  # the last chunk ended with a CR: a LF first in the next one is its pair
    while True:
        chunk = fh.read1(_CHUNK_BYTES)
        if not chunk:
            break
        if cr_last and chunk[:1] == b"\n":
            chunk = chunk[1:]
        cr_last = chunk[-1:] == b"\r"
        for piece in chunk.splitlines(keepends=True):  # bytes split at CR LF, LF, CR only
            ended = piece[-1:] in (b"\n", b"\r")
            body = piece.rstrip(b"\r\n") if ended else piece
            size += len(body)
            if size > limit:
                raise _long_line(path, lineno + 1, limit)
            if not ended:  # the last piece of the chunk: the line goes on in the next
                parts.append(body)
                continue
            lineno += 1
            yield b"".join((*parts, body)) if parts else body
            parts, size = [], 0
    if parts:
        yield b"".join(parts)


def _long_line(path: Path, lineno: int, limit: int) -> budget.BudgetError:
    return budget.BudgetError(
        f"{path}:{lineno}: line longer than {budget.format_bytes(limit)}, the line-length "
        "bound of the memory budget (raise it with --memory-budget)"
    )


def _lines(path: Path, fh: io.BufferedIOBase) -> Iterator[tuple[int, str]]:
    """Numbered text lines, each at most the budget's line length, UTF-8 (ASCII in practice),
    without a UTF-8 byte order mark at the start of the file."""
    limit = budget.current().line_bytes
    for lineno, raw in enumerate(_raw_lines(path, fh, limit), start=1):
        if lineno == 1 and raw.startswith(_BOM):
            raw = raw[len(_BOM) :]  # as Windows editors save "UTF-8" text
        if b"\x00" in raw:
            raise LogFormatError(
                f"{path}:{lineno}: binary data (NUL bytes); expected a CARMEN text log"
            )
        try:
            yield lineno, raw.decode("utf-8")
        except UnicodeDecodeError as exc:
            raise LogFormatError(
                f"{path}:{lineno}: not UTF-8/ASCII text (byte {raw[exc.start]:#04x} at column "
                f"{exc.start + 1}); expected a CARMEN text log"
            ) from None


def iter_carmen(path: str | os.PathLike[str]) -> Iterator[CarmenMessage]:
    """Every message of a CARMEN log, in file order, read as a stream (plain text, or gzip,
    bzip2 or xz)."""
    p = Path(path)
    lineno = 0
    with _open_binary(p) as fh:
        try:
            for lineno, text in _lines(p, fh):
                msg = parse_line(text, str(p), lineno)
                if msg is not None:
                    yield msg
        except _DAMAGED as exc:
            compressed = isinstance(fh, (gzip.GzipFile, bz2.BZ2File, lzma.LZMAFile))
            what = "the compressed file is damaged or truncated" if compressed else "cannot read it"
            raise LogFormatError(f"{p}:{lineno + 1}: {what} ({exc})") from None


# ------------------------------------------------------------------------------ whole log
@dataclass
class _Stream:
    """Scans of one laser collected from the log."""

    times: list[float] = field(default_factory=list)
    ranges: list[NDArray[np.float64]] = field(default_factory=list)
    start: list[float] = field(default_factory=list)
    inc: list[float] = field(default_factory=list)
    max_range: list[float] = field(default_factory=list)
    laser_pose: list[tuple[float, float, float]] = field(default_factory=list)
    robot_pose: list[tuple[float, float, float]] = field(default_factory=list)
    lines: list[int] = field(default_factory=list)
    bytes_held: int = 0

    def add(self, m: CarmenLaser, path: Path) -> None:
        # a few MB of gzip can expand to gigabytes of scans: keep them within the budget
        self.bytes_held += 8 * m.ranges.size + SCAN_OVERHEAD_BYTES
        if self.bytes_held > budget.current().memory_bytes:
            budget.require(
                f"{path}:{m.line}: scans kept",
                len(self.times) + 1,
                self.bytes_held / (len(self.times) + 1),
                "scans",
            )
        self.times.append(m.timestamp)
        self.lines.append(m.line)
        self.ranges.append(m.ranges)
        self.start.append(m.start_angle)
        self.inc.append(m.angle_increment)
        self.max_range.append(m.max_range)
        if m.laser_pose is not None and m.robot_pose is not None:
            self.laser_pose.append(m.laser_pose)
            self.robot_pose.append(m.robot_pose)

    def __len__(self) -> int:
        return len(self.times)


def read_carmen(
    path: str | os.PathLike[str],
    *,
    laser: int = 1,
    max_range_m: float | None = None,
    odometry_sign: str = "auto",
) -> RecordedLog:
    """The scans of one laser of a CARMEN log with the robot's pose at each scan.

    Args:
        path: the log (plain, or compressed with gzip, bzip2 or xz).
        laser: 1 = front (``FLASER``, ``ROBOTLASER1``, ``RAWLASER1``), 2 = rear (``RLASER``,
            ``ROBOTLASER2``, ...), 3 and 4 the numbered lasers.
        max_range_m: the sensor's maximum; readings at or beyond it mean no return. Default:
            the message's own field (ROBOTLASER/RAWLASER), else ``PARAM
            robot_front_laser_max``/``robot_rear_laser_max``, else CARMEN's 80 m.
        odometry_sign: ``"auto"``: when the ``ODOM`` lines' velocity shows that the odometry
            lost its sign (its poses keep moving forward while the robot backs up), each
            increment between scans takes the velocity's sign (:mod:`ceamcl.io.odometry_sign`;
            ``info["odometry_sign"]`` says so); ``"recorded"``: the poses as recorded.

    Messages with poses (FLASER/RLASER/ROBOTLASER) are used when the log has them; a log with
    only RAWLASER messages takes the robot's pose from ODOM, interpolated at each scan's time
    (scans and ODOM lines need timestamps then, and times that overlap:
    :func:`~ceamcl.io.recorded.poses_at_scans`).
    The robot's pose at a scan is the message's robot (odometry) pose; the laser's mounting
    pose on the robot is the difference of the two poses the message holds.

    ``info`` of the result holds the message counts, the skipped message names and the
    parameters.
    """
    p = Path(path)
    if odometry_sign not in ("auto", "recorded"):
        raise ConfigError(f"odometry-sign: expected auto or recorded, got {odometry_sign!r}")
    with_pose, raw = _Stream(), _Stream()
    odom: list[tuple[float, float, float, float, float]] = []
    untimed_odom: int | None = None  # the line of the first ODOM without a timestamp
    counts: Counter[str] = Counter()
    skipped: Counter[str] = Counter()
    params: dict[str, str] = {}
    param_lines: dict[str, int] = {}
    for msg in iter_carmen(p):
        if isinstance(msg, CarmenLaser):
            counts[msg.kind] += 1
            if msg.laser_id == laser:
                (with_pose if msg.laser_pose is not None else raw).add(msg, p)
        elif isinstance(msg, CarmenOdometry):
            counts["ODOM"] += 1
            held = ODOM_BYTES * (len(odom) + 1) + with_pose.bytes_held + raw.bytes_held
            if held > budget.current().memory_bytes:  # ODOM lines are kept too
                budget.require(f"{p}:{msg.line}: odometry kept", len(odom) + 1, ODOM_BYTES, "ODOM")
            odom.append((msg.timestamp, msg.x, msg.y, msg.theta, msg.tv))
            if math.isnan(msg.timestamp) and untimed_odom is None:
                untimed_odom = msg.line
        elif isinstance(msg, CarmenParam):
            counts["PARAM"] += 1
            params[msg.name] = msg.value
            param_lines[msg.name] = msg.line
        elif isinstance(msg, CarmenComment):
            counts["#"] += 1
        else:
            skipped[msg.kind] += 1

    stream = with_pose if len(with_pose) else raw
    if not len(stream):
        found = ", ".join(f"{k} x{v}" for k, v in sorted(counts.items()))
        if skipped:
            other = ", ".join(f"{k[:20]!r}" for k, _ in skipped.most_common(3))
            n_other = sum(skipped.values())
            found += f"{', ' if found else ''}{n_other} lines of other kinds (such as {other})"
        found = found or "nothing"
        raise LogFormatError(
            f"{p}: no scan of laser {laser} (FLASER/RLASER/ROBOTLASER{laser}/RAWLASER{laser}); "
            f"the log holds: {found}"
        )
    n = len(stream)
    times = np.asarray(stream.times, dtype=np.float64)
    untimed = np.isnan(times)
    timed = not untimed.any()
    if not timed and not untimed.all():
        # numbering only some scans would mix their indices with the others' seconds
        k = int(np.argmax(untimed))
        raise LogFormatError(
            f"{p}:{stream.lines[k]}: {len(untimed) - int(untimed.sum())} scans of laser {laser} "
            f"have a timestamp and {int(untimed.sum())} none, this one the first: expected a "
            "timestamp after the robot pose on every scan line, or on none"
        )
    o = np.asarray(odom, dtype=np.float64).reshape(-1, 5)
    # odometry that lost its sign (ceamcl.io.odometry_sign), told by the ODOM lines' velocity
    sign = check_sign(o[:, 0], o[:, 1:4], o[:, 4]) if timed and odometry_sign == "auto" else None
    unsigned = sign is not None and sign.unsigned
    if not timed:
        # No scan line has a timestamp: number the scans instead.
        times = np.where(np.isnan(times), np.arange(n, dtype=np.float64), times)

    reversed_increments = 0
    if stream is with_pose:
        robot = np.asarray(stream.robot_pose, dtype=np.float64)
        laser_world = np.asarray(stream.laser_pose, dtype=np.float64)
        mount = relative_poses(robot, laser_world)
        if unsigned:
            robot, reversed_increments = signed_poses(times, robot, o[:, 0], o[:, 4])
    else:
        if not odom:
            raise LogFormatError(
                f"{p}: RAWLASER{laser} scans carry no pose and the log has no ODOM line"
            )
        # the pose at a scan is the odometry's at the scan's time: both need a clock
        if not timed:
            raise LogFormatError(
                f"{p}:{stream.lines[0]}: RAWLASER{laser} scan without a timestamp: RAWLASER "
                "scans carry no pose and take the robot's from ODOM at their time; expected "
                "timestamp host logger_timestamp after the remissions"
            )
        if untimed_odom is not None:
            raise LogFormatError(
                f"{p}:{untimed_odom}: ODOM line without a timestamp: the RAWLASER{laser} "
                "scans take the robot's pose from ODOM at their time; expected a timestamp "
                "after x y theta tv rv accel on every ODOM line"
            )
        odom_poses = o[:, 1:4]
        if unsigned:
            odom_poses, _ = signed_poses(o[:, 0], odom_poses, o[:, 0], o[:, 4])
        lines = f"lines {stream.lines[0]}-{stream.lines[-1]}"
        robot = poses_at_scans(
            o[:, 0],
            odom_poses,
            times,
            scans=f"the RAWLASER{laser} scans ({lines})",
            odometry=f"the {len(odom)} ODOM lines",
            error=lambda what: LogFormatError(f"{p}: {what}"),
        )
        if unsigned:
            reversed_increments = int(np.count_nonzero(forward_steps(robot) < -MOVE_M))
        mount = np.zeros((n, 3))

    per_msg = np.asarray(stream.max_range, dtype=np.float64)
    max_range_from = ""
    if max_range_m is not None:
        range_max = np.full(n, float(max_range_m))
    elif np.isnan(per_msg).any():  # old-style messages: the PARAM (checked only when used)
        default_max = _param_max_range(params, param_lines, laser, p)
        old_style = np.isnan(per_msg)
        if _param_key(laser) not in params:
            sentinel = no_return_reading(
                [r for r, old in zip(stream.ranges, old_style, strict=True) if old],
                below=default_max,
            )
            if sentinel is not None:
                default_max, times_seen = sentinel
                max_range_from = (
                    f"{times_seen} readings of exactly {default_max:g} m, the log's largest, "
                    "taken as the laser's no-return value (--max-range sets another)"
                )
        range_max = np.where(old_style, default_max, per_msg)
    else:
        range_max = per_msg

    lengths = np.array([r.size for r in stream.ranges], dtype=np.intp)
    offsets = np.concatenate([[0], np.cumsum(lengths)]).astype(np.intp)
    info = {
        "format": "carmen",
        "laser": laser,
        "scan_messages": sorted({k for k in counts if k not in ("ODOM", "PARAM", "#")}),
        "message_counts": dict(sorted(counts.items())),
        "skipped_messages": dict(sorted(skipped.items())),
        "poses_from": "laser messages" if stream is with_pose else "ODOM (interpolated)",
        "params": params,
        "scan_lines": np.asarray(stream.lines, dtype=np.int64),  # for errors naming the line
    }
    if max_range_from:
        info["max_range_from"] = max_range_from
    if unsigned:
        assert sign is not None
        info["odometry_sign"] = (
            f"{sign.summary()}; {reversed_increments} of {max(n - 1, 0)} increments between "
            "scans now go backwards"
        )
    return RecordedLog(
        path=str(p),
        times=times,
        poses=robot,
        ranges_flat=np.concatenate(stream.ranges) if n else np.zeros(0),
        offsets=offsets,
        angle_min=np.asarray(stream.start, dtype=np.float64),
        angle_increment=np.asarray(stream.inc, dtype=np.float64),
        range_min=np.zeros(n),
        range_max=range_max,
        laser_mount=mount,
        info=info,
    )


#: A log's largest reading is its laser's no-return value when it occurs at least this many
#: times ...
NO_RETURN_MIN_COUNT = 100
#: ... and this many times as often as any other reading within ``NO_RETURN_BAND_M`` below it
#: (ACES: 11,139 readings of 50.00 m, at most 3 of any value in the metre below; the Radish
#: logs' 81.83 and 81.91 m likewise).
NO_RETURN_RATIO = 20
NO_RETURN_BAND_M = 1.0
#: ... among a laser's measurements: at least this many distinct readings below it (a log
#: of one repeated value says nothing about which value means "no return").
NO_RETURN_MIN_DISTINCT = 100


def no_return_reading(
    ranges: list[NDArray[np.float64]], below: float = math.inf
) -> tuple[float, int] | None:
    """The value a laser writes for "no return", found in its readings: the largest finite
    reading, when it lies below ``below`` (a maximum that already makes it no-return) and
    recurs (:data:`NO_RETURN_MIN_COUNT`, :data:`NO_RETURN_RATIO`) as a measured distance does
    not, among many measured distances (:data:`NO_RETURN_MIN_DISTINCT`); with its count.
    ``None``: no such value."""
    if not ranges:
        return None
    r = np.concatenate(ranges)
    r = r[np.isfinite(r) & (r > 0.0)]
    if r.size == 0:
        return None
    top = float(r.max())
    count = int(np.count_nonzero(r == top))
    if top >= below or count < NO_RETURN_MIN_COUNT:
        return None
    rest = r[r < top]
    if np.unique(rest).size < NO_RETURN_MIN_DISTINCT:
        return None
    near = rest[rest >= top - NO_RETURN_BAND_M]
    if near.size:
        _, counts = np.unique(near, return_counts=True)
        if count < NO_RETURN_RATIO * int(counts.max()):
            return None
    return top, count


def _param_key(laser: int) -> str | None:
    return {1: "robot_front_laser_max", 2: "robot_rear_laser_max"}.get(laser)


def _param_max_range(
    params: dict[str, str], lines: dict[str, int], laser: int, path: Path
) -> float:
    """The old-style lasers' maximum range: ``PARAM robot_front_laser_max`` (or ``_rear_``)
    if the log sets it, else CARMEN's 80 m. A value that is not a positive finite number is
    an error naming its line (``-1`` or ``nan`` fell back to 80 m, ``inf`` failed later
    naming no file)."""
    key = _param_key(laser)
    if key is None or key not in params:
        return CARMEN_DEFAULT_MAX_RANGE_M
    try:
        value = float(params[key])
    except ValueError:
        value = math.nan
    if not (math.isfinite(value) and value > 0):
        raise LogFormatError(
            f"{path}:{lines[key]}: PARAM {key}: expected a positive finite number of metres, "
            f"got {params[key]!r} (--max-range sets the maximum instead)"
        )
    return value
