"""Fuzzing the map parser: any YAML and image give a grid or the project's own error."""

from __future__ import annotations

import io
import tempfile
from pathlib import Path
from typing import Any

import numpy as np
import yaml
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from PIL import Image

from ceamcl.errors import CeamclError
from ceamcl.maps.ros_io import load_map

FUZZ = settings(
    max_examples=1000,
    deadline=None,
    suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large],
)

scalars = st.one_of(
    st.none(),
    st.booleans(),
    st.integers(-3, 300),
    st.floats(allow_nan=True, allow_infinity=True),
    st.text(max_size=8),
)
values = st.one_of(scalars, st.lists(scalars, max_size=4))
KEYS = ["image", "resolution", "origin", "negate", "occupied_thresh", "free_thresh", "mode"]


@st.composite
def map_documents(draw: st.DrawFn) -> dict[str, Any]:
    """Mostly valid map YAML with a few keys dropped, added or replaced by junk."""
    doc: dict[str, Any] = {
        "image": "map.png",
        "resolution": draw(st.sampled_from([0.05, 0.1, 1])),
        "origin": [0.0, 0.0, 0.0],
        "negate": draw(st.sampled_from([0, 1, False])),
        "occupied_thresh": 0.65,
        "free_thresh": 0.196,
        "mode": draw(st.sampled_from(["trinary", "scale", "raw", "Trinary"])),
    }
    for key in draw(st.lists(st.sampled_from(KEYS), max_size=3)):
        if draw(st.booleans()):
            doc.pop(key, None)
        else:
            doc[key] = draw(values)
    if draw(st.integers(0, 9)) == 0:
        doc[draw(st.text(min_size=1, max_size=6))] = draw(values)
    return doc


@st.composite
def image_bytes(draw: st.DrawFn) -> bytes:
    """A small image in some mode and format, possibly truncated or with bytes flipped."""
    mode = draw(st.sampled_from(["L", "LA", "RGB", "RGBA", "P", "1", "I;16", "I", "F", "CMYK"]))
    fmt = draw(st.sampled_from(["PNG", "PPM", "BMP", "TIFF"]))
    h, w = draw(st.integers(1, 6)), draw(st.integers(1, 6))
    pixels = np.frombuffer(draw(st.binary(min_size=h * w, max_size=h * w)), np.uint8)
    img = Image.fromarray(pixels.reshape(h, w), "L").convert(mode)
    buf = io.BytesIO()
    try:
        img.save(buf, format=fmt)
    except (OSError, ValueError, KeyError):
        img.convert("L").save(buf, format="PNG")
    data = bytearray(buf.getvalue())
    damage = draw(st.sampled_from(["none", "truncate", "flip", "junk"]))
    if damage == "truncate":
        data = data[: draw(st.integers(0, len(data)))]
    elif damage == "flip" and data:
        i = draw(st.integers(0, len(data) - 1))
        data[i] ^= draw(st.integers(1, 255))
    elif damage == "junk":
        data = bytearray(draw(st.binary(max_size=64)))
    return bytes(data)


def _load(yaml_text: str | bytes, image: bytes | None) -> None:
    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(tmp)
        path = folder / "map.yaml"
        path.write_bytes(yaml_text.encode() if isinstance(yaml_text, str) else yaml_text)
        if image is not None:
            (folder / "map.png").write_bytes(image)
        try:
            grid = load_map(path)
        except CeamclError as exc:
            assert str(exc), "an error must say what is wrong"
            return
        assert grid.data.ndim == 2 and grid.resolution > 0
        assert set(np.unique(grid.data)) <= set(range(-1, 101))


@FUZZ
@given(doc=map_documents(), image=st.one_of(st.none(), image_bytes()))
def test_fuzz_map_yaml_and_image(doc: dict[str, Any], image: bytes | None) -> None:
    _load(yaml.safe_dump(doc), image)


@FUZZ
@given(text=st.one_of(st.text(max_size=200), st.binary(max_size=200)))
def test_fuzz_map_yaml_text(text: str | bytes) -> None:
    _load(text, None)
