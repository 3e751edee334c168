"""Coulomb friction (seed eqs. 2.8-2.11): the contact model and its exact simulation.

Model
-----
One friction contact with sliding velocity ``y = C x`` and Coulomb force ``F``::

    x' = A x + B u - F g sgn(C x)              (sliding, y != 0)
    x' = A x + B u + g lam,  C x' = 0          (stuck: y = 0 and |lam| <= F)

``g`` is the state derivative per newton of friction force (``C g > 0``: the
force opposes the sliding velocity).  While stuck the contact force ``lam``
holds ``y`` at zero: ``lam = -a``, ``a(x, u) = C (A x + B u) / (C g)`` (the
net applied force at the contact, N), so the stuck dynamics are linear too,
``x' = P (A x + B u)`` with ``P = I - g C / (C g)``: the constraint force
enters every state that ``g`` touches.  The contact breaks loose when
``|a|`` exceeds ``F``.

Assumption for a :class:`ModalModel` (:func:`rigid_contact`): friction acts
on the rigid-body coordinate only, ``g = |b0| e_v``, ``y = v`` (friction on
the guide of the whole machine, proportional to mass: the generalised
friction force on every vibration mode is zero).  Then ``a = sgn(b0) u``:
the rigid body sticks while ``|u| <= F`` and the modes keep moving under
``u`` unchanged.  Friction at a physical point of the structure (the cart of
a crane, one mass of a chain) is :func:`contact_at_coordinate`; there the
stuck point changes the modal dynamics through ``P``.

Exactness
---------
Between events the dynamics are affine with constant input, propagated with
:func:`~flexmotion_ros.core.simulation.step_matrices` (matrix exponentials).
Events (the sliding velocity reaching zero, a stuck contact breaking loose)
are located on the exact solution: in closed form when ``C A = alpha C``
(the rigid-body contact: ``y`` obeys a scalar linear ODE), otherwise
bracketed on a grid of 1/16 of the fastest period with a cubic Hermite dip
test and refined by Brent's method on the matrix-exponential solution
(:mod:`.events`).  The simulator never steps over an event.  The planners'
fast path propagates with the modal closed forms instead (:class:`~.closed_form.ClosedForm`).
The contact itself (``g``, ``C``, ``F``) is :mod:`.contact_model`.

The planners built on this simulator: :mod:`.time_optimal` (the
bang-bang extremal, :func:`~.time_optimal.plan_time_optimal_friction`),
its certificate :mod:`.certificate` and the zero-order-hold version
:mod:`.zoh` (:func:`~.zoh.plan_time_optimal_friction_zoh`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from ..model.modal_model import ModalModel
from ..simulation.exact import PiecewiseConstant, step_matrices
from .closed_form import ClosedForm
from .contact_model import Contact, rigid_contact
from .events import first_root

STICK = 0  # mode of a stuck contact (sliding modes are +1, -1)
#: Step matrices a :class:`FrictionSystem` keeps per step length (cleared when full).
STEP_CACHE_SIZE = 256


# ------------------------------------------------------------------ simulation
@dataclass
class FrictionRun:
    """An exact friction simulation.

    Attributes
    ----------
    states : ndarray
        States at the requested times.
    segments : list of tuple
        ``(t0, t1, mode, level)``: ``mode`` +1/-1 sliding, 0 stuck; constant input ``level``.
    events : list of tuple
        ``(t, kind, x)`` with ``kind`` in ``"reversal"``, ``"stick"``, ``"slip"``.
    """

    states: np.ndarray
    segments: list = field(default_factory=list)
    events: list = field(default_factory=list)
    starts: list = field(default_factory=list)  # state at the start of each segment
    #: The step length (s) each segment was propagated by: ``t1 - t0`` can differ from it in the last bit,
    #: and the step matrices are cached per length (the costate sweep then reuses the run's own).
    lengths: list = field(default_factory=list)
    #: With ``record=True``: ``(t, x, mode, segments, events)`` right after each input-level change (index
    #: ``k - 1`` for the change at ``u.breaks[k]``), where a run of an input equal up to there resumes.
    snapshots: list = field(default_factory=list)


class FrictionSystem:
    """``x' = A x + B u - F g sgn(C x)`` with sticking; exact event-located simulation."""

    def __init__(self, A: np.ndarray, B: np.ndarray, contact: Contact) -> None:
        self.A = np.ascontiguousarray(A, float)
        self.B = np.ascontiguousarray(B, float).ravel()
        self.contact = contact
        self.n = self.A.shape[0]
        c = contact
        self.Cg = float(c.C @ c.g)
        self.F = c.force
        self.P = np.eye(self.n) - np.outer(c.g, c.C) / self.Cg
        self.PA = self.P @ self.A
        self.PB = self.P @ self.B
        CA = c.C @ self.A
        self.alpha = float(CA @ c.C) / float(c.C @ c.C)
        # y = C x obeys a scalar ODE when C A = alpha C: closed-form events
        self.scalar = bool(
            np.max(np.abs(CA - self.alpha * c.C)) <= 1e-14 * (np.max(np.abs(CA)) + 1e-300)
        ) or not np.any(CA)
        nz = np.flatnonzero(c.C)
        self.unit = int(nz[0]) if nz.size == 1 and c.C[nz[0]] == 1.0 else None
        self.CB = float(c.C @ self.B)  # C B: the scalar event test's input gain, fixed
        self._wmax = {}
        self._steps: dict[tuple[bool, float], tuple] = {}
        self.fast: ClosedForm | None = None

    @classmethod
    def for_model(cls, model: ModalModel, coulomb_force: float, closed_form: bool = False) -> FrictionSystem:
        """Rigid-body friction on ``model``; ``closed_form=True`` propagates with the modal
        closed forms (the planners' fast path) instead of matrix exponentials."""
        system = cls(model.A(), model.B(), rigid_contact(model, coulomb_force))
        if closed_form:
            system.fast = ClosedForm(model)
        return system

    def transition(self, h: float) -> np.ndarray:
        """``e^{A h}`` (sliding modes)."""
        if self.fast is not None:
            return self.fast.steps(h)[0]
        return step_matrices(self.A, self.B, h)[0]

    # --------------------------------------------------------------- pieces
    def applied(self, x: np.ndarray, level: float) -> float:
        """Net applied force at the contact ``a = C (A x + B u) / (C g)`` (N)."""
        return float(self.contact.C @ (self.A @ x + self.B * level)) / self.Cg

    def mode_at_rest(self, x: np.ndarray, level: float) -> int:
        """With ``y = 0``: stick if ``|a| <= F``, else slide in the direction of ``a``."""
        a = self.applied(x, level)
        return int(np.sign(a)) if abs(a) > self.F else STICK

    def field(self, x: np.ndarray, level: float, mode: int) -> np.ndarray:
        """``x'`` in ``mode``."""
        if mode == STICK:
            return self.PA @ x + self.PB * level
        return self.A @ x + self.B * level - self.F * mode * self.contact.g

    def _affine(self, mode: int, level: float) -> tuple[np.ndarray, np.ndarray]:
        if mode == STICK:
            return self.PA, self.PB * level
        return self.A, self.B * level - self.F * mode * self.contact.g

    def advance(self, x: np.ndarray, level: float, mode: int, h: float) -> np.ndarray:
        """Exact state after ``h`` seconds in ``mode`` (matrix exponentials)."""
        if h <= 0.0:
            return x.copy()
        if self.fast is not None:
            Phi, Gam, Gg = self.fast.steps(h)
            if mode == STICK:  # rigid body held: p and v = 0 stay, the modes move under u
                out = Phi @ x + Gam * level
                out[:2] = x[0], 0.0
                return out
            return Phi @ x + Gam * level - (self.F * mode) * Gg
        key = (mode == STICK, h)
        steps = self._steps.get(key)
        if steps is None:  # the same matrix exponentials, looked up once per (stuck, h): a ZOH check at
            # 1 kHz asks for the same period thousands of times, and step_matrices hashes A, B each time
            if len(self._steps) > STEP_CACHE_SIZE:
                self._steps.clear()
            if mode == STICK:
                steps = (*step_matrices(self.PA, self.PB, h), None)
            else:
                steps = (*step_matrices(self.A, self.B, h), step_matrices(self.A, self.contact.g, h)[1])
            self._steps[key] = steps
        Phi, Gam, Gg = steps
        if mode == STICK:
            out = Phi @ x + Gam * level
        else:
            out = Phi @ x + Gam * level - (self.F * mode) * Gg
        if mode == STICK:
            self._zero_y(out)
        return out

    def _zero_y(self, x: np.ndarray) -> None:
        if self.unit is not None:
            x[self.unit] = 0.0

    # ---------------------------------------------------------------- events
    def next_event(self, x: np.ndarray, level: float, mode: int, h: float) -> float | None:
        """Earliest event time in ``(0, h]`` for the current mode, or None."""
        C = self.contact.C
        if self.scalar:
            if mode == STICK:
                return None  # a = C B u / C g is constant while y = 0
            y0 = float(x[self.unit]) if self.unit is not None else float(C @ x)
            beta = self.CB * level - self.F * mode * self.Cg
            if y0 * mode <= 0.0 or beta * mode >= 0.0:
                return None  # already at zero (moving away) or not decelerating
            al = self.alpha
            if al == 0.0:
                tau = -y0 / beta
            else:
                z = -al * y0 / (al * y0 + beta)
                tau = math.log1p(z) / al if z > -1.0 else math.inf
            return tau if 0.0 < tau <= h else None
        M, m = self._affine(mode, level)
        wmax = self._omega_max(M)
        if mode == STICK:
            w = C @ self.A / self.Cg
            k0 = float(C @ self.B) * level / self.Cg
            roots = [
                first_root(M, m, x, w, k0 - self.F, h, wmax, _affine_step),
                first_root(M, m, x, w, k0 + self.F, h, wmax, _affine_step),
            ]
        else:
            roots = [first_root(M, m, x, C, 0.0, h, wmax, _affine_step, start_sign=mode)]
        roots = [r for r in roots if r is not None]
        return min(roots) if roots else None

    def _omega_max(self, M: np.ndarray) -> float:
        key = M.tobytes()
        if key not in self._wmax:
            self._wmax[key] = float(np.max(np.abs(np.linalg.eigvals(M).imag), initial=0.0))
        return self._wmax[key]

    # ------------------------------------------------------------- simulate
    def run(
        self,
        x0,
        u: PiecewiseConstant,
        times=None,
        lock_after: float = math.inf,
        *,
        record: bool = False,
        resume: tuple[FrictionRun, int] | None = None,
    ) -> FrictionRun:
        """Exact states at ``times`` (default ``u.breaks``); input zero after ``u.duration``.

        ``lock_after``: no events after this time (the mode is frozen), for
        the planner's smooth shooting map only.
        ``record``: keep a snapshot at every input-level change (:attr:`FrictionRun.snapshots`).
        ``resume = (run, j)``: start at the ``j``-th level change of ``run`` (a recorded run from the same
        ``x0`` whose input had the same breaks and levels up to there, and no report time before it): the
        same operations as a run from ``x0``, so the same numbers to the bit, without the common part.
        """
        times = u.breaks if times is None else np.atleast_1d(np.asarray(times, float))
        order = np.argsort(times, kind="stable")
        out = np.empty((times.size, self.n))
        x = np.array(x0, dtype=float)
        # plain Python floats in the loop (one segment per sample of a long sampled move: the loop's own
        # overhead, not the matrix products, was most of an exact check)
        levels, breaks = u.levels.tolist(), u.breaks.tolist()
        targets, rows = times[order].tolist(), order.tolist()
        n_levels, unit, C = len(levels), self.unit, self.contact.C
        starts, segments, events, lengths = [], [], [], []
        k = 0
        level = float(levels[0]) if n_levels else 0.0
        y = float(C @ x)
        mode = int(np.sign(y)) if y != 0.0 else self.mode_at_rest(x, level)
        t = 0.0
        if resume is not None:
            prev, j = resume
            t, xs, mode, n_seg, n_ev = prev.snapshots[j]
            if targets and targets[0] <= t:
                raise ValueError("a resumed run cannot report a time before its snapshot")
            x, k = xs.copy(), j + 1
            level = float(levels[k]) if k < n_levels else 0.0
            starts, segments, lengths = prev.starts[:n_seg], prev.segments[:n_seg], prev.lengths[:n_seg]
            events = prev.events[:n_ev]
        run = FrictionRun(out, segments, events, starts, lengths)
        snapshots = run.snapshots
        if resume is not None and record:
            snapshots.extend(resume[0].snapshots[: resume[1] + 1])
        ti, n_times = 0, len(targets)
        while ti < n_times:
            target = targets[ti]
            t_int = breaks[k + 1] if k < n_levels else math.inf
            seg_end = min(t_int, target)
            if seg_end > t:
                if mode != STICK and t < lock_after:
                    y = float(x[unit]) if unit is not None else float(C @ x)
                    if y * mode <= 0.0:  # at (or, by rounding, just past) zero velocity
                        new = self.mode_at_rest(x, level)
                        if new != mode:
                            events.append((t, "stick" if new == STICK else "reversal", x.copy()))
                        self._zero_y(x)
                        mode = new
                h = seg_end - t
                tau = self.next_event(x, level, mode, h) if t < lock_after else None
                step = h if tau is None else tau
                starts.append(x.copy())
                x = self.advance(x, level, mode, step)
                segments.append((t, t + step, mode, level))
                lengths.append(step)
                t = t + step if tau is not None and tau < h else seg_end
                if tau is not None:
                    if mode == STICK:
                        mode = int(np.sign(self.applied(x, level)))
                        events.append((t, "slip", x.copy()))
                    else:
                        if unit is not None:
                            x[unit] = 0.0
                        new = self.mode_at_rest(x, level)
                        events.append((t, "stick" if new == STICK else "reversal", x.copy()))
                        mode = new
                    continue
            if t >= target:
                out[rows[ti]] = x
                ti += 1
                continue
            if t >= t_int:  # next input level
                k += 1
                level = float(levels[k]) if k < n_levels else 0.0
                if mode == STICK:
                    new = self.mode_at_rest(x, level)
                    if mode == STICK and new != STICK:
                        events.append((t, "slip", x.copy()))
                    mode = new
                if record:
                    snapshots.append((t, x.copy(), mode, len(segments), len(events)))
        return run


