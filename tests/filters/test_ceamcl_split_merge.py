"""The splitting-merging process (paper section 3.5): a species whose occupied cells form
several connected regions splits; two species whose living domains overlap with no valley of
fitness between them merge. Set up on a real map and a simulated scan, then the filter's own
split-and-merge phase is called."""

from __future__ import annotations

import numpy as np
import pytest
from numpy.typing import NDArray

from ceamcl.filters import make_filter
from ceamcl.filters.ceamcl import CEAMCL
from ceamcl.filters.ceamcl.species import (
    ALL_PAIRS_MAX,
    SpeciesStats,
    domains_overlap,
    overlapping_pairs,
)
from ceamcl.filters.clustering import pose_cluster_labels
from ceamcl.filters.particles import ParticleSet
from ceamcl.maps.worlds import symmetric_hall, symmetric_images
from ceamcl.sensors import LaserScan, fitness
from ceamcl.simulation import Simulator

TRUTH = np.array([3.75, 3.75, np.pi / 2])  # centre of room 0, facing north (paper start)
SD = np.array([0.08, 0.08, 0.03])


@pytest.fixture(scope="module")
def scan() -> LaserScan:
    log = Simulator(symmetric_hall()).run(TRUTH[None], np.random.default_rng(7))
    return log.scan(0)


def arranged(scan: LaserScan, poses: NDArray[np.float64], species: NDArray[np.int64]) -> CEAMCL:
    """A CEAMCL on symmetric-hall whose state is ``poses`` grouped into ``species``, weighted
    by ``scan`` (what the filter holds after its weighting and evolution phases)."""
    f = make_filter("ceamcl", symmetric_hall(), np.random.default_rng(0))
    assert isinstance(f, CEAMCL)
    prepared = f.sensor.prepare(scan)
    f._prepared = prepared
    f.particle_set = ParticleSet.from_poses(poses.copy(), species.astype(np.int64))
    f.particle_set.loglik = f.sensor.log_likelihood(f.particle_set.poses, prepared)
    f.particle_set.fitness = fitness(f.particle_set.loglik, prepared, f.sensor)
    f._next_id = int(species.max()) + 1
    f.competition.dn = {int(s): 0.0 for s in np.unique(species)}
    f._refresh_stats()
    f._initialised = True  # arranged in place of an initialisation
    return f


def blob(rng: np.random.Generator, centre: NDArray[np.float64], n: int = 60) -> NDArray[np.float64]:
    p = centre + rng.standard_normal((n, 3)) * SD
    p[:, 2] = np.angle(np.exp(1j * p[:, 2]))
    return p


def members(f: CEAMCL) -> list[set[int]]:
    """The species as sets of indices into the arranged pose array (poses are not reordered
    by split or merge; they are only relabelled)."""
    return sorted(
        (
            set(np.nonzero(f.particle_set.labels == s)[0].tolist())
            for s in np.unique(f.particle_set.labels)
        ),
        key=min,
    )


# ---------------------------------------------------------------- split
def test_a_species_of_two_distant_blobs_splits(scan: LaserScan) -> None:
    rng = np.random.default_rng(1)
    a = blob(rng, TRUTH)
    b = blob(rng, TRUTH + np.array([0.0, 3.0, 0.0]))  # 3 m north, same heading
    f = arranged(scan, np.vstack([a, b]), np.zeros(120, dtype=np.int64))
    assert len(f.stats) == 1
    f._split_and_merge()
    f._refresh_stats()
    assert f.events.splits == 1.0
    assert members(f) == [set(range(60)), set(range(60, 120))]
    assert len(f.stats) == 2 and set(f.competition.dn) >= set(f.stats)
    means = sorted((s.mean for s in f.stats.values()), key=lambda m: m[1])
    np.testing.assert_allclose(means[0][:2], TRUTH[:2], atol=0.05)
    np.testing.assert_allclose(means[1][:2], TRUTH[:2] + np.array([0.0, 3.0]), atol=0.05)


def test_a_species_with_two_heading_modes_splits(scan: LaserScan) -> None:
    rng = np.random.default_rng(2)
    a = blob(rng, TRUTH)
    b = blob(rng, TRUTH + np.array([0.0, 0.0, np.pi / 2]))  # same place, 90 degrees apart
    poses = np.vstack([a, b])
    labels, count = pose_cluster_labels(poses, 0.5, np.deg2rad(30.0))
    assert count == 2
    assert np.unique(labels[:60]).size == 1 and np.unique(labels[60:]).size == 1
    assert labels[0] != labels[60]
    f = arranged(scan, poses, np.zeros(120, dtype=np.int64))
    f._split_and_merge()
    f._refresh_stats()
    assert f.events.splits == 1.0
    assert members(f) == [set(range(60)), set(range(60, 120))]
    # Two species at the same place: their living domains overlap, but the fitness along the
    # heading turn between them has a valley, so they are not merged back.
    s0, s1 = f.stats.values()
    assert domains_overlap(s0, s1)


