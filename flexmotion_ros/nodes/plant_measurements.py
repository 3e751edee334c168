"""The plant's ``measurements`` topic: what a real machine's sensors read, with their noise.

``measurements`` (``sensor_msgs/JointState``, reliable, keep last 10000 -- 10 s at
1 kHz, as ``joint_states``: a reliable writer with a shorter history drops
samples a lagging reader has not acknowledged: with depth 100, one run in six
of ``test/ros/test_measurements.py`` missed readings of a 300-command burst): one
message per plant sample, ``name`` = ``measurement.names`` (physical
coordinates: a cart, a rope angle, a tip), ``position`` = the readings
whatever their kind (position m or rad, velocity m/s, acceleration m/s^2),
``velocity`` and ``effort`` empty.  The readings come from the plant's TRUE
model (the parameter file's with ``plant.omega_scale`` / ``plant.extra_zeta``
applied, or the plant's own file), through the map of
:mod:`flexmotion_ros.core.model.measurement` (``y = C x + D u`` exactly), plus
white Gaussian noise of ``plant.noise_std`` per channel (seeded by
``plant.noise_seed``: the same seed gives the same noise).

Sample convention (the one :mod:`flexmotion_ros.core.identification` uses,
"sample ``k`` is read just after command ``k`` is applied"): at ``t_k`` the
plant has state ``x_k`` and applies ``u_k``; it publishes ``y_k = C x_k + D
u_k + noise`` (``D`` is non-zero only for acceleration channels), then
integrates exactly to ``x_{k+1}``.

* Lockstep: ``y_k`` is published when command ``k`` arrives, stamped with the
  command's send time (its DDS source timestamp, system clock): the time of
  sample ``k`` on the commanding clock, however late the plant handles it, so
  a recorder can pair each reading with the command it was read after.
  While no command arrives nothing is published (the machine's time stands
  still).
* Real time: one reading per integration tick (``rate_hz`` or
  ``publish_rate_hz``), stamped with the plant's clock at the tick, with the
  command held then.

With ``plant.coulomb_force`` the acceleration channels read the model's
``A x + B u`` (the friction force is not in them).
"""

from __future__ import annotations

import numpy as np
from builtin_interfaces.msg import Time
from rclpy.node import Node
from rclpy.qos import HistoryPolicy, QoSProfile, ReliabilityPolicy
from sensor_msgs.msg import JointState

from .plant_parameters import PlantConfig

#: ``measurements``: reliable and deep (10 s at 1 kHz), so a recorder or a Kalman filter that lags a burst of a
#: lockstep plant still gets every sample (with the spec's depth 100 a 300-command burst lost readings once in six).
MEASUREMENT_QOS = QoSProfile(depth=10000, reliability=ReliabilityPolicy.RELIABLE, history=HistoryPolicy.KEEP_LAST)
#: The topic's name (relative: in the plant's namespace; remap to taste).
TOPIC = "measurements"


def stamp_from_ns(ns: int) -> Time:
    """A ``builtin_interfaces/Time`` from integer nanoseconds."""
    return Time(sec=int(ns // 1_000_000_000), nanosec=int(ns % 1_000_000_000))


class MeasurementPublisher:
    """Publishes ``y = C x + D u + noise`` on ``measurements`` for a plant node.

    Parameters
    ----------
    node : Node
        The plant.
    cfg : PlantConfig
        Its configuration (the true model, the map, the noise).
    """

    def __init__(self, node: Node, cfg: PlantConfig) -> None:
        self._node = node
        self._pub = node.create_publisher(JointState, TOPIC, MEASUREMENT_QOS)
        self._rng = np.random.default_rng(cfg.noise_seed)
        self.published = 0
        self.configure(cfg)

    def configure(self, cfg: PlantConfig) -> None:
        """Use ``cfg``'s true model and noise from the next reading on (the noise sequence continues)."""
        self.map = cfg.measurement
        # D: one column per input (several drives: a reading of an acceleration feeds every input through)
        self._C, self._D = self.map.matrices(cfg.model.A(), cfg.model.B())
        self._std = np.asarray(cfg.noise_std, float) if cfg.noise_std else np.zeros(self.map.channels)
        self._names = list(self.map.names)

    def reading(self, x: np.ndarray, u) -> np.ndarray:
        """``C x + D u`` plus one draw of the noise (units of each channel); ``u``: one value per input."""
        y = self._C @ x + self._D @ np.atleast_1d(np.asarray(u, float))
        if np.any(self._std > 0.0):
            y = y + self._std * self._rng.standard_normal(y.size)
        return y

    def publish(self, x: np.ndarray, u, stamp: Time) -> None:
        """Publish the reading of state ``x`` just after command ``u`` is applied, stamped ``stamp``."""
        msg = JointState()
        msg.header.stamp = stamp
        msg.name = self._names
        msg.position = [float(v) for v in self.reading(x, u)]
        self._pub.publish(msg)
        self.published += 1

    def subscription_count(self) -> int:
        """Writer-side matched subscriptions of ``measurements``."""
        return self._pub.get_subscription_count()


__all__ = ["MEASUREMENT_QOS", "TOPIC", "MeasurementPublisher", "stamp_from_ns"]
