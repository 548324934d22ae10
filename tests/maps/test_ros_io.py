"""Tests of ROS map_server map I/O (``ceamcl.maps.ros_io``)."""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np
import pytest
import yaml
from PIL import Image

from ceamcl.errors import CeamclError, InputWarning, MapFormatError
from ceamcl.maps.grid import OccupancyGrid
from ceamcl.maps.ros_io import load_map, save_map

# ---------------------------------------------------------------------------------- helpers


def write_pgm(path: Path, rows: list[list[int]], maxval: int = 255) -> Path:
    """Write a binary PGM (P5) by hand; ``rows[0]`` is the top row of the image."""
    height, width = len(rows), len(rows[0])
    header = f"P5\n# test image\n{width} {height}\n{maxval}\n".encode("ascii")
    if maxval > 255:
        body = np.asarray(rows, dtype=">u2").tobytes()
    else:
        body = bytes(v for row in rows for v in row)
    path.write_bytes(header + body)
    return path


def write_yaml(
    path: Path,
    image: str = "map.pgm",
    *,
    resolution: str = "0.05",
    origin: str = "[0.0, 0.0, 0.0]",
    negate: str = "0",
    occupied_thresh: str = "0.65",
    free_thresh: str = "0.196",
    mode: str | None = None,
    extra: str = "",
) -> Path:
    lines = [
        f"image: {image}",
        f"resolution: {resolution}",
        f"origin: {origin}",
        f"negate: {negate}",
        f"occupied_thresh: {occupied_thresh}",
        f"free_thresh: {free_thresh}",
    ]
    if mode is not None:
        lines.append(f"mode: {mode}")
    path.write_text("\n".join(lines) + "\n" + extra)
    return path


# Top row first, as on disk; 3 wide and 2 high so a transpose or a missing flip shows.
PATTERN = [[0, 254, 205], [255, 100, 50]]


def sample_grid() -> OccupancyGrid:
    data = np.array(
        [
            [0, 0, 100, -1, 0],
            [100, -1, 0, 0, 0],
            [-1, -1, 100, 100, 0],
            [0, 100, -1, 0, 100],
        ],
        dtype=np.int8,
    )
    return OccupancyGrid(data, 0.05, (1.5, -2.25, 0.3), name="sample")


# ---------------------------------------------------------------------------------- round trip


@pytest.mark.parametrize("fmt", ["pgm", "png"])
def test_round_trip(tmp_path: Path, fmt: str) -> None:
    grid = sample_grid()
    out = save_map(grid, tmp_path / "office.yaml", image_format=fmt)
    assert out == tmp_path / "office.yaml"
    assert sorted(p.name for p in tmp_path.iterdir()) == [f"office.{fmt}", "office.yaml"]

    loaded = load_map(out)
    assert loaded == grid
    assert loaded.origin == pytest.approx((1.5, -2.25, 0.3))
    assert loaded.name == "office"

    # The image is stored top row first: image row 0 is the grid's highest iy.
    with Image.open(tmp_path / f"office.{fmt}") as img:
        assert img.mode == "L"
        pixels = np.asarray(img)
    expected = np.select([grid.data == 0, grid.data == 100], [254, 0], 205)
    np.testing.assert_array_equal(pixels, np.flipud(expected))

    meta = yaml.safe_load((tmp_path / "office.yaml").read_text())
    assert meta == {
        "image": f"office.{fmt}",
        "mode": "trinary",
        "resolution": 0.05,
        "origin": [1.5, -2.25, 0.3],
        "negate": 0,
        "occupied_thresh": 0.65,
        "free_thresh": 0.196,
    }


def test_round_trip_awkward_floats(tmp_path: Path) -> None:
    # 1e-05 is written by repr() without a dot, which PyYAML would read back as a string
    # (the origin within the 10^7 m bound of map origins and log poses).
    grid = OccupancyGrid(
        np.array([[0, -1], [100, 0]], dtype=np.int8), 1e-5, (-1e-7, 9876543.125, -3.0)
    )
    assert load_map(save_map(grid, tmp_path / "m.yaml")) == grid


