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


def _domain_id() -> int:
    """1..100, inside the range whose ports are always valid: a domain per session (by process
    id); under pytest-xdist (``make test`` runs two workers) the session's workers share the
    run's id, a random string, and each takes its own domain from it by its worker number,
    so two workers of one run never share a domain."""
    worker = os.environ.get("PYTEST_XDIST_WORKER")  # "gw0", "gw1", ...
    run = os.environ.get("PYTEST_XDIST_TESTRUNUID")
    if worker is None or run is None or not worker.startswith("gw"):
        return 1 + os.getpid() % 100
    index = int(worker[2:])
    count = max(1, int(os.environ.get("PYTEST_XDIST_WORKER_COUNT", "1")))
    slots = 100 // count
    return 1 + (int(run, 16) % slots) * count + index % count


os.environ["ROS_DOMAIN_ID"] = str(_domain_id())

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


@pytest.fixture(scope="session", autouse=True)
def compiled_kernels() -> None:
    """The kernels in Numba's cache before any node starts: a node readies them when it is
    configured (``ceamcl.warmup``), which on a cold cache (a fresh clone) is compiling for
    tens of seconds on a busy machine, longer than a test's lifecycle transition waits; from
    the cache it is a fraction of a second."""
    from ceamcl.warmup import warm_up

    warm_up()


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