def test_one_blob_does_not_split(scan: LaserScan) -> None:
    rng = np.random.default_rng(3)
    f = arranged(scan, blob(rng, TRUTH, 120), np.zeros(120, dtype=np.int64))
    f._split_and_merge()
    f._refresh_stats()
    assert len(f.stats) == 1 and not f.events.splits


def _weights(f: CEAMCL) -> dict[frozenset[int], float]:
    """Each species' weight in ``hypotheses()``, keyed by its members (arranged indices)."""
    by_id = {h.label: h.weight for h in f.hypotheses()}
    return {
        frozenset(np.nonzero(f.particle_set.labels == sid)[0].tolist()): by_id[sid]
        for sid in f.stats
    }


@pytest.mark.parametrize("best_in_child", [False, True])
def test_a_split_part_holds_the_weight_its_own_samples_earn(
    scan: LaserScan, best_in_child: bool
) -> None:
    """A tracked species splits: its samples at the truth and a group 1 m off and turned
    1 rad. Each part keeps the species' past evidence but not the evidence of the other
    part's samples: the part that holds the best sample keeps the species' weight, the other
    falls behind by its best sample's log-likelihood deficit (docs/ceamcl.md, "a split part's
    own evidence"). Before, both parts inherited the whole and held 50 % each, and the state
    experiment scored a wrong place holding half the weight."""
    rng = np.random.default_rng(9)
    right = blob(rng, TRUTH, 70)
    turned = blob(rng, TRUTH + np.array([1.0, 0.0, 1.0]), 40)  # the smaller part: a child
    poses = np.vstack([turned, right]) if best_in_child else np.vstack([right, turned])
    f = arranged(scan, poses, np.zeros(110, dtype=np.int64))
    f.log_weight = {0: 0.0}
    ll = f.particle_set.loglik.copy()
    f._split_and_merge(scores=ll)
    assert f.events.splits == 1.0 and len(f.stats) == 2
    right_idx = frozenset(range(40, 110) if best_in_child else range(70))
    turned_idx = frozenset(range(40) if best_in_child else range(70, 110))
    w = _weights(f)
    deficit = float(np.max(ll[list(turned_idx)]) - np.max(ll[list(right_idx)]))
    assert deficit < np.log(0.05)  # the other group fits the room clearly worse
    np.testing.assert_allclose(w[turned_idx] / w[right_idx], np.exp(deficit), rtol=1e-9)
    assert w[right_idx] > 0.95
    assert f.state().n_hypotheses <= 1  # the turned part holds no weight worth a rival

    # Without the step's scores (a split at initialisation), both parts keep the whole's.
    g = arranged(scan, poses, np.zeros(110, dtype=np.int64))
    g.log_weight = {0: 0.0}
    g._split_and_merge()
    assert sorted(_weights(g).values()) == pytest.approx([0.5, 0.5])


# ---------------------------------------------------------------- merge
def test_overlapping_species_without_a_valley_merge(scan: LaserScan) -> None:
    rng = np.random.default_rng(4)
    a = blob(rng, TRUTH + np.array([0.1, 0.0, 0.0]))
    b = blob(rng, TRUTH - np.array([0.1, 0.0, 0.0]))
    f = arranged(scan, np.vstack([a, b]), np.r_[np.zeros(60), np.ones(60)].astype(np.int64))
    s0, s1 = f.stats[0], f.stats[1]
    assert domains_overlap(s0, s1)
    # No valley: the likelihood at the truth, between them, is at least that of either end.
    prepared = f._prepared
    assert prepared is not None
    probes = np.vstack([s0.mean, TRUTH, s1.mean])
    fit = fitness(f.sensor.log_likelihood(probes, prepared), prepared, f.sensor)
    assert fit[1] >= min(fit[0], fit[2])
    fitter = 0 if s0.fitness >= s1.fitness else 1
    f._split_and_merge()
    f._refresh_stats()
    assert f.events.merges == 1.0
    assert list(f.stats) == [fitter]  # the less fit joins the fitter
    assert f.stats[fitter].n == 120
    np.testing.assert_allclose(f.stats[fitter].mean[:2], TRUTH[:2], atol=0.1)


def test_species_at_distant_symmetric_images_do_not_merge(scan: LaserScan) -> None:
    rng = np.random.default_rng(5)
    images = symmetric_images(TRUTH)
    a = blob(rng, images[0])
    b = blob(rng, images[2])  # the opposite room: equally fit, 10.6 m away
    f = arranged(scan, np.vstack([a, b]), np.r_[np.zeros(60), np.ones(60)].astype(np.int64))
    f._split_and_merge()
    f._refresh_stats()
    assert not f.events.merges
    assert members(f) == [set(range(60)), set(range(60, 120))]


