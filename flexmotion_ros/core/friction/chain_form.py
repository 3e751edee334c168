"""The equality rows of a chain-form friction LP (:meth:`~.sampled_lp.FrictionLP.solve`), in compressed columns."""

from __future__ import annotations

import numpy as np
from scipy.sparse import csc_array


def chain_matrix(G: np.ndarray, w: np.ndarray, v0: float, ev: float, drive: np.ndarray, fric: np.ndarray) -> csc_array:
    """The equality rows of :meth:`~.sampled_lp.FrictionLP.solve` built column by column in compressed columns (what
    HiGHS takes; the same matrix as the triplets ``coo -> csr -> csc`` it was assembled from before, in
    a fraction of the time: the conversions were a third of a structure LP's cost).

    Rows: ``nI`` arrival rows ``G^T z - mu w = 0``, then ``y_0 - v0 mu = 0``, then the chain
    ``y_{k+1} - ev y_k + drive_k z_k + fric_k mu = 0``.  Columns: ``z_0..z_{K-1}``, ``y_0..y_K``, ``mu``.
    Explicit zeros are kept (the solver's input drops them).
    """
    K, nI = G.shape
    chain0 = nI + 1  # row of the chain equation of sample 0
    # z_k: the arrival rows, then its chain row
    z_rows = np.empty((K, nI + 1), dtype=np.int32)
    z_rows[:, :nI] = np.arange(nI, dtype=np.int32)
    z_rows[:, nI] = chain0 + np.arange(K, dtype=np.int32)
    z_vals = np.column_stack([G, drive])
    # y_j: its own chain row (j - 1, coefficient 1; y_0: the initial row) and the next one (-ev; none for y_K)
    y_rows = np.empty((K + 1, 2), dtype=np.int32)
    y_rows[:, 0] = np.arange(nI, nI + K + 1, dtype=np.int32)
    y_rows[:K, 1] = chain0 + np.arange(K, dtype=np.int32)
    y_vals = np.empty((K + 1, 2))
    y_vals[:, 0] = 1.0
    y_vals[:K, 1] = -ev
    # mu: every row
    mu_rows = np.arange(nI + 1 + K, dtype=np.int32)
    mu_vals = np.concatenate([-w, [-v0], fric])
    indices = np.concatenate([z_rows.ravel(), y_rows.ravel()[:-1], mu_rows])
    data = np.concatenate([z_vals.ravel(), y_vals.ravel()[:-1], mu_vals])
    indptr = np.empty(2 * K + 3, dtype=np.int32)
    indptr[0] = 0
    counts = np.concatenate([np.full(K, nI + 1), np.full(K, 2), [1], [mu_rows.size]])
    np.cumsum(counts, out=indptr[1:])
    return csc_array((data, indices, indptr), shape=(nI + 1 + K, 2 * K + 2))
