"""Every tolerance and guard that decides a verdict, in one table.

Each constant says why it has its value.  A planner accepts a profile, a
certificate passes, a linear program counts as solved or a request is
refused by these numbers only; tuning knobs of one algorithm stay named
beside their use.
"""

from __future__ import annotations

# time_optimal
#: Accept a profile whose relative final-state error is below this: the error
#: ``max_i |x_i(T) - x_f,i| / s_i`` of
#: :func:`~flexmotion_ros.core.simulation.error_scale.relative_final_state_error`,
#: with the scale ``s`` defined once in
#: :func:`~flexmotion_ros.core.simulation.error_scale.state_scale` (how large each
#: state can get in a move of that length, whatever the profile).
FINAL_STATE_RTOL = 1e-9


#: A shifted state whose every entry is below this (state units) is at rest:
#: no physical move is 1e-100 m, and squares of such numbers underflow.
AT_REST = 1e-100


#: A goal within this many units in the last place of the state (entry by
#: entry) is the state itself: the difference is rounding (a position re-sent
#: through a message), not a move.  ``methods.already_there``.
AT_REST_ULPS = 4


#: Refuse moves whose optimum needs more switches than this (an actuator far
#: too weak for the state: a chattering move of thousands of periods).
MAX_SWITCHES = 5000


# certificate
SWITCH_RESIDUAL_TOL = 1e-8


SWITCH_TIME_RTOL = 1e-9


#: A profile this close (relative) to a proved lower bound on the time is optimal.
GAP_RTOL = 1e-8


#: Where the switching function is tiny at the end of the move (a last switch
#: within 1e-7 of ``T``, ``S(0) ~ 0``), the optimal time itself is that
#: ill-conditioned: a final-state error of 1e-14 (relative) leaves ``T`` proved
#: only to about 1e-7 (``certificate.end_gap``).  Such a profile is certified
#: ``within_gap`` with the lower bound ``T - end_gap`` that the duality identity
#: proves, if that gap is below this (relative); above it, it is not certified.
END_GAP_RTOL = 1e-6


HAMILTONIAN_TOL = 1e-6


# fixed_time
#: Requests within this relative distance of ``T*`` are the time-optimal move itself.
SAME_TIME_RTOL = 1e-12


# fuel_lp
#: Accept a window LP when its duality gap on the full problem is below this (relative to the fuel).
LP_GAP_RTOL = 1e-9


#: HiGHS tolerances: the LP solutions are corrected to an exact arrival afterwards.
HIGHS_OPTIONS = {"primal_feasibility_tolerance": 1e-10, "dual_feasibility_tolerance": 1e-10}


#: Move times within this (relative) of ``T*`` are the time-optimal move.
T_STAR_RTOL = 1e-9


MAX_SAMPLES = 5_000_000


# limit_dual
#: A bound must exceed 1 by this (relative) to count as a proof.
PROOF_RTOL = 1e-9


# limit_lp
#: A limit row inside a run counts as violated above ``(1 + ROW_RTOL) t``.
ROW_RTOL = 1e-9


# model
#: Two modal frequencies closer than this (relative) count as repeated.
REPEATED_FREQUENCY_RTOL = 1e-9


# numerical_shapers
#: Defining constraints must hold to this (dimensionless) after solving.
CONSTRAINT_TOL = 1e-11


# reachable_set
#: The Newton polish has converged when the scaled final state is below this.
POLISH_TOL = 1e-12


# sensitivity
#: Relative slack when comparing a vibration with the tolerance: an EI shaper
#: meets its tolerance with equality at its humps.
TOLERANCE_SLACK = 1e-9


# shaped_profile
#: Residual vibration may differ from the impulse formula by this, relative to a full step's.
RESIDUAL_RTOL = 1e-8


# zoh
#: Relative slack on the bound in a proof of infeasibility (dual bound).
BOUND_RTOL = 1e-12


#: LP peak commands up to this far above u_max are tried: the LP solver's own
#: tolerance; the exact correction then either lands within u_max or fails.
LP_RTOL = 1e-6
