"""Result types of the planners: continuous and sampled profiles, the certificate, the planned move.

The status enums they carry are :mod:`~flexmotion_ros.core.statuses`; they are
exported from here too (``SolverPath``, ``ProofKind``, ``CertificateStatus``),
the import path of the planners that name them.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any, Protocol

import numpy as np

from .errors import SolverError
from .model.boundary import MoveProblem
from .simulation.exact import PiecewiseConstant
from .statuses import CertificateStatus, ProofKind, SolverPath

__all__ = [
    "BangBangProfile",
    "Certificate",
    "CertificateStatus",
    "ContinuousProfile",
    "PlanResult",
    "ProofKind",
    "SampledProfile",
    "SolverPath",
    "optimal_or_zeros",
    "sampled_summary",
]


@dataclass(frozen=True, kw_only=True)
class BangBangProfile:
    """A continuous-time bang-bang input and its checks.

    Frozen and keyword-only (the ``extra`` dict may still be filled in).

    Attributes
    ----------
    problem : MoveProblem
        What was planned.
    switch_times : ndarray
        Interior switching times (s), increasing.
    levels : ndarray
        Input on each interval (one more than ``switch_times``), each ``+-u_max``.
    duration : float
        Move time ``T`` (s).
    final_state : ndarray
        State at ``T`` from the exact matrix-exponential simulation (absolute
        coordinates; with a free final position, the position reached).
    final_state_error : float
        ``max |x(T) - x_f|`` over the constrained states (state units).
    final_state_error_relative : float
        The same, each state divided by its scale during the move.
    certificate : Certificate
        Pontryagin certificate.
    solve_time_s : float
        Wall time of the planner (s).
    iterations : int
        Work count of the time-optimal solver: evaluations of the exact
        shooting function (final state and co-state Hessian of the convex
        inner problem, ``Shooting.evaluate``) in its inner and outer
        iterations and polish.  Usually 0 on the ``"fast"`` path (it skips
        the exact inner problems) and always on ``"at_rest"`` and ``"rigid"``.
    method : str
        The planner (``"time_optimal"``).
    extra : dict
        Diagnostics of the planner, outside the guarantees:

        ``solver_path`` : SolverPath
            A ``str`` enum member.  What produced the profile: ``"at_rest"`` (nothing to do),
            ``"rigid"`` (the rigid body's optimum leaves every mode at rest),
            ``"fast"`` (guess, switch-time Newton, certify:
            :mod:`~flexmotion_ros.core.structure_guess`) or ``"full"`` (the
            full solver).  Either way the profile passed the same checks.
        ``fast_path_candidates`` : int
            With ``"fast"``: converged extremals the fast path certified (1
            plus structure corrections).
        ``fast_path_error`` : str
            With ``"full"``: ``repr`` of an exception raised in the fast path
            (a bug there; the full solver answered instead).  Absent otherwise.
    """

    problem: MoveProblem
    switch_times: np.ndarray
    levels: np.ndarray
    duration: float
    final_state: np.ndarray
    final_state_error: float
    final_state_error_relative: float
    certificate: Certificate
    solve_time_s: float = 0.0
    iterations: int = 0
    method: str = "time_optimal"
    extra: dict = field(default_factory=dict)

    @property
    def certified(self) -> bool:
        """Whether the Pontryagin certificate passed."""
        return bool(self.certificate.passed)

    def input(self) -> PiecewiseConstant:
        """The input as a :class:`PiecewiseConstant`."""
        return PiecewiseConstant.from_switches(self.switch_times, self.levels, self.duration)

    def __call__(self, t) -> np.ndarray:
        """Input ``u(t)`` (0 outside the move)."""
        return self.input()(t)

    def to_dict(self) -> dict:
        """JSON-friendly summary (with ``solver_path`` if the planner recorded it)."""
        out = {
            "method": self.method,
            "duration": float(self.duration),
            "switch_times": [float(t) for t in self.switch_times],
            "levels": [float(v) for v in self.levels],
            "final_state": [float(v) for v in self.final_state],
            "final_state_error": float(self.final_state_error),
            "final_state_error_relative": float(self.final_state_error_relative),
            "certified": self.certified,
            "certificate": self.certificate.to_dict(),
            "solve_time_s": float(self.solve_time_s),
        }
        if "solver_path" in self.extra:
            out["solver_path"] = str(self.extra["solver_path"])
        return out


@dataclass
class SampledProfile:
    """A zero-order-hold input at a fixed rate and its checks.

    Attributes
    ----------
    problem : MoveProblem
    commands : ndarray
        ``u_k`` held on ``[k dt, (k+1) dt)``; ``|u_k| <= u_max``.
    dt : float
        Sample period (s).
    states : ndarray
        Exact states at every sample instant (``len(commands) + 1`` rows,
        absolute coordinates), from the matrix-exponential simulation.
    final_state_error, final_state_error_relative : float
        As for :class:`BangBangProfile`, at the last sample instant.
    minimal : bool
        Whether ``len(commands)`` is proved to be the fewest samples.
    lower_bound_samples : int
        Samples below which no sequence can reach the target (proved).
    continuous : BangBangProfile or None
        The continuous optimum the sampled one was built from.
    """

    problem: MoveProblem
    commands: np.ndarray
    dt: float
    states: np.ndarray
    final_state_error: float
    final_state_error_relative: float
    minimal: bool
    lower_bound_samples: int
    continuous: BangBangProfile | None = None
    solve_time_s: float = 0.0
    method: str = "time_optimal"
    extra: dict = field(default_factory=dict)

    @property
    def samples(self) -> int:
        """Number of commands."""
        return int(self.commands.size)

    @property
    def duration(self) -> float:
        """``samples * dt`` (s)."""
        return self.samples * self.dt

    def input(self) -> PiecewiseConstant:
        """The input as a :class:`PiecewiseConstant`."""
        return PiecewiseConstant.from_samples(self.commands, self.dt)

    def to_dict(self) -> dict:
        """JSON-friendly summary (commands included)."""
        return {**sampled_summary(self), "commands": [float(v) for v in self.commands]}


def sampled_summary(profile: Any) -> dict:
    """The JSON fields every sampled profile shares (one input or several): rate, count, proof, arrival error."""
    return {
        "method": profile.method,
        "rate_hz": 1.0 / profile.dt,
        "samples": profile.samples,
        "sampled_duration": float(profile.duration),
        "minimal": bool(profile.minimal),
        "lower_bound_samples": int(profile.lower_bound_samples),
        "sampled_final_state_error": float(profile.final_state_error),
        "sampled_final_state_error_relative": float(profile.final_state_error_relative),
    }


@dataclass(frozen=True, kw_only=True)
class Certificate:
    """Evidence that a bang-bang profile is time-optimal.

    Frozen and keyword-only: build it with every value final.

    Attributes
    ----------
    passed : bool
        All checks hold.
    costate_initial : ndarray
        ``lambda_0`` of eq. 2.36, scaled so that the Hamiltonian is zero.
    costate_final : ndarray
        ``lambda(T)``.
    switch_residual : float
        ``max_j |B^T lambda(t_j)|`` relative to ``max_t |B^T lambda(t)|`` (eq. 2.37).
    extra_zeros : int
        Sign changes of the switching function that are not switches of the
        profile, plus switches where it does not change sign.
    unproved_cells : int
        Grid cells where neither zero-freeness nor monotonicity could be proved.
    sign_consistent : bool
        ``u = -u_max sgn(B^T lambda)`` on every interval (eq. 2.34).
    min_margin : float
        Smallest ``|B^T lambda|`` at interval midpoints, relative to its maximum.
    hamiltonian_max_abs : float
        ``max |H(t)|`` at the switch times and ends (should be 0; amplified
        by the scaling of ``lambda`` when ``B^T lambda(T)`` is tiny).
    message : str
        Why it failed, or ``"ok"``.
    lower_bound : float or None
        Proved lower bound on the optimal time (s) used for the gap test.
    details : dict
        ``zeros_tau``: the sign changes of the switching function found with
        proof (time-to-go ``T - t``, s, increasing); ``sign0``: its sign
        before the first of them.  Empty if no isolation was run.
    within_gap : bool
        Passed only because the duration is within
        :data:`~flexmotion_ros.core.tolerances.GAP_RTOL` of ``lower_bound``
        (s), the sign test being undecided (``message`` says so).  Not in
        :meth:`to_dict` (``message`` carries it).
    """

    passed: bool
    costate_initial: np.ndarray
    costate_final: np.ndarray
    switch_residual: float
    extra_zeros: int
    unproved_cells: int
    sign_consistent: bool
    min_margin: float
    hamiltonian_max_abs: float
    message: str = "ok"
    lower_bound: float | None = None
    details: dict = field(default_factory=dict)
    within_gap: bool = False

    @classmethod
    def at_rest(cls, n: int, message: str = "already at rest") -> Certificate:
        """The certificate of a move of zero duration (nothing to switch, nothing to prove beyond the state).

        ``n`` is the state size (the zero co-states' length); ``message`` says why the move is empty.
        """
        zeros = np.zeros(n)
        return cls(
            passed=True,
            costate_initial=zeros,
            costate_final=zeros.copy(),
            switch_residual=0.0,
            extra_zeros=0,
            unproved_cells=0,
            sign_consistent=True,
            min_margin=1.0,
            hamiltonian_max_abs=0.0,
            message=message,
        )

    @property
    def status(self) -> CertificateStatus:
        """What was proved: :attr:`CertificateStatus.OPTIMAL`, ``WITHIN_GAP`` or ``FAILED``.

        ``FAILED`` whenever ``passed`` is false; ``WITHIN_GAP`` if it passed by
        the gap to ``lower_bound`` only (``within_gap``); else ``OPTIMAL``.
        """
        if not self.passed:
            return CertificateStatus.FAILED
        return CertificateStatus.WITHIN_GAP if self.within_gap else CertificateStatus.OPTIMAL

    def to_dict(self) -> dict:
        """JSON-friendly summary."""
        return {
            "passed": bool(self.passed),
            "costate_initial": [float(v) for v in self.costate_initial],
            "switch_residual": float(self.switch_residual),
            "extra_zeros": int(self.extra_zeros),
            "unproved_cells": int(self.unproved_cells),
            "sign_consistent": bool(self.sign_consistent),
            "min_margin": float(self.min_margin),
            "hamiltonian_max_abs": float(self.hamiltonian_max_abs),
            "message": self.message,
            "lower_bound": None if self.lower_bound is None else float(self.lower_bound),
        }


class ContinuousProfile(Protocol):
    """What every method's continuous result offers."""

    duration: float

    def input(self) -> PiecewiseConstant: ...

    def to_dict(self) -> dict: ...


@dataclass(frozen=True, kw_only=True)
class PlanResult:
    """A planned move.

    Frozen and keyword-only (the ``info`` dict may still be filled in).

    Attributes
    ----------
    method : str
    problem : MoveProblem
    continuous : ContinuousProfile or None
        The continuous-time profile (None if a method plans only sampled).
    sampled : SampledProfile or None
        The exact command sequence at the requested rate (None if no rate).
    info : dict
        Method-specific figures (added time, robustness, ...), JSON-friendly.
    """

    method: str
    problem: MoveProblem
    continuous: Any = None
    sampled: SampledProfile | None = None
    info: dict = field(default_factory=dict)

    @property
    def duration(self) -> float:
        """Move time (s): the sampled one if sampled, else the continuous one."""
        if self.sampled is not None:
            return self.sampled.duration
        return float(self.continuous.duration)

    def summary(self) -> dict:
        """JSON-friendly summary: the continuous profile's fields, then the sampled ones."""
        out: dict = {"method": self.method}
        if self.continuous is not None:
            out.update(self.continuous.to_dict())
        out["method"] = self.method
        if self.sampled is not None:
            out.update(self.sampled.to_dict())
        out.update(self.info)
        return out


def optimal_or_zeros(build: Callable[[], BangBangProfile]) -> tuple[BangBangProfile | None, Any, float]:
    """A candidate profile judged by its certificate: the structure searches' one verdict.

    Returns
    -------
    tuple
        ``(profile, None, 0.0)`` if ``build()`` gives a profile certified
        :attr:`CertificateStatus.OPTIMAL`; else ``(None, zeros_tau, sign0)``,
        the switching function's zeros its certificate found (time to go, s)
        and its sign before the first, for the next guess; ``(None, None,
        0.0)`` if it cannot be built (:class:`~.errors.SolverError`).
    """
    try:
        profile = build()
    except SolverError:
        return None, None, 0.0
    cert = profile.certificate
    if cert.status is CertificateStatus.OPTIMAL:
        return profile, None, 0.0
    return None, cert.details.get("zeros_tau"), float(cert.details.get("sign0", 0.0))
