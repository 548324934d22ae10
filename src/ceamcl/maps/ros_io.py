"""Read and write maps in the ROS ``map_server`` format (a YAML file plus an image).

This implements the map file format of ROS 1 ``map_server`` and ROS 2 ``nav2_map_server``:

* :func:`load_map` reads a map YAML file and its image into an
  :class:`~ceamcl.maps.grid.OccupancyGrid`, with the pixel semantics of
  ``nav2_map_server/src/map_io.cpp`` (``loadMapFromFile``);
* :func:`save_map` writes a grid the way ``map_saver`` does in ``trinary`` mode (free 254,
  occupied 0, unknown 205) together with a YAML file that loads the grid back unchanged.

YAML keys (all required except ``mode``; any other key is an error):

``image``
    Image file name, relative to the YAML file's folder unless absolute.
``resolution``
    Cell side in metres, a finite number > 0.
``origin``
    ``[x, y, yaw]``: pose of the lower-left corner of the image (cell (0, 0)) in the world,
    within the bounds of log poses (``|x|, |y| <= 10^7 m``, ``|yaw| <= 10^6 rad``).
``negate``
    An integer, nonzero meaning yes (as nav2's ``loadMapYaml`` reads it, ``as<int>``), or
    ``false``/``true`` (also ``no``/``yes``, ``off``/``on``): if set, white means occupied and
    black free.
``occupied_thresh``, ``free_thresh``
    Numbers in [0, 1] with ``free_thresh < occupied_thresh``.
``mode``
    ``trinary`` (default), ``scale`` or ``raw`` (case-insensitive, as nav2).

Numbers are read as yaml-cpp reads them for Nav2: a quoted scalar whose text is a number
(``resolution: "0.05"``) is that number, since yaml-cpp converts a scalar's text whatever its
quoting.

Pixel to cell value, for a pixel with colour channels averaged to a brightness
``shade`` in [0, 1] and ``p = 1 - shade`` (``p = shade`` when ``negate``):

``trinary``
    ``p > occupied_thresh`` -> 100, ``p < free_thresh`` -> 0, otherwise -1. As in both ROS 1 and
    nav2, when the image has an alpha channel the alpha (255 = opaque) is averaged in with R, G
    and B to form ``shade``; an opaque image is therefore read a little lighter than its colour.
``scale``
    A pixel that is not fully opaque is unknown (-1), as nav2 does (any alpha < 255, not only
    fully transparent pixels); otherwise ``p > occupied_thresh`` -> 100, ``p < free_thresh``
    -> 0, and in between ``rint(100 * (p - free) / (occ - free))`` (nav2's formula; ROS 1 used
    ``1 + 98 * ratio``). Alpha is not averaged in.
``raw``
    The cell is ``round(255 * shade)`` if that lies in [0, 100], else -1. As in nav2, ``negate``
    is ignored in this mode and alpha is not averaged in.

Image row 0 is the top of the map (largest y); the grid's row 0 is its bottom, so images are
flipped vertically on load and save.

Accepted images (anything Pillow reads, e.g. PGM/PPM/PBM, PNG, BMP): 8-bit greyscale ``L``,
``LA``, ``RGB``, ``RGBA`` and palette ``P``/``PA`` images, bilevel ``1`` images, and images with a
``tRNS`` transparent colour (which then have an alpha channel, as in GraphicsMagick). 16-bit
greyscale images (Pillow modes ``I;16``, ``I;16B``, ``I;16L`` and ``I`` with values in
[0, 65535], e.g. a PGM with maxval > 255) are accepted and scaled to [0, 1] by their full
16-bit range, which is what nav2 does through GraphicsMagick's quantum scaling; note that
Pillow reduces 16-bit colour PNGs to 8 bits per channel. Other modes (CMYK, YCbCr, 32-bit
float, ...) are refused with a :class:`~ceamcl.errors.MapFormatError` naming the mode.

Saving writes ``free_thresh: 0.196`` (the ROS 1 ``map_saver`` value), not nav2's default 0.25:
with 0.25 the unknown grey 205 (``p = 50/255 = 0.196...``) would load back as free. Cells are
classified with the grid's own masks (free 0..19, occupied >= 65, anything else unknown).

Every problem with the input raises :class:`~ceamcl.errors.MapFormatError` whose message names
the file, the YAML key or the image problem, and what was expected.
"""

