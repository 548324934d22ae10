"""Drawing shared by the figures and the animation: the map under everything."""

from __future__ import annotations

import numpy as np
from matplotlib.axes import Axes

from ceamcl.maps.grid import OccupancyGrid


def draw_map(ax: Axes, grid: OccupancyGrid) -> None:
    """The grid in world coordinates: occupied black, unknown grey, free white."""
    img = np.full(grid.data.shape, 1.0)
    img[grid.unknown_mask] = 0.75
    img[grid.occupied_mask] = 0.0
    x0, x1, y0, y1 = grid.bounds
    if grid.origin[2] == 0.0:
        ax.imshow(
            img,
            origin="lower",
            cmap="gray",
            vmin=0,
            vmax=1,
            interpolation="nearest",
            extent=(x0, x1, y0, y1),
        )
    else:
        iy, ix = np.nonzero(grid.occupied_mask)
        x, y = grid.cell_to_world(ix, iy)
        ax.scatter(x, y, s=0.5, c="k", marker="s")
    ax.set_aspect("equal")
    ax.set_xlabel("x [m]")
    ax.set_ylabel("y [m]")
