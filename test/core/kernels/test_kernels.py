"""The compiled kernels (numba) against their numpy references, and the planner on both paths.

Each kernel is checked on random inputs against the numpy code it replaces;
the end-to-end test plans random 1-3-mode moves with the compiled path on and
off.  Without numba (the ``fast`` extra absent) the kernel tests are skipped
as such: the numpy path is then the only one.
"""

from __future__ import annotations

import math
import os
import subprocess
import sys

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from flexmotion_ros.core import ModalModel, motion_to_rest, plan_time_optimal, rest_to_rest
from flexmotion_ros.core.kernels import AVAILABLE, backend, warm_up
from flexmotion_ros.core.kernels import roots as kroots
from flexmotion_ros.core.kernels import smoothed as ksmoothed
from flexmotion_ros.core.simulation.modal_response import ModalResponse
from flexmotion_ros.core.time_optimal import lean
from flexmotion_ros.core.time_optimal.root_refine import hermite_root, refine_roots
from flexmotion_ros.core.time_optimal.switching import isolate_roots, root_grid

needs_numba = pytest.mark.skipif(not AVAILABLE, reason="numba absent (the 'fast' extra): the numpy path only")
SETTINGS = {"deadline": None, "max_examples": 25}


@pytest.fixture(scope="module")
def compiled():
    """The compiled path on for the tests that use it (restored after; module scope: no state per example)."""
    saved = backend.ACTIVE
    backend.ACTIVE = True
    yield
    backend.ACTIVE = saved


@st.composite
def responses(draw, max_modes: int = 3):
    """A random modal response and a co-state: 0-3 modes, damped or not, friction or not, position or not."""
    n = draw(st.integers(0, max_modes))
    w = sorted(draw(st.lists(st.floats(0.3, 30.0), min_size=n, max_size=n, unique=True)))
    zeta = [draw(st.sampled_from([0.0, 0.02, 0.3])) for _ in w]
    b = [draw(st.floats(0.1, 10.0)) * draw(st.sampled_from([-1.0, 1.0])) for _ in w]
    c = draw(st.sampled_from([0.0, -0.7, -5.0]))
    model = ModalModel(b0=draw(st.floats(0.1, 10.0)), c=c, omega=tuple(w), zeta=tuple(zeta), b=tuple(b))
    resp = ModalResponse(model, include_position=draw(st.booleans()))
    nu = np.array(draw(st.lists(st.floats(-1.0, 1.0), min_size=resp.n, max_size=resp.n)))
    return resp, nu


@needs_numba
@settings(**SETTINGS)
@given(responses(), st.integers(0, 8), st.floats(0.01, 20.0))
def test_switching_orders_is_the_modal_responses_switching(case, k, T):
    resp, nu = case
    tau = np.linspace(0.0, T, 37)
    ref = np.atleast_2d(np.array(resp.switching(nu, tau, order=k) if k else resp.switching(nu, tau)))
    got = kroots.switching_orders(tau, k, *resp.switching_terms(nu, k))
    # per order: rounding of exp / sin / cos and of the sums, relative to the terms' magnitude
    scale = (np.abs(resp.switching_terms(nu, k)[7]).sum(axis=0) if resp.w.size else 0.0) + np.max(np.abs(ref), axis=1)
    assert np.all(np.abs(got - ref) <= 1e-13 * (np.atleast_1d(scale)[:, None] + 1.0))


@needs_numba
@settings(**SETTINGS)
@given(responses(), st.floats(0.01, 20.0))
def test_derivative_bound_from_is_the_numpy_bound(case, T):
    resp, nu = case
    tau = np.linspace(0.0, T, 19)
    ref = resp.switching_derivative_bound_from(nu, 9, tau)
    got = kroots.derivative_bound_from(tau, *_bound_args(resp, nu, 9))
    assert np.allclose(got, ref, rtol=1e-13, atol=0.0)


def _bound_args(resp, nu, order):
    rigid, amp = resp.switching_derivative_bound_terms(nu, order)
    return rigid, resp.c, np.ascontiguousarray(resp.sig, dtype=float), amp