from __future__ import annotations

import math
import os
import re
import secrets
import stat
import threading
import warnings
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import yaml
from numpy.typing import NDArray
from PIL import Image

from ceamcl import budget
from ceamcl.errors import InputWarning, MapFormatError
from ceamcl.io.safe_yaml import load_yaml_file
from ceamcl.maps.grid import OccupancyGrid
from ceamcl.pose import HEADING_LIMIT_RAD, POSE_LIMIT_M

__all__ = ["load_map", "save_map"]

REQUIRED_KEYS: tuple[str, ...] = (
    "image",
    "resolution",
    "origin",
    "negate",
    "occupied_thresh",
    "free_thresh",
)
OPTIONAL_KEYS: tuple[str, ...] = ("mode",)
MODES: tuple[str, ...] = ("trinary", "scale", "raw")
IMAGE_FORMATS: dict[str, str] = {"pgm": "PPM", "png": "PNG"}

# Pixel values written by map_saver in trinary mode.
SAVE_FREE = 254
SAVE_OCCUPIED = 0
SAVE_UNKNOWN = 205
SAVE_OCCUPIED_THRESH = 0.65
SAVE_FREE_THRESH = 0.196


@dataclass(frozen=True)
class _MapMeta:
    image: Path
    resolution: float
    origin: tuple[float, float, float]
    negate: bool
    occupied_thresh: float
    free_thresh: float
    mode: str


# ---------------------------------------------------------------------------------- loading
def load_map(yaml_path: str | os.PathLike[str]) -> OccupancyGrid:
    """Load a ROS ``map_server`` map (YAML file plus image) as an occupancy grid.

    Args:
        yaml_path: the map's YAML file. The image path inside it is taken relative to the
            folder of this file unless it is absolute.

    Returns:
        The grid, named after the YAML file's stem.

    Raises:
        MapFormatError: the YAML file or the image is missing, unreadable or malformed.
    """
    path = Path(yaml_path)
    meta = _read_meta(path)
    shade_rgb, alpha = _read_image(meta.image, path)
    data = _pixels_to_cells(shade_rgb, alpha, meta)
    return OccupancyGrid(np.flipud(data), meta.resolution, meta.origin, name=path.stem)


