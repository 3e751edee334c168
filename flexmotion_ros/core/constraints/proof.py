"""What the limited planner's proofs of impossibility rest on, and the proof that no move meets the limits.

A sample count ``K`` is claimed impossible only with a proof
(:meth:`.level.Level.prove`): the weak-duality bound of a probe's LP (lifted
to every sample from a window solution, :mod:`.dual`), or HiGHS's
infeasibility verdict on the feasibility LP with every limit loosened by
:data:`LOOSEN`, confirmed by the independent state-space formulation
(:mod:`.certify`).  :func:`prove_impossible` shows that no move of any length
can: the limits break within a prefix whatever the command.
"""

from __future__ import annotations

from ..errors import GoalError
from ..model.boundary import MoveProblem
from ..results import ProofKind
from .certify import prefix_feasible
from .limits import Limits

#: The last-resort infeasibility proof loosens every limit by this (relative; above HiGHS's 1e-10 feasibility tolerance).
LOOSEN = 1e-9

#: How a lower bound on the sample count was proved (``LimitedProfile.extra["lower_bound_proof"]``):
#: aliases of the :class:`~flexmotion_ros.core.results.ProofKind` members (``str`` values).
PROOF_UNLIMITED = ProofKind.UNLIMITED
PROOF_DUAL = ProofKind.DUAL
PROOF_HIGHS = ProofKind.HIGHS


#: Lifting window multipliers to every sample is one sparse LU of about ``K n`` unknowns: at 42,000
#: (4,200 samples, 10 states) it takes 10 s; above this the lifted bound is not tried.
LIFT_MAX_UNKNOWNS = 30000
#: The prefix of the impossibility proof covers at most this many samples.
PREFIX_SAMPLES = 4000


def prove_impossible(problem: MoveProblem, dt: float, limits: Limits, K: int, exc: Exception) -> None:
    """Raise :class:`GoalError` if no move of any length meets the limits (proved), else return.

    The proof: the limits cannot be held even over the first ``M`` samples
    with no arrival asked, and both HiGHS methods agree on the independent
    state-space formulation (:func:`.certify.prefix_feasible`).  A ``K``-sample
    move held at rest after its arrival would hold them, so none exists.
    """
    M = min(K, PREFIX_SAMPLES)
    said, method = prefix_feasible(problem, M, dt, limits, scale=1.0 + LOOSEN)
    if said is False:
        names = ", ".join(f"limits.{n}" for n in limits.active)
        raise GoalError(
            names,
            f"no move satisfies the limits: from this initial state they are broken within {M} samples "
            f"({M * dt:.4g} s) whatever the command (proved: {method} on the state-space LP); relax them",
        ) from exc
