"""A recovery keeps the species the filter had beside the new ones (``recovery_prior``,
docs/ceamcl.md departure 9): when the kidnap test fires while the tracked hypothesis still
explains the scans, the estimate stays on it instead of passing to whichever look-alike place
fits the step's scan as well; a robot that was really carried off is still found again (the
kidnap tests in ``test_ceamcl_recovery.py`` run with the default)."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from ceamcl.experiments.routes import paper_course
from ceamcl.filters import make_filter
from ceamcl.filters.ceamcl import CEAMCL, CEAMCLConfig
from ceamcl.motion.odometry import OdometryIncrement
from ceamcl.pose import position_error

STILL = OdometryIncrement(0.0, 0.0, 0.0)


def tracked_then_recovered(seed: int, config: CEAMCLConfig) -> tuple[CEAMCL, np.ndarray, int]:
    """Track the robot at the centre of room 0 of the symmetric hall (four rooms that look
    alike), then make the kidnap test fire at the next step, as a stretch of scans the map
    explains poorly would; returns the filter after that step, the truth and the old species'
    id."""
    course = paper_course()
    log = course.scenario(0).simulate(np.random.default_rng(seed), course.grid())
    f = make_filter("ceamcl", course.grid(), np.random.default_rng(seed), config=config)
    assert isinstance(f, CEAMCL)
    f.initialise_pose(log.true_poses[0], np.diag([0.05**2, 0.05**2, 0.03**2]))
    for _ in range(3):
        f.step(STILL, log.scan(0))
    (tracked,) = f.stats
    # the kidnap test's running averages after fitness that collapsed (filter.py)
    f._steps_since_init = f.config.recovery_warmup_steps + 1
    f._fit_slow, f._fit_fast = 1.0, 0.0
    record = f.step(STILL, log.scan(0))
    assert record.reinitialised and record.columns()["recoveries"] == 1.0
    return f, log.true_poses[0], tracked


@pytest.mark.parametrize(("seed", "prior"), [(0, None), (1, None), (2, None), (0, 1e-2)])
def test_a_recovery_keeps_the_tracked_hypothesis_beside_the_new_ones(
    seed: int, prior: float | None
) -> None:
    config = CEAMCLConfig() if prior is None else replace(CEAMCLConfig(), recovery_prior=prior)
    f, truth, tracked = tracked_then_recovered(seed, config)
    hyps = f.hypotheses()
    # the restart proposed the other rooms' look-alikes ...
    images = paper_course().images(truth)
    for image in images[1:]:
        assert min(position_error(h.pose, image) for h in hyps) < 0.5
    # ... each at about recovery_prior of the tracked hypothesis' weight (they fit the scan as
    # well as it does; polished test poses may fit a little better), which keeps the lead
    lead = hyps[0]
    assert lead.label == tracked
    assert position_error(f.estimate().pose, truth) < 0.5
    p = f.config.recovery_prior
    assert p is not None
    newcomers = [h.weight / lead.weight for h in hyps[1:]]
    assert len(newcomers) >= 3
    assert max(newcomers) < 3 * p and np.median(newcomers) > p / 3


def test_without_a_prior_the_recovery_starts_from_the_scan_alone() -> None:
    f, _, tracked = tracked_then_recovered(0, replace(CEAMCLConfig(), recovery_prior=None))
    assert tracked not in f.stats
    weights = sorted((h.weight for h in f.hypotheses()), reverse=True)
    assert weights[0] < 0.5  # four rooms that look alike share the weight