@needs_numba
@settings(**SETTINGS)
@given(st.lists(st.tuples(st.floats(-1.0, 1.0), st.floats(-1.0, 1.0), st.floats(-5, 5), st.floats(-5, 5)), min_size=1))
def test_hermite_start_is_hermite_root(rows):
    fa, fb, da, db = (np.array(x) for x in zip(*rows))
    a, b = np.zeros(fa.size), np.full(fa.size, 0.5)
    ref = hermite_root(a, b, fa, fb, da, db)
    got = np.array([kroots.hermite_start(0.0, 0.5, *r) for r in zip(fa, fb, da, db)])
    assert np.array_equal(got, ref)


@needs_numba
@settings(**SETTINGS)
@given(responses(), st.floats(0.05, 20.0))
def test_isolate_and_refine_gives_the_numpy_roots(compiled, case, T):
    resp, nu = case
    grid = root_grid(resp, T, density=2.0)
    ref = isolate_roots(resp, nu, T, grid)  # the numpy reference (compiled=False)
    got = isolate_roots(resp, nu, T, grid, compiled=True)
    assert got.unproved == ref.unproved and got.sign0 == ref.sign0
    assert got.roots.size == ref.roots.size
    # each root to its precision: rounding of S over |S'| (a tangency resolves worse than 1e-13 T)
    if ref.roots.size:
        _, dS = resp.switching(nu, ref.roots, derivative=True)
        noise = 1e3 * np.finfo(float).eps * resp.switching_magnitude(nu, T)[0]
        assert np.all(np.abs(got.roots - ref.roots) <= np.maximum(1e-13 * T, noise / np.abs(dS)))


@needs_numba
def test_refine_bracket_is_refine_roots():
    resp = ModalResponse(ModalModel(b0=0.5, c=-0.3, omega=(2.0, 7.0), zeta=(0.05, 0.0), b=(1.0, -0.4)))
    nu = np.array([0.3, -1.0, 0.2, 0.5, -0.1, 0.05])
    tau = np.linspace(0.0, 10.0, 2001)
    S = resp.switching(nu, tau)
    i = np.flatnonzero(np.sign(S[:-1]) != np.sign(S[1:]))
    assert i.size >= 2
    a, b, fa, fb = tau[i], tau[i + 1], S[i], S[i + 1]
    mag = resp.switching_magnitude(nu, 10.0)[0]
    ref = refine_roots(lambda t: resp.switching(nu, t, derivative=True), a, b, fa, fb, mag)
    noise = 16.0 * np.finfo(float).eps * mag
    terms = resp.switching_terms(nu, 1)
    got = [kroots.refine_bracket(*x, 0.5 * (x[0] + x[1]), noise, *terms) for x in zip(a, b, fa)]
    assert np.allclose(got, ref, rtol=0.0, atol=1e-14 * 10.0)


@needs_numba
@pytest.mark.parametrize("eps_rel", [0.1, 0.005])
def test_smoothed_newton_is_the_numpy_inner_problem(monkeypatch, eps_rel):
    # the lean warm start's inner problem, both paths from the same start: the same BLAS and LAPACK
    # calls, so the same iterates (bit for bit on this machine; 1e-12 leaves room for another BLAS)
    problem = rest_to_rest(ModalModel(b0=1.0, c=0.0, omega=(3.0, 11.0), zeta=(0.01, 0.0), b=(0.8, -0.5)), 2.0, 1.5)
    resp = ModalResponse(problem.model, problem.include_position)
    x0 = problem.x0 - problem.model.rest_state(problem.target)
    out = {}
    for active in (False, True):
        monkeypatch.setattr(backend, "ACTIVE", active)
        lm = lean.LeanMove(resp, x0, 2.0, 2.0)
        out[active] = lean._inner(lm, 2.5, None, eps_rel)  # noqa: SLF001 - the function whose two paths are compared
    for ref, got in zip(out[False], out[True]):
        assert np.allclose(got, ref, rtol=1e-12, atol=1e-15)


@needs_numba
def test_solve_or_none_is_gesv_and_flags_a_singular_matrix():
    A = np.array([[4.0, 1.0], [2.0, 3.0]])
    x, ok = ksmoothed.solve_or_none(A, np.array([1.0, 2.0]))
    assert ok and np.allclose(A @ x, [1.0, 2.0])
    assert not ksmoothed.solve_or_none(np.zeros((2, 2)), np.ones(2))[1]