def _read_meta(path: Path) -> _MapMeta:
    doc = load_yaml_file(path, "map YAML file", MapFormatError)
    expected = ", ".join(REQUIRED_KEYS + OPTIONAL_KEYS)
    if not isinstance(doc, dict):
        got = "an empty file" if doc is None else f"a {type(doc).__name__}"
        raise MapFormatError(
            f"{path}: expected a YAML mapping with keys {expected} at the top level, got {got}"
        )
    unknown = [k for k in doc if k not in REQUIRED_KEYS + OPTIONAL_KEYS]
    if unknown:  # map_server ignores keys it does not know: so do we, saying so
        names = ", ".join(repr(k) for k in unknown)
        warnings.warn(
            f"{path}: ignoring unknown key(s) {names}; known keys: {expected}",
            InputWarning,
            stacklevel=2,
        )
    missing = [k for k in REQUIRED_KEYS if k not in doc]
    if missing:
        names = ", ".join(repr(k) for k in missing)
        raise MapFormatError(f"{path}: missing required key(s) {names}; expected keys: {expected}")

    def fail(key: str, what: str) -> MapFormatError:
        return MapFormatError(f"{path}: key {key!r}: expected {what}, got {doc[key]!r}")

    image = doc["image"]
    if not isinstance(image, str) or not image.strip():
        raise fail("image", "a non-empty image file name")
    image_path = Path(image)
    if not image_path.is_absolute():
        image_path = path.parent / image_path

    resolution = _number(doc["resolution"])
    if resolution is None or not math.isfinite(resolution) or resolution <= 0:
        raise fail("resolution", "a finite number > 0 (metres per cell)")

    origin_raw = doc["origin"]
    origin_vals = [_number(v) for v in origin_raw] if isinstance(origin_raw, list | tuple) else []
    if len(origin_vals) != 3 or any(v is None or not math.isfinite(v) for v in origin_vals):
        raise fail("origin", "a list of three finite numbers [x, y, yaw]")
    ox, oy, oyaw = (float(v or 0.0) for v in origin_vals)
    if max(abs(ox), abs(oy)) > POSE_LIMIT_M or abs(oyaw) > HEADING_LIMIT_RAD:
        # as log poses: beyond, the cells' centres lose their precision (an origin of 1e17 m
        # put every pose at 99999999999999984.0) and the plots their axes
        raise fail(
            "origin",
            f"[x, y, yaw] with |x|, |y| <= {POSE_LIMIT_M:g} m and |yaw| <= "
            f"{HEADING_LIMIT_RAD:g} rad (the bounds of log poses)",
        )

    negate = _negate(doc["negate"])
    if negate is None:
        raise fail(
            "negate",
            "an integer (0: no, any other: yes, as Nav2 reads it) or true/false, yes/no, on/off",
        )

    thresholds: dict[str, float] = {}
    for key in ("occupied_thresh", "free_thresh"):
        value = _number(doc[key])
        if value is None or not 0.0 <= value <= 1.0:
            raise fail(key, "a number in [0, 1]")
        thresholds[key] = value
    if not thresholds["free_thresh"] < thresholds["occupied_thresh"]:
        raise MapFormatError(
            f"{path}: key 'free_thresh': expected a value smaller than 'occupied_thresh' "
            f"({thresholds['occupied_thresh']!r}), got {thresholds['free_thresh']!r}"
        )

    mode_raw = doc.get("mode", "trinary")
    if not isinstance(mode_raw, str) or mode_raw.lower() not in MODES:
        raise MapFormatError(
            f"{path}: key 'mode': expected one of {', '.join(MODES)}, got {mode_raw!r}"
        )

    return _MapMeta(
        image=image_path,
        resolution=resolution,
        origin=(ox, oy, oyaw),
        negate=negate,
        occupied_thresh=thresholds["occupied_thresh"],
        free_thresh=thresholds["free_thresh"],
        mode=mode_raw.lower(),
    )


# What yaml-cpp's ``as<double>``/``as<int>`` read in a scalar's text, whatever its quoting
# (``YAML_DEFINE_CONVERT_STREAMABLE``: ``stream >> value`` with no leading white space, any
# trailing; integers in decimal, hex ``0x..`` or octal ``0..``, as ``std::ios::dec`` is unset).
_CPP_SPACE = "[ \t\n\v\f\r]*"
_CPP_DOUBLE = re.compile(r"[-+]?(?:[0-9]+\.?[0-9]*|\.[0-9]+)(?:[eE][-+]?[0-9]+)?" + _CPP_SPACE)
_CPP_INT = re.compile(r"([-+]?)(0[xX][0-9a-fA-F]+|0[0-7]*|[1-9][0-9]*)" + _CPP_SPACE)
_INT32 = range(-(2**31), 2**31)
# yaml-cpp's ``as<bool>``: these names in lower case, upper case or capitalised.
_CPP_BOOL = {"y": True, "yes": True, "true": True, "on": True}
_CPP_BOOL |= {"n": False, "no": False, "false": False, "off": False}


def _number(value: Any) -> float | None:
    """``value`` as a float if it is a YAML number (int or float, not bool), or a string whose
    text yaml-cpp's ``as<double>`` reads as one (``resolution: "0.05"``: Nav2 reads any
    scalar's text, quoted or not); else None."""
    if isinstance(value, str) and _CPP_DOUBLE.fullmatch(value):
        return float(value)
    if isinstance(value, bool) or not isinstance(value, int | float):
        return None
    try:
        return float(value)
    except OverflowError:  # an integer of hundreds of digits: yaml-cpp's as<double> fails too
        return None


