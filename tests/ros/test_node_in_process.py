"""The node's parameter handling and lifecycle, run in this process (no DDS traffic needed):
what counts as set by the user, runtime parameter sets, scans held across a deactivate."""

from __future__ import annotations

from collections.abc import Iterator
from typing import Any

import pytest

pytestmark = pytest.mark.needs_ros


@pytest.fixture
def make_node() -> Iterator[Any]:
    import rclpy

    made: list[tuple[Any, Any]] = []

    def make(*params: str) -> Any:
        from ceamcl.ros.node import LocalisationNode

        context = rclpy.Context()
        args = ["--ros-args", *[a for p in params for a in ("-p", p)]]
        rclpy.init(args=args, context=context)
        node = LocalisationNode(context=context)
        made.append((node, context))
        return node

    yield make
    for node, context in made:
        node.destroy_node()
        rclpy.shutdown(context=context)


def test_nav2_defaults_declared_by_the_node_do_not_count_as_set(make_node: Any) -> None:
    """The node declares every Nav2 parameter with its default; all of them counted as set,
    so kld-amcl-recovery ran with Nav2's 0.0 recovery rates (recovery off) and the presets
    lost their tuned particle count, beams and KLD quantile."""
    from ceamcl.filters import registry
    from ceamcl.ros.localiser import chosen_sensor_settings, particle_budget

    node = make_node("algorithm:=kld-amcl-recovery")
    node.trigger_configure()
    own = registry.get("kld-amcl-recovery").default()
    assert node.params.config.recovery
    assert (node.params.config.alpha_slow, node.params.config.kld_z) == (
        own.alpha_slow,
        own.kld_z,
    )
    tuned = make_node("algorithm:=kld-amcl-tuned")
    tuned.trigger_configure()
    assert particle_budget(tuned.params) is None and chosen_sensor_settings(tuned.params) == {}
    # what the command line sets is set
    chosen = make_node("algorithm:=kld-amcl-recovery", "recovery_alpha_slow:=0.002")
    chosen.trigger_configure()
    assert chosen.params.config.alpha_slow == 0.002


def test_runtime_parameter_sets_are_checked_and_refused_once_configured(
    make_node: Any,
) -> None:
    """`ros2 param set` reported success for every value, typos and bad values included,
    applied none of them, and a bad one broke the next configure."""
    from rclpy.parameter import Parameter

    node = make_node()
    (typo,) = node.set_parameters([Parameter("alhpa1", value=0.3)])
    assert not typo.successful and "unknown parameter: alhpa1" in typo.reason
    (bad,) = node.set_parameters([Parameter("max_beams", value=-4)])
    assert not bad.successful and "max_beams" in bad.reason
    (good,) = node.set_parameters([Parameter("max_particles", value=1500)])
    assert good.successful
    node.trigger_configure()
    assert node.params["max_particles"] == 1500 and "max_particles" in node.params.given
    (late,) = node.set_parameters([Parameter("alpha1", value=0.5)])
    assert not late.successful and "reads its parameters at configure" in late.reason
    assert node.params["alpha1"] != 0.5


def test_a_scan_held_for_its_transform_is_not_stepped_after_deactivate(
    make_node: Any,
) -> None:
    node = make_node()
    node.trigger_configure()
    node.trigger_activate()
    node.waiting.append((object(), "waiting for odom"))
    node.trigger_deactivate()
    assert not node.waiting and not node.active
    node.waiting.append((object(), "an odometry transform comes after deactivate"))
    node._retry_waiting()  # what a /tf message does
    assert not node.waiting