def test_overlapping_domains_with_a_valley_do_not_merge(scan: LaserScan) -> None:
    """Two images in neighbouring rooms, each species with a few stray individuals spread
    along the hall: the (unweighted) living domains overlap, the (weighted) means stay at the
    images, and the valley between them, through the board, keeps them apart."""
    rng = np.random.default_rng(6)
    images = symmetric_images(TRUTH)
    parts, labels = [], []
    for sid, image in enumerate(images[:2]):  # room 0 and room 1, 7.5 m apart along x
        stray = np.column_stack(
            [rng.uniform(0.5, 14.5, 30), rng.normal(3.75, 0.3, 30), rng.uniform(-np.pi, np.pi, 30)]
        )
        parts += [blob(rng, image), stray]
        labels += [np.full(90, sid)]
    f = arranged(scan, np.vstack(parts), np.concatenate(labels))
    s0, s1 = f.stats[0], f.stats[1]
    np.testing.assert_allclose(s0.mean[:2], images[0, :2], atol=0.1)
    np.testing.assert_allclose(s1.mean[:2], images[1, :2], atol=0.1)
    assert domains_overlap(s0, s1)
    f._merge()
    f._refresh_stats()
    assert not f.events.merges
    assert sorted(f.stats) == [0, 1]


# ---------------------------------------------------------------- heading wrap
def test_pose_cluster_joins_across_the_heading_wrap() -> None:
    rng = np.random.default_rng(8)
    n = 200
    xy = rng.normal(2.0, 0.1, (n, 2))
    # Headings within 10 degrees of 180: half just below +pi, half just above -pi.
    th = np.pi - np.abs(rng.normal(0, np.deg2rad(4.0), n))
    th[n // 2 :] = -th[n // 2 :]
    labels, count = pose_cluster_labels(np.column_stack([xy, th]), 0.5, np.deg2rad(30.0))
    assert count == 1
    assert np.all(labels == 0)
    # Control: the same cloud turned to face 0 degrees is also one cluster, and two clouds
    # facing 0 and 180 degrees are two.
    _, count0 = pose_cluster_labels(np.column_stack([xy, th - np.pi]), 0.5, np.deg2rad(30))
    assert count0 == 1
    both = np.vstack(
        [np.column_stack([xy, th]), np.column_stack([xy, np.angle(np.exp(1j * (th - np.pi)))])]
    )
    _, count2 = pose_cluster_labels(both, 0.5, np.deg2rad(30.0))
    assert count2 == 2


def test_one_cell_joins_every_region_it_touches_across_the_heading_wrap() -> None:
    # Heading slices of 45 degrees; one cell in the last slice (just below +pi) at x-cell 1
    # touches two first-slice cells (just above -pi) at x-cells 0 and 2, which do not touch
    # each other: all three are one region.
    th_last, th_first = np.pi - 0.1, -np.pi + 0.1
    poses = np.array([[1.5, 0.5, th_last], [0.5, 0.5, th_first], [2.5, 0.5, th_first]])
    labels, count = pose_cluster_labels(poses, 1.0, np.pi / 4)
    assert count == 1
    assert labels.tolist() == [0, 0, 0]
    # Control: without the bridging cell the two first-slice cells are two regions.
    _, count_apart = pose_cluster_labels(poses[1:], 1.0, np.pi / 4)
    assert count_apart == 2


def test_overlapping_pairs_from_the_tree_are_every_pair_that_overlaps() -> None:
    """Above ``ALL_PAIRS_MAX`` species a k-d tree proposes the pairs to test: the result is
    the all-pairs test's, pair for pair and in the same order, for species crowded together
    (many overlaps), spread out, of very different widths, and with a domain of zero width."""
    rng = np.random.default_rng(45)
    found = []
    for trial in range(12):
        m = int(rng.integers(ALL_PAIRS_MAX + 1, 400))
        spread = [3.0, 30.0, 300.0][trial % 3]
        poses = np.column_stack([rng.uniform(0, spread, (m, 2)), rng.uniform(-3, 3, m)])
        stats = []
        for k in range(m):
            sd = rng.choice([0.0, 0.02, 0.3, 2.0]) * rng.uniform(0.5, 1.5, 2)
            angle = rng.uniform(0, np.pi)
            axes = np.array([[np.cos(angle), -np.sin(angle)], [np.sin(angle), np.cos(angle)]])
            stats.append(
                SpeciesStats(
                    species_id=k,
                    members=np.arange(1),
                    weights=np.ones(1),
                    mean=poses[k],
                    covariance=np.eye(3),
                    cov_xy=np.eye(2),
                    heading_sd=0.1,
                    fitness=1.0,
                    domain_variances=sd**2,
                    domain_axes=axes,
                    area_m2=0.0,
                )
            )
        got = overlapping_pairs(stats)
        want = [
            (i, j) for i in range(m) for j in range(i + 1, m) if domains_overlap(stats[i], stats[j])
        ]
        assert got == want
        found.append(len(want))
    assert min(found[0::3]) > 100  # crowded: many pairs overlap
    assert max(found[2::3]) < 50  # spread out: few do
