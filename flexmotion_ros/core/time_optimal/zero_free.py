"""Blocks of grid cells on which the switching function ``S`` is proved zero-free, without sampling.

``system.switching_zero_free`` (the rigid part dominating the modes' bound)
proves blocks of :data:`EXCLUSION_BLOCK` cells free of zeros of ``S``;
root isolation (:func:`~.switching.isolate_roots`) and the structure guess
(:func:`examined_points`) then sample only the cells left, so their work
grows with where ``S`` can vanish, not with ``T``.
"""

from __future__ import annotations

import numpy as np

#: Cells per block of the zero-free test of :func:`cells_to_examine`.
EXCLUSION_BLOCK = 16
#: About this many blocks at the coarsest level of the test (:func:`unproved_blocks`).
EXCLUSION_TOP = 64


def unproved_blocks(system, nu: np.ndarray, grid: np.ndarray, margin: float):
    """Blocks of :data:`EXCLUSION_BLOCK` cells not proved zero-free, and whether any block was.

    Returns ``(starts, ends, any_free)`` (cell indices of the blocks left to
    examine; None if ``system`` has no test or the grid is short), or None.
    The test of an interval covers every interval inside it (the rigid part
    is monotone and the modal bound decreasing), so it runs coarse to fine:
    from about :data:`EXCLUSION_TOP` blocks of ``EXCLUSION_BLOCK 2^k`` cells,
    halving only the blocks not proved.  The blocks left are exactly those the
    test at ``EXCLUSION_BLOCK`` cells leaves, at a cost that grows with where
    ``S`` can vanish and ``log T``, not with ``T`` (a 2000 s move of a
    60 rad/s mode: 65,000 block tests before, a few hundred now).
    """
    test = getattr(system, "switching_zero_free", None)
    n = grid.size - 1
    if test is None or n < 4 * EXCLUSION_BLOCK:
        return None
    size = EXCLUSION_BLOCK
    while n > 2 * size * EXCLUSION_TOP:
        size *= 2
    starts = np.arange(0, n, size)
    ends = np.minimum(starts + size, n)
    any_free = False
    while True:
        free = test(nu, grid[starts], grid[ends], margin)
        any_free = any_free or bool(free.any())
        starts, ends = starts[~free], ends[~free]
        if size == EXCLUSION_BLOCK or starts.size == 0:
            return starts, ends, any_free
        size //= 2
        mid = np.minimum(starts + size, ends)
        second = mid < ends
        starts = np.concatenate([starts, mid[second]])
        ends = np.concatenate([mid, ends[second]])
        order = np.argsort(starts, kind="stable")
        starts, ends = starts[order], ends[order]


def _ranges(starts: np.ndarray, ends: np.ndarray) -> np.ndarray:
    """The integers of the half-open ranges ``[starts, ends)``, concatenated."""
    lengths = ends - starts
    if lengths.size == 0:
        return np.empty(0, dtype=np.int64)
    offsets = np.repeat(starts - np.concatenate([[0], np.cumsum(lengths)[:-1]]), lengths)
    return np.arange(int(lengths.sum())) + offsets


def cell_points(cells: np.ndarray) -> np.ndarray:
    """``union1d(cells, cells + 1)`` for strictly increasing ``cells``, in linear time (no sort).

    Interleaved, ``c_0, c_0 + 1, c_1, c_1 + 1, ...`` is already non-decreasing;
    only repeats (neighbouring cells) are dropped.  (``union1d`` sorted and
    hashed 40,000 cells per root isolation: 10 % of an 8-mode plan.)
    """
    if cells.size == 0:
        return cells
    both = np.empty(2 * cells.size, dtype=cells.dtype)
    both[0::2] = cells
    both[1::2] = cells + 1
    return both[np.concatenate([[True], np.diff(both) > 0])]


def cells_to_examine(system, nu: np.ndarray, grid: np.ndarray, noise: float) -> np.ndarray | None:
    """Indices of the grid cells not proved zero-free by ``system.switching_zero_free``; None: all of them.

    Blocks of :data:`EXCLUSION_BLOCK` cells are tested (coarse to fine:
    :func:`unproved_blocks`).  Systems without the test (the robust augmented
    one) keep every cell.
    """
    blocks = unproved_blocks(system, nu, grid, noise)
    if blocks is None or not blocks[2]:
        return None
    return _ranges(blocks[0], blocks[1])


def examined_points(system, nu: np.ndarray, grid: np.ndarray, margin: float) -> np.ndarray:
    """``grid`` without the points inside blocks where ``|S| > margin`` is proved (see :func:`cells_to_examine`).

    Block boundaries stay, so consecutive points of the result either are
    consecutive grid points or bound a block on which ``S`` keeps its sign
    and ``|S| > margin``.
    """
    blocks = unproved_blocks(system, nu, grid, margin)
    if blocks is None or not blocks[2]:
        return grid
    starts, ends, _ = blocks
    # the points of the kept blocks, ends included (sorted; adjacent blocks share an end), and 0 and T
    idx = _ranges(starts, ends + 1)
    idx = np.concatenate([[0], idx, [grid.size - 1]])
    idx = idx[np.concatenate([[True], np.diff(idx) > 0])]
    return grid[idx]
