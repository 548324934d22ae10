"""``laser_min_range`` / ``laser_max_range`` narrow a scan's own limits as Nav2 amcl does
(``max`` of the minima, ``min`` of the maxima); they never widen them."""

from __future__ import annotations

import pytest

pytestmark = pytest.mark.needs_ros


@pytest.mark.parametrize(
    ("param_min", "param_max", "want_min", "want_max"),
    [
        (-1.0, -1.0, 0.1, 8.0),  # unset: the scan's own
        (-1.0, 100.0, 0.1, 8.0),  # Nav2's default 100 m keeps an 8 m laser's max-range readings
        (0.5, 5.0, 0.5, 5.0),  # narrower: applied
        (0.05, 12.0, 0.1, 8.0),  # wider: the scan's own
    ],
)
def test_scan_limits_are_narrowed_never_widened(
    param_min: float, param_max: float, want_min: float, want_max: float
) -> None:
    from sensor_msgs.msg import LaserScan as LaserScanMsg

    from ceamcl.ros.messages import scan_from_msg

    msg = LaserScanMsg()
    msg.angle_min, msg.angle_increment, msg.range_min, msg.range_max = -1.0, 0.5, 0.1, 8.0
    msg.ranges = [1.0, 8.0, 3.0, 8.0, 2.0]
    scan = scan_from_msg(msg, (0.0, 0.0, 0.0), range_min=param_min, range_max=param_max)
    assert scan.range_min == pytest.approx(want_min)
    assert scan.range_max == pytest.approx(want_max)
