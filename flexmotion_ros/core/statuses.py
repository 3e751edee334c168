"""The status enums of the planners' results: what produced a profile, what a certificate proved, how a bound was proved.

Each is a ``str`` enum (:class:`_StrEnum`): a member compares equal to its
value, serialises to it and formats as it, so results and messages read as
with bare strings.  The result types that carry them are in
:mod:`~flexmotion_ros.core.results` (which also exports these names).
"""

from __future__ import annotations

from enum import Enum


class _StrEnum(str, Enum):
    """An enum whose members are their string values.

    Members compare equal to their value (``SolverPath.FAST == "fast"``),
    serialise to it in JSON, and ``str()`` / f-string formatting give the value
    itself, so the text of results and messages is what it was with bare
    strings.
    """

    def __str__(self) -> str:
        return str(self.value)

    def __format__(self, format_spec: str) -> str:
        return format(str(self.value), format_spec)


class SolverPath(_StrEnum):
    """What produced a time-optimal profile (``BangBangProfile.extra["solver_path"]``).

    Every path's profile passed the same exact final-state check and
    Pontryagin certificate; the path is a diagnostic only.
    """

    #: Nothing to do: the initial state is already at rest at the target (duration 0 s).
    AT_REST = "at_rest"
    #: The rigid body's time-optimal input also leaves every flexible mode at rest.
    RIGID = "rigid"
    #: The full solver (convex inner problems, outer Newton on the duration, polish).
    FULL = "full"
    #: Guess, switch-time Newton, certify (:mod:`~flexmotion_ros.core.time_optimal.structure_guess`).
    FAST = "fast"
    #: A cluster of switches below rounding: switch times from the final state
    #: alone, optimal within the gap to the proved lower bound.
    CLUSTER = "cluster"
    #: The bounded structure search (:mod:`~flexmotion_ros.core.time_optimal.fallbacks`: a
    #: notch added to a known structure, final state alone), after the co-state iterations missed.
    SEARCH = "search"


class ProofKind(_StrEnum):
    """How the limited planner proved its lower bound on the sample count.

    Stored (as the member, a ``str``) in ``LimitedProfile.extra["lower_bound_proof"]``;
    a HiGHS verdict is stored as the text ``f"{ProofKind.HIGHS} ({method})"``
    with the LP method that gave it.
    """

    #: No limit binds below the unlimited zero-order-hold optimum's sample count.
    UNLIMITED = "unlimited ZOH optimum"
    #: A weak-duality bound over every sample exceeds 1 (independently checked).
    DUAL = "weak-duality bound"
    #: HiGHS found the feasibility LP with loosened limits infeasible (not independently checked).
    HIGHS = "HiGHS infeasible verdict"


class CertificateStatus(_StrEnum):
    """What a :class:`Certificate` proved (:attr:`Certificate.status`)."""

    #: Pontryagin's conditions hold with proof: the profile is time-optimal
    #: (also a zero-duration move already at rest).
    OPTIMAL = "optimal"
    #: The sign test could not decide, but the duration is within
    #: :data:`~flexmotion_ros.core.tolerances.GAP_RTOL` (relative) of a proved
    #: lower bound on the optimal time (s): optimal to that gap.  Also a profile
    #: whose every check passed but whose end an exact arrival could undercut by
    #: at most :data:`~flexmotion_ros.core.tolerances.END_GAP_RTOL` of ``T``
    #: (the certificate's ``end_gap``): the lower bound is then ``T - end_gap``.
    WITHIN_GAP = "within_gap"
    #: The checks failed: optimality is not proved.
    FAILED = "failed"