def _affine_step(M: np.ndarray, m: np.ndarray, h: float) -> tuple[np.ndarray, np.ndarray]:
    """``x(h) = Phi x + Gam`` for ``x' = M x + m`` (``m`` a constant vector)."""
    Phi, Gam = (
        step_matrices(M, m, h) if np.any(m) else (step_matrices(M, np.zeros(M.shape[0]), h)[0], np.zeros(M.shape[0]))
    )
    return Phi, Gam


def simulate_coulomb(model: ModalModel, x0, u: PiecewiseConstant, coulomb_force: float, times=None) -> np.ndarray:
    """Exact states of ``model`` with Coulomb friction ``coulomb_force`` (N) on the rigid body.

    Parameters
    ----------
    model : ModalModel
    x0 : array_like
        Full initial state ``[p, v, q1, q1', ...]``.
    u : PiecewiseConstant
        Input (zero after ``u.duration``).
    coulomb_force : float
        Friction force ``F >= 0`` (N): ``v' = c v + b0 u - |b0| F sgn(v)``;
        stuck while ``v = 0`` and ``|u| <= F`` (the modes keep moving).
    times : array_like, optional
        Report times (s); default ``u.breaks``.

    Returns
    -------
    ndarray, shape ``(len(times), n_states)``
    """
    system = FrictionSystem(model.A(), model.B(), rigid_contact(model, coulomb_force))
    return system.run(x0, u, times).states


def simulate_contact(A, B, contact: Contact, x0, u: PiecewiseConstant, times=None) -> FrictionRun:
    """Exact simulation of any linear system with one friction contact (states and events)."""
    return FrictionSystem(A, B, contact).run(x0, u, times)