def test_save_classifies_intermediate_values_like_the_grid(tmp_path: Path) -> None:
    grid = OccupancyGrid(np.array([[10, 19, 20, 50], [64, 65, 99, 100]], dtype=np.int8), 0.1)
    loaded = load_map(save_map(grid, tmp_path / "m.yaml"))
    np.testing.assert_array_equal(loaded.data, [[0, 0, -1, -1], [-1, 100, 100, 100]])


def test_save_creates_parent_folders_and_overwrites(tmp_path: Path) -> None:
    target = tmp_path / "a" / "b" / "map.yaml"
    save_map(sample_grid(), target)
    other = sample_grid().with_data(np.zeros((2, 3), dtype=np.int8))
    save_map(other, target)
    assert load_map(target) == other
    assert sorted(p.name for p in target.parent.iterdir()) == ["map.pgm", "map.yaml"]


@pytest.mark.parametrize(
    ("name", "fmt"), [("hall.png", "pgm"), ("hall.pgm", "png"), ("m.JPG", "pgm")]
)
def test_an_image_name_for_the_yaml_is_refused(tmp_path: Path, name: str, fmt: str) -> None:
    """``-o hall.png`` wrote the YAML into ``hall.png`` and the image into ``hall.pgm``."""
    with pytest.raises(MapFormatError, match=r"expected a YAML file name such as 'map\.yaml'"):
        save_map(sample_grid(), tmp_path / name, fmt)
    assert not list(tmp_path.iterdir())


@pytest.mark.skipif(os.name != "posix", reason="POSIX permissions")
def test_saved_files_respect_umask(tmp_path: Path) -> None:
    old = os.umask(0o022)
    try:
        save_map(sample_grid(), tmp_path / "m.yaml")
    finally:
        os.umask(old)
    assert (tmp_path / "m.yaml").stat().st_mode & 0o777 == 0o644
    assert (tmp_path / "m.pgm").stat().st_mode & 0o777 == 0o644


# ---------------------------------------------------------------------------------- loading


def test_trinary_negate_0_and_orientation(tmp_path: Path) -> None:
    write_pgm(tmp_path / "map.pgm", PATTERN)
    grid = load_map(
        write_yaml(
            tmp_path / "map.yaml", free_thresh="0.25", origin="[2.0, 3.0, 0.5]", resolution="0.1"
        )
    )
    assert (grid.width, grid.height) == (3, 2)
    # p = (255 - v) / 255: 0 -> 1.0 occ; 254 -> 0.004 free; 205 -> 0.196 < 0.25 free (as nav2);
    # 255 -> 0 free; 100 -> 0.61 unknown; 50 -> 0.80 occ.
    assert grid.data[1].tolist() == [100, 0, 0]  # top image row = highest iy
    assert grid.data[0].tolist() == [0, -1, 100]
    assert grid.resolution == 0.1
    assert grid.origin == (2.0, 3.0, 0.5)
    assert grid.name == "map"


def test_trinary_map_saver_unknown_grey(tmp_path: Path) -> None:
    write_pgm(tmp_path / "map.pgm", PATTERN)
    grid = load_map(write_yaml(tmp_path / "map.yaml", free_thresh="0.196"))
    assert grid.data[1].tolist() == [100, 0, -1]
    assert grid.data[0].tolist() == [0, -1, 100]


@pytest.mark.parametrize("negate", ["1", "true", "yes"])
def test_trinary_negate_1(tmp_path: Path, negate: str) -> None:
    write_pgm(tmp_path / "map.pgm", PATTERN)
    grid = load_map(write_yaml(tmp_path / "map.yaml", negate=negate, free_thresh="0.25"))
    # p = v / 255: 0 -> free; 254, 205, 255 -> occ; 100 -> 0.39 unknown; 50 -> 0.196 free.
    assert grid.data[1].tolist() == [0, 100, 100]
    assert grid.data[0].tolist() == [100, -1, 0]


