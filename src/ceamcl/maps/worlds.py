"""Built-in worlds, usable by name from the API and the CLI.

``symmetric-hall``
    The paper's 15 x 15 m hall (section 4), split by thin boards (0.1 m) along its two
    midlines into four identical 7.5 x 7.5 m rooms. Each board has a 1.2 m doorway centred
    3.75 m from the hall's centre, so a robot can drive from the centre of any room into its
    neighbours and on to their corners. Each room also has one cabinet against its outer wall,
    off the room's diagonal: without it every room would be mirror-symmetric about its
    diagonal and the map would have eight images of every pose instead of four. The grid is
    built by drawing one room and stamping it at the four 90 degree rotations, so
    ``np.rot90(data)`` equals ``data`` cell for cell.

``marked-hall``
    The same hall with one box (0.6 x 0.6 m) standing out from the board on the east side of
    the north-west room (room 3). Boards hide it from almost everywhere else (it can be glimpsed
    from about 5% of the free space outside room 3, through doorways), so in practice a robot
    sees it from inside room 3: a run that ends there breaks the symmetry late.

``small-office``
    A 10 x 8 m asymmetric floor (four rooms of different sizes, two south and two north of a
    corridor, with a pillar, a shelf and a cupboard) where
    global localisation has one answer; used by tests and quick examples.

Rooms are numbered counter-clockwise from the south-west one: 0 SW, 1 SE, 2 NE, 3 NW.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from ceamcl.angles import wrap
from ceamcl.errors import ConfigError
from ceamcl.maps.grid import FREE, OCCUPIED, OccupancyGrid

HALL_SIZE_M = 15.0
HALL_RESOLUTION_M = 0.05
HALL_CENTRE = (HALL_SIZE_M / 2.0, HALL_SIZE_M / 2.0)
WALL_M = 0.1
BOARD_M = 0.1
DOOR_CENTRE_FROM_HALL_CENTRE_M = 3.75
DOOR_WIDTH_M = 1.2
# Cabinet in room 0 (south-west), against the south wall, off the room's diagonal.
CABINET_SW = (1.2, 2.6, WALL_M, 0.7)  # x0, x1, y0, y1
# The mark of marked-hall: a box against the east board of room 3 (north-west), north of the
# board's doorway.
MARK_BOX = (HALL_SIZE_M / 2 - BOARD_M / 2 - 0.6, HALL_SIZE_M / 2 - BOARD_M / 2, 12.6, 13.2)


@dataclass(frozen=True)
class WorldInfo:
    """A built-in world: its grid and, for the halls, the points the scenarios use."""

    name: str
    grid: OccupancyGrid
    description: str


def rotate_about_centre(xy: NDArray[np.float64], quarter_turns: int) -> NDArray[np.float64]:
    """Rotate points ``(N, 2)`` by ``quarter_turns`` x 90 degrees counter-clockwise about the
    hall's centre."""
    cx, cy = HALL_CENTRE
    angle = quarter_turns * np.pi / 2.0
    c, s = np.cos(angle), np.sin(angle)
    centre = np.array([cx, cy])
    p = np.asarray(xy, dtype=np.float64).reshape(-1, 2) - centre
    out = np.column_stack([c * p[:, 0] - s * p[:, 1], s * p[:, 0] + c * p[:, 1]]) + centre
    return np.round(out, 12)


def rotate_poses_about_centre(
    poses: NDArray[np.float64], quarter_turns: int
) -> NDArray[np.float64]:
    """Rotate poses ``(N, 3)`` about the hall's centre; headings turn with them."""
    p = np.asarray(poses, dtype=np.float64).reshape(-1, 3)
    xy = rotate_about_centre(p[:, :2], quarter_turns)
    return np.column_stack([xy, wrap(p[:, 2] + quarter_turns * np.pi / 2.0)])


def symmetric_images(pose: NDArray[np.float64]) -> NDArray[np.float64]:
    """The four images ``(4, 3)`` of a pose under the hall's 90 degree rotations (itself first)."""
    p = np.asarray(pose, dtype=np.float64).reshape(1, 3)
    return np.vstack([rotate_poses_about_centre(p, k) for k in range(4)])


def room_centre(room: int) -> tuple[float, float]:
    """Centre of room ``room`` (0 SW, 1 SE, 2 NE, 3 NW)."""
    q = HALL_SIZE_M / 4.0
    xy = rotate_about_centre(np.array([[q, q]]), room % 4)[0]
    return float(xy[0]), float(xy[1])


