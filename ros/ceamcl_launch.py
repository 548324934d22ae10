"""Localisation with ceamcl in place of Nav2's amcl (ros2 launch ros/ceamcl_launch.py map:=...).

The same nodes as nav2_bringup's localization_launch.py: map_server, the localiser named amcl,
and a lifecycle manager that configures and activates both. Only the amcl Node differs: it runs
the `ceamcl node` executable (pip install 'ceamcl[ros]') instead of nav2_amcl.
"""

from launch import LaunchDescription
from launch.actions import DeclareLaunchArgument
from launch.substitutions import LaunchConfiguration
from launch_ros.actions import Node


def generate_launch_description() -> LaunchDescription:
    params = LaunchConfiguration("params_file")
    return LaunchDescription([
        DeclareLaunchArgument("map", description="map YAML for map_server"),
        DeclareLaunchArgument("params_file", default_value="ceamcl_params.yaml"),
        Node(package="nav2_map_server", executable="map_server", name="map_server",
             parameters=[{"yaml_filename": LaunchConfiguration("map")}]),
        Node(executable="ceamcl", arguments=["node"], name="amcl", output="screen",
             parameters=[params]),
        # bond_timeout 0: the node does not answer Nav2's bond heartbeat (bond_msgs has no
        # PyPI wheel), and with the default 4 s the manager would abort the bringup
        Node(package="nav2_lifecycle_manager", executable="lifecycle_manager",
             name="lifecycle_manager_localization",
             parameters=[{"autostart": True, "node_names": ["map_server", "amcl"],
                          "bond_timeout": 0.0}]),
    ])
