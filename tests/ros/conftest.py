"""ROS 2 tests: real rclpy, DDS kept on this machine, every process bounded and ended.

Discovery is limited to this host (``ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST``) and each test
session takes its own ``ROS_DOMAIN_ID``, so parallel sessions on a shared machine do not see
each other. Skipped with a reason where rclpy or tf2_msgs is missing (``make test`` installs
both; see docs/ros.md).
"""

from __future__ import annotations

import os
from collections.abc import Iterator

import pytest

os.environ["ROS_AUTOMATIC_DISCOVERY_RANGE"] = "LOCALHOST"
os.environ.setdefault("RMW_IMPLEMENTATION", "rmw_fastrtps_cpp")
# 1..100: a domain per session (by process id), inside the range whose ports are always valid
os.environ["ROS_DOMAIN_ID"] = str(1 + os.getpid() % 100)

try:
    import rclpy  # noqa: F401
    import tf2_msgs.msg  # noqa: F401

    MISSING = None
except ImportError as exc:
    MISSING = f"ROS 2 Python packages not installed ({exc}); `make test` installs them"


def pytest_collection_modifyitems(config: pytest.Config, items: list[pytest.Item]) -> None:
    if MISSING is None:
        return
    for item in items:
        if "needs_ros" in item.keywords:
            item.add_marker(pytest.mark.skip(reason=MISSING))


@pytest.fixture
def driver() -> Iterator[object]:
    """The test's own ROS node (publishes inputs, listens to outputs); one per test, so no
    latched message of an earlier test reaches the next node."""
    from tests.ros.harness import Driver

    d = Driver()
    try:
        yield d
    finally:
        d.close()
