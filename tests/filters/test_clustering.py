"""The compiled pose clustering (CEAMCL's split rule, KLD-AMCL's hypotheses) against SciPy's
``ndimage.label`` on a dense grid: the same regions, numbered the same way."""

from __future__ import annotations

import numpy as np
import pytest

from ceamcl.filters.clustering import pose_cluster_labels, pose_cluster_labels_reference


def _random_poses(rng: np.random.Generator) -> np.ndarray:
    n = int(rng.integers(1, 300))
    k = int(rng.integers(1, 6))
    centres = np.column_stack([rng.uniform(-5, 5, (k, 2)), rng.uniform(-np.pi, np.pi, k)])
    sd_xy, sd_th = rng.uniform(0.05, 1.5), rng.uniform(0.05, 1.0)
    p = centres[rng.integers(0, k, n)] + rng.normal(0.0, [sd_xy, sd_xy, sd_th], (n, 3))
    p[:, 2] = np.arctan2(np.sin(p[:, 2]), np.cos(p[:, 2]))
    return p


@pytest.mark.parametrize("cell_rad", [0.1, np.deg2rad(30.0), 2.5, 4.0, 7.0])
@pytest.mark.parametrize("cell_m", [0.1, 0.5, 1.0])
def test_compiled_labels_equal_the_dense_grid_reference(cell_m: float, cell_rad: float) -> None:
    # cell_rad 2.5 gives two heading cells (no wrap), 4.0 and 7.0 one; the others wrap at pi.
    rng = np.random.default_rng(int(cell_m * 100 + cell_rad * 10))
    split = 0
    for _ in range(60):
        poses = _random_poses(rng)
        labels, count = pose_cluster_labels(poses, cell_m, cell_rad)
        ref_labels, ref_count = pose_cluster_labels_reference(poses, cell_m, cell_rad)
        assert count == ref_count
        np.testing.assert_array_equal(labels, ref_labels)
        split += count > 1
    assert split > 0  # the cases include several regions


def test_regions_join_across_the_heading_wrap() -> None:
    th = np.array([np.pi - 0.05, -np.pi + 0.05, 0.0])
    labels, count = pose_cluster_labels(np.column_stack([np.zeros(3), np.zeros(3), th]), 0.5, 0.3)
    assert count == 2
    assert labels[0] == labels[1] != labels[2]


def test_pose_that_is_not_finite_or_too_far_is_a_clear_error() -> None:
    with pytest.raises(ValueError, match="not finite"):
        pose_cluster_labels(np.array([[np.nan, 0.0, 0.0]]), 0.5, 0.5)
    with pytest.raises(ValueError, match="spread too far"):
        pose_cluster_labels(np.array([[1e300, 0.0, 0.0], [-1e300, 0.0, 0.0]]), 0.5, 0.5)
