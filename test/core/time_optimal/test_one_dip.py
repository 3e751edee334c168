"""Issue 15's tail: the fast path's one-dip structures (``structure_guess.one_dip_structures``).

Fuzz case 6328 (seed 15; 4 modes, a 93 m rest-to-rest move) took 0.8-1.05 s
CPU on 9dfd8b4, over the issue's 200 ms for ``N <= 4``: the fast path's
switch-time Newton converged to a 9-switch extremal whose switching function
dips through zero in 8 places; the structure edit put a pulse in all 8 (25
switches), Newton failed on it and on its merged descendants, and the full
solver then spent 586 exact co-state evaluations.  The optimum has a pulse
(48 us) in one dip only: the fast path now tries those one-dip structures,
deepest first, and answers.
"""

from __future__ import annotations

import numpy as np
from reference_solutions import bang_bang_final_error

from flexmotion_ros.core import ModalModel, MoveProblem
from flexmotion_ros.core.results import SolverPath
from flexmotion_ros.core.time_optimal import structure_guess
from flexmotion_ros.core.time_optimal.solver import plan_time_optimal
from flexmotion_ros.core.time_optimal.structure_guess import one_dip_structures

CASE_6328 = MoveProblem(
    ModalModel(
        b0=0.43871640201441175,
        c=0.0,
        omega=(0.4745550479719188, 15.788580861279955, 23.584281935214552, 36.74230039940554),
        zeta=(0.010548198614887561, 0.08015035134671455, 0.022880149636309487, 0.24277885365160443),
        b=(-1.8803893340284348, -0.11334647214327742, -1.8978098165885324, 0.20176107255463693),
    ),
    1.2097796589229022,
    np.zeros(10),
    93.27049957875303,
)
#: Its certified optimum on 9dfd8b4 (the full solver, 586 co-state evaluations), s.
T_6328 = 26.632743200921837


def test_case_6328_is_answered_by_the_fast_path_with_the_same_optimum():
    problem = CASE_6328
    profile = plan_time_optimal(problem)
    assert profile.certified, profile.certificate.message
    assert profile.extra["solver_path"] is SolverPath.FAST  # the full solver on 9dfd8b4
    assert profile.iterations == 0  # no exact co-state evaluation: 586 on 9dfd8b4
    assert abs(profile.duration - T_6328) <= 1e-9 * T_6328
    assert profile.switch_times.size == 11
    gaps = np.diff(profile.switch_times)
    assert 1e-5 < np.min(gaps) < 1e-4  # the 48 us pulse in one dip
    assert bang_bang_final_error(problem, profile) <= 1e-9  # own expm propagation
    assert np.all(np.abs(profile.levels) <= problem.u_max)


def _dipping(tau, sign0, dips, depth):
    """``S`` with sign ``sign0`` before ``tau[0]`` flipping at each switch, and dips of ``depth`` (against the sign)."""
    signs = sign0 * (1.0 - 2.0 * (np.arange(tau.size + 1) % 2))

    def S(x):
        x = np.asarray(x, float)
        base = signs[np.searchsorted(tau, x)] * 1.0
        for (a, b), d in zip(dips, depth):
            inside = (x > a) & (x < b)
            bump = np.sin(np.pi * (x - a) / (b - a))
            base = np.where(inside, base - signs[np.searchsorted(tau, x)] * (1.0 + d) * 2.0 * bump, base)
        return base

    return S


def test_one_dip_structures_add_one_pulse_each_deepest_dip_first():
    tau = np.array([1.0, 5.0, 9.0])
    dips = [(2.0, 2.4), (3.0, 3.2), (6.0, 6.6)]
    depth = [0.2, 0.9, 0.5]
    S = _dipping(tau, 1.0, dips, depth)
    zeros = np.sort(np.concatenate([tau, np.ravel(dips)]))
    found = one_dip_structures(tau, 1.0, zeros, 1.0, S)
    assert len(found) == 3
    order = []
    for roots in found:
        assert roots.size == tau.size + 2
        extra = np.setdiff1d(roots, tau)
        assert extra.size == 2
        k = next(i for i, (a, b) in enumerate(dips) if a < extra[0] < extra[1] < b)
        order.append(k)
    assert order == [1, 2, 0]  # by depth


def test_one_dip_structures_only_where_they_differ_from_the_edit():
    tau = np.array([1.0, 5.0])
    S = _dipping(tau, 1.0, [(2.0, 2.4)], [0.5])
    assert one_dip_structures(tau, 1.0, np.array([1.0, 2.0, 2.4, 5.0]), 1.0, S) == []  # one clean pair: the edit
    assert one_dip_structures(tau, 1.0, np.array([1.0, 2.0, 5.0]), 1.0, S) == []  # an odd zero inside: no dip
    # a sign change near tau = 0 besides the dip (the edit then takes the zeros as they are): the dip alone
    found = one_dip_structures(tau, 1.0, np.array([0.01, 1.0, 2.0, 2.4, 5.0]), -1.0, S)
    assert len(found) == 1
    extra = np.setdiff1d(found[0], tau)
    assert extra.size == 2 and 2.0 < extra[0] < extra[1] < 2.4


def test_the_structure_search_is_bounded_however_many_dips(monkeypatch):
    """Every converged extremal dips everywhere: the runs stop at MAX_TRIES + MAX_ALTERNATIVES."""
    runs = []
    n_dips = 20

    def refine(roots, sign0, nuh, T):
        runs.append(roots.size)
        return True, roots, nuh, T, 0.0

    def check(nuh, T, roots, signs):
        edges = np.linspace(0.01, 0.99, 2 * n_dips) * T
        zeros = np.sort(np.concatenate([roots, edges + 1e-7 * len(runs)]))
        return None, zeros, float(signs[0])

    def switching(nuh, x):
        return -np.ones_like(x)  # every dip violated

    out = structure_guess.newton_from_guess(
        None,
        np.ones(3),
        10.0,
        check,
        refine=refine,
        structure=(np.array([5.0]), 1.0),
        switching=switching,
    )
    assert out is None
    assert len(runs) <= structure_guess.MAX_TRIES + structure_guess.MAX_ALTERNATIVES
