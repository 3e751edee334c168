"""Result types of the multi-input planners (frozen, keyword-only; ``to_dict`` gives the JSON)."""

from __future__ import annotations

from dataclasses import dataclass, field
from enum import Enum

import numpy as np

from ..results import sampled_summary
from .exact import VectorPiecewise
from .problem import MultiMoveProblem


class SyncMode(str, Enum):
    """How the inputs that do not set the minimum time ``T*`` move (parameter ``sync``).

    Whatever the mode: the move ends at rest, exactly (checked by matrix
    exponentials), and no command exceeds its ``u_max_i``.

    * ``time`` (default): the move takes ``T*``, proved minimal (weak duality).
      Every decoupled part finishes exactly at ``T*``; a part that could finish
      sooner moves with the lowest common peak fraction ``rho`` of its inputs
      (``|u_i| <= rho u_max_i``) that arrives exactly then, proved lowest by
      its dual.  Inside a part, inputs the optimal co-state does not see
      (singular) finish the move with their own lowest peak after the others.
    * ``none``: the move takes ``T*`` too; every part is time-optimal on its
      own (certified) and then holds 0, so parts arrive at different instants.
    * ``phase``: the rigid bodies travel the straight line from start to
      target; the time-optimal move among such moves (certified as a
      single-input problem), in general slower than ``T*``.  Refused, with the
      reason, where the dynamics do not allow it (see :mod:`.phase`).
    """

    TIME = "time"
    NONE = "none"
    PHASE = "phase"

    def __str__(self) -> str:
        return str(self.value)


class PartRole(str, Enum):
    """What one decoupled part of the model did (``MultiProfile.parts[i]["role"]``)."""

    CRITICAL = "critical"  # sets T*: time-optimal, certified
    LOWEST_PEAK = "lowest_peak"  # sync=time: lowest peak arriving exactly at T*
    OWN_OPTIMUM = "own_optimum"  # sync=none: its own time-optimal move
    AT_REST = "at_rest"  # nothing to do
    PATH = "path"  # sync=phase: the straight-line path

    def __str__(self) -> str:
        return str(self.value)


@dataclass(frozen=True, kw_only=True)
class MultiCertificate:
    """Evidence that a multi-input bang-bang profile is optimal.

    Attributes
    ----------
    passed : bool
        Every check of every part holds.
    costate_initial : ndarray
        ``lambda_0`` of eq. 2.36 (full reduced state; zero on parts that do
        not set the time), scaled for a zero Hamiltonian on the critical part.
    switch_residual : float
        Largest ``|B_i^T lambda(t)|`` at input ``i``'s switches, relative to
        ``max |B_i^T lambda|`` (eq. 2.37), over all inputs.
    extra_zeros : int
        Sign changes of some ``B_i^T lambda`` that are not switches of input
        ``i``, plus switches where it does not change sign.
    unproved_cells : int
        Cells where root isolation could not prove zero-freeness or monotonicity.
    sign_consistent : bool
        ``u_i = -u_max_i sgn(B_i^T lambda)`` on every interval (eq. 2.34).
    hamiltonian_spread : float
        Relative spread of ``lambda^T (A x + B u)`` along the motion (0 for a
        constant, so that ``1 + lambda^T(Ax + Bu) = 0`` with one scaling).
    lower_bound : float
        A proved lower bound on the minimum time (s): weak duality, with
        independent matrix-exponential integrals, shows that no admissible
        input reaches the target by then.
    duality_margin : float
        ``nu^T w(T_lo) - h_{T_lo}(nu)`` relative to its terms (> 0: the proof holds).
    message : str
        ``"ok"`` or why a check failed.
    parts : tuple of dict
        One summary per decoupled part (role, inputs, duration, peak fraction, checks).
    """

    passed: bool
    costate_initial: np.ndarray
    switch_residual: float
    extra_zeros: int
    unproved_cells: int
    sign_consistent: bool
    hamiltonian_spread: float
    lower_bound: float
    duality_margin: float
    message: str = "ok"
    parts: tuple = ()

    def to_dict(self) -> dict:
        """JSON-friendly summary."""
        return {
            "passed": bool(self.passed),
            "costate_initial": [float(v) for v in self.costate_initial],
            "switch_residual": float(self.switch_residual),
            "extra_zeros": int(self.extra_zeros),
            "unproved_cells": int(self.unproved_cells),
            "sign_consistent": bool(self.sign_consistent),
            "hamiltonian_spread": float(self.hamiltonian_spread),
            "lower_bound": float(self.lower_bound),
            "duality_margin": float(self.duality_margin),
            "message": self.message,
            "parts": [dict(p) for p in self.parts],
        }


