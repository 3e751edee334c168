"""flexmotion_ros: time-optimal and vibration-free moves for flexible machines.

``flexmotion_ros.core`` is the ROS-free numerical core (numpy/scipy only);
``flexmotion_ros.nodes`` holds the thin rclpy adapters; ``flexmotion_ros.cli``
the ``flexmotion`` command line.  Importing this package never imports rclpy.
"""

__version__ = "0.1.0"
