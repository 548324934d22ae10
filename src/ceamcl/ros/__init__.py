"""ROS 2 front end: ``ceamcl node``, a drop-in for Nav2's ``amcl`` (docs/ros.md).

Needs ``rclpy`` and the message packages (the ``[ros]`` extra, or a sourced ROS 2), plus
``tf2_msgs``; the core never imports this package. Importing ``ceamcl.ros`` itself loads no
ROS module: :mod:`ceamcl.ros.node` does.
"""
