"""A walled box room for tests that need a real-looking CARMEN log: exact ranges from a pose."""

from __future__ import annotations

import math

#: x_min, x_max, y_min, y_max of the room [m].
BOX = (-1.0, 3.0, -1.5, 1.5)


def box_ranges(
    x: float, y: float = 0.0, beams: int = 180, box: tuple[float, float, float, float] = BOX
) -> list[float]:
    """Ranges of a 180-degree scan from ``(x, y)`` facing +x to the walls of ``box``, first beam
    to the right (CARMEN's order)."""
    x0, x1, y0, y1 = box
    out = []
    for i in range(beams):
        a = -math.pi / 2 + math.pi * i / (beams - 1)
        dx, dy = math.cos(a), math.sin(a)
        hits = []
        if dx > 1e-9:
            hits.append((x1 - x) / dx)
        if dx < -1e-9:
            hits.append((x0 - x) / dx)
        if dy > 1e-9:
            hits.append((y1 - y) / dy)
        if dy < -1e-9:
            hits.append((y0 - y) / dy)
        out.append(min(hits))
    return out