@pytest.mark.parametrize("negate", ["2", "-1", "0x1", "07", '"1"', '"yes"', "y", "On", "TRUE"])
def test_negate_as_nav2_reads_it_any_integer_nonzero_is_yes(tmp_path: Path, negate: str) -> None:
    """nav2's loadMapYaml reads negate with as<int> (nonzero: yes), else as<bool>; yaml-cpp
    reads a scalar's text whatever its quoting. 'negate: 2' was refused ('expected 0, 1,
    false or true, got 2')."""
    write_pgm(tmp_path / "map.pgm", [[0, 255]])
    grid = load_map(write_yaml(tmp_path / "map.yaml", negate=negate))
    assert grid.data.tolist() == [[0, 100]]


@pytest.mark.parametrize("negate", ["0", "false", "no", "0x0", "-0", '"0"', '"No"', "n", "OFF"])
def test_negate_false_spellings(tmp_path: Path, negate: str) -> None:
    write_pgm(tmp_path / "map.pgm", [[0, 255]])
    grid = load_map(write_yaml(tmp_path / "map.yaml", negate=negate))
    assert grid.data.tolist() == [[100, 0]]


@pytest.mark.parametrize("mode", ["scale", "SCALE", "Scale"])
def test_scale_mode(tmp_path: Path, mode: str) -> None:
    write_pgm(tmp_path / "map.pgm", [[255, 140, 0], [166, 100, 92]])
    grid = load_map(write_yaml(tmp_path / "map.yaml", mode=mode, free_thresh="0.25"))
    # p = (255 - v)/255; between the thresholds value = rint(100 (p - 0.25) / 0.4) (nav2):
    # 140 -> p 0.451 -> 50.2 -> 50; 166 -> p 0.349 -> 24.8 -> 25; 100 -> p 0.608 -> 89.46 -> 89;
    # 92 -> p 0.639 -> 97.3 -> 97 (ROS 1's 1 + 98 ratio would give 96).
    assert grid.data[1].tolist() == [0, 50, 100]
    assert grid.data[0].tolist() == [25, 89, 97]


def test_scale_mode_negate(tmp_path: Path) -> None:
    write_pgm(tmp_path / "map.pgm", [[0, 115, 255]])
    grid = load_map(write_yaml(tmp_path / "map.yaml", mode="scale", negate="1", free_thresh="0.25"))
    # p = v / 255: 0 -> free, 115 -> 0.451 -> 50, 255 -> occupied.
    assert grid.data.tolist() == [[0, 50, 100]]


def test_scale_mode_alpha_is_unknown(tmp_path: Path) -> None:
    rgba = np.array(
        [[[0, 0, 0, 255], [0, 0, 0, 0], [255, 255, 255, 128], [255, 255, 255, 255]]],
        dtype=np.uint8,
    )
    Image.fromarray(rgba).save(tmp_path / "map.png")
    grid = load_map(write_yaml(tmp_path / "map.yaml", "map.png", mode="scale"))
    # Opaque pixels by colour; transparent and half transparent ones unknown (nav2).
    assert grid.data.tolist() == [[100, -1, -1, 0]]


def test_trinary_mode_averages_alpha_in(tmp_path: Path) -> None:
    rgba = np.array(
        [[[205, 205, 205, 255], [0, 0, 0, 0], [255, 255, 255, 0], [0, 0, 0, 255]]],
        dtype=np.uint8,
    )
    Image.fromarray(rgba).save(tmp_path / "map.png")
    grid = load_map(write_yaml(tmp_path / "map.yaml", "map.png"))
    # shade = (R + G + B + A) / 4 / 255 as nav2 (and ROS 1) in trinary mode:
    # opaque 205 -> p 0.147 free; transparent black -> p 1 occ; transparent white -> p 0.25
    # unknown; opaque black -> p 0.75 occ.
    assert grid.data.tolist() == [[0, 100, -1, 100]]