def _negate(value: Any) -> bool | None:
    """``negate`` as nav2's ``loadMapYaml`` reads it: ``as<int>`` (any 32-bit integer, nonzero
    meaning yes), else ``as<bool>``; None if neither reads it."""
    if isinstance(value, bool):
        return value
    if isinstance(value, int):
        return bool(value) if value in _INT32 else None
    if not isinstance(value, str):
        return None
    m = _CPP_INT.fullmatch(value)
    if m is not None:
        sign, digits = m.groups()
        if digits[:2] in ("0x", "0X"):
            number = int(digits[2:], 16)
        else:
            number = int(digits, 8 if digits[0] == "0" else 10)
        number = -number if sign == "-" else number
        return bool(number) if number in _INT32 else None
    return _CPP_BOOL.get(value.lower()) if _flexible_case(value) else None


def _flexible_case(text: str) -> bool:
    """yaml-cpp's ``IsFlexibleCase``: lower case, upper case, or capitalised."""

    def lower(t: str) -> bool:
        return all("a" <= c <= "z" for c in t)

    def upper(t: str) -> bool:
        return all("A" <= c <= "Z" for c in t)

    return lower(text) or (upper(text[:1]) and (lower(text[1:]) or upper(text[1:])))


#: Held while Pillow's decompression-bomb limit is lifted (a process-wide setting).
_PILLOW_LIMIT_OFF = threading.Lock()


def _read_image(
    image_path: Path, yaml_path: Path
) -> tuple[NDArray[np.float64], NDArray[np.float64] | None]:
    """Mean of the colour channels and the alpha channel (or None), both scaled to [0, 1]."""
    where = f"{yaml_path}: image {str(image_path)!r}"
    if not image_path.exists():
        raise MapFormatError(f"{where} (key 'image'): file not found")
    if not image_path.is_file():
        raise MapFormatError(
            f"{where} (key 'image'): expected a regular image file, got {_file_kind(image_path)}"
        )
    try:
        try:
            with warnings.catch_warnings():
                # the budget below decides what is too large, not Pillow's warning threshold
                warnings.simplefilter("ignore", Image.DecompressionBombWarning)
                img = Image.open(image_path)  # reads the header only
        except Image.DecompressionBombError:
            # The budget below decides what is too large, not Pillow's decompression-bomb
            # guard: Image.open refuses over 2 x MAX_IMAGE_PIXELS (179 M pixels), a 700 m
            # square map at 5 cm that Nav2 loads. Only for such a map, the guard is lifted for
            # the moment of this header read (it is process-wide: a lock keeps two map loads
            # from undoing each other).
            with _PILLOW_LIMIT_OFF:
                saved = Image.MAX_IMAGE_PIXELS
                Image.MAX_IMAGE_PIXELS = None
                try:
                    img = Image.open(image_path)
                finally:
                    Image.MAX_IMAGE_PIXELS = saved
        with img:
            w, h = img.size  # from the header: checked before the pixels are decoded
            budget.require(
                f"{where} (key 'image'): {w} x {h} pixels",
                w * h,
                budget.MAP_CELL_BYTES,
                "map cells",
            )
            img.load()
            return _image_channels(img, where)
    except (MapFormatError, budget.BudgetError):
        raise
    except Exception as e:  # Pillow raises many types on corrupt files: OSError, SyntaxError...
        raise MapFormatError(
            f"{where}: cannot read the image (unreadable or truncated): {e}"
        ) from e


def _file_kind(path: Path) -> str:
    """What a path that exists but is no regular file is, for a message."""
    try:
        mode = path.stat().st_mode
    except OSError as e:
        return f"a path that cannot be read ({e.strerror or e})"
    if stat.S_ISDIR(mode):
        return "a folder"
    if stat.S_ISFIFO(mode):
        return "a FIFO (named pipe)"
    if stat.S_ISCHR(mode) or stat.S_ISBLK(mode):
        return "a device"
    if stat.S_ISSOCK(mode):
        return "a socket"
    return "a special file"