class _Canvas:
    """Marks rectangles of a world on a grid by cell centres."""

    def __init__(self, width_m: float, height_m: float, resolution: float) -> None:
        self.resolution = resolution
        self.nx = round(width_m / resolution)
        self.ny = round(height_m / resolution)
        self.data = np.full((self.ny, self.nx), FREE, dtype=np.int8)
        self.cx = (np.arange(self.nx) + 0.5) * resolution
        self.cy = (np.arange(self.ny) + 0.5) * resolution

    def rect(self, x0: float, x1: float, y0: float, y1: float, value: int = OCCUPIED) -> None:
        xs = (self.cx > min(x0, x1)) & (self.cx < max(x0, x1))
        ys = (self.cy > min(y0, y1)) & (self.cy < max(y0, y1))
        self.data[np.ix_(ys, xs)] = value

    def border(self, thickness: float) -> None:
        w, h = self.nx * self.resolution, self.ny * self.resolution
        self.rect(0, w, 0, thickness)
        self.rect(0, w, h - thickness, h)
        self.rect(0, thickness, 0, h)
        self.rect(w - thickness, w, 0, h)


def _hall_data() -> NDArray[np.int8]:
    """One quarter (room 0's walls, boards and cabinet) stamped at four rotations."""
    s, c = HALL_SIZE_M, HALL_SIZE_M / 2.0
    canvas = _Canvas(s, s, HALL_RESOLUTION_M)
    # Room 0's south and west outer walls; the rotations give the rest of the outer wall.
    canvas.rect(0.0, c, 0.0, WALL_M)
    canvas.rect(0.0, WALL_M, 0.0, c)
    # The board running west from the centre (y = 7.5), with its doorway. Rotations give the
    # other three boards, each with the doorway at the same distance from the centre.
    door_lo = c - DOOR_CENTRE_FROM_HALL_CENTRE_M - DOOR_WIDTH_M / 2.0
    door_hi = c - DOOR_CENTRE_FROM_HALL_CENTRE_M + DOOR_WIDTH_M / 2.0
    half = BOARD_M / 2.0
    canvas.rect(0.0, door_lo, c - half, c + half)
    canvas.rect(door_hi, c, c - half, c + half)
    # Room 0's cabinet.
    x0, x1, y0, y1 = CABINET_SW
    canvas.rect(x0, x1, y0, y1)
    quarter = canvas.data
    out = quarter.copy()
    for k in range(1, 4):
        out = np.maximum(out, np.rot90(quarter, k))
    return out


def symmetric_hall() -> OccupancyGrid:
    return OccupancyGrid(_hall_data(), HALL_RESOLUTION_M, (0.0, 0.0, 0.0), name="symmetric-hall")


def marked_hall() -> OccupancyGrid:
    data = _hall_data()
    canvas = _Canvas(HALL_SIZE_M, HALL_SIZE_M, HALL_RESOLUTION_M)
    canvas.data = data
    x0, x1, y0, y1 = MARK_BOX
    canvas.rect(x0, x1, y0, y1)
    return OccupancyGrid(canvas.data, HALL_RESOLUTION_M, (0.0, 0.0, 0.0), name="marked-hall")


def small_office() -> OccupancyGrid:
    w, h = 10.0, 8.0
    canvas = _Canvas(w, h, HALL_RESOLUTION_M)
    canvas.border(WALL_M)
    # Corridor along y in [3.5, 5], rooms south and north of it.
    canvas.rect(0.0, 3.2, 3.45, 3.55)  # south wall of corridor, west part
    canvas.rect(4.4, 10.0, 3.45, 3.55)  # ... east part (door 3.2-4.4)
    canvas.rect(0.0, 1.0, 4.95, 5.05)  # north wall of corridor
    canvas.rect(2.0, 7.0, 4.95, 5.05)
    canvas.rect(8.2, 10.0, 4.95, 5.05)
    canvas.rect(6.0, 6.1, 0.0, 3.5)  # divides the south into a large and a small room
    canvas.rect(6.0, 6.1, 2.0, 2.6, FREE)  # door between the south rooms
    canvas.rect(4.0, 4.1, 5.0, 8.0)  # divides the north
    canvas.rect(2.2, 2.6, 1.4, 1.8)  # pillar
    canvas.rect(7.0, 9.9, 7.3, 7.9)  # shelf in the north-east room
    canvas.rect(0.1, 0.8, 5.1, 6.6)  # cupboard in the north-west room
    return OccupancyGrid(canvas.data, HALL_RESOLUTION_M, (0.0, 0.0, 0.0), name="small-office")


_WORLDS: dict[str, tuple[Callable[[], OccupancyGrid], str]] = {
    "symmetric-hall": (symmetric_hall, "the paper's 15 x 15 m hall of four identical rooms"),
    "marked-hall": (marked_hall, "symmetric-hall with one box in the north-west room"),
    "small-office": (small_office, "a 10 x 8 m asymmetric floor with one answer"),
}

WORLD_NAMES: tuple[str, ...] = tuple(_WORLDS)


def get_world(name: str) -> OccupancyGrid:
    """The grid of a built-in world by name (see :data:`WORLD_NAMES`)."""
    try:
        factory, _ = _WORLDS[name]
    except KeyError:
        raise ConfigError(
            f"world: unknown world {name!r}; expected one of {', '.join(WORLD_NAMES)}"
        ) from None
    return factory()


def describe_worlds() -> dict[str, str]:
    return {name: desc for name, (_, desc) in _WORLDS.items()}
