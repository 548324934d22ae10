"""The node as a process, fed the paper's run of the hall through real DDS (on this host).

Symmetric hall: four rooms alike, so the node must keep the four symmetric poses as
hypotheses. Marked hall: the mark in the goal room breaks the symmetry, so ``amcl_pose``
must end on the truth. Both check that ``map -> odom`` composed with the odometry gives the
published estimate.
"""

from __future__ import annotations

import time
from pathlib import Path

import numpy as np
import pytest

from ceamcl.maps.worlds import rotate_poses_about_centre
from ceamcl.simulation.scenarios import paper_scenario

pytestmark = pytest.mark.needs_ros

TOLERANCE_S = 0.5
#: Whole run through the node, wall clock (about 15 s on 2 shared cores).
RUN_BUDGET_S = 150.0


def run_route(  # type: ignore[no-untyped-def]
    driver,
    world: str,
    tmp_path: Path,
    seed: int = 0,
    extra: dict[str, float] | None = None,
    log=None,
):
    from tests.ros.harness import NodeProcess, pose_error

    scenario = paper_scenario(0, world)
    if log is None:
        log = scenario.simulate(np.random.default_rng(seed))
    args = ["--ros-args", "-p", f"seed:={seed}", "-p", f"transform_tolerance:={TOLERANCE_S}"]
    for name, value in (extra or {}).items():
        args += ["-p", f"{name}:={value}"]
    with NodeProcess(tmp_path, args) as node:
        driver.configure_and_activate()
        driver.start_run(node, log, scenario.grid())
        t0 = 1_000.0
        driver.map_to_odom.clear()
        deadline = time.monotonic() + RUN_BUDGET_S
        missed = []
        for k in range(len(log)):
            if time.monotonic() > deadline:
                pytest.fail(f"run not done in {RUN_BUDGET_S} s (step {k})\n{node.log()[-3000:]}")
            if not driver.step(log, k, t0, TOLERANCE_S, timeout_s=10.0):
                missed.append(k)
                if len(missed) >= 3:
                    break
        assert not missed, f"no map -> odom for steps {missed[:10]}...\n{node.log()[-3000:]}"
        assert driver.spin_until(lambda: len(driver.poses) > 0, 10.0)
        assert node.alive
        final_stamp = t0 + float(log.times[-1])
        return log, final_stamp, node, pose_error


def latest_pose(driver):  # type: ignore[no-untyped-def]
    from ceamcl.ros.messages import pose2_from_msg, seconds

    msg = driver.poses[-1]
    return seconds(msg.header.stamp), pose2_from_msg(msg.pose.pose)


def check_tf_composes(driver, log, t0: float, stamp: float, estimate) -> None:  # type: ignore[no-untyped-def]
    from tests.ros.harness import composed, pose_error

    k = int(np.argmin(np.abs(t0 + log.times - stamp)))
    map_T_odom = driver.map_to_odom[stamp + TOLERANCE_S]
    d, a = pose_error(composed(map_T_odom, log.odometry[k]), estimate)
    assert d < 1e-6 and a < 1e-6, (d, a)


def test_symmetric_hall_four_hypotheses(driver, tmp_path: Path) -> None:
    from tests.ros.harness import pose_error

    driver.poses.clear()
    driver.hypotheses.clear()
    driver.states.clear()
    log, _, _, _ = run_route(driver, "symmetric-hall", tmp_path)
    stamp, estimate = latest_pose(driver)
    check_tf_composes(driver, log, 1_000.0, stamp, estimate)
    assert driver.spin_until(lambda: len(driver.hypotheses) > 0, 5.0)
    from ceamcl.ros.messages import pose2_from_msg

    hyps = [pose2_from_msg(p) for p in driver.hypotheses[-1].poses]
    truth = log.true_poses[-1]
    images = [rotate_poses_about_centre(truth, q)[0] for q in range(4)]
    for q, image in enumerate(images):
        best = min(hyps, key=lambda h: pose_error(h, image)[0])
        d, a = pose_error(best, image)
        assert d < 0.3 and a < 0.3, f"image {q} {image}: nearest hypothesis {best} ({d:.2f} m)"
    assert driver.markers and len(driver.markers[-1].markers) >= 1 + 3 * 4
    # ~/state: the four images are one AMBIGUOUS state with four hypotheses
    assert driver.spin_until(lambda: len(driver.states) > 0, 5.0)
    state = driver.last_state()
    assert state["state"] == "AMBIGUOUS" and state["n_hypotheses"] == "4", state


def test_marked_hall_converges_to_truth(driver, tmp_path: Path) -> None:
    from tests.ros.harness import pose_error

    driver.poses.clear()
    driver.states.clear()
    log, _, _, _ = run_route(driver, "marked-hall", tmp_path)
    stamp, estimate = latest_pose(driver)
    d, a = pose_error(estimate, log.true_poses[-1])
    assert d < 0.3 and a < 0.3, f"amcl_pose {estimate} vs truth {log.true_poses[-1]}"
    assert driver.spin_until(lambda: len(driver.states) > 0, 5.0)
    assert driver.last_state()["state"] == "LOCALISED", driver.last_state()
    check_tf_composes(driver, log, 1_000.0, stamp, estimate)


def test_the_node_process_ends_the_demos_run_with_the_demos_hypotheses(
    driver,
    tmp_path: Path,  # type: ignore[no-untyped-def]
) -> None:
    """``ceamcl demo --seed 0``'s run of the symmetric hall through the node process with the
    demo's settings (tests/ros/test_node_reproduces_demo.py): the four published hypotheses are
    the demo's, to the float32 rounding of the ranges (measured offline: 0.018-0.042 m)."""
    from ceamcl.demo import run_demo, seeded_generators
    from ceamcl.ros.messages import pose2_from_msg
    from tests.ros.harness import pose_error
    from tests.ros.test_node_reproduces_demo import DEMO_SETTINGS

    demo = run_demo("ceamcl", world="symmetric-hall", seed=0)
    scenario = paper_scenario(0, "symmetric-hall")
    log = scenario.simulate(seeded_generators(0, 2)[0], scenario.grid())
    driver.hypotheses.clear()
    run_route(driver, "symmetric-hall", tmp_path, seed=0, extra=DEMO_SETTINGS, log=log)
    assert driver.spin_until(lambda: len(driver.hypotheses) > 0, 5.0)
    hyps = [pose2_from_msg(p) for p in driver.hypotheses[-1].poses]
    expected = demo.result.hypotheses[-1][:, :3]
    assert len(hyps) == len(expected) == 4
    for h in hyps:
        d, a = min(pose_error(h, e) for e in expected)
        assert d < 0.1 and a < 0.1, f"hypothesis {h}: nearest of the demo's {d:.3f} m off"