def _random_move(i: int):
    rng = np.random.default_rng([7, i])
    n = int(rng.integers(1, 4))
    w = np.cumprod(
        np.concatenate([[math.exp(rng.uniform(math.log(0.3), math.log(30.0)))], rng.uniform(1.05, 4.0, n - 1)])
    )
    zeta = tuple(rng.uniform(0.0, 0.3, n)) if rng.random() < 0.5 else (0.0,) * n
    model = ModalModel(b0=rng.uniform(0.2, 5.0), c=0.0, omega=tuple(w), zeta=zeta, b=tuple(rng.uniform(-5, 5, n)))
    u_max = rng.uniform(0.5, 5.0)
    if rng.random() < 0.8:
        return rest_to_rest(model, u_max, model.natural_distance(u_max) * math.exp(rng.uniform(-5, 3)))
    return motion_to_rest(model, u_max, model.b0 * u_max / w[0] * rng.uniform(0.1, 5.0))


@needs_numba
@pytest.mark.parametrize("i", range(12))
def test_both_paths_plan_the_same_certified_optimum(monkeypatch, i):
    problem = _random_move(i)
    plans = {}
    for active in (False, True):
        monkeypatch.setattr(backend, "ACTIVE", active)
        plans[active] = plan_time_optimal(problem)
    ref, got = plans[False], plans[True]
    assert got.certificate.status == ref.certificate.status
    assert np.array_equal(got.levels, ref.levels) and got.switch_times.size == ref.switch_times.size
    assert abs(got.duration - ref.duration) <= 1e-13 * ref.duration
    assert np.all(np.abs(got.switch_times - ref.switch_times) <= 1e-13 * ref.duration)


def test_the_environment_variable_forces_the_numpy_path():
    code = "from flexmotion_ros.core.kernels import backend; print(backend.ACTIVE, backend.REQUESTED)"
    env = dict(os.environ, FLEXMOTION_KERNELS="numpy")
    out = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True, check=True)
    assert out.stdout.split() == ["False", "numpy"]


@needs_numba
def test_warm_up_compiles_every_kernel(compiled):
    assert warm_up() >= 0.0
    for kernel in (kroots.isolate_and_refine, kroots.switching_orders, ksmoothed.smoothed_newton):
        assert kernel.signatures  # compiled (or loaded from the cache) for the types the planners pass


@needs_numba
def test_after_warm_up_a_plan_compiles_nothing(compiled):
    # the types a plan passes (read-only memoised coefficients, C-ordered arrays) are the ones warm_up compiled:
    # a new signature would compile for seconds inside the first plan of a node
    warm_up()
    kernels = (kroots.isolate_and_refine, ksmoothed.smoothed_newton)
    before = [len(k.signatures) for k in kernels]
    plan_time_optimal(_random_move(0))
    plan_time_optimal(_random_move(3))
    assert [len(k.signatures) for k in kernels] == before


def test_warm_up_is_free_on_the_numpy_path(monkeypatch):
    monkeypatch.setattr(backend, "ACTIVE", False)
    assert warm_up() == 0.0


def test_without_numba_the_numpy_path_plans():
    # the 'fast' extra absent: numba cannot be imported, the kernels are plain Python never called, the plan is made
    code = (
        "import sys; sys.modules['numba'] = None\n"
        "from flexmotion_ros.core.kernels import backend, warm_up\n"
        "from flexmotion_ros.core import ModalModel, plan_time_optimal, rest_to_rest\n"
        "m = ModalModel(b0=0.5, c=0.0, omega=(2.0**0.5,), zeta=(0.0,), b=(1.0,))\n"
        "p = plan_time_optimal(rest_to_rest(m, 1.0, 1.0))\n"
        "print(backend.AVAILABLE, backend.ACTIVE, warm_up(), round(p.duration, 4), p.certified)\n"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.split() == ["False", "False", "0.0", "4.2179", "True"]  # Wie-Bernstein's optimum
