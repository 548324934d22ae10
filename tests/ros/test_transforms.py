"""The node's planar TF buffer: composition, chains, interpolation, refusals."""

from __future__ import annotations

import math

import pytest

from ceamcl.ros.transforms import (
    ExtrapolationError,
    TransformBuffer,
    TransformError,
    compose,
    inverse,
    is_upside_down,
    quaternion_of,
    yaw_of,
)


def close(a, b, tol=1e-9) -> bool:  # type: ignore[no-untyped-def]
    return all(abs(x - y) < tol for x, y in zip(a, b, strict=True))


def test_compose_and_inverse() -> None:
    a = (1.0, 2.0, math.pi / 2)
    b = (1.0, 0.0, 0.0)
    assert close(compose(a, b), (1.0, 3.0, math.pi / 2))
    assert close(compose(a, inverse(a)), (0.0, 0.0, 0.0))
    assert close(compose(inverse(a), a), (0.0, 0.0, 0.0))
    for yaw in (-3.0, -1.0, 0.0, 2.5):
        assert abs(yaw_of(*quaternion_of(yaw)) - yaw) < 1e-12
    assert is_upside_down(1.0, 0.0, 0.0, 0.0) and not is_upside_down(*quaternion_of(1.0))


def test_chain_lookup_and_interpolation() -> None:
    tf = TransformBuffer()
    tf.set_transform("base", "laser", (0.2, 0.0, math.pi), 0.0, static=True)
    tf.set_transform("odom", "base", (0.0, 0.0, 0.0), 10.0, static=False)
    tf.set_transform("odom", "base", (1.0, 0.0, 0.4), 11.0, static=False)
    assert close(tf.lookup("odom", "base", 10.5), (0.5, 0.0, 0.2))
    assert close(tf.lookup("odom", "laser", 11.0), compose((1.0, 0.0, 0.4), (0.2, 0.0, math.pi)))
    # the reverse direction is the inverse
    assert close(tf.lookup("laser", "odom", 11.0), inverse(tf.lookup("odom", "laser", 11.0)))
    # yaw interpolates along the shorter arc
    tf.set_transform("odom", "wheel", (0.0, 0.0, 3.0), 10.0, static=False)
    tf.set_transform("odom", "wheel", (0.0, 0.0, -3.0), 11.0, static=False)
    yaw = tf.lookup("odom", "wheel", 10.5)[2]
    assert abs(abs(yaw) - math.pi) < 1e-9


def test_a_post_dated_parent_does_not_block_lookups_below_it() -> None:
    tf = TransformBuffer()
    tf.set_transform("odom", "base", (1.0, 0.0, 0.0), 5.0, static=False)
    tf.set_transform("map", "odom", (0.0, 1.0, 0.0), 99.0, static=False)
    assert close(tf.lookup("odom", "base", 5.0), (1.0, 0.0, 0.0))
    with pytest.raises(ExtrapolationError, match="outside the samples"):
        tf.lookup("map", "base", 5.0)


def test_refusals_name_the_frames() -> None:
    tf = TransformBuffer()
    tf.set_transform("odom", "base", (0.0, 0.0, 0.0), 1.0, static=False)
    with pytest.raises(TransformError, match=r"'nowhere'.*not connected"):
        tf.lookup("base", "nowhere", 1.0)
    with pytest.raises(ExtrapolationError):
        tf.lookup("odom", "base", 2.0)
    with pytest.raises(TransformError, match="non-finite"):
        tf.set_transform("odom", "base", (math.nan, 0.0, 0.0), 1.5, static=False)
    with pytest.raises(TransformError, match="bad frame ids"):
        tf.set_transform("odom", "odom", (0.0, 0.0, 0.0), 1.5, static=False)


def test_history_is_bounded_and_restarts_after_a_jump_back() -> None:
    tf = TransformBuffer()
    for k in range(5_000):
        tf.set_transform("odom", "base", (0.01 * k, 0.0, 0.0), 0.01 * k, static=False)
    edge = tf._edges["base"]
    assert len(edge.times) <= 2_000 and edge.times[-1] - edge.times[0] <= 10.0
    tf.set_transform("odom", "base", (0.0, 0.0, 0.0), 0.0, static=False)  # a replay restarts
    assert tf.lookup("odom", "base", 0.0) == (0.0, 0.0, 0.0)