def _image_channels(
    img: Image.Image, where: str
) -> tuple[NDArray[np.float64], NDArray[np.float64] | None]:
    mode = img.mode
    if mode in ("I;16", "I;16B", "I;16L", "I"):
        grey = np.asarray(img).astype(np.float64)
        if grey.size and (grey.min() < 0 or grey.max() > 65535):
            raise MapFormatError(
                f"{where}: unsupported image depth: mode {mode!r} holds values outside the "
                f"16-bit range [0, 65535]"
            )
        return grey / 65535.0, None

    if "transparency" in img.info and mode in ("1", "L", "P", "RGB"):
        img = img.convert("RGBA")  # a tRNS transparent colour becomes an alpha channel
    elif mode in ("1", "L"):
        img = img.convert("L")
    elif mode in ("La",):
        img = img.convert("LA")
    elif mode in ("P", "RGBX"):
        img = img.convert("RGB")
    elif mode in ("PA", "RGBa"):
        img = img.convert("RGBA")
    elif mode not in ("LA", "RGB", "RGBA"):
        raise MapFormatError(
            f"{where}: unsupported image mode {mode!r}; expected 8-bit greyscale, greyscale with "
            f"alpha, RGB, RGBA or palette, or 16-bit greyscale"
        )

    pixels = np.asarray(img).astype(np.float64) / 255.0
    if img.mode == "L":
        return pixels, None
    if img.mode == "LA":
        return pixels[..., 0], pixels[..., 1]
    if img.mode == "RGB":
        return pixels.mean(axis=-1), None
    return pixels[..., :3].mean(axis=-1), pixels[..., 3]


def _pixels_to_cells(
    shade_rgb: NDArray[np.float64], alpha: NDArray[np.float64] | None, meta: _MapMeta
) -> NDArray[np.int8]:
    """Cell values in image row order (row 0 = top), as nav2's ``loadMapFromFile``."""
    occ_th, free_th = meta.occupied_thresh, meta.free_thresh

    if meta.mode == "raw":
        value = np.floor(shade_rgb * 255.0 + 0.5)  # std::round on non-negative values
        return np.where((value >= 0) & (value <= 100), value, -1).astype(np.int8)

    if meta.mode == "trinary" and alpha is not None:
        shade = (3.0 * shade_rgb + alpha) / 4.0  # alpha averaged in with R, G, B
    else:
        shade = shade_rgb
    occ = shade if meta.negate else 1.0 - shade

    if meta.mode == "trinary":
        cells = np.full(occ.shape, -1, dtype=np.int8)
    else:  # scale
        ratio = (occ - free_th) / (occ_th - free_th)
        cells = np.rint(ratio * 100.0).clip(-1, 100).astype(np.int8)
    cells[occ < free_th] = 0
    cells[occ > occ_th] = 100
    if meta.mode == "scale" and alpha is not None:
        cells[alpha < 1.0] = -1
    return cells


# ---------------------------------------------------------------------------------- saving
#: Names that say "image": the YAML written under one would pass for a broken image.
IMAGE_SUFFIXES = frozenset(
    {".pgm", ".png", ".jpg", ".jpeg", ".bmp", ".gif", ".tif", ".tiff", ".ppm"}
)


