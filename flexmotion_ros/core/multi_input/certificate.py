"""Pontryagin checks of a multi-input bang-bang extremal (seed eqs. 2.30-2.37 with ``m`` inputs).

One co-state ``lambda_0`` must make every input's switching function
``B_i^T e^{-A^T t} lambda_0`` (eq. 2.33):

1. vanish at input ``i``'s switches (eq. 2.37, one system per input, one ``lambda_0``);
2. change sign nowhere else on ``[0, T]`` (zeros isolated with proof,
   :func:`~flexmotion_ros.core.time_optimal.switching.isolate_roots`);
3. have the sign of (2.34) on every interval: ``u_i = -rho u_max_i sgn(B_i^T lambda)``;
4. keep the Hamiltonian ``1 + lambda^T (A x + B u)`` at zero along the motion:
   ``lambda^T (A x + B u)`` negative and constant, with ``x`` from the exact
   matrix-exponential simulation and ``lambda`` propagated by ``expm(A^T h)``.

Together with an exact final state, this proves the extremal time-optimal
(minimum-peak at fixed ``T`` when ``rho < 1``) for the linear system; the
planner adds the independent weak-duality bound of :mod:`.dual`.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.linalg import expm

from ..time_optimal.root_refine import root_tolerance
from ..time_optimal.switching import isolate_roots, sample_grid
from .exact import VectorPiecewise, simulate
from .response import MultiResponse


@dataclass(frozen=True, kw_only=True)
class PontryaginChecks:
    """The figures of the four checks (see the module docstring)."""

    switch_residual: float
    extra_zeros: int
    unproved_cells: int
    sign_consistent: bool
    hamiltonian_spread: float
    costate_initial: np.ndarray
    reasons: tuple
    #: per input, the proved sign changes of ``S_i`` on ``[0, T]`` (time-to-go, s)
    zeros_tau: tuple = ()

    @property
    def passed(self) -> bool:
        return not self.reasons


SWITCH_RESIDUAL_TOL = 1e-8
HAMILTONIAN_TOL = 1e-6


def pontryagin_checks(
    resp: MultiResponse,
    A: np.ndarray,
    B: np.ndarray,
    x0: np.ndarray,
    nu: np.ndarray,
    T: float,
    switch_times: list,
    levels: list,
    free_time: bool = True,
    singular=(),
) -> PontryaginChecks:
    """Check an extremal: ``nu = -lambda(T)`` (any positive scale), forward switch times and levels per input.

    ``free_time``: the duration is free (minimum time): the Hamiltonian must be
    zero for a positive scaling of ``lambda``.  Otherwise (lowest peak at a
    fixed ``T``) it must only be constant.  ``singular``: inputs whose
    ``B_i^T lambda`` must vanish identically (they do not set the time; their
    levels come from a later stage): checked for that instead of (2.34).
    """
    m = resp.m
    extra = 0
    unproved = 0
    sign_ok = True
    sw_res = 0.0
    grid0 = sample_grid(resp, T, density=2.0)
    zeros = []
    S_all = resp.switching_all(nu, grid0)[0]
    top = float(np.max(np.abs(np.delete(S_all, list(singular), axis=0)), initial=0.0)) or 1.0
    sing_res = max((float(np.max(np.abs(S_all[i]))) / top for i in singular), default=0.0)
    for i in range(m):
        if i in singular:
            zeros.append(np.empty(0))
            continue
        sys_i = resp.for_input(i)
        tau_sw = np.sort(T - np.asarray(switch_times[i], float))
        grid = grid0
        if tau_sw.size and grid.size > 2:  # keep every switch well inside a cell
            h = grid[1] - grid[0]
            k = np.clip(np.searchsorted(tau_sw, grid), 1, tau_sw.size) - 1
            dist = np.minimum(np.abs(grid - tau_sw[k]), np.abs(grid - tau_sw[np.minimum(k + 1, tau_sw.size - 1)]))
            near = dist < 0.25 * h
            near[[0, -1]] = False
            grid = grid[~near]
        iso = isolate_roots(sys_i, nu, T, grid)
        unproved += iso.unproved
        zeros.append(iso.roots)
        tol = root_tolerance(sys_i, nu, T, tau_sw, 1e-9)
        matched = np.zeros(tau_sw.size, dtype=bool)
        for z in iso.roots:
            j = int(np.argmin(np.abs(tau_sw - z))) if tau_sw.size else -1
            if j >= 0 and not matched[j] and abs(tau_sw[j] - z) <= tol[j]:
                matched[j] = True
            else:
                extra += 1
        extra += int(np.count_nonzero(~matched))
        S_grid = sys_i.switching(nu, grid)
        s_max = float(np.max(np.abs(S_grid))) or 1.0
        breaks = np.concatenate([[0.0], np.asarray(switch_times[i], float), [T]])
        mids_tau = T - 0.5 * (breaks[:-1] + breaks[1:])
        S_mid = sys_i.switching(nu, mids_tau)
        lv = np.asarray(levels[i], float)
        if not (np.all(np.sign(S_mid) == np.sign(lv)) and np.all(np.abs(lv) == np.abs(lv[0]))):
            sign_ok = False
        if tau_sw.size:
            sw_res = max(sw_res, float(np.max(np.abs(sys_i.switching(nu, tau_sw)))) / s_max)
    # co-state along the motion by matrix exponentials (independent of the closed forms)
    starts = [np.asarray(s, float) for s in switch_times]
    breaks = np.unique(np.concatenate([[0.0, T], *starts]))
    mids = 0.5 * (breaks[:-1] + breaks[1:])
    rows = np.column_stack(
        [np.asarray(levels[i], float)[np.searchsorted(starts[i], mids, side="right")] for i in range(m)]
    )
    u = VectorPiecewise(breaks, rows)
    states = simulate(A, B, x0, u)
    lam = np.empty((breaks.size, A.shape[0]))
    lam[-1] = -np.asarray(nu, float)
    for k in range(breaks.size - 2, -1, -1):
        lam[k] = expm(A.T * (breaks[k + 1] - breaks[k])) @ lam[k + 1]
    u_after = np.vstack([rows, rows[-1:]])
    drift = np.einsum("ij,ij->i", lam, states @ A.T)
    push = np.einsum("ij,ij->i", lam @ B, u_after)
    kappa = drift + push
    parts = float(np.max(np.abs(drift) + np.abs(push))) or 1.0
    mean = float(np.mean(kappa))
    spread = float(np.max(np.abs(kappa - mean))) / parts if (mean < 0 or not free_time) else np.inf
    lam0 = lam[0] * (-1.0 / mean if mean < 0 else 1.0)
    reasons = []
    if sing_res > SWITCH_RESIDUAL_TOL:
        reasons.append(f"a singular input's switching function is not identically zero ({sing_res:.2e})")
    if sw_res > SWITCH_RESIDUAL_TOL:
        reasons.append(f"a switching function is not zero at its switch (residual {sw_res:.2e})")
    if extra:
        reasons.append(f"switching functions have {extra} sign change(s) that are not switches")
    if unproved:
        reasons.append(f"{unproved} cell(s) could not be proved zero-free or monotone")
    if not sign_ok:
        reasons.append("levels do not follow u_i = -u_max_i sgn(B_i^T lambda)")
    if not spread <= HAMILTONIAN_TOL:
        reasons.append(f"Hamiltonian not constant zero (relative spread {spread:.2e})")
    return PontryaginChecks(
        switch_residual=sw_res,
        extra_zeros=extra,
        unproved_cells=unproved,
        sign_consistent=sign_ok,
        hamiltonian_spread=spread,
        costate_initial=lam0,
        reasons=tuple(reasons),
        zeros_tau=tuple(zeros),
    )
