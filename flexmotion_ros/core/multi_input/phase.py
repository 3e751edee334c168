"""``sync=phase``: the fastest move whose rigid bodies travel the straight line from start to target.

With one input per rigid body (``b0`` square, invertible) and one viscous
term ``c`` for every rigid body, the path ``p(t) = p0 + Delta s(t)``
(``Delta = target - p0``) is followed exactly by ``u(t) = d v(t)`` with
``d = b0^{-1} Delta`` and ``s'' = c s' + v``: one scalar "path input" ``v``
drives every input in fixed proportion.  The modes then see ``v`` through
the gains ``b d``, so the straight-line move is a single-input problem
(:class:`~flexmotion_ros.core.model.modal_model.ModalModel` with ``b0 = 1``)
with the bound ``|v| <= min_i u_max_i / |d_i|``, solved and certified by the
existing single-input planner.  Its guarantee: the time-optimal move among
straight-line moves, at rest, exactly; in general slower than ``T*``.

Refused, with the reason, when the dynamics do not allow a straight line
followed exactly: a free final position, ``b0`` not square and invertible,
different ``c``, an initial rigid-body velocity off the line, a vibrating
mode that no input combination along the line reaches, or two vibrating
modes at one frequency.
"""

from __future__ import annotations

import time

import numpy as np

from ..errors import ConfigError
from ..model.boundary import MoveProblem, state_to_rest
from ..model.modal_model import ModalModel
from ..time_optimal.solver import plan_time_optimal
from ..tolerances import REPEATED_FREQUENCY_RTOL
from .assembly import check_final_state
from .problem import MultiMoveProblem
from .results import MultiCertificate, MultiProfile, SyncMode


def _refuse(reason: str) -> ConfigError:
    return ConfigError("sync", f"phase is not possible here: {reason}; use sync: time or none")


def path_problem(problem: MultiMoveProblem) -> tuple[MoveProblem, np.ndarray]:
    """The single-input path problem of a straight-line move and the input direction ``d``.

    Returns ``(MoveProblem, d)``: ``u_i(t) = d_i v(t)`` with ``v`` the path
    problem's input; path coordinate ``s`` from 0 to 1.
    """
    model = problem.model
    if any(t is None for t in problem.targets):
        raise _refuse("every rigid body needs a target (the line runs from the start to the target)")
    if model.k != model.m or model.k == 0:
        raise _refuse(f"it needs one input per rigid body (k = m), got k = {model.k}, m = {model.m}")
    B0 = model.B0
    if np.linalg.cond(B0) > 1e12:
        raise _refuse("b0 is not invertible")
    c = np.asarray(model.c)
    if np.any(c != c[0]):
        raise _refuse(f"the rigid bodies have different viscous terms c = {list(model.c)}")
    x0 = problem.x0
    p0 = x0[0 : 2 * model.k : 2]
    v0 = x0[1 : 2 * model.k : 2]
    delta = np.array([float(t) for t in problem.targets]) - p0
    dd = float(delta @ delta)
    if dd == 0.0:
        raise _refuse("the rigid bodies are already at their targets (no line to follow)")
    sd0 = float(delta @ v0) / dd
    if np.max(np.abs(v0 - delta * sd0)) > 1e-12 * max(float(np.max(np.abs(v0))), 1e-300) and np.any(v0):
        raise _refuse("the initial rigid-body velocity does not point along the line")
    d = np.linalg.solve(B0, delta)
    with np.errstate(divide="ignore"):
        V = float(np.min(np.where(d != 0.0, problem.u_max / np.abs(d), np.inf)))
    g = model.Bm @ d if model.n_modes else np.zeros(0)
    q0 = x0[2 * model.k :: 2]
    qd0 = x0[2 * model.k + 1 :: 2]
    keep = []
    gmax = float(np.max(np.abs(g), initial=0.0))
    for l in range(model.n_modes):
        if abs(g[l]) <= 1e-14 * max(gmax, 1e-300):
            if q0[l] != 0.0 or qd0[l] != 0.0:
                raise _refuse(
                    f"mode {model.mode_names[l]!r} vibrates but no input combination along the line reaches it"
                )
            continue
        keep.append(l)
    # modes sharing one frequency are driven identically by v: at rest they stay proportional (one mode)
    merged: list[list[int]] = []
    for l in keep:
        for grp in merged:
            j = grp[0]
            if (
                abs(model.omega[l] - model.omega[j]) <= REPEATED_FREQUENCY_RTOL * model.omega[j]
                and model.zeta[l] == model.zeta[j]
            ):
                grp.append(l)
                break
        else:
            merged.append([l])
    omega, zeta, gains, xs = [], [], [], [0.0, sd0]
    for grp in merged:
        if len(grp) > 1 and any(q0[l] != 0.0 or qd0[l] != 0.0 for l in grp):
            names = [model.mode_names[l] for l in grp]
            raise _refuse(f"modes {names} share one frequency and vibrate: one path input cannot damp both")
        l = grp[0]
        omega.append(model.omega[l])
        zeta.append(model.zeta[l])
        if len(grp) > 1:  # y with q_l = g_l y: one mode of gain 1
            gains.append(1.0)
            xs += [0.0, 0.0]
        else:
            gains.append(float(g[l]))
            xs += [float(q0[l]), float(qd0[l])]
    single = ModalModel(b0=1.0, c=float(c[0]), omega=tuple(omega), zeta=tuple(zeta), b=tuple(gains))
    return state_to_rest(single, V, np.array(xs), 1.0), d


def plan_phase(problem: MultiMoveProblem, t0: float | None = None) -> MultiProfile:
    """The time-optimal straight-line move (see the module notes), checked exactly."""
    t0 = time.perf_counter() if t0 is None else t0
    path, d = path_problem(problem)
    prof = plan_time_optimal(path)
    m = problem.model.m
    switch_times = [np.asarray(prof.switch_times, float) for _ in range(m)]
    levels = [np.clip(d[i] * np.asarray(prof.levels, float), -problem.u_max[i], problem.u_max[i]) for i in range(m)]
    T = float(prof.duration)
    final_state, err, rel = check_final_state(problem, switch_times, levels, T)
    cert = prof.certificate
    mc = MultiCertificate(
        passed=bool(cert.passed),
        costate_initial=np.zeros(problem.kept.size),
        switch_residual=float(cert.switch_residual),
        extra_zeros=int(cert.extra_zeros),
        unproved_cells=int(cert.unproved_cells),
        sign_consistent=bool(cert.sign_consistent),
        hamiltonian_spread=0.0,
        lower_bound=float(cert.lower_bound or 0.0),
        duality_margin=0.0,
        message=("optimal among straight-line moves: " + cert.message),
        parts=(
            {
                "role": "path",
                "inputs": list(problem.model.inputs),
                "duration": T,
                "direction": [float(v) for v in d],
                "path_costate_initial": [float(v) for v in cert.costate_initial],
            },
        ),
    )
    return MultiProfile(
        problem=problem,
        switch_times=tuple(switch_times),
        levels=tuple(levels),
        duration=T,
        final_state=final_state,
        final_state_error=err,
        final_state_error_relative=rel,
        certificate=mc,
        sync=SyncMode.PHASE,
        solve_time_s=time.perf_counter() - t0,
        extra={"path_problem": path, "path_profile": prof, "path_direction": d},
    )