def test_thresholds_are_strict(tmp_path: Path) -> None:
    write_pgm(tmp_path / "map.pgm", [[0, 255, 128]])
    # p = 1 is not > occupied_thresh 1.0 and p = 0 is not < free_thresh 0.0: both unknown.
    grid = load_map(write_yaml(tmp_path / "map.yaml", occupied_thresh="1.0", free_thresh="0.0"))
    assert grid.data.tolist() == [[-1, -1, -1]]
    grid = load_map(write_yaml(tmp_path / "map.yaml", occupied_thresh="0.99", free_thresh="0.01"))
    assert grid.data.tolist() == [[100, 0, -1]]


def test_raw_mode(tmp_path: Path) -> None:
    write_pgm(tmp_path / "map.pgm", [[0, 50, 100, 101, 255]])
    for negate in ("0", "1"):  # nav2 ignores negate in raw mode
        grid = load_map(write_yaml(tmp_path / "map.yaml", mode="raw", negate=negate))
        assert grid.data.tolist() == [[0, 50, 100, -1, -1]]


def test_colour_image_uses_mean_of_channels(tmp_path: Path) -> None:
    rgb = np.array([[[255, 0, 0], [0, 255, 255], [254, 254, 254]]], dtype=np.uint8)
    Image.fromarray(rgb).save(tmp_path / "map.png")
    grid = load_map(write_yaml(tmp_path / "map.yaml", "map.png"))
    # means 85 -> p 0.667 occ; 170 -> p 0.333 unknown; 254 -> free.
    assert grid.data.tolist() == [[100, -1, 0]]


def test_palette_and_greyscale_alpha_images(tmp_path: Path) -> None:
    pal = Image.new("P", (3, 1))
    pal.putpalette([0, 0, 0, 255, 255, 255, 205, 205, 205])
    pal.putdata([0, 1, 2])
    pal.save(tmp_path / "pal.png")
    grid = load_map(write_yaml(tmp_path / "pal.yaml", "pal.png"))
    assert grid.data.tolist() == [[100, 0, -1]]

    la = np.array([[[0, 255], [255, 255], [255, 0]]], dtype=np.uint8)
    Image.fromarray(la, mode="LA").save(tmp_path / "la.png")
    grid = load_map(write_yaml(tmp_path / "la.yaml", "la.png", mode="scale"))
    assert grid.data.tolist() == [[100, 0, -1]]


def test_sixteen_bit_images_are_scaled(tmp_path: Path) -> None:
    rows = [[0, 65535, 205 * 257]]
    write_pgm(tmp_path / "map.pgm", rows, maxval=65535)
    grid = load_map(write_yaml(tmp_path / "map.yaml"))
    assert grid.data.tolist() == [[100, 0, -1]]

    Image.fromarray(np.array(rows, dtype=np.uint16)).save(tmp_path / "m16.png")
    with Image.open(tmp_path / "m16.png") as img:
        assert img.mode.startswith("I")
    grid = load_map(write_yaml(tmp_path / "m16.yaml", "m16.png"))
    assert grid.data.tolist() == [[100, 0, -1]]


