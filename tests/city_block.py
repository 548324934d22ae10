"""Brute-force city-block distances to labelled seed regions, the ground truth the SKIZ
partition's tests compare with."""

from __future__ import annotations

import numpy as np


def seed_distances(seeds: np.ndarray) -> tuple[list[int], np.ndarray]:
    """The labels present in ``seeds`` (> 0) and, stacked in that order, each cell's
    city-block distance to the nearest cell of each label: ``(n_labels, *seeds.shape)``."""
    labels = [lab for lab in range(1, int(seeds.max(initial=0)) + 1) if np.any(seeds == lab)]
    ys, xs = np.indices(seeds.shape)
    dist = (
        np.stack(
            [
                np.min(
                    np.abs(ys[..., None] - np.nonzero(seeds == lab)[0])
                    + np.abs(xs[..., None] - np.nonzero(seeds == lab)[1]),
                    axis=-1,
                )
                for lab in labels
            ]
        )
        if labels
        else np.zeros((0, *seeds.shape), dtype=np.intp)
    )
    return labels, dist
