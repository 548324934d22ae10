"""Reading and writing files: trajectories (TUM), maps (see ``ceamcl.maps.ros_io``)."""
