"""``ceamcl bench --ros-latency``'s measurement: it times every scan the node updates on and
ends its node. (The speed target itself is the bench's to judge, not a test's.)"""

from __future__ import annotations

import pytest

pytestmark = pytest.mark.needs_ros


def test_latency_measurement_is_complete() -> None:
    from ceamcl.ros.latency import measure_latency

    r = measure_latency("mcl", 300, scans=15, timeout_s=120.0)
    assert r["algorithm"] == "mcl" and r["particles"] == 300
    assert 10 <= r["scans"] <= 15  # every scan after the first where the odometry moved
    assert 0.0 < r["p50_ms"] <= r["p95_ms"] <= r["max_ms"] < 30_000.0
