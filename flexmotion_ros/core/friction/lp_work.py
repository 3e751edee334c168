"""Work budgets of the friction LPs: simplex iterations per LP, and the effort a search's LPs may share.

Counts, not wall time, so a planner's answer does not depend on the machine's load.
"""

from __future__ import annotations

#: Simplex iterations a friction LP may take, per row and column (plus :data:`LP_ITERATION_FLOOR`): a work
#: budget, not a wall-clock one, so the planner's answer does not depend on the machine's load (a 1 s time
#: limit refused LPs at load 25 that plan in 0.6 s CPU: fuzz cases 82, 824 of seed 18).  The dual simplex
#: can stall on a degenerate windowed LP; such an LP counts as "no solution" (wider windows, or another
#: count, are tried), never as a verdict.  Seed-18 fuzz cases 0-99 at 100 Hz (2,850 LPs): at most 1.17
#: iterations per row and column, median 0.47 (2026-12-05): ten is a wide margin.
LP_ITERATIONS_PER_SIZE = 10
#: The smallest iteration budget of a friction LP.
LP_ITERATION_FLOOR = 1000


def lp_iteration_limit(n_columns: int, n_rows: int) -> int:
    """The simplex iteration budget of a friction LP with ``n_columns`` variables and ``n_rows`` rows."""
    return LP_ITERATION_FLOOR + LP_ITERATIONS_PER_SIZE * (int(n_columns) + int(n_rows))


class EffortSpent(RuntimeError):
    """A :class:`~.sampled_lp.FrictionLP` was asked for an LP past its shared effort budget (the search stops there)."""


def lp_effort(size: int) -> int:
    """Effort of one LP of ``size`` rows plus columns, ``size^2``: the dual simplex's iterations grow with
    the size and so does each one's cost (seed-18 fuzz case 691: 2 s of HiGHS at 11,500, 3 ms at 580)."""
    return int(size) * int(size)
