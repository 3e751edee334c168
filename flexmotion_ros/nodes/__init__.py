"""ROS 2 adapters (rclpy): the planner and the simulated plant.

The nodes hold no math: every plan comes from
:func:`flexmotion_ros.core.methods.plan_move`, every simulation step from
:mod:`flexmotion_ros.core.simulation`, and the command stream and the splice of
a new plan into a running one from the ROS-free :mod:`flexmotion_ros.execution`.
One module per concept:

* :mod:`.parameters` -- parameter descriptors and their map to the core's
  :func:`~flexmotion_ros.core.config.config_from_parameters`;
* :mod:`.planner_status` -- the ``/diagnostics`` status thread;
* :mod:`.messages` -- conversions to and from standard messages;
* :mod:`.planner_node` -- ``flexmotion_planner`` (``ros2 run flexmotion_ros planner``);
* :mod:`.plant_node` -- ``flexmotion_plant`` (``ros2 run flexmotion_ros plant``).

The nodes work on matrices of size 2N + 3 at most.  A multi-threaded BLAS
only slows them down (measured: ``scipy.linalg.expm`` of a 7 x 7 matrix took
17-20 ms instead of 0.14 ms on a loaded 2-core machine), which wrecks a
real-time loop; so BLAS runs single-threaded unless the user says otherwise.
This takes effect when the nodes are the first to load numpy (the console
scripts, ``python -m``).
"""

import os as _os

for _var in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    _os.environ.setdefault(_var, "1")
