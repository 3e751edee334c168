"""Identification of the modal model from measured moves, with standard errors and 95 % intervals.

What a node (or any caller) needs, all pure functions on arrays:

* ``design_excitation(config.model, config.u_max, config.rate_hz, band,
  position_limits=(config.position_min, config.position_max), start=p0)``
  -> :class:`Excitation`: ``commands`` to stream at ``rate_hz`` (``|u| <= u_max``,
  within the limits, back at rest at ``p0`` for the believed model; checked by
  exact propagation), ``duration``, ``to_dict()``.
* ``identify(t, u, [SensorOutput(samples=y, kind="position", rigid_weight=1.0,
  name="cart"), ...], modes=N or None, prior=config.model, u_max=config.u_max)``
  -> :class:`IdentificationResult` (frozen): ``b0``, ``c``, ``modes[i].omega`` /
  ``.zeta`` as :class:`Estimate` (value, std_error, 95 % ``interval``),
  ``noise_std``, ``fit_rms``, ``converged``; ``to_model(b=config.model.b)`` gives
  the :class:`~flexmotion_ros.core.model.modal_model.ModalModel` to adopt
  (``config.with_changes(model=...)``), ``to_dict()`` plain values for JSON /
  a service message / diagnostics.  ``u[k]`` is the command held from ``t[k]``
  to ``t[k+1]``; the machine is at rest before ``t[0]``.  Refusals raise
  :class:`~flexmotion_ros.core.errors.InputError` (one line, parameter named).
* ``predicted_std_errors(model, commands, dt, noise_std)``: the Cramer-Rao
  standard errors a sequence would give, before running it.
"""

from .data import IdentificationData, SensorOutput, check_data
from .excitation import Excitation, design_excitation, predicted_std_errors
from .identify import identify
from .response import OutputKind
from .result import Estimate, IdentificationResult, ModeEstimate, ModeSelection, OutputFit

__all__ = [
    "Estimate",
    "Excitation",
    "IdentificationData",
    "IdentificationResult",
    "ModeEstimate",
    "ModeSelection",
    "OutputFit",
    "OutputKind",
    "SensorOutput",
    "check_data",
    "design_excitation",
    "identify",
    "predicted_std_errors",
]