@dataclass(frozen=True, kw_only=True)
class MultiProfile:
    """A continuous-time multi-input profile and its checks.

    Attributes
    ----------
    problem : MultiMoveProblem
    switch_times : tuple of ndarray
        Per input: its interior switch times (s), increasing.
    levels : tuple of ndarray
        Per input: its level on each of its intervals (one more than its switches).
    duration : float
        Move time ``T`` (s).
    final_state : ndarray
        Full state at ``T`` by exact simulation (absolute coordinates).
    final_state_error, final_state_error_relative : float
        ``max |x(T) - x_f|`` over the constrained states, absolute and relative
        to the move's state scale.
    certificate : MultiCertificate
    sync : SyncMode
    method : str
    solve_time_s : float
    extra : dict
        Diagnostics outside the guarantees.
    """

    problem: MultiMoveProblem
    switch_times: tuple
    levels: tuple
    duration: float
    final_state: np.ndarray
    final_state_error: float
    final_state_error_relative: float
    certificate: MultiCertificate
    sync: SyncMode = SyncMode.TIME
    method: str = "time_optimal"
    solve_time_s: float = 0.0
    extra: dict = field(default_factory=dict)

    @property
    def certified(self) -> bool:
        """Whether the certificate passed."""
        return bool(self.certificate.passed)

    def merged_switch_times(self) -> np.ndarray:
        """Interior instants where any input switches, sorted (s)."""
        allt = np.concatenate([np.asarray(s, float) for s in self.switch_times] + [np.empty(0)])
        allt = np.unique(allt)
        return allt[(allt > 0.0) & (allt < self.duration)]

    def input(self) -> VectorPiecewise:
        """The command vector as a :class:`VectorPiecewise` (one row per merged interval)."""
        breaks = np.concatenate([[0.0], self.merged_switch_times(), [self.duration]])
        mids = 0.5 * (breaks[:-1] + breaks[1:])
        rows = np.empty((mids.size, len(self.levels)))
        for i, (sw, lv) in enumerate(zip(self.switch_times, self.levels)):
            rows[:, i] = np.asarray(lv, float)[np.searchsorted(np.asarray(sw, float), mids, side="right")]
        return VectorPiecewise(breaks, rows)

    def peak(self) -> np.ndarray:
        """Largest ``|u_i|`` per input."""
        return np.array([float(np.max(np.abs(lv))) if np.size(lv) else 0.0 for lv in self.levels])

    def to_dict(self) -> dict:
        """The JSON of ``flexmotion plan --json`` for ``m > 1``."""
        u = self.input()
        return {
            "method": self.method,
            "duration": float(self.duration),
            "switch_times": [float(t) for t in u.breaks[1:-1]],
            "levels": [[float(v) for v in row] for row in u.levels],
            "inputs": list(self.problem.model.inputs),
            "input_switch_times": {
                name: [float(t) for t in sw] for name, sw in zip(self.problem.model.inputs, self.switch_times)
            },
            "final_state": [float(v) for v in self.final_state],
            "final_state_error": float(self.final_state_error),
            "final_state_error_relative": float(self.final_state_error_relative),
            "certified": self.certified,
            "certificate": self.certificate.to_dict(),
            "solve_time_s": float(self.solve_time_s),
            "sync": str(self.sync),
            "normal": bool(self.problem.model.is_normal),
        }


@dataclass(frozen=True, kw_only=True)
class MultiSampledProfile:
    """A zero-order-hold command sequence ``(K, m)`` at a fixed rate and its checks.

    Attributes
    ----------
    problem : MultiMoveProblem
    commands : ndarray, shape ``(K, m)``
        Row ``k`` held on ``[k dt, (k+1) dt)``; ``|commands[:, i]| <= u_max[i]``.
    dt : float
        Sample period (s).
    states : ndarray
        Exact states at every sample instant (``K + 1`` rows, absolute).
    final_state_error, final_state_error_relative : float
        At the last sample instant.
    minimal : bool
        ``K - 1`` samples proved infeasible.
    lower_bound_samples : int
        Fewer samples than this are proved infeasible.
    proof : str
        How ``K - 1`` was proved infeasible (``"dual"``: a weak-duality bound
        of the ``K - 1`` linear program above 1; ``"continuous"``:
        ``(K - 1) dt`` below the proved continuous lower bound).
    dual_bound : float
        The ``K - 1`` bound on the peak fraction (> 1 proves infeasibility).
    continuous : MultiProfile or None
    sync : SyncMode
    method : str
    solve_time_s : float
    extra : dict
    """

    problem: MultiMoveProblem
    commands: np.ndarray
    dt: float
    states: np.ndarray
    final_state_error: float
    final_state_error_relative: float
    minimal: bool
    lower_bound_samples: int
    proof: str = ""
    dual_bound: float = float("nan")
    continuous: MultiProfile | None = None
    sync: SyncMode = SyncMode.TIME
    method: str = "time_optimal"
    solve_time_s: float = 0.0
    extra: dict = field(default_factory=dict)

    @property
    def samples(self) -> int:
        """Number of command rows ``K``."""
        return int(self.commands.shape[0])

    @property
    def duration(self) -> float:
        """``K dt`` (s)."""
        return self.samples * self.dt

    def input(self) -> VectorPiecewise:
        """The sequence as a :class:`VectorPiecewise`."""
        return VectorPiecewise.from_samples(self.commands, self.dt)

    def to_dict(self) -> dict:
        """JSON summary: ``samples``, ``commands`` (K rows of m values), proofs."""
        return {
            **sampled_summary(self),
            "minimality_proof": self.proof,
            "commands": [[float(v) for v in row] for row in self.commands],
            "sync": str(self.sync),
        }