def save_map(
    grid: OccupancyGrid, yaml_path: str | os.PathLike[str], image_format: str = "pgm"
) -> Path:
    """Save a grid as a ROS ``map_server`` map, like ``map_saver`` in trinary mode.

    Writes ``NAME.pgm`` (or ``NAME.png``) beside ``NAME.yaml``; the YAML refers to the image by
    its bare file name. Free cells become 254, occupied 0 and unknown 205 (cells are classified
    with the grid's masks), and the YAML holds ``mode: trinary``, ``negate: 0``,
    ``occupied_thresh: 0.65`` and ``free_thresh: 0.196`` so that :func:`load_map` gives the grid
    back. Both files are written to temporary files in the target folder and moved into place
    with :func:`os.replace` (the image first, then the YAML), so an error leaves neither a
    half-written file nor a temporary file behind; a missing parent folder is created, and
    removed again if the save fails.

    Args:
        grid: the grid to save.
        yaml_path: where to write the YAML file.
        image_format: ``"pgm"`` or ``"png"``.

    Returns:
        The YAML file's path.

    Raises:
        MapFormatError: unknown image format, or the files cannot be written.
    """
    fmt = str(image_format).lower()
    if fmt not in IMAGE_FORMATS:
        raise MapFormatError(
            f"image_format: expected one of {', '.join(IMAGE_FORMATS)}, got {image_format!r}"
        )
    yaml_file = Path(yaml_path)
    if not yaml_file.name or yaml_file.suffix.lower() in IMAGE_SUFFIXES:
        raise MapFormatError(
            f"{yaml_file}: expected a YAML file name such as 'map.yaml' (the image is written "
            f"beside it as '<name>.{fmt}')"
        )
    image_file = yaml_file.with_suffix(f".{fmt}")
    for target in (yaml_file, image_file):
        if target.is_dir():
            raise MapFormatError(f"{yaml_file}: cannot write the map: {target} is a folder")

    pixels = np.full(grid.data.shape, SAVE_UNKNOWN, dtype=np.uint8)
    pixels[grid.free_mask] = SAVE_FREE
    pixels[grid.occupied_mask] = SAVE_OCCUPIED
    image = Image.fromarray(np.ascontiguousarray(np.flipud(pixels)))

    meta = {
        "image": image_file.name,
        "mode": "trinary",
        "resolution": float(grid.resolution),
        "origin": [float(v) for v in grid.origin],
        "negate": 0,
        "occupied_thresh": SAVE_OCCUPIED_THRESH,
        "free_thresh": SAVE_FREE_THRESH,
    }
    yaml_text = yaml.safe_dump(meta, sort_keys=False, default_flow_style=None)

    created = _make_parents(yaml_file)
    temps: list[Path] = []
    try:
        tmp_image = _write_temp(image_file, lambda f: image.save(f, format=IMAGE_FORMATS[fmt]))
        temps.append(tmp_image)
        tmp_yaml = _write_temp(yaml_file, lambda f: f.write(yaml_text.encode("utf-8")))
        temps.append(tmp_yaml)
        os.replace(tmp_image, image_file)
        temps.remove(tmp_image)
        os.replace(tmp_yaml, yaml_file)
        temps.remove(tmp_yaml)
    except BaseException as e:
        for tmp in temps:
            tmp.unlink(missing_ok=True)
        for folder in reversed(created):
            try:
                folder.rmdir()
            except OSError:
                break
        if isinstance(e, OSError):
            raise MapFormatError(f"{yaml_file}: cannot write the map: {e}") from e
        raise
    return yaml_file


def _make_parents(path: Path) -> list[Path]:
    """Create the missing parent folders of ``path``; return those created, outermost first."""
    missing: list[Path] = []
    folder = path.parent
    while not folder.exists() and folder != folder.parent:
        missing.append(folder)
        folder = folder.parent
    missing.reverse()
    created: list[Path] = []
    try:
        for folder in missing:
            folder.mkdir()
            created.append(folder)
    except OSError as e:
        for folder in reversed(created):
            folder.rmdir()
        raise MapFormatError(f"{path}: cannot create the folder {folder}: {e}") from e
    if not path.parent.is_dir():
        raise MapFormatError(f"{path}: cannot write the map: {path.parent} is not a folder")
    return created


def _write_temp(final: Path, write: Callable[[Any], object]) -> Path:
    """Write a new temporary file beside ``final`` (mode 0666 minus umask) and return its path."""
    while True:
        tmp = final.with_name(f".{final.name}.{secrets.token_hex(6)}.tmp")
        try:
            fd = os.open(tmp, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o666)
        except FileExistsError:
            continue
        break
    try:
        with os.fdopen(fd, "wb") as f:
            write(f)
            f.flush()
            os.fsync(f.fileno())
    except BaseException:
        tmp.unlink(missing_ok=True)
        raise
    return tmp
