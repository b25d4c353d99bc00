"""ROS 2 on the wire: the DDS bridge (``cufund ros2``) and ROS 2 bags of runs (``cufund bag``)."""
