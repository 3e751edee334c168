"""flexmotion_ros: time-optimal and vibration-free moves for flexible machines.

``flexmotion_ros.core`` is the ROS-free numerical core (numpy/scipy only);
``flexmotion_ros.nodes`` holds the thin rclpy adapters; ``flexmotion_ros.cli``
the ``flexmotion`` command line.  Importing this package never imports rclpy.
"""

import os as _os

# Our matrices are tiny (the states of a modal model): BLAS threads only add
# overhead (on a loaded 2-core machine a 9x9 expm took 100x longer).  Takes
# effect if numpy is not imported yet; a user's setting always wins.
_os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
_os.environ.setdefault("OMP_NUM_THREADS", "1")

__version__ = "0.1.0"
