"""Markov parameters from arbitrary input, and the eigensystem realization algorithm (ERA).

For ``x_{k+1} = A x_k + B u_k``, ``y_k = C x_k + D u_k`` the Markov parameters
are ``Y_0 = D``, ``Y_k = C A^{k-1} B``.  Two least-squares estimates:

* :func:`fir_markov`: ``y_k = sum_{j<m} Y_j u_{k-j}``, which assumes the
  response has died out after ``m`` samples (the textbook estimate, and what
  ``control.markov`` computes).  Lightly damped modes ring for thousands of
  samples, so this is for checks only.
* :func:`observer_markov` (OKID, Juang, Phan, Horta and Longman 1993): an ARX
  model ``y_k = D u_k + sum_{j=1}^{p} (beta_j u_{k-j} + alpha_j y_{k-j}) + d``
  is the input-output form of the system with an observer that makes it decay
  in ``p`` samples, so ``p`` need only exceed the order, whatever the damping;
  ``d`` absorbs a sensor offset.  The system's Markov parameters follow by
  ``Y_k = beta_k + alpha_k D + sum_{i=1}^{k-1} alpha_i Y_{k-i}`` (``beta_k = alpha_k = 0``
  for ``k > p``).  An order ``p`` well above the system's also absorbs coloured
  equation error, which is why output noise biases it little.

:func:`era` then builds the block Hankel matrices of ``Y_1, Y_2, ...``, keeps the
``r`` largest singular values and returns the balanced realization (Juang and
Pappa 1985), the same construction as ``control.eigensys_realization``.
"""

from __future__ import annotations

import numpy as np
from scipy.signal import lfilter


def fir_markov(u: np.ndarray, y: np.ndarray, m: int) -> np.ndarray:
    """First ``m`` Markov parameters ``[D, CB, CAB, ...]`` by least squares on a finite impulse response.

    Parameters
    ----------
    u : ndarray, shape ``(N,)``
        Input, from rest.
    y : ndarray, shape ``(N,)`` or ``(N, q)``
        Outputs.
    m : int
        Number of Markov parameters.

    Returns
    -------
    ndarray, shape ``(m,)`` or ``(m, q)``
    """
    u = np.asarray(u, dtype=float)
    n = u.size
    Phi = np.zeros((n, m))
    for j in range(m):
        Phi[j:, j] = u[: n - j]
    return np.linalg.lstsq(Phi, np.asarray(y, dtype=float), rcond=None)[0]


def observer_markov(u: np.ndarray, y: np.ndarray, order: int, count: int) -> np.ndarray:
    """System Markov parameters ``Y_0 .. Y_count`` from an ARX (observer) model of order ``order``.

    Parameters
    ----------
    u : ndarray, shape ``(N,)``
        Input.
    y : ndarray, shape ``(N, q)``
        Outputs (a constant offset is allowed).
    order : int
        ARX order ``p`` (``p q`` at least the system order).
    count : int
        Highest Markov index returned.

    Returns
    -------
    ndarray, shape ``(count + 1, q)``
    """
    u = np.asarray(u, dtype=float)
    y = np.asarray(y, dtype=float)
    if y.ndim == 1:
        y = y[:, None]
    n, q = y.shape
    p = int(order)
    rows = n - p
    cols = [u[p:]]
    for j in range(1, p + 1):
        cols.append(u[p - j : n - j])
        cols.extend(y[p - j : n - j, i] for i in range(q))
    cols.append(np.ones(rows))
    R = np.column_stack(cols)
    scale = np.linalg.norm(R, axis=0)
    scale[scale == 0.0] = 1.0
    theta = np.linalg.lstsq(R / scale, y[p:], rcond=None)[0] / scale[:, None]  # (1 + p (1 + q) + 1, q)
    D = theta[0]
    beta = np.zeros((p + 1, q))
    alpha = np.zeros((p + 1, q, q))
    for j in range(1, p + 1):
        base = 1 + (j - 1) * (1 + q)
        beta[j] = theta[base]
        alpha[j] = theta[base + 1 : base + 1 + q].T  # y_k = ... + alpha_j y_{k-j}
    if q == 1:  # the recursion is the impulse response of (D + sum beta_j z^-j) / (1 - sum alpha_j z^-j)
        impulse = np.zeros(count + 1)
        impulse[0] = 1.0
        num = np.concatenate([D, beta[1:, 0]])
        den = np.concatenate([[1.0], -alpha[1:, 0, 0]])
        return lfilter(num, den, impulse)[:, None]
    Y = np.zeros((count + 1, q))
    Y[0] = D
    for k in range(1, count + 1):
        acc = beta[k] + alpha[k] @ D if k <= p else np.zeros(q)
        for i in range(1, min(k - 1, p) + 1):
            acc = acc + alpha[i] @ Y[k - i]
        Y[k] = acc
    return Y


def hankel_matrices(markov: np.ndarray, rows: int, cols: int) -> tuple[np.ndarray, np.ndarray]:
    """Block Hankel matrices ``H0[i, j] = Y_{1+i+j}`` and ``H1[i, j] = Y_{2+i+j}`` (single input)."""
    Y = np.asarray(markov, dtype=float)
    if Y.ndim == 1:
        Y = Y[:, None]
    q = Y.shape[1]
    H0 = np.empty((rows * q, cols))
    H1 = np.empty((rows * q, cols))
    for i in range(rows):
        H0[i * q : (i + 1) * q, :] = Y[1 + i : 1 + i + cols].T
        H1[i * q : (i + 1) * q, :] = Y[2 + i : 2 + i + cols].T
    return H0, H1


def era(
    markov: np.ndarray, order: int, rows: int | None = None, cols: int | None = None
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Balanced realization of order ``order`` from Markov parameters (Hankel SVD).

    Parameters
    ----------
    markov : ndarray, shape ``(K,)`` or ``(K, q)``
        ``Y_0 = D, Y_1, ...``; needs ``K >= rows + cols + 1``.
    order : int
        State dimension ``r``.
    rows, cols : int, optional
        Block rows and columns of the Hankel matrix (default ``2 r`` each).

    Returns
    -------
    A, B, C, D : ndarray
        Discrete-time realization (``B`` shape ``(r, 1)``, ``C`` shape ``(q, r)``).
    singular_values : ndarray
        All singular values of ``H0``: the gap after the ``r``-th says how many states the data supports.
    """
    Y = np.asarray(markov, dtype=float)
    if Y.ndim == 1:
        Y = Y[:, None]
    q = Y.shape[1]
    r = int(order)
    rows = 2 * r if rows is None else int(rows)
    cols = 2 * r if cols is None else int(cols)
    if Y.shape[0] < rows + cols + 1:
        raise ValueError(f"era needs {rows + cols + 1} Markov parameters, got {Y.shape[0]}")
    H0, H1 = hankel_matrices(Y, rows, cols)
    U, S, Vt = np.linalg.svd(H0, full_matrices=False)
    Ur, Sr, Vr = U[:, :r], S[:r], Vt[:r, :]
    si = 1.0 / np.sqrt(Sr)
    A = (si[:, None] * (Ur.T @ H1 @ Vr.T)) * si[None, :]
    B = (np.sqrt(Sr)[:, None] * Vr)[:, :1]
    C = (Ur * np.sqrt(Sr)[None, :])[:q, :]
    return A, B, C, Y[0][:, None], S