def test_image_path_relative_to_yaml_folder(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    folder = tmp_path / "maps" / "site"
    (folder / "img").mkdir(parents=True)
    write_pgm(folder / "img" / "floor.pgm", PATTERN)
    write_yaml(folder / "floor.yaml", "img/floor.pgm")
    elsewhere = tmp_path / "elsewhere"
    elsewhere.mkdir()
    monkeypatch.chdir(elsewhere)
    grid = load_map(os.path.relpath(folder / "floor.yaml"))
    assert grid.data[1].tolist() == [100, 0, -1]
    assert grid.name == "floor"

    # An absolute image path is used as is.
    write_yaml(tmp_path / "abs.yaml", str(folder / "img" / "floor.pgm"))
    assert load_map(tmp_path / "abs.yaml") == grid


# ---------------------------------------------------------------------------------- errors


def assert_map_error(yaml_path: Path, *fragments: str) -> str:
    with pytest.raises(MapFormatError) as info:
        load_map(yaml_path)
    message = str(info.value)
    assert isinstance(info.value, CeamclError)
    assert yaml_path.name in message, message
    for fragment in fragments:
        assert fragment in message, message
    return message


@pytest.mark.parametrize(
    ("overrides", "key"),
    [
        ({"resolution": '"abc"'}, "resolution"),
        ({"resolution": "abc"}, "resolution"),
        ({"resolution": "0"}, "resolution"),
        ({"resolution": "-0.05"}, "resolution"),
        ({"resolution": ".nan"}, "resolution"),
        ({"resolution": ".inf"}, "resolution"),
        ({"resolution": "true"}, "resolution"),
        ({"resolution": "[0.05]"}, "resolution"),
        ({"origin": "[1.0, 2.0]"}, "origin"),
        ({"origin": "[1.0, 2.0, 0.0, 4.0]"}, "origin"),
        ({"origin": "[1.0, 2.0, x]"}, "origin"),
        ({"origin": "[1.0, 2.0, .inf]"}, "origin"),
        ({"origin": "1.0"}, "origin"),
        ({"origin": "{x: 1}"}, "origin"),
        ({"negate": "0.5"}, "negate"),
        ({"negate": "1.0"}, "negate"),
        ({"negate": '"maybe"'}, "negate"),
        ({"negate": "tRUE"}, "negate"),
        ({"negate": "4294967296"}, "negate"),  # beyond yaml-cpp's as<int>
        ({"negate": '"08"'}, "negate"),  # octal, as yaml-cpp's stream reads a leading 0
        ({"resolution": '" 0.05"'}, "resolution"),  # yaml-cpp reads no leading space
        ({"resolution": '"0x10"'}, "resolution"),
        ({"resolution": '"5e"'}, "resolution"),
        ({"resolution": "1" + "0" * 400}, "resolution"),  # an int too large for a float
        ({"origin": '["1.0", "2.0", "x"]'}, "origin"),
        ({"occupied_thresh": "1.5"}, "occupied_thresh"),
        ({"occupied_thresh": "high"}, "occupied_thresh"),
        ({"free_thresh": "-0.1"}, "free_thresh"),
        ({"free_thresh": "0.7"}, "free_thresh"),
        ({"free_thresh": "0.65"}, "free_thresh"),
        ({"mode": "fuzzy"}, "mode"),
        ({"mode": "3"}, "mode"),
        ({"image": '""'}, "image"),
        ({"image": "123"}, "image"),
        ({"image": "[a.pgm]"}, "image"),
    ],
)
def test_bad_values(tmp_path: Path, overrides: dict[str, str], key: str) -> None:
    write_pgm(tmp_path / "map.pgm", PATTERN)
    path = write_yaml(tmp_path / "bad_values.yaml", **overrides)
    assert_map_error(path, f"'{key}'", "expected")


@pytest.mark.parametrize(
    "key", ["image", "resolution", "origin", "negate", "occupied_thresh", "free_thresh"]
)
def test_missing_key(tmp_path: Path, key: str) -> None:
    write_pgm(tmp_path / "map.pgm", PATTERN)
    path = write_yaml(tmp_path / "missing.yaml")
    text = "".join(
        line + "\n" for line in path.read_text().splitlines() if not line.startswith(f"{key}:")
    )
    path.write_text(text)
    assert_map_error(path, f"'{key}'", "missing")


def test_unknown_key_is_ignored_with_a_warning_as_map_server_does(tmp_path: Path) -> None:
    write_pgm(tmp_path / "map.pgm", PATTERN)
    path = write_yaml(tmp_path / "unknown.yaml", extra="occupied_thres: 0.6\n")
    with pytest.warns(InputWarning, match="ignoring unknown key.*'occupied_thres'") as record:
        grid = load_map(path)
    message = str(record[0].message)
    assert str(path) in message
    for expected in ("image", "resolution", "origin", "negate", "free_thresh", "mode"):
        assert expected in message
    assert grid == load_map(write_yaml(tmp_path / "plain.yaml"))


def test_yaml_12_numbers_are_read_as_ros_reads_them(tmp_path: Path) -> None:
    """yaml-cpp (YAML 1.2) reads 5e-2 as a number; PyYAML's YAML 1.1 resolver does not."""
    write_pgm(tmp_path / "map.pgm", PATTERN)
    for text, value in (("5e-2", 0.05), ("5E-2", 0.05), (".5", 0.5), ("1e0", 1.0)):
        path = write_yaml(tmp_path / "sci.yaml", resolution=text)
        assert load_map(path).resolution == value


def test_a_repeated_key_is_refused_naming_it(tmp_path: Path) -> None:
    """'resolution: 0.05' and later 'resolution: 0.5' loaded at 0.5 silently; which one
    yaml-cpp (Nav2) keeps has varied by version."""
    write_pgm(tmp_path / "map.pgm", PATTERN)
    path = write_yaml(tmp_path / "dup.yaml", extra="resolution: 0.5\n")
    assert_map_error(
        path, f"{path}:7: not valid YAML: duplicate key 'resolution' (first on line 2)"
    )


def test_quoted_numbers_are_read_as_nav2_reads_them(tmp_path: Path) -> None:
    """yaml-cpp's as<double> converts a scalar's text whatever its quoting, so Nav2 loads
    'resolution: "0.05"'; it was refused ('expected a finite number > 0, got '0.05'')."""
    write_pgm(tmp_path / "map.pgm", PATTERN)
    plain = load_map(write_yaml(tmp_path / "plain.yaml", origin="[1.5, -2.0, 0.25]"))
    quoted = load_map(
        write_yaml(
            tmp_path / "quoted.yaml",
            resolution='"0.05"',
            origin='[\'1.5\', "-2", "0.25 "]',
            occupied_thresh="'0.65'",
            free_thresh='"1.96e-1"',
        )
    )
    assert quoted == plain
    assert quoted.resolution == 0.05 and quoted.origin == (1.5, -2.0, 0.25)


def test_the_budget_not_pillows_bomb_guard_decides_how_large_a_map_may_be(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """Pillow's Image.open refuses images over 2 x MAX_IMAGE_PIXELS (179 M pixels) as
    decompression bombs: a 14000 x 14000 map (700 m at 5 cm, which Nav2 loads) was refused
    as 'cannot read the image (unreadable or truncated)' whatever the budget."""
    from ceamcl import budget

    monkeypatch.setattr(Image, "MAX_IMAGE_PIXELS", 2)  # every image is a "bomb" now
    write_pgm(tmp_path / "map.pgm", PATTERN)
    grid = load_map(write_yaml(tmp_path / "map.yaml"))
    assert grid.data.shape == (2, 3)
    assert Image.MAX_IMAGE_PIXELS == 2  # the process-wide setting is put back
    # a header of 196 M pixels: the budget refuses it, before anything is decoded
    (tmp_path / "big.pgm").write_bytes(b"P5\n14000 14000\n255\n\x00")
    path = write_yaml(tmp_path / "big.yaml", image="big.pgm")
    with budget.use(budget.Budget(1 << 30)):
        with pytest.raises(
            budget.BudgetError,
            match=r"big\.pgm' \(key 'image'\): 14000 x 14000 pixels: 196,000,000 map cells "
            r"would need 23\.4 GiB, over the memory budget of 1\.0 GiB",
        ):
            load_map(path)


@pytest.mark.parametrize(
    "origin", ["[1e17, 0, 0]", "[0, -2.0e7, 0]", "[0, 0, 1.5e6]", "[1e300, 0, 0]"]
)
def test_an_origin_beyond_the_bounds_of_log_poses_is_refused(tmp_path: Path, origin: str) -> None:
    """An origin of 1e17 m was accepted: every pose of the run came out as
    99999999999999984.0 (the precision lost), and 1e300 leaked a matplotlib warning. The
    origin is bounded as log poses are (10^7 m, 10^6 rad)."""
    write_pgm(tmp_path / "map.pgm", PATTERN)
    path = write_yaml(tmp_path / "far.yaml", origin=origin)
    assert_map_error(
        path, "key 'origin': expected [x, y, yaw] with |x|, |y| <= 1e+07 m and |yaw| <= 1e+06 rad"
    )
    grid = load_map(write_yaml(tmp_path / "edge.yaml", origin="[1e7, -1e7, -1e6]"))
    assert grid.origin == (1e7, -1e7, -1e6)


def test_aliases_are_refused_with_the_line(tmp_path: Path) -> None:
    write_pgm(tmp_path / "map.pgm", PATTERN)
    path = write_yaml(tmp_path / "alias.yaml", extra="a: &x [1, 2]\nb: *x\n")
    assert_map_error(path, "aliases (*x) are not accepted", f"{path}:")


@pytest.mark.parametrize(
    ("text", "fragment"),
    [
        ("image: [unclosed\n", "YAML"),
        ("image: map.pgm\n  resolution: : 0.05\n", "YAML"),
        ("- image\n- resolution\n", "mapping"),
        ("just a string\n", "mapping"),
        ("", "empty"),
    ],
)
def test_unparseable_or_not_a_mapping(tmp_path: Path, text: str, fragment: str) -> None:
    path = tmp_path / "broken.yaml"
    path.write_text(text)
    assert_map_error(path, fragment)


def test_yaml_file_missing(tmp_path: Path) -> None:
    assert_map_error(tmp_path / "nowhere.yaml", "not found")


def test_image_file_missing(tmp_path: Path) -> None:
    path = write_yaml(tmp_path / "lonely.yaml", "ghost.pgm")
    assert_map_error(path, "ghost.pgm", "'image'", "not found")


def test_image_is_a_folder(tmp_path: Path) -> None:
    (tmp_path / "dir.pgm").mkdir()
    path = write_yaml(tmp_path / "m.yaml", "dir.pgm")
    assert_map_error(path, "dir.pgm", "expected a regular image file, got a folder")


@pytest.mark.parametrize(
    "content",
    [
        b"this is not an image at all",
        b"P5\n4 4\n255\n\x00\x01\x02",  # truncated pixel data
        b"P5\nx y\n255\n",  # broken header
        b"",
    ],
)
def test_image_unreadable(tmp_path: Path, content: bytes) -> None:
    (tmp_path / "junk.pgm").write_bytes(content)
    path = write_yaml(tmp_path / "m.yaml", "junk.pgm")
    assert_map_error(path, "junk.pgm", "cannot read the image")


def test_truncated_png(tmp_path: Path) -> None:
    Image.fromarray(np.full((40, 40), 254, dtype=np.uint8)).save(tmp_path / "full.png")
    data = (tmp_path / "full.png").read_bytes()
    (tmp_path / "cut.png").write_bytes(data[: len(data) // 2])
    path = write_yaml(tmp_path / "m.yaml", "cut.png")
    assert_map_error(path, "cut.png", "cannot read the image")


@pytest.mark.parametrize(
    ("mode", "array", "fragment"),
    [
        ("F", np.zeros((2, 2), dtype=np.float32), "'F'"),
        ("I", np.full((2, 2), 70000, dtype=np.int32), "16-bit"),
        ("CMYK", None, "'CMYK'"),
    ],
)
def test_unsupported_image_mode(
    tmp_path: Path, mode: str, array: np.ndarray | None, fragment: str
) -> None:
    img = Image.new("CMYK", (2, 2)) if array is None else Image.fromarray(array)
    assert img.mode == mode
    img.save(tmp_path / "odd.tiff")
    path = write_yaml(tmp_path / "m.yaml", "odd.tiff")
    assert_map_error(path, "odd.tiff", fragment)


# ---------------------------------------------------------------------------------- failed saves


def test_save_into_a_file_instead_of_a_folder(tmp_path: Path) -> None:
    (tmp_path / "blocker").write_text("x")
    before = sorted(p.name for p in tmp_path.iterdir())
    for target in (tmp_path / "blocker" / "map.yaml", tmp_path / "blocker" / "sub" / "map.yaml"):
        with pytest.raises(MapFormatError, match=r"map\.yaml"):
            save_map(sample_grid(), target)
    assert sorted(p.name for p in tmp_path.iterdir()) == before
    assert (tmp_path / "blocker").read_text() == "x"


def test_save_onto_a_folder(tmp_path: Path) -> None:
    (tmp_path / "map.yaml").mkdir()
    with pytest.raises(MapFormatError, match="folder"):
        save_map(sample_grid(), tmp_path / "map.yaml")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["map.yaml"]


def test_failed_image_write_leaves_nothing(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    def broken_save(self: Image.Image, fp: object, format: str | None = None) -> None:
        fp.write(b"P5\n")  # type: ignore[attr-defined]
        raise OSError("disk full")

    monkeypatch.setattr(Image.Image, "save", broken_save)
    with pytest.raises(MapFormatError, match="disk full"):
        save_map(sample_grid(), tmp_path / "new" / "deeper" / "map.yaml")
    assert list(tmp_path.iterdir()) == []  # created folders removed again


def test_failed_replace_keeps_old_map(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    old = sample_grid()
    save_map(old, tmp_path / "map.yaml")

    def broken_replace(src: object, dst: object) -> None:
        raise PermissionError(13, "Permission denied")

    monkeypatch.setattr(os, "replace", broken_replace)
    with pytest.raises(MapFormatError, match=r"map\.yaml"):
        save_map(old.with_data(np.zeros((4, 5), dtype=np.int8)), tmp_path / "map.yaml")
    monkeypatch.undo()
    assert sorted(p.name for p in tmp_path.iterdir()) == ["map.pgm", "map.yaml"]
    assert load_map(tmp_path / "map.yaml") == old


def test_non_os_error_during_save_cleans_up(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    def exploding_fsync(fd: int) -> None:
        raise KeyboardInterrupt

    monkeypatch.setattr(os, "fsync", exploding_fsync)
    with pytest.raises(KeyboardInterrupt):
        save_map(sample_grid(), tmp_path / "sub" / "map.yaml")
    assert list(tmp_path.iterdir()) == []


@pytest.mark.parametrize("fmt", ["jpg", "", "bmp"])
def test_bad_image_format(tmp_path: Path, fmt: str) -> None:
    with pytest.raises(MapFormatError, match="image_format"):
        save_map(sample_grid(), tmp_path / "map.yaml", image_format=fmt)
    assert list(tmp_path.iterdir()) == []


def test_yaml_path_that_would_be_overwritten_by_the_image(tmp_path: Path) -> None:
    with pytest.raises(MapFormatError, match=r"map\.pgm"):
        save_map(sample_grid(), tmp_path / "map.pgm", image_format="pgm")
    assert list(tmp_path.iterdir()) == []


def test_png_format_name_is_case_insensitive(tmp_path: Path) -> None:
    save_map(sample_grid(), tmp_path / "map.yaml", image_format="PNG")
    assert (tmp_path / "map.png").exists()
    assert load_map(tmp_path / "map.yaml") == sample_grid()
