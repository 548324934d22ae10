"""The core never imports ROS: importing the library and its filters loads no rclpy."""

from __future__ import annotations

from tests.architecture.imports import loaded_at_run_time


def test_core_imports_no_ros() -> None:
    code = (
        "import ceamcl, ceamcl.filters, ceamcl.filters.registry, ceamcl.maps.ros_io, "
        "ceamcl.simulation, ceamcl.cli, ceamcl.ros, ceamcl.ros.params, ceamcl.ros.transforms"
    )
    roots = ("rclpy", "rcl_interfaces", "geometry_msgs", "sensor_msgs", "tf2_msgs")
    assert loaded_at_run_time(code, roots) == []
