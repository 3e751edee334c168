"""A shaped command that remembers how it was made: the rigid command and the shaper's factors.

A multi-mode shaped command has as many pieces as the rigid command's breaks
times the convolved shaper's impulses (an 8-mode UM-ZVD or EI3 shaper has
5^8 = 390,625 impulses: about a million pieces).  Two things are linear in it
and factorise over the rigid command and the shaper's factors
(:mod:`~flexmotion_ros.core.shaping.shaper`):

* its vibration sum (the insensitivity figures): the product of the rigid
  command's jumps' sum and each factor's, evaluated at each factor's few
  impulses (:func:`factored_vibration`);
* its exact final state (:func:`factored_final_state`): the rigid command's
  forced response at its end, carried to the shaped command's end by
  ``prod_j sum_i A_ji Phi(t_nj - t_ji)``, every ``Phi`` a
  :func:`scipy.linalg.expm` of the model's full ``A`` (as
  :mod:`~flexmotion_ros.core.simulation.exact`, no modal formula): one
  exponential per factor impulse instead of one per piece (a million
  exponentials, over a minute of CPU).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.linalg import expm

from ..model.modal_model import ModalModel
from ..simulation.exact import PiecewiseConstant, final_state, simulate
from .numerical_shapers import impulse_vibration


@dataclass(frozen=True)
class ShapedCommand(PiecewiseConstant):
    """A piecewise-constant command that is ``rigid`` convolved with the shaper of ``factors``.

    Attributes
    ----------
    breaks, levels : ndarray
        As :class:`~flexmotion_ros.core.simulation.exact.PiecewiseConstant`
        (s; input units): the command itself, clipped to the bound (the clip
        changes levels by rounding only: the shaped level is within
        ``1e-12 u_max`` of the bound).
    rigid : PiecewiseConstant or None
        The unshaped command (s; input units).
    factors : tuple of (ndarray, ndarray)
        The shaper's factors' ``(times, amplitudes)`` (s, dimensionless).
    """

    rigid: PiecewiseConstant | None = None
    factors: tuple[tuple[np.ndarray, np.ndarray], ...] = ()


def rigid_impulses(rigid: PiecewiseConstant) -> tuple[np.ndarray, np.ndarray]:
    """The jumps of ``rigid`` (times, s; ``Delta u``, input units), the end kept as the last time."""
    jumps = np.diff(np.concatenate([[0.0], rigid.levels, [0.0]]))
    return rigid.breaks, jumps


def factored_vibration(command: ShapedCommand, omega, zeta, u_ref: float) -> np.ndarray:
    """Residual vibration (fraction) of ``command`` relative to a step of ``u_ref``, by its factors (broadcast).

    Equal to :func:`~flexmotion_ros.core.shaping.sensitivity.command_vibration`
    of the command (its jumps are the convolution of the rigid command's and
    the factors' impulses, its end the sum of their ends) up to rounding.
    """
    t, a = rigid_impulses(command.rigid)
    out = impulse_vibration(t, a / u_ref, omega, zeta)
    for ft, fa in command.factors:
        out = out * impulse_vibration(ft, fa, omega, zeta)
    return out


def factored_final_state(model: ModalModel, x0, command: ShapedCommand) -> np.ndarray:
    """Exact state at ``command.duration`` (absolute), from ``x0``, by the factorisation.

    ``x(T) = Phi(T) x0 + prod_j (sum_i A_ji Phi(d_j - t_ji)) g``, ``g`` the
    rigid command's forced response at its own end (exact simulation, a few
    pieces), ``d_j`` factor ``j``'s duration; ``T`` = the rigid duration plus
    the ``d_j``.  The matrices commute (functions of one ``A``).
    """
    A = model.A()
    n = A.shape[0]
    g = final_state(model, np.zeros(n), command.rigid)
    for ft, fa in command.factors:
        d = float(ft[-1])
        M = sum(ai * expm(A * (d - ti)) for ti, ai in zip(ft, fa))
        g = M @ g
    return expm(A * command.duration) @ np.asarray(x0, dtype=float) + g


#: Largest shaped command simulated piece by piece (one ``expm`` per distinct piece, ~0.1 ms each);
#: longer ones are simulated by their factors (:func:`factored_final_state`).
MAX_SIMULATED_PIECES = 5000


def exact_end(model: ModalModel, x0, command: PiecewiseConstant) -> tuple[np.ndarray, np.ndarray]:
    """The exact final state (absolute) and rigid-body states (position, velocity) along the move.

    Up to :data:`MAX_SIMULATED_PIECES` pieces (or without factors) both come
    from simulating the command piece by piece.  Past it the final state is
    :func:`factored_final_state` and the rigid-body states are those of the
    rigid command (at its breaks and the shaped end): their excursion only
    scales the final-state error, and shaping changes it little.
    """
    if command.levels.size <= MAX_SIMULATED_PIECES or not isinstance(command, ShapedCommand) or command.rigid is None:
        states = simulate(model, x0, command)
        return states[-1], states[:, :2]
    xT = factored_final_state(model, x0, command)
    rigid = command.rigid
    along = simulate(model, x0, rigid, times=np.append(rigid.breaks, command.duration))[:, :2]
    return xT, np.vstack([along, xT[:2]])
