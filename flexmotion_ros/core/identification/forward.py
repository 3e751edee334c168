"""The parametrised output model of the fit: prediction, exact Jacobian, and the linear part alone.

Parameter vector ``theta`` (one layout for the whole subpackage)::

    [c, omega_1, zeta_1, ..., omega_N, zeta_N,  b0,  g_11 ... g_1N, ..., g_M1 ... g_MN,  o_1 ... o_M]

for ``M`` outputs and ``N`` modes; output ``j`` is
``o_j + a0_j b0 R_j(c) + sum_i g_ji M_j(omega_i, zeta_i)`` with the unit
responses of :mod:`~flexmotion_ros.core.identification.response`.  The
first ``2N + 1`` entries enter nonlinearly, the rest linearly.
"""

from __future__ import annotations

import numpy as np
from scipy.linalg import solve_triangular

from .data import IdentificationData
from .response import unit_response, unit_response_and_derivatives

#: Relative size of R's smallest diagonal entry below which the linear fit falls back to an SVD.
LINEAR_RANK_TOL = 1e-10


class ForwardModel:
    """Predictions and Jacobians of ``N`` modes seen by the outputs of ``data``.

    Parameters
    ----------
    data : IdentificationData
    n_modes : int
        Number of vibration modes ``N``.
    """

    def __init__(self, data: IdentificationData, n_modes: int) -> None:
        self.data = data
        self.n_modes = int(n_modes)
        self.n_outputs = len(data.outputs)
        self.kinds = tuple(o.kind for o in data.outputs)
        self.a0 = np.array([o.rigid_weight for o in data.outputs])
        self.n_nonlinear = 1 + 2 * self.n_modes
        self.n_params = self.n_nonlinear + 1 + self.n_outputs * self.n_modes + self.n_outputs
        self.y = [o.samples for o in data.outputs]

    # ------------------------------------------------------------ layout
    def names(self) -> list[str]:
        """Parameter names in ``theta`` order."""
        out = ["c"]
        for i in range(self.n_modes):
            out += [f"omega[{i}]", f"zeta[{i}]"]
        out.append("b0")
        for j in range(self.n_outputs):
            out += [f"gain[{j}][{i}]" for i in range(self.n_modes)]
        out += [f"offset[{j}]" for j in range(self.n_outputs)]
        return out

    def split(self, theta: np.ndarray) -> tuple[float, np.ndarray, np.ndarray, float, np.ndarray, np.ndarray]:
        """``c, omega, zeta, b0, gains (M x N), offsets (M)`` from ``theta``."""
        theta = np.asarray(theta, dtype=float)
        n, m = self.n_modes, self.n_outputs
        c = float(theta[0])
        omega = theta[1 : 1 + 2 * n : 2].copy()
        zeta = theta[2 : 2 + 2 * n : 2].copy()
        k = self.n_nonlinear
        b0 = float(theta[k])
        gains = theta[k + 1 : k + 1 + m * n].reshape(m, n).copy()
        offsets = theta[k + 1 + m * n :].copy()
        return c, omega, zeta, b0, gains, offsets

    def join(self, c, omega, zeta, b0, gains, offsets) -> np.ndarray:
        """The inverse of :meth:`split`."""
        nl = [float(c)]
        for w, z in zip(omega, zeta):
            nl += [float(w), float(z)]
        gains = np.asarray(gains, dtype=float).reshape(self.n_outputs, self.n_modes)
        return np.concatenate([nl, [float(b0)], gains.ravel(), np.asarray(offsets, dtype=float).ravel()])

    # ------------------------------------------------------------ linear part
    def basis(self, c: float, omega, zeta) -> list[np.ndarray]:
        """Per output, the columns the linear parameters multiply: ``[a0 R, M_1 .. M_N, 1]``."""
        dt, u = self.data.dt, self.data.u
        cache: dict = {}
        out = []
        for j, kind in enumerate(self.kinds):
            if kind not in cache:
                cols = [unit_response(kind, True, dt, u, c)]
                cols += [unit_response(kind, False, dt, u, w, z) for w, z in zip(omega, zeta)]
                cache[kind] = cols
            cols = cache[kind]
            out.append(np.column_stack([self.a0[j] * cols[0], *cols[1:], np.ones(u.size)]))
        return out

    def linear_fit(self, c: float, omega, zeta, weights=None) -> tuple[np.ndarray, np.ndarray]:
        """Best linear parameters for fixed ``c, omega, zeta`` (variable projection).

        ``b0`` is shared by the outputs, so all outputs are solved together
        (each weighted by ``weights[j]``, default 1).  Returns ``theta`` and the
        residual sum of squares per output.
        """
        n, m = self.n_modes, self.n_outputs
        w = np.ones(m) if weights is None else np.asarray(weights, dtype=float)
        cols = self.basis(c, omega, zeta)
        n_lin = 1 + m * n + m
        rows = []
        rhs = []
        for j in range(m):
            block = np.zeros((self.data.samples, n_lin))
            block[:, 0] = cols[j][:, 0]
            block[:, 1 + j * n : 1 + (j + 1) * n] = cols[j][:, 1 : 1 + n]
            block[:, 1 + m * n + j] = 1.0
            rows.append(w[j] * block)
            rhs.append(w[j] * self.y[j])
        G = np.vstack(rows)
        scale = np.linalg.norm(G, axis=0)
        scale[scale == 0.0] = 1.0
        Gs, b = G / scale, np.concatenate(rhs)
        q, r = np.linalg.qr(Gs)  # ten times cheaper than an SVD-based lstsq on tall thin columns
        d = np.abs(np.diag(r))
        if d.min(initial=1.0) > LINEAR_RANK_TOL * d.max(initial=1.0):
            lin = solve_triangular(r, q.T @ b) / scale
        else:  # (nearly) dependent columns, e.g. two modes at one frequency: minimum-norm solution
            lin = np.linalg.lstsq(Gs, b, rcond=None)[0] / scale
        theta = np.concatenate([[c], np.column_stack([omega, zeta]).ravel(), lin])
        rss = np.array([float(np.sum((self.y[j] - p) ** 2)) for j, p in enumerate(self.predict(theta))])
        return theta, rss

    # ------------------------------------------------------------ prediction
    def predict(self, theta: np.ndarray) -> list[np.ndarray]:
        """Predicted outputs (one array per output)."""
        c, omega, zeta, b0, gains, offsets = self.split(theta)
        cols = self.basis(c, omega, zeta)
        out = []
        for j in range(self.n_outputs):
            coef = np.concatenate([[b0], gains[j], [offsets[j]]])
            out.append(cols[j] @ coef)
        return out

    def predict_and_jacobian(self, theta: np.ndarray) -> tuple[list[np.ndarray], list[np.ndarray]]:
        """Predicted outputs and, per output, ``d y_j / d theta`` (samples x parameters), exact."""
        c, omega, zeta, b0, gains, offsets = self.split(theta)
        dt, u = self.data.dt, self.data.u
        n, m, k = self.n_modes, self.n_outputs, self.n_nonlinear
        cache: dict = {}
        preds, jacs = [], []
        for j, kind in enumerate(self.kinds):
            if kind not in cache:
                r, (dr,) = unit_response_and_derivatives(kind, True, dt, u, (c,))
                modes = [unit_response_and_derivatives(kind, False, dt, u, (w, z)) for w, z in zip(omega, zeta)]
                cache[kind] = (r, dr, modes)
            r, dr, modes = cache[kind]
            J = np.zeros((u.size, self.n_params))
            a0 = self.a0[j]
            y = offsets[j] + a0 * b0 * r
            J[:, 0] = a0 * b0 * dr
            J[:, k] = a0 * r
            for i, (mi, (dw, dz)) in enumerate(modes):
                g = gains[j, i]
                y = y + g * mi
                J[:, 1 + 2 * i] = g * dw
                J[:, 2 + 2 * i] = g * dz
                J[:, k + 1 + j * n + i] = mi
            J[:, k + 1 + m * n + j] = 1.0
            preds.append(y)
            jacs.append(J)
        return preds, jacs
