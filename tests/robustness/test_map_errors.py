"""Every bad map input of issue 7 is a MapFormatError naming the file and the key or problem."""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np
import pytest
from PIL import Image

from ceamcl.errors import MapFormatError
from ceamcl.maps.ros_io import load_map

GOOD = {
    "image": "map.png",
    "resolution": "0.05",
    "origin": "[0.0, 0.0, 0.0]",
    "negate": "0",
    "occupied_thresh": "0.65",
    "free_thresh": "0.196",
}


def write_map(folder: Path, image_mode: str = "L", **changes: str | None) -> Path:
    doc = {**GOOD, **changes}
    text = "".join(f"{k}: {v}\n" for k, v in doc.items() if v is not None)
    path = folder / "map.yaml"
    path.write_text(text)
    img = Image.fromarray(np.full((4, 5), 254, np.uint8), "L").convert(image_mode)
    img.save(folder / ("map.tiff" if image_mode == "F" else "map.png"))
    return path


@pytest.mark.parametrize(
    ("changes", "expected"),
    [
        ({"resolution": None}, "missing required key(s) 'resolution'"),
        ({"resolution": "fast"}, "key 'resolution': expected a finite number > 0"),
        ({"resolution": "0"}, "key 'resolution': expected a finite number > 0"),
        ({"resolution": "-0.05"}, "key 'resolution': expected a finite number > 0"),
        ({"resolution": ".nan"}, "key 'resolution': expected a finite number > 0"),
        ({"origin": "[0, 0]"}, "key 'origin': expected a list of three finite numbers"),
        ({"negate": "0.5"}, "key 'negate': expected an integer (0: no, any other: yes"),
        ({"occupied_thresh": "1.5"}, "key 'occupied_thresh': expected a number in [0, 1]"),
        ({"free_thresh": "0.7"}, "key 'free_thresh': expected a value smaller than"),
        ({"mode": "fancy"}, "key 'mode': expected one of trinary, scale, raw"),
        ({"image": "missing.png"}, "(key 'image'): file not found"),
        ({"image": "''"}, "key 'image': expected a non-empty image file name"),
    ],
)
def test_bad_yaml(tmp_path: Path, changes: dict[str, str | None], expected: str) -> None:
    path = write_map(tmp_path, **changes)
    with pytest.raises(MapFormatError) as info:
        load_map(path)
    assert str(path) in str(info.value)
    assert expected in str(info.value)


def test_truncated_and_unreadable_images(tmp_path: Path) -> None:
    path = write_map(tmp_path)
    image = tmp_path / "map.png"
    data = image.read_bytes()
    for broken in (data[: len(data) // 2], b"", b"P5\n5 4\n255\n\x00\x01"):
        image.write_bytes(broken)
        with pytest.raises(MapFormatError, match="cannot read the image"):
            load_map(path)
    image.unlink()
    image.mkdir()
    with pytest.raises(MapFormatError, match="expected a regular image file, got a folder"):
        load_map(path)


def test_a_fifo_or_a_device_as_the_image_is_named_as_such(tmp_path: Path) -> None:
    """A FIFO or /dev/zero as the image was reported as 'expected an image file, not a
    folder'."""
    path = write_map(tmp_path, image="img.fifo")
    os.mkfifo(tmp_path / "img.fifo")
    with pytest.raises(
        MapFormatError,
        match=r"image '.*img\.fifo' \(key 'image'\): expected a regular image file, got a FIFO",
    ):
        load_map(path)
    path = write_map(tmp_path, image="/dev/zero")
    with pytest.raises(MapFormatError, match=r"'/dev/zero' .*regular image file, got a device"):
        load_map(path)


def test_wrong_image_depth(tmp_path: Path) -> None:
    path = write_map(tmp_path, image_mode="F", image="map.tiff")  # 32-bit float pixels
    with pytest.raises(MapFormatError, match="unsupported image mode 'F'"):
        load_map(path)
    cmyk = write_map(tmp_path, image="map.jpg")
    Image.new("CMYK", (3, 3)).save(tmp_path / "map.jpg")
    with pytest.raises(MapFormatError, match="unsupported image mode 'CMYK'"):
        load_map(cmyk)


def test_not_yaml_and_missing_file(tmp_path: Path) -> None:
    path = tmp_path / "map.yaml"
    path.write_text("image: [unclosed\n")
    with pytest.raises(MapFormatError, match="not valid YAML"):
        load_map(path)
    with pytest.raises(MapFormatError, match="map YAML file not found"):
        load_map(tmp_path / "nope.yaml")
