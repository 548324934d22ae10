"""The core never imports ROS: importing the library and its filters loads no rclpy."""

from __future__ import annotations

import subprocess
import sys


def test_core_imports_no_ros() -> None:
    code = (
        "import sys, ceamcl, ceamcl.filters, ceamcl.filters.registry, ceamcl.maps.ros_io, "
        "ceamcl.simulation, ceamcl.cli, ceamcl.ros, ceamcl.ros.params, ceamcl.ros.transforms\n"
        "loaded = sorted(m for m in sys.modules if m.split('.')[0] in "
        "('rclpy', 'rcl_interfaces', 'geometry_msgs', 'sensor_msgs', 'tf2_msgs'))\n"
        "assert not loaded, loaded\n"
    )
    run = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
    assert run.returncode == 0, run.stderr
